"""msid.plot: the phase is not unwrapped across noise-dominated lines, and an ETFE file
(`msid frf --method etfe`) gets the band of its Tsiamis et al. 2024 bound.

Needs no msid binary: the phase case is built here with a known phase, the ETFE case is the golden
file `msid frf --method etfe` wrote (tests/integration/golden/etfe.json)."""
import numpy as np
import pytest
from conftest import ROOT

import msid as pkg

pytest.importorskip("matplotlib")
from matplotlib.collections import PolyCollection  # noqa: E402

from msid import plot  # noqa: E402

ETFE = ROOT / "tests" / "integration" / "golden" / "etfe.json"


def phase_case():
    """SISO, 30 lines, true phase falling 0.3 rad per line; line 12 is noise: its region (variance 25,
    |G| = 1) covers the origin and its value sits 3 rad above line 11, so the naive unwrap takes the
    next line (3.6 rad below it) one turn up."""
    L, noisy_k = 30, 12
    theta = -0.3 * np.arange(L)
    G = np.exp(1j * theta)
    G[noisy_k] = np.exp(1j * (theta[noisy_k - 1] + 3.0))
    var = np.full(L, 1e-4)
    var[noisy_k] = 25.0
    cov = var.reshape(L, 1, 1).astype(complex)
    f = pkg.FRF(G.reshape(L, 1, 1), 0.01 * (1 + np.arange(L)), cov=cov, dof=np.full(L, 10.0), meta={"method": "periodic"})
    return f, theta, noisy_k


def test_unwrap_skips_noise_dominated_lines_with_negative_control():
    f, theta, k = phase_case()
    r = f.radius()[:, 0, 0]
    noisy = r >= np.abs(f.G[:, 0, 0])
    assert list(np.flatnonzero(noisy)) == [k]          # exactly the noise line's region covers the origin
    ph = plot.unwrap_phase(f.G[:, 0, 0], noisy)
    clean = ~noisy
    assert np.allclose(ph[clean], theta[clean], atol=1e-12)
    # the noise line is put on the branch nearest the line before it, not joined to the others
    assert abs(ph[k] - (theta[k - 1] + 3.0)) < 1e-12
    # negative control: the plain unwrap (the old drawing) moves every line after the noise line one turn
    naive = np.unwrap(np.angle(f.G[:, 0, 0]))
    assert np.allclose(naive[k + 1:] - theta[k + 1:], 2 * np.pi, atol=1e-12)
    # nothing noisy: exactly np.unwrap
    g = np.exp(1j * np.linspace(0, -20, 50))
    assert np.array_equal(plot.unwrap_phase(g, np.zeros(50, bool)), np.unwrap(np.angle(g)))


def test_drawn_phase_breaks_at_noise_lines():
    f, theta, k = phase_case()
    fig = plot.bode(f)
    ap = [a for a in fig.axes if a.get_ylabel() == "phase (deg)"][0]
    est = [ln for ln in ap.get_lines() if ln.get_label() == "estimate"][0]
    y = np.asarray(est.get_ydata(), float)
    assert np.isnan(y[k]) and np.sum(np.isnan(y)) == 1       # the line is broken at the noise line only
    assert np.allclose(y[~np.isnan(y)], np.degrees(np.delete(theta, k)), atol=1e-9)
    (nl,) = [ln for ln in ap.get_lines() if ln.get_label() == plot.NOISE_LABEL]
    assert len(nl.get_xdata()) == 1 and nl.get_markerfacecolor() == "none"
    # a clean FRF (small covariance everywhere) has no noise markers and an unbroken line
    f.cov = np.full_like(f.cov, 1e-4)
    ap2 = [a for a in plot.bode(f).axes if a.get_ylabel() == "phase (deg)"][0]
    assert not [ln for ln in ap2.get_lines() if ln.get_label() == plot.NOISE_LABEL]


def _bands(ax, label):
    return [c for c in ax.collections if isinstance(c, PolyCollection) and c.get_label() == label]


def test_etfe_bound_band_from_the_etfe_file():
    f = pkg.read_frf(ETFE)
    assert f.meta["method"] == "etfe"
    bound = plot.etfe_bound(f)
    assert bound is not None and bound.shape == (f.n_lines,) and np.all(bound > 0)
    fig = plot.bode(f)
    hz, _ = f.hz_axis()
    mags = [a for a in fig.axes if a.get_ylabel() == "|G| (dB)"]
    phs = [a for a in fig.axes if a.get_ylabel() == "phase (deg)"]
    assert len(mags) == 4 and len(phs) == 4
    for a in mags:
        (band,) = _bands(a, plot.BOUND_LABEL)
        i, j = (int(s[1]) - 1 for s in a.get_title().split(" / "))
        v = band.get_paths()[0].vertices
        got = np.array([max(y for x, y in v if abs(x - fk) < 1e-9 * fk) for fk in hz])
        want = 20 * np.log10(np.abs(f.G[:, i, j]) + bound)     # |G_ij - Ghat_ij| <= ||G - Ghat||_2 <= bound
        assert np.allclose(got, want, rtol=0, atol=1e-9)
        assert len(_bands(a, "95% region")) == 1                 # the exact region is still drawn
    for a in phs:
        assert len(_bands(a, plot.BOUND_LABEL)) == 1
    # the bound is wider than the 95% region at every line (it is loose by design, docs/statistics.md)
    assert np.all(bound[:, None, None] > f.radius())
    # negative control: the same lines without the etfe method get no bound band
    f.meta["method"] = "periodic"
    assert plot.etfe_bound(f) is None
    assert not any(_bands(a, plot.BOUND_LABEL) for a in plot.bode(f).axes)
