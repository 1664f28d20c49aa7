"""msid fit --method multi end to end: records written by NumPy (closed-form
ring-downs and a state-space recursion, independent of msid), the model file checked
against the truth, the schema and itself (determinism); bad input refused with one
message, a non-zero exit and no file."""
import numpy as np

from helpers import load_json, run, run_ok, validate

FN = np.array([80.0, 130.0, 200.0])
ZETA = np.array([0.15, 0.1, 0.2])
TS = 1e-3


def ringdown(rng, T):
    w = 2 * np.pi * FN
    sig, wd = -ZETA * w, w * np.sqrt(1 - ZETA ** 2)
    t = np.arange(T)[:, None] * TS
    a, b = rng.standard_normal(3), rng.standard_normal(3)
    return (np.exp(sig * t) * (a * np.cos(wd * t) + b * np.sin(wd * t))).sum(axis=1)


def write_csv(path, cols, header):
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=",".join(header), comments="", fmt="%.17g")


def m1_files(tmp_path, n=6, seed=3):
    rng = np.random.default_rng(seed)
    ys = [ringdown(rng, int(rng.integers(60, 121))) for _ in range(n)]
    sd = np.sqrt(np.mean(np.concatenate(ys) ** 2)) / 100.0
    files = []
    for i, y in enumerate(ys):
        f = tmp_path / f"r{i + 1}.csv"
        write_csv(f, [y + sd * rng.standard_normal(y.size)], ["y1"])
        files.append(f)
    return files


def exp_args(files):
    out = []
    for f in files:
        out += ["--experiment", f]
    return out


def test_ringdowns_modes_and_crb(tmp_path):
    files = m1_files(tmp_path)
    out = tmp_path / "m.json"
    r = run_ok("fit", "--method", "multi", "--order", "6", "--fs", "1000", *exp_args(files), "-o", out)
    assert "mode" in r.stdout
    doc = load_json(out)
    validate(doc, "msid-model-1")
    assert doc["method"] == "multi" and doc["n_inputs"] == 0 and doc["multi"]["converged"] is not False
    modes = doc["multi"]["modes"]
    assert len(modes) == 3
    for m, fn, z in zip(modes, FN, ZETA):
        assert abs(m["fn_hz"] - fn) < 4 * m["sd_fn_hz"] + 1e-9, (m, fn)
        assert abs(m["zeta"] - z) < 4 * m["sd_zeta"] + 1e-12, (m, z)
        assert m["sd_fn_hz"] < 0.01 * fn
    # the reported covariance and the independently computed CRB at the estimate agree
    assert doc["multi"]["cramer_rao"]["rel_diff_cov"] < 0.05
    assert len(doc["multi"]["records"]) == len(files)
    # determinism: the same files give the same bytes
    out2 = tmp_path / "m2.json"
    run_ok("fit", "--method", "multi", "--order", "6", "--fs", "1000", *exp_args(files), "-o", out2)
    assert out.read_bytes() == out2.read_bytes()


def io_plant():
    """The 4th-order input-output plant of the I/O tests: poles p (one of each pair), a(q^-1) coefficients
    alpha, numerator beta and the observer-form A whose first column is -alpha."""
    p = [0.9 * np.exp(0.5j), 0.8 * np.exp(1.4j)]
    alpha = np.real(np.poly([p[0], np.conj(p[0]), p[1], np.conj(p[1])]))[1:]
    beta = np.array([1.0, -0.5, 0.3, 0.2])
    A = np.zeros((4, 4))
    A[:, 0] = -alpha
    A[:3, 1:] = np.eye(3)
    return p, alpha, beta, A


def test_input_output_transients(tmp_path):
    rng = np.random.default_rng(5)
    p, alpha, beta, A = io_plant()
    files = []
    for i, T in enumerate([50, 90, 140, 200]):
        x = 3 * rng.standard_normal(4)
        u = rng.standard_normal(T)
        y = np.empty(T)
        for t in range(T):
            y[t] = x[0]
            x = A @ x + beta * u[t]
        f = tmp_path / f"io{i}.csv"
        write_csv(f, [u, y + 0.02 * rng.standard_normal(T)], ["u1", "y1"])
        files.append(f)
    out = tmp_path / "io.json"
    run_ok("fit", "--method", "multi", "--order", "4", *exp_args(files), "-o", out)
    doc = load_json(out)
    validate(doc, "msid-model-1")
    par = doc["parameters"]
    th = np.array(par["values"])
    sd = np.sqrt(np.diag(np.array(par["cov"])))
    truth = np.concatenate([alpha, beta])
    assert np.all(np.abs(th - truth) < 4.5 * sd), (th, truth, sd)
    assert doc["n_inputs"] == 1 and "lmfd" in doc


def refused(tmp_path, args, words, code=None):
    out = tmp_path / "bad.json"
    r = run("fit", "--method", "multi", *args, "-o", out)
    assert r.returncode != 0
    if code is not None:
        assert r.returncode == code
    msg = r.stderr.strip()
    assert msg.count("\n") == 0, msg          # one message
    for w in words:
        assert w in msg, msg
    assert not out.exists()                   # nothing written
    return msg


def test_bad_input(tmp_path):
    files = m1_files(tmp_path, n=2)
    short = tmp_path / "short.csv"
    write_csv(short, [np.arange(5.0)], ["y1"])
    refused(tmp_path, ["--order", "6", *exp_args([files[0], short])], ["short.csv", "too few"])
    two = tmp_path / "two.csv"
    write_csv(two, [np.arange(100.0), np.arange(100.0)], ["y1", "y2"])
    refused(tmp_path, ["--order", "6", *exp_args([files[0], two])], ["two.csv", "same channels"])
    nan = tmp_path / "nan.csv"
    y = np.linspace(1, 0, 100)
    y[40] = np.nan
    write_csv(nan, [y], ["y1"])
    refused(tmp_path, ["--order", "6", *exp_args([files[0], nan])], ["nan.csv"])
    tiny = tmp_path / "tiny.csv"
    write_csv(tiny, [np.linspace(1, 0, 12)], ["y1"])
    refused(tmp_path, ["--order", "6", "--experiment", tiny], ["too few samples"])
    refused(tmp_path, exp_args(files), ["--order"], code=2)
    refused(tmp_path, ["--order", "6"], ["--experiment"], code=2)
    refused(tmp_path, ["--order", "6", "--feedthrough", "yes", *exp_args(files)], ["feedthrough"], code=2)


def test_two_channel_ringdowns(tmp_path):
    """Two outputs sharing the modes with different amplitudes (mode shapes) per record."""
    rng = np.random.default_rng(9)
    files = []
    for i in range(5):
        T = int(rng.integers(60, 121))
        y1, y2 = ringdown(rng, T), ringdown(rng, T)
        f = tmp_path / f"c{i}.csv"
        write_csv(f, [y1 + 0.01 * rng.standard_normal(T), y2 + 0.01 * rng.standard_normal(T)], ["y1", "y2"])
        files.append(f)
    out = tmp_path / "c.json"
    run_ok("fit", "--method", "multi", "--order", "6", "--fs", "1000", *exp_args(files), "-o", out)
    doc = load_json(out)
    validate(doc, "msid-model-1")
    assert doc["n_outputs"] == 2 and doc["order"] == 12   # observer form: n per output
    for m, fn, z in zip(doc["multi"]["modes"], FN, ZETA):
        assert abs(m["fn_hz"] - fn) < 4 * m["sd_fn_hz"], (m, fn)
        assert abs(m["zeta"] - z) < 4 * m["sd_zeta"], (m, z)


def ar_noise(rng, c, n, sd):
    """Stationary AR noise c(q^-1) v = e scaled to standard deviation sd (burn-in 500 samples)."""
    v = np.zeros(n + 500)
    e = rng.standard_normal(n + 500)
    for t in range(n + 500):
        v[t] = e[t] - sum(c[k] * v[t - k - 1] for k in range(len(c)) if t - k - 1 >= 0)
    v = v[500:]
    return v * sd / np.sqrt(np.mean(v ** 2))


def test_order_auto_modes_validate(tmp_path):
    """--order auto picks 6 on M1 ring-downs; msid modes reads the free-response model; msid validate
    checks it on fresh records (consistent) and refuses an FRF for it."""
    files = m1_files(tmp_path, n=6, seed=11)
    fresh_dir = tmp_path / "fresh"
    fresh_dir.mkdir()
    fresh = m1_files(fresh_dir, n=6, seed=12)
    out = tmp_path / "auto.json"
    r = run_ok("fit", "--method", "multi", "--order", "auto", "--fs", "1000", *exp_args(files), "-o", out)
    assert "<- chosen" in r.stdout
    doc = load_json(out)
    validate(doc, "msid-model-1")
    sel = doc["multi"]["order_selection"]
    assert sel["chosen"] == 6 and sel["rule"] == "mdl" and doc["multi"]["alpha"].__len__() == 6
    assert [row["order"] for row in sel["rows"]] == list(range(1, 13))
    assert sel["hankel_gap_order"] == 6
    # msid modes on the free-response model: frequencies and damping with sd
    mo = tmp_path / "modes.json"
    r = run_ok("modes", out, "-o", mo)
    assert "+-" in r.stdout
    m = load_json(mo)
    assert m["format"] == "msid-modes/1" and len(m["modes"]) == 3
    for x, fn, z in zip(m["modes"], FN, ZETA):
        assert abs(x["fn"] - fn) < 4 * x["sd_fn"] and abs(x["zeta"] - z) < 4 * x["sd_zeta"]
    # validate on fresh records: consistent; on its own records: only whiteness counts
    rep = tmp_path / "rep.json"
    r = run_ok("validate", out, *exp_args(fresh), "-o", rep)
    assert "verdict: consistent" in r.stdout
    v = load_json(rep)
    assert v["kind"] == "records" and not v["own_records"] and v["p_value_cost"] > 0.025 and v["p_value_whiteness"] > 0.025
    assert v["dof"] == sum(np.loadtxt(f, skiprows=1).size - 6 for f in fresh)
    r = run_ok("validate", out, *exp_args(files))
    assert "own records" in r.stdout
    # a wrong model (order 4 forced) fails validation on fresh records
    bad = tmp_path / "o4.json"
    run_ok("fit", "--method", "multi", "--order", "4", "--fs", "1000", *exp_args(files), "-o", bad)
    r = run_ok("validate", bad, *exp_args(fresh))
    assert "NOT consistent" in r.stdout
    # an FRF cannot validate a free-response model: one message, non-zero exit
    r = run("validate", out, tmp_path / "none.json")
    assert r.returncode != 0 and "--experiment" in r.stderr and r.stderr.strip().count("\n") == 0


def test_coloured_noise_cli(tmp_path):
    """AR(2) noise: --noise-ar given, estimated from the residuals, and from noise-only records."""
    rng = np.random.default_rng(21)
    c = np.array([-2 * 0.8 * np.cos(2 * np.pi * 0.13), 0.64])
    ys = [ringdown(rng, int(rng.integers(80, 121))) for _ in range(8)]
    sd = np.sqrt(np.mean(np.concatenate(ys) ** 2)) / 100.0
    files = []
    for i, y in enumerate(ys):
        f = tmp_path / f"r{i}.csv"
        write_csv(f, [y + ar_noise(rng, c, y.size, sd)], ["y1"])
        files.append(f)
    noise = tmp_path / "noise.csv"
    write_csv(noise, [ar_noise(rng, c, 4000, sd)], ["y1"])
    given = tmp_path / "given.json"
    run_ok("fit", "--method", "multi", "--order", "6", "--fs", "1000", "--noise-ar", f"{c[0]:.17g},{c[1]:.17g}",
           *exp_args(files), "-o", given)
    doc = load_json(given)
    validate(doc, "msid-model-1")
    assert doc["settings"]["weight"] == "noise-ar" and np.allclose(doc["multi"]["noise"]["ar"], c)
    for m, fn, z in zip(doc["multi"]["modes"], FN, ZETA):
        assert abs(m["fn_hz"] - fn) < 4 * m["sd_fn_hz"] and abs(m["zeta"] - z) < 4 * m["sd_zeta"]
    assert doc["multi"]["cramer_rao"]["rel_diff_cov"] < 0.05
    est = tmp_path / "est.json"
    run_ok("fit", "--method", "multi", "--order", "6", "--fs", "1000", "--noise-ar-order", "2", *exp_args(files), "-o", est)
    assert np.abs(np.array(load_json(est)["multi"]["noise"]["ar"]) - c).max() < 0.15
    rec = tmp_path / "rec.json"
    run_ok("fit", "--method", "multi", "--order", "6", "--fs", "1000", "--noise-ar-order", "2", "--noise-record", noise,
           *exp_args(files), "-o", rec)
    d = load_json(rec)["multi"]["noise"]
    assert np.abs(np.array(d["ar"]) - c).max() < 0.05 and "noise record" in d["source"]
    # validation with the noise model: white residuals; the white-noise fit's residuals are not
    r = run_ok("validate", given, *exp_args(files))
    assert "verdict: consistent" in r.stdout
    white = tmp_path / "white.json"
    run_ok("fit", "--method", "multi", "--order", "6", "--fs", "1000", *exp_args(files), "-o", white)
    r = run_ok("validate", white, *exp_args(files))
    assert "NOT consistent" in r.stdout
    # refusals: a non-stationary AR model, --noise-record without an order, both noise options
    refused(tmp_path, ["--order", "6", "--noise-ar", "0,1.5", *exp_args(files)], ["stationary"], code=2)
    refused(tmp_path, ["--order", "6", "--noise-record", noise, *exp_args(files)], ["--noise-ar-order"], code=2)
    refused(tmp_path, ["--order", "6", "--noise-ar", "0.5", "--noise-ar-order", "2", *exp_args(files)], ["either"], code=2)
    refused(tmp_path, ["--order", "0:x", *exp_args(files)], ["--order"], code=2)


def test_noisy_inputs_cli(tmp_path):
    """--input-noise-ratio: white noise on u and y (sigma_u = sigma_y), errors-in-variables estimate."""
    rng = np.random.default_rng(31)
    p, alpha, beta, A = io_plant()
    files = []
    sd = 0.15
    for i in range(10):
        T = int(rng.integers(60, 200))
        x = 3 * rng.standard_normal(4)
        u = rng.standard_normal(T)
        y = np.empty(T)
        for t in range(T):
            y[t] = x[0]
            x = A @ x + beta * u[t]
        f = tmp_path / f"e{i}.csv"
        write_csv(f, [u + sd * rng.standard_normal(T), y + sd * rng.standard_normal(T)], ["u1", "y1"])
        files.append(f)
    out = tmp_path / "eiv.json"
    run_ok("fit", "--method", "multi", "--order", "4", "--input-noise-ratio", "1", *exp_args(files), "-o", out)
    doc = load_json(out)
    validate(doc, "msid-model-1")
    assert doc["multi"]["errors_in_variables"]["input_noise_ratio"] == 1.0
    th = np.array(doc["parameters"]["values"])
    cov = np.array(doc["parameters"]["cov"])
    e = th - np.concatenate([alpha, beta])
    assert e @ np.linalg.solve(cov, e) < 26.1   # chi2(8) 99.9%
    assert abs(np.sqrt(doc["multi"]["noise_variance"]) - sd) < 0.2 * sd
    ring = m1_files(tmp_path, n=2)
    refused(tmp_path, ["--order", "6", "--input-noise-ratio", "1", *exp_args(ring)], ["input columns"], code=2)


def fir_record(path, seed, T=3000, noise=0.01):
    """Two white inputs through 8-tap FIRs (direct term included, which the default model without
    feedthrough lacks), one output: a plant whose equation-error starts can have poles outside the unit circle."""
    rng = np.random.default_rng(seed)
    b1, b2 = rng.standard_normal(8), rng.standard_normal(8)
    u1, u2 = rng.standard_normal(T), rng.standard_normal(T)
    y = np.convolve(u1, b1)[:T] + np.convolve(u2, b2)[:T] + noise * rng.standard_normal(T)
    write_csv(path, [u1, u2, y], ["u1", "u2", "y1"])
    return path


def test_start_with_nonfinite_cost(tmp_path):
    """A start whose model response overflows over the record takes no part in the choice: seed 1
    made Steiglitz-McBride unstable (its cost NaN, the file refused at /multi/starts/1/cost), seed 10
    gives Prony a pole outside the unit circle (listed failed, with cost null and the reason, and
    retried reflected). Every start failing: test_fit_multi's test_failed_starts (the reader refuses
    samples large enough to overflow every cost)."""
    out = tmp_path / "s1.json"
    run_ok("fit", "--method", "multi", "--order", "8", "--experiment", fir_record(tmp_path / "s1.csv", 1), "-o", out)
    doc = load_json(out)
    validate(doc, "msid-model-1")
    m = doc["multi"]
    assert [s["start"] for s in m["starts"]] == ["prony", "sm"]
    assert all(np.isfinite(s["cost"]) and "failed" not in s for s in m["starts"])
    assert np.isfinite(m["cost"]) and m["cost"] <= min(s["cost"] for s in m["starts"])

    out = tmp_path / "s10.json"
    r = run_ok("fit", "--method", "multi", "--order", "8", "--experiment", fir_record(tmp_path / "s10.csv", 10), "-o", out)
    assert "start prony failed" in r.stdout
    doc = load_json(out)
    validate(doc, "msid-model-1")
    m = doc["multi"]
    st = {s["start"]: s for s in m["starts"]}
    assert st["prony"]["cost"] is None and "outside the unit circle" in st["prony"]["failed"]
    assert np.isfinite(st["prony-reflected"]["cost"]) and np.isfinite(st["sm"]["cost"])
    assert m["best_start"] in ("sm", "prony-reflected")
    assert m["cost"] <= min(st[k]["cost"] for k in ("sm", "prony-reflected"))



def test_fir_poles_at_origin(tmp_path):
    """An exact FIR plant (8 taps from one sample's delay, no noise): the fitted poles sit at z = 0,
    where ln z has no value; the modes carry null there and the file is written."""
    rng = np.random.default_rng(2)
    T = 3000
    b1, b2 = rng.standard_normal(8), rng.standard_normal(8)
    u1, u2 = rng.standard_normal(T), rng.standard_normal(T)
    y = np.convolve(u1, np.r_[0.0, b1])[:T] + np.convolve(u2, np.r_[0.0, b2])[:T]
    f = tmp_path / "fir.csv"
    write_csv(f, [u1, u2, y], ["u1", "u2", "y1"])
    out = tmp_path / "fir.json"
    run_ok("fit", "--method", "multi", "--order", "8", "--experiment", f, "-o", out)
    doc = load_json(out)
    validate(doc, "msid-model-1")
    b = np.array(doc["parameters"]["values"])[8:]
    assert np.allclose(b, np.r_[b1, b2], atol=1e-6)
