"""`msid frf --period auto --lines auto` on a closed-loop drive record `t,r1,u1,y1` (closed_loop_drive.py:
a prismatic joint under a PD position controller, a periodic multisine reference, a force disturbance
and encoder noise inside the loop). The lines come from the reference r1 (used without asking); the
controller leaves some of them with little plant input, where the ratio of the averaged spectra is
biased and its covariance does not hold. msid leaves those lines out, naming them in one note and in
the file's lines_auto block, instead of refusing the record; the lines kept give the FRF that giving them
with --lines gives; given lines are still refused. A Monte Carlo over fixed seeds checks that the 95%
regions of the default path cover the plant's true FRF (voltage to position) within binomial bounds; its
negative control keeps the lines that the FRF's own test on each line would keep, whose regions
under-cover (docs/statistics.md, "Closed loop")."""
import json

import numpy as np
import pytest
from scipy import stats

import closed_loop_drive as cl
import helpers as h

P, K = 2048, 3
BINS = np.arange(1, 300, 2)          # odd bins to 146 Hz


def frf(tmp, path, *args, name=None):
    out = tmp / (name or path.stem + ".frf.json")
    r = h.run("frf", *args, "--fs", str(cl.FS), "--experiment", str(path), "-o", str(out))
    return r, (json.loads(out.read_text()) if r.returncode == 0 else None), out


def default_path(tmp, path):
    """The command of a new user: period and lines found from the record."""
    return frf(tmp, path, "--period", "auto", "--lines", "auto")


def line_arrays(doc):
    """Bins, G, the variance of G (`cov`: the errors-in-variables covariance, with the input-output cross term
    that holds the loop's correlation) and its dof."""
    bins = np.array([ln["bin"] for ln in doc["lines"]])
    G = np.array([ln["G"]["re"][0][0] + 1j * ln["G"]["im"][0][0] for ln in doc["lines"]])
    var = np.array([ln["cov"]["re"][0][0] for ln in doc["lines"]])
    dof = np.array([ln["dof"] for ln in doc["lines"]])
    return bins, G, var, dof


def inside95(G, G0, var, dof):
    """|e|^2 / var ~ F(2, 2 dof): P(F > x) = (1 + x / dof)^-dof, the 95% quantile dof (0.05^(-1/dof) - 1)."""
    return np.abs(G - G0) ** 2 / var <= dof * (0.05 ** (-1 / dof) - 1)


def test_closed_loop_record_is_estimated_not_refused(tmp_path):
    path = cl.drive(tmp_path / "drive.csv", P, K, BINS, seed=1)
    r, doc, out = default_path(tmp_path, path)
    assert r.returncode == 0, r.stderr
    assert f"--period auto: {P}" in r.stdout or f"period {P}" in r.stdout, r.stdout
    la = doc["lines_auto"]
    assert la["from"] == "the reference r1=r1" and la["found"] == len(BINS)
    bins = [ln["bin"] for ln in doc["lines"]]
    dropped = la["unusable_bins"]
    assert dropped and sorted(set(BINS) - set(bins)) == dropped
    # the lines dropped are those where the loop leaves the averaged input near its noise; the lines with
    # a clear input are all kept
    snr = dict(zip(BINS, cl.input_snr_db(BINS, P, K)))
    assert all(snr[k] < 16 for k in dropped), [(k, round(snr[k], 1)) for k in dropped if snr[k] >= 16]
    assert all(k in bins for k in BINS if snr[k] > 22)
    # one note names them, by frequency
    notes = [ln for ln in r.stderr.splitlines() if "left out of the FRF" in ln]
    assert len(notes) == 1 and r.stderr.count("note:") == 1, r.stderr
    assert notes[0].startswith(f"msid frf: note: --lines auto: {len(dropped)} of the {len(BINS)} line(s) found are "
                               "left out of the FRF: the input is too weak at ")
    assert "closed loop" in notes[0] and " Hz" in notes[0]
    h.validate(doc, "msid-frf-1")
    # the FRF of the lines kept is the one those lines give when given
    r2, doc2, _ = frf(tmp_path, path, "--period", str(P), "--lines", ",".join(map(str, bins)))
    assert r2.returncode == 0, r2.stderr
    assert doc2["lines"] == doc["lines"] and "lines_auto" not in doc2
    # given lines are refused as before: the first one the input does not excite is named
    r3, _, out3 = frf(tmp_path, path, "--period", str(P), "--lines", "1:2:299", name="given.json")
    assert r3.returncode != 0 and "do not excite line" in r3.stderr and not out3.exists()


def test_open_loop_record_with_reference_drops_nothing(tmp_path):
    # the plant driven directly by the reference (open loop, input noise only): every line is used, the
    # file has no unusable_bins and there is no note
    rng = np.random.default_rng(3)
    R = np.zeros(P // 2 + 1, complex)
    R[BINS] = np.exp(2j * np.pi * rng.random(BINS.size)) * P / 2
    Y = R * cl.plant_frf(np.arange(P // 2 + 1), P) * 1e3
    r, y = (np.tile(np.fft.irfft(X, P), K) for X in (R, Y))
    u = r + 0.05 * rng.standard_normal(r.size)
    y = y + 1e-2 * rng.standard_normal(y.size)
    path = tmp_path / "open.csv"
    np.savetxt(path, np.column_stack([np.arange(K * P) / cl.FS, r, u, y]), delimiter=",", header="t,r1,u1,y1",
               comments="", fmt="%.12g")
    r, doc, _ = default_path(tmp_path, path)
    assert r.returncode == 0, r.stderr
    assert [ln["bin"] for ln in doc["lines"]] == list(BINS)
    assert "unusable_bins" not in doc["lines_auto"] and "note:" not in r.stderr


RUNS = 60


def own_input_snr_db(path, bins):
    """The input SNR of each line's period mean from its own periods (dB): what the core's excitation test
    computes, |mean U|^2 / (s_U^2 / K)."""
    u = np.loadtxt(path, delimiter=",", skiprows=1, usecols=2).reshape(K, P)
    U = np.fft.rfft(u, axis=1)[:, bins]
    s2 = (np.abs(U - U.mean(0)) ** 2).sum(0) / (K - 1)
    return 10 * np.log10(np.abs(U.mean(0)) ** 2 / (s2 / K))


@pytest.fixture(scope="module")
def monte_carlo(tmp_path_factory):
    """Per run: the default path's lines inside their 95% regions, the same for the lines that the core's own
    test alone would keep (negative control), and the number of lines left out."""
    tmp = tmp_path_factory.mktemp("closed_loop_mc")
    ins, ins_own, n_drop = [], [], []
    for run in range(RUNS):
        path = cl.drive(tmp / "mc.csv", P, K, BINS, seed=1000 + run)
        r, doc, _ = default_path(tmp, path)
        assert r.returncode == 0, r.stderr
        bins, G, var, dof = line_arrays(doc)
        ins.append(inside95(G, cl.plant_frf(bins, P), var, dof))
        n_drop.append(len(doc["lines_auto"].get("unusable_bins", [])))
        # the lines whose own input SNR passes 10 dB, given: what leaving out only the lines the core
        # refuses would keep
        snr = own_input_snr_db(path, BINS)
        own = BINS[snr > 10 + 1e-6]
        r, doc, _ = frf(tmp, path, "--period", str(P), "--lines", ",".join(map(str, own)))
        assert r.returncode == 0, r.stderr
        bins, G, var, dof = line_arrays(doc)
        ins_own.append(inside95(G, cl.plant_frf(bins, P), var, dof))
    return np.concatenate(ins), np.concatenate(ins_own), np.array(n_drop)


def binomial_bounds(n, p=0.95, a=1e-3):
    """The counts of n trials outside which a coverage p is rejected (two-sided, level a)."""
    return stats.binom.ppf(a / 2, n, p), stats.binom.isf(a / 2, n, p)


def test_closed_loop_regions_cover_the_plant(monte_carlo):
    ins, _, n_drop = monte_carlo
    lo, hi = binomial_bounds(ins.size)
    assert lo <= ins.sum() <= hi, (ins.mean(), ins.size, lo / ins.size, hi / ins.size)
    assert (n_drop > 0).all()   # every record had lines to leave out


def test_lines_kept_by_their_own_snr_do_not_cover(monte_carlo):
    # negative control: keeping every line whose own input SNR passes (the core's test alone) keeps lines
    # whose noise happened to look small, and their regions under-cover: the test above tells it apart
    _, ins_own, _ = monte_carlo
    lo, _ = binomial_bounds(ins_own.size)
    assert ins_own.sum() < lo, ins_own.mean()
