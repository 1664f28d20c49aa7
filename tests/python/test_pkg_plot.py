"""Plots of the msid Python package: msid.plot (figure objects and saved pixels), python3 -m msid.plot,
python3 -m msid.report and the `msid plot` command that wraps them (docs/python.md).

The regions are checked against the exact radius (msid.regions) through the drawn polygon vertices, and
in the saved PNG through the band colour; a zero covariance (no band) is the negative control."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, msid

import msid as pkg

mpl = pytest.importorskip("matplotlib")
from matplotlib.collections import PolyCollection  # noqa: E402
from matplotlib.image import imread  # noqa: E402

from msid import plot  # noqa: E402

ENV = dict(os.environ, PYTHONPATH=str(ROOT / "tools" / "python"), PYTHONDONTWRITEBYTECODE="1")
BAND_RGB = np.array(mpl.colors.to_rgb("tab:blue")) * 0.25 + 0.75   # alpha 0.25 over white


def noisy(frf, factor):
    """The same FRF with its covariances scaled (wide, visible bands)."""
    g = pkg.read_frf(frf) if not isinstance(frf, pkg.FRF) else frf
    g.cov = g.cov * factor
    return g


def band_pixels(png):
    img = imread(png)[..., :3]
    return int(np.sum(np.all(np.abs(img - BAND_RGB) < 0.03, axis=-1))), img


def bands(ax):
    return [c for c in ax.collections if isinstance(c, PolyCollection)]


def test_bode_axes_regions_and_residuals(demo):
    f = pkg.read_frf(demo / "frf.json")
    m = pkg.read_model(demo / "model.json")
    fig = plot.bode(f, m)
    axes = fig.axes
    assert len(axes) == 2 * 2 * 3   # 2 outputs x 2 inputs x (magnitude, phase, residual); no order scan
    labels = [a.get_ylabel() for a in axes]
    assert labels.count("|G| (dB)") == 4 and labels.count("phase (deg)") == 4 and labels.count("|e|/sd") == 4
    assert {a.get_title() for a in axes if a.get_title()} == {"y1 / u1", "y1 / u2", "y2 / u1", "y2 / u2"}
    assert all(a.get_xscale() == "log" for a in axes)
    assert sum(a.get_xlabel() == "frequency (Hz)" for a in axes) == 2
    r = f.radius()
    hz, _ = f.hz_axis()
    for a in axes:
        if a.get_ylabel() == "|G| (dB)":
            (band,) = bands(a)
            i, j = (int(s[1]) - 1 for s in a.get_title().split(" / "))
            # the upper edge of the drawn band is 20 log10(|G| + r) at every line
            v = band.get_paths()[0].vertices
            top = {round(x, 9): y for x, y in v if True}
            want = 20 * np.log10(np.abs(f.G[:, i, j]) + r[:, i, j])
            got = np.array([max(y for x, y in v if abs(x - fk) < 1e-9 * fk) for fk in hz])
            assert np.allclose(got, want, rtol=0, atol=1e-9), (got, want)
            assert top
            lines = [ln.get_label() for ln in a.get_lines()]
            assert "estimate" in lines and "model" in lines
        elif a.get_ylabel() == "phase (deg)":
            assert len(bands(a)) == 1
        else:
            # residual rows: one point per line and the F(2, 2 dof) 95% threshold (above the chi2 one)
            thr = [ln for ln in a.get_lines() if ln.get_linestyle() == "--"][0].get_ydata()
            assert np.all(thr > np.sqrt(-np.log(0.05))) and np.allclose(thr, pkg.regions.radius(1.0, f.dof))


def test_stabilisation_diagram_when_the_model_has_one(demo):
    m = pkg.read_model(demo / "auto.json")
    assert m.stabilisation is not None
    fig = plot.bode(demo / "frf.json", m)
    assert len(fig.axes) == 13
    st = fig.axes[-1]
    assert st.get_title() == "stabilisation diagram" and st.get_ylabel() == "order"
    orders = {o["order"] for o in m.stabilisation["orders"] if o["ok"] and o["poles"]}
    ys = {int(y) for ln in st.get_lines() for y in ln.get_ydata() if ln.get_linestyle() == "None"}
    assert ys == orders
    chosen = [ln for ln in st.get_lines() if ln.get_label().startswith("chosen order")]
    assert chosen and chosen[0].get_ydata()[0] == m.stabilisation["chosen"]


def test_saved_png_not_blank_with_bands_and_negative_control(siso, tmp_path):
    f = pkg.read_frf(siso / "frf.json")
    plot.save(plot.bode(noisy(f, 400.0)), tmp_path / "wide.png")
    n_wide, img = band_pixels(tmp_path / "wide.png")
    assert img.shape[0] > 300 and img.shape[1] > 300
    assert np.std(img) > 0.05 and np.mean(np.all(img > 0.98, axis=-1)) < 0.97   # not blank
    assert n_wide > 0.01 * img.shape[0] * img.shape[1], n_wide
    zero = noisy(pkg.read_frf(siso / "frf.json"), 0.0)
    plot.save(plot.bode(zero), tmp_path / "none.png")
    n_none, _ = band_pixels(tmp_path / "none.png")
    assert n_none < n_wide / 50, (n_none, n_wide)


def test_svg_and_cli(demo, siso, tmp_path):
    out = tmp_path / "b.svg"
    r = subprocess.run([sys.executable, "-m", "msid.plot", str(siso / "frf.json"), "--model",
                        str(siso / "model.json"), "-o", str(out)], env=ENV, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    text = out.read_text()
    assert text.lstrip().startswith("<?xml") and "<svg" in text and text.count("<path") > 20
    # bad input: one message, non-zero exit, no file
    for args, code, msg in (([str(tmp_path / "nope.json"), "-o", str(tmp_path / "x.png")], 1, "cannot read"),
                            ([str(demo / "model.json"), "-o", str(tmp_path / "x.png")], 1, "expected \"msid-frf/1\""),
                            ([str(demo / "frf.json"), "-o", str(tmp_path / "x.gif")], 2, ".png, .svg or .pdf"),
                            ([str(demo / "frf.json"), "--model", str(demo / "frf.json"), "-o",
                              str(tmp_path / "x.png")], 1, "expected \"msid-model/1\"")):
        r = subprocess.run([sys.executable, "-m", "msid.plot"] + args, env=ENV, capture_output=True, text=True)
        assert r.returncode == code and msg in r.stderr, r.stderr
        assert sum("error" in ln for ln in r.stderr.splitlines()) == 1, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.svg"]


def test_report(demo, siso, tmp_path):
    d = tmp_path / "out"
    d.mkdir()
    for n in ("frf.json", "model.json"):
        (d / n).write_bytes((siso / n).read_bytes())
    r = subprocess.run([sys.executable, "-m", "msid.report", str(d)], env=ENV, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    html = (d / "report.html").read_text()
    assert '<img alt="Bode plot' in html and "data:image/png;base64," in html and "weighted cost" in html
    assert (d / "bode.png").stat().st_size > 10000 and "<svg" in (d / "bode.svg").read_text()
    # FRF only (no model), and a directory without frf.json: one message, nothing written
    (d / "model.json").unlink()
    assert subprocess.run([sys.executable, "-m", "msid.report", str(d)], env=ENV).returncode == 0
    e = tmp_path / "empty"
    e.mkdir()
    r = subprocess.run([sys.executable, "-m", "msid.report", str(e)], env=ENV, capture_output=True, text=True)
    assert r.returncode == 1 and "frf.json" in r.stderr and not any(e.iterdir())


def test_msid_plot_command(demo, siso, tmp_path):
    out = tmp_path / "bode.png"
    r = msid("plot", siso / "frf.json", "--model", siso / "model.json", "-o", out)
    assert out.stat().st_size > 10000 and imread(out).shape[2] in (3, 4)
    r = msid("plot", demo / "frf.json", "-o", tmp_path / "x.gif", check=False)
    assert r.returncode == 2 and "png" in r.stderr and not (tmp_path / "x.gif").exists()
    # no Python package to be found: one clear message
    env = dict(os.environ, MSID_PYTHON_DIR=str(tmp_path / "nowhere"), PYTHONPATH="", MSID_PYTHON="false")
    r = subprocess.run([os.environ["MSID_BIN"], "plot", str(demo / "frf.json"), "-o", str(tmp_path / "y.png")],
                       env=env, capture_output=True, text=True)
    assert r.returncode != 0 and "python" in r.stderr.lower() and not (tmp_path / "y.png").exists()
    assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert Path(os.environ["MSID_BIN"]).exists()


def test_saved_files_are_reproducible(siso, tmp_path):
    """Same files -> the same bytes (no dates, fixed SVG ids), for PNG and SVG."""
    for ext in ("png", "svg"):
        a, b = tmp_path / f"a.{ext}", tmp_path / f"b.{ext}"
        plot.save(plot.bode(siso / "frf.json", siso / "model.json"), a)
        plot.save(plot.bode(siso / "frf.json", siso / "model.json"), b)
        assert a.read_bytes() == b.read_bytes(), ext
