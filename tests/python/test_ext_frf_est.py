"""msid.frf(method="lpm" | "etfe"): the FRF of arbitrary records in process, against `msid frf --method
lpm|etfe` on the same samples (the same bits), with the command line's messages for bad requests."""
import numpy as np
import pytest

from conftest import msid as cli, refuse_processes
from npy_cli import cli_error, cli_frf

import msid

N = 4096
# output i from input j: taps of a short FIR filter
TAPS = [[[1.0, 0.5, 0.25], [0.2, -0.1, 0.05]], [[0.3, 0.2, 0.0], [1.0, -0.4, 0.1]]]


def fir(u, nu, ny):
    y = np.zeros((u.shape[0], ny))
    for i in range(ny):
        for j in range(nu):
            for k, c in enumerate(TAPS[i][j]):
                y[k:, i] += c * u[:len(u) - k, j]
    return y


def noise_records(nu, ny, m, seed=3, noise=0.05):
    """m records of white-noise inputs through the FIR plant, with output noise."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(m):
        u = rng.standard_normal((N, nu))
        out.append(np.hstack([u, fir(u, nu, ny) + noise * rng.standard_normal((N, ny))]))
    return out


def periodic_records(nu, ny, m, M=256, seed=4, noise=0.05):
    """m records of a random periodic input (period M, N / M periods) through the plant (steady state)."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(m):
        u1 = rng.standard_normal((M, nu))
        u = np.tile(u1, (N // M + 1, 1))
        y = fir(u, nu, ny)[M:]
        out.append(np.hstack([u[M:], y + noise * rng.standard_normal((N, ny))]))
    return out


def assert_same_bits(a, b):
    for k in ("G", "cov", "dof", "cov_known_input", "dof_known_input", "freq", "freq_hz", "bins"):
        x, y = getattr(a, k), getattr(b, k)
        assert (x is None) == (y is None), k
        if x is not None:
            assert x.shape == y.shape and np.array_equal(x, y), k
    for k in ("method", "noise_cov", "lpm", "etfe", "n_inputs", "n_outputs", "period_samples", "fs_hz"):
        assert a.meta.get(k) == b.meta.get(k), k
    assert [{k: v for k, v in e.items()} for e in a.line_extra] == [{k: v for k, v in e.items()} for e in b.line_extra]


@pytest.mark.parametrize("nu, ny, m, py_opts, cli_opts", [
    (1, 1, 1, {}, []),
    (1, 2, 2, {"order": 1, "window": 4, "band": (0.01, 0.2)}, ["--order", 1, "--window", 4, "--band", "0.01:0.2"]),
    (2, 2, 3, {"fs": 1000.0, "band": "20:300", "threads": 1}, ["--fs", 1000, "--band", "20:300", "--threads", 1]),
])
def test_lpm_same_bits_as_cli(tmp_path, nu, ny, m, py_opts, cli_opts):
    recs = noise_records(nu, ny, m)
    want = cli_frf(tmp_path, recs, nu, "--method", "lpm", *cli_opts)
    got = msid.frf(recs, method="lpm", n_inputs=nu, **py_opts)
    assert got.meta["method"] == "lpm" and got.G.shape[1:] == (ny, nu)
    assert_same_bits(got, want)


def test_lpm_reference_same_bits_as_cli(tmp_path):
    """Noisy input in a closed loop: the LPM of [y; u] on the reference r (Pintelon et al. 2010)."""
    rng = np.random.default_rng(7)
    r = rng.standard_normal(N)
    u = np.zeros(N)
    y = np.zeros(N)
    for t in range(N):   # u = r - 0.3 y[t-1] (feedback), y = FIR(u)
        u[t] = r[t] - 0.3 * (y[t - 1] if t else 0.0)
        y[t] = sum(c * u[t - k] for k, c in enumerate(TAPS[0][0]) if t - k >= 0)
    u_meas = u + 0.05 * rng.standard_normal(N)
    y_meas = y + 0.05 * rng.standard_normal(N)
    p = tmp_path / "cl.csv"
    np.savetxt(p, np.column_stack([r, u_meas, y_meas]), delimiter=",", fmt="%.17g", header="r1,u1,y1", comments="")
    cli("frf", "--method", "lpm", "--reference", "r1", "--band", "0.01:0.3", "--experiment", p,
        "-o", tmp_path / "cl.json")
    want = msid.read_frf(tmp_path / "cl.json")
    rec = np.column_stack([u_meas, y_meas])
    # the reference as samples, as a DataFrame column, and through the file
    got = msid.frf(rec, method="lpm", n_inputs=1, reference=r, band=(0.01, 0.3))
    for k in ("G", "cov", "bins"):
        assert np.array_equal(getattr(got, k), getattr(want, k)), k
    assert [e["noise_z"] for e in got.line_extra] == [e["noise_z"] for e in want.line_extra]
    assert want.meta["lpm"]["reference_signals"] == ["r1=r1"]
    pd = pytest.importorskip("pandas")
    df = pd.DataFrame({"u1": u_meas, "y1": y_meas, "Cmd": r})
    got_df = msid.frf(df, method="lpm", columns="u1=u1,y1=y1", reference=["Cmd"], band="0.01:0.3")
    assert np.array_equal(got_df.G, want.G) and np.array_equal(got_df.cov, want.cov)
    got_file = msid.frf(p, method="lpm", reference="r1", band="0.01:0.3")
    assert_same_bits(got_file, want)


@pytest.mark.parametrize("nu, ny, m, py_opts, cli_opts", [
    (1, 1, 1, {"period": 256}, ["--period", 256]),
    (2, 2, 2, {"period": 256, "delta": 0.1, "gstar": 3.0, "fs": 2.0, "band": (0.05, 0.5)},
     ["--period", 256, "--delta", 0.1, "--gstar", 3, "--fs", 2, "--band", "0.05:0.5"]),
])
def test_etfe_same_bits_as_cli(tmp_path, nu, ny, m, py_opts, cli_opts):
    recs = periodic_records(nu, ny, m)
    want = cli_frf(tmp_path, recs, nu, "--method", "etfe", *cli_opts)
    got = msid.frf(recs, method="etfe", n_inputs=nu, **py_opts)
    assert all("bound" in e for e in got.line_extra)
    assert_same_bits(got, want)


def test_files_same_bits_and_no_process(tmp_path, monkeypatch):
    recs = noise_records(1, 1, 2)
    csvs = []
    for k, r in enumerate(recs):
        p = tmp_path / f"c{k + 1}.csv"
        np.savetxt(p, r, delimiter=",", fmt="%.17g", header="u1,y1", comments="")
        csvs.append(p)
    cli("frf", "--method", "lpm", "--experiment", csvs[0], "--experiment", csvs[1], "-o", tmp_path / "f.json")
    want = msid.read_frf(tmp_path / "f.json")
    refuse_processes(monkeypatch)
    got = msid.frf(csvs, method="lpm")
    assert_same_bits(got, want)
    assert np.array_equal(msid.frf(recs, method="lpm", n_inputs=1).G, got.G)
    with pytest.raises(OSError, match="cannot open .*nope.csv"):
        msid.frf([tmp_path / "nope.csv"], method="lpm")


def test_errors_as_cli(tmp_path):
    recs = noise_records(1, 1, 1)
    per = periodic_records(1, 1, 1)
    cases = [
        (recs, {"method": "lpm", "order": 9}, ["--method", "lpm", "--order", 9]),
        (recs, {"method": "lpm", "window": 0}, ["--method", "lpm", "--window", 0]),
        (per, {"method": "etfe", "period": 256, "delta": 1.5}, ["--method", "etfe", "--period", 256, "--delta", 1.5]),
        (recs, {"method": "lpm", "band": (0.1, 0.7)}, ["--method", "lpm", "--band", "0.1:0.7"]),
        (recs, {"method": "lpm", "band": (0.2, 0.1)}, ["--method", "lpm", "--band", "0.2:0.1"]),
        (recs, {"method": "lpm", "fs": 100.0, "band": "0.001:0.002"},
         ["--method", "lpm", "--fs", 100, "--band", "0.001:0.002"]),
        (per, {"method": "etfe", "period": 100}, ["--method", "etfe", "--period", 100]),
        (per, {"method": "lpm"}, ["--method", "lpm"]),
    ]
    for r, py, args in cases:
        want = cli_error(tmp_path, r, 1, *args)
        with pytest.raises(ValueError) as e:
            msid.frf(r, n_inputs=1, **py)
        assert str(e.value) == msid._msid._python_words(want), args
    # a non-finite sample: the command line's message (the file named as the array)
    bad = [recs[0].copy()]
    bad[0][100, 1] = np.nan
    want = cli_error(tmp_path, bad, 1, "--method", "lpm")
    with pytest.raises(ValueError) as e:
        msid.frf(bad, n_inputs=1, method="lpm")
    assert str(e.value) == msid._msid._python_words(want)


def test_keyword_errors():
    recs = noise_records(1, 1, 2)
    # a keyword of another estimator: Python's own refusal of an unknown keyword, naming the function
    # whose keywords they are not (msid.frf(method=...) is msid.lpm / msid.etfe)
    with pytest.raises(TypeError, match=r"^lpm\(\) got an unexpected keyword argument 'skip_periods'$"):
        msid.frf(recs, method="lpm", n_inputs=1, skip_periods=1)
    with pytest.raises(TypeError, match=r"^frf\(\) got an unexpected keyword argument 'order'$"):
        msid.frf(recs, period=64, lines="1:10", n_inputs=1, order=2)
    with pytest.raises(ValueError, match=r"method must be 'periodic', 'lpm' or 'etfe', not 'arx'"):
        msid.frf(recs, method="arx", n_inputs=1)
    with pytest.raises(ValueError, match="reference: 1 array"):
        msid.frf(recs, method="lpm", n_inputs=1, reference=[recs[0][:, 0]])
    with pytest.raises(ValueError, match=r"reference\[1\] has 4095 rows and 1 columns"):
        msid.frf(recs, method="lpm", n_inputs=1, reference=[recs[0][:, 0], recs[1][1:, 0]])
    with pytest.raises(ValueError, match="records\\[0\\] is an array without column names"):
        msid.frf(recs, method="lpm", n_inputs=1, reference="r1")
    r = [recs[0][:, 0].copy(), recs[1][:, 0]]
    r[0][7] = np.inf
    with pytest.raises(ValueError, match=r"reference\[0\]"):
        msid.frf(recs, method="lpm", n_inputs=1, reference=r)
    with pytest.raises(ValueError, match="band must be"):
        msid.frf(recs, method="lpm", n_inputs=1, band=0.2)


def test_one_function_per_estimator(tmp_path):
    """msid.lpm and msid.etfe give the bits of msid.frf(method="lpm" | "etfe") with the same keywords,
    on arrays and on files, notes included: the older call is the new function."""
    import warnings
    recs = noise_records(2, 2, 3)
    per = periodic_records(1, 2, 2)
    cases = [(msid.lpm, "lpm", recs, {"n_inputs": 2, "order": 1, "window": 4, "band": (0.01, 0.2)}),
             (msid.lpm, "lpm", recs, {"n_inputs": 2, "fs": 1000.0, "band": "20:300", "threads": 1}),
             (msid.etfe, "etfe", per, {"n_inputs": 1, "period": 256}),
             (msid.etfe, "etfe", per, {"n_inputs": 1, "period": 256, "delta": 0.1, "gstar": 2.0, "fs": 50.0})]
    for fn, method, r, kw in cases:
        with warnings.catch_warnings(record=True) as w_new:
            warnings.simplefilter("always")
            new = fn(r, **kw)
        with warnings.catch_warnings(record=True) as w_old:
            warnings.simplefilter("always")
            old = msid.frf(r, method=method, **kw)
        assert_same_bits(new, old)
        assert new.meta["method"] == method and new.notes == old.notes
        assert [str(x.message) for x in w_new] == [str(x.message) for x in w_old]
    # files: the same bits from the new function and the older call
    def saved(records, stem):
        out = []
        for k, r in enumerate(records):
            np.save(tmp_path / f"{stem}{k}.npy", r)
            out.append(tmp_path / f"{stem}{k}.npy")
        return out
    paths, cols = saved(per, "e"), "u1=1,y1=2,y2=3"
    assert_same_bits(msid.etfe(paths, period=256, columns=cols), msid.frf(paths, method="etfe", period=256, columns=cols))
    paths, cols = saved(recs, "n"), "u1=1,u2=2,y1=3,y2=4"
    assert_same_bits(msid.lpm(paths, columns=cols), msid.frf(paths, method="lpm", columns=cols))


def test_estimator_keywords_are_their_own():
    """Each estimator's function takes its own keywords only: another's is Python's TypeError for an
    unknown keyword (never reaching the library), and the signatures say which they are."""
    import inspect
    recs = noise_records(1, 1, 1)
    refused = [
        (lambda: msid.frf(recs, n_inputs=1, period=64, lines="1:10", order=2), "frf", "order"),
        (lambda: msid.frf(recs, n_inputs=1, window=3), "frf", "window"),
        (lambda: msid.frf(recs, n_inputs=1, delta=0.1), "frf", "delta"),
        (lambda: msid.lpm(recs, n_inputs=1, period=64), "lpm", "period"),
        (lambda: msid.lpm(recs, n_inputs=1, skip_periods=1), "lpm", "skip_periods"),
        (lambda: msid.lpm(recs, n_inputs=1, delta=0.1), "lpm", "delta"),
        (lambda: msid.etfe(recs, n_inputs=1, period=64, order=2), "etfe", "order"),
        (lambda: msid.etfe(recs, n_inputs=1, period=64, reference="r1"), "etfe", "reference"),
        (lambda: msid.etfe(recs, n_inputs=1, period=64, design=None), "etfe", "design"),
        # the older form: refused by the function it stands for
        (lambda: msid.frf(recs, method="etfe", n_inputs=1, period=64, order=2), "etfe", "order"),
        (lambda: msid.frf(recs, method="lpm", n_inputs=1, period=64), "lpm", "period"),
        (lambda: msid.frf(recs, method="lpm", n_inputs=1, transient="off"), "lpm", "transient"),
    ]
    for call, fn, kw in refused:
        with pytest.raises(TypeError) as e:
            call()
        assert str(e.value) == f"{fn}() got an unexpected keyword argument '{kw}'"
    with pytest.raises(TypeError, match=r"etfe\(\) missing 1 required keyword-only argument: 'period'"):
        msid.etfe(recs, n_inputs=1)
    with pytest.raises(TypeError, match=r"etfe\(\) missing 1 required keyword-only argument: 'period'"):
        msid.frf(recs, method="etfe", n_inputs=1)
    shared = {"records", "fs", "columns", "n_inputs"}
    params = {f.__name__: set(inspect.signature(f).parameters) - shared for f in (msid.frf, msid.lpm, msid.etfe)}
    assert params["lpm"] == {"order", "window", "band", "reference", "threads"}
    assert params["etfe"] == {"period", "delta", "gstar", "band", "threads"}
    assert params["frf"] >= {"design", "period", "lines", "skip_periods", "detect_lines", "transient", "alpha", "dft",
                             "block", "realisations", "direct"}
    assert not params["frf"] & {"order", "window", "band", "reference", "delta", "gstar", "threads"}
