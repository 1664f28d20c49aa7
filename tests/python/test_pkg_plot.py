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
    assert len(fig.axes) == 14   # 12 Bode/residual axes, the diagram and its mode-indicator axis
    st, mif = fig.axes[-2], fig.axes[-1]
    assert st.get_title().startswith("stabilisation diagram") and st.get_ylabel() == "order"
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


def test_interrupted_run_is_marked_incomplete(siso, tmp_path):
    """An FRF written after a stop ("complete": false, msid measure) says INCOMPLETE in the Bode title and in
    report.html (title, heading, banner, table); the same FRF without the key says nothing of the kind."""
    import json
    d = tmp_path / "out"
    d.mkdir()
    doc = json.loads((siso / "frf.json").read_text())
    doc.update({"complete": False, "experiments_completed": 1, "experiments_planned": 2,
                "incomplete_reason": "stopped by signal 2 during experiment 2 of 2"})
    (d / "frf.json").write_text(json.dumps(doc))
    f = pkg.read_frf(d / "frf.json")
    assert plot.bode(f)._suptitle.get_text().startswith("INCOMPLETE: ")
    r = subprocess.run([sys.executable, "-m", "msid.report", str(d)], env=ENV, capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    html = (d / "report.html").read_text()
    assert "<title>INCOMPLETE msid report" in html and "<h1>INCOMPLETE msid report" in html
    assert "stopped by signal 2 during experiment 2 of 2" in html and "1 of 2 experiments complete" in html
    # negative control: the complete file
    assert "INCOMPLETE" not in plot.bode(siso / "frf.json")._suptitle.get_text()
    e = tmp_path / "complete"
    e.mkdir()
    (e / "frf.json").write_bytes((siso / "frf.json").read_bytes())
    assert subprocess.run([sys.executable, "-m", "msid.report", str(e)], env=ENV).returncode == 0
    assert "INCOMPLETE" not in (e / "report.html").read_text()


def test_stabilisation_diagram_reads_like_the_bode_plot(demo, tmp_path):
    """The diagram spans the Bode plot's frequency range, has integer order ticks, draws the FRF's mode
    indicator (the singular values of G, dB) behind the poles, and its x tick labels do not overlap
    (checked on the drawn text boxes); the rendered PNG holds the grey curve's pixels."""
    f = pkg.read_frf(demo / "frf.json")
    m = pkg.read_model(demo / "auto.json")
    fig = plot.bode(f, m)
    st, mif = fig.axes[-2], fig.axes[-1]
    hz = f.hz_axis()[0]
    assert st.get_xlim() == pytest.approx((hz.min(), hz.max()))
    assert all(float(t).is_integer() for t in st.get_yticks())
    sv = np.linalg.svd(f.G, compute_uv=False)
    curves = [ln for ln in mif.get_lines()]
    assert len(curves) == sv.shape[1]
    assert np.allclose(curves[0].get_ydata(), 20 * np.log10(sv[:, 0]), rtol=1e-12)
    assert np.allclose(curves[0].get_xdata(), hz)
    assert st.get_zorder() > mif.get_zorder()   # the poles above the curve
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    FigureCanvasAgg(fig).draw()
    xr = st.get_xlim()
    labels = [t for t in st.get_xticklabels() + st.get_xticklabels(minor=True)
              if t.get_text() and t.get_visible() and xr[0] <= t.get_position()[0] <= xr[1]]
    inside = [t.get_window_extent() for t in labels]
    assert len(inside) >= 2
    for i in range(len(inside)):
        for j in range(i + 1, len(inside)):
            assert not inside[i].overlaps(inside[j]), (i, j)
    plot.save(fig, tmp_path / "stab.png")
    img = imread(tmp_path / "stab.png")[..., :3]
    grey = np.all(np.abs(img - 0.55) < 0.04, axis=-1)
    h = img.shape[0]
    assert grey[int(0.75 * h):].sum() > 200   # the mode indicator in the diagram's (lowest) part


def test_report_says_when_what_how_and_stability(demo, tmp_path):
    """report.html carries the run (dates, msid version, the command line given with --command), the design
    (period, rate, lines, amplitudes from design.json), the channels (names and units from the file, else
    u1.. with "unit not recorded"), and one unambiguous sentence on the model's stability; an unstable model
    (one pole moved outside the unit circle) says UNSTABLE (negative control)."""
    import json
    import re
    d = tmp_path / "out"
    d.mkdir()
    doc = json.loads((demo / "frf.json").read_text())
    (d / "frf.json").write_text(json.dumps(doc))
    (d / "model.json").write_bytes((demo / "model.json").read_bytes())
    (d / "design.json").write_bytes((demo / "design.json").read_bytes())
    cmd = "msid measure --device modbus-tcp://127.0.0.1:1502 --design 'my design.json' -o out"
    r = subprocess.run([sys.executable, "-m", "msid.report", str(d), "--command", cmd], env=ENV, capture_output=True,
                       text=True)
    assert r.returncode == 0, r.stderr
    page = (d / "report.html").read_text()
    text = re.sub(r"<[^>]+>", " ", page)
    import html as h
    text = h.unescape(text)
    assert cmd in text
    assert re.search(r"FRF written\s+\d{4}-\d\d-\d\d \d\d:\d\d:\d\d UTC", text)
    assert doc["generator"] in text and f"Python package {pkg.__version__}" in text
    assert re.search(r"period\s+1024 samples", text)
    assert re.search(r"sample rate\s+1000 Hz", text)
    assert "2,3,5,8,12,17,20,25,35,50,80,92,150,300 (14 lines)" in text
    assert re.search(r"amplitudes \(peak\)\s+0\.5 \(every line and input\)", text)
    assert re.search(r"input 1\s+u1 \(unit not recorded\)", text) and re.search(r"output 2\s+y2 \(unit not recorded\)", text)
    assert re.search(r"stability of the model\s+stable: all 4 poles inside the unit circle", text)
    assert "stable poles" not in text and "INCOMPLETE" not in text
    # names and units from the file; an unstable model
    doc.update(input_names=["force", "torque"], output_names=["acc", "vel"], input_units=["N", "N m"],
               output_units=["m/s^2", "m/s"])
    (d / "frf.json").write_text(json.dumps(doc))
    m = pkg.read_model(demo / "model.json")
    w, V = np.linalg.eig(m.A)
    w2 = w.copy()
    w2[np.abs(w) == np.abs(w).max()] *= 1.05 / np.abs(w).max()
    m.A = np.real(V @ np.diag(w2) @ np.linalg.inv(V))
    pkg.write_model(d / "model.json", m)
    assert subprocess.run([sys.executable, "-m", "msid.report", str(d)], env=ENV).returncode == 0
    text = h.unescape(re.sub(r"<[^>]+>", " ", (d / "report.html").read_text()))
    assert re.search(r"input 2\s+torque \[N m\]", text) and re.search(r"output 1\s+acc \[m/s\^2\]", text)
    assert re.search(r"UNSTABLE: [12] of 4 poles not inside the unit circle \(largest \|pole\| 1\.05\)", text)
    assert "not recorded (msid measure passes it)" in text
