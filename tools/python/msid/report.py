"""One-page HTML report of a measurement directory (docs/python.md).

    python3 -m msid.report OUTDIR

reads OUTDIR/frf.json (msid-frf/1) and, when present, OUTDIR/model.json (msid-model/1), writes the Bode
plot (msid.plot.bode: 95% regions, model overlay, residuals, stabilisation diagram) as OUTDIR/bode.png
and OUTDIR/bode.svg, and OUTDIR/report.html: a self-contained page (the PNG embedded as data) with the
plot and the figures of the files (lines, periods, dof, acquisition counters, model cost and modes).
Exit status 0, 1 with one message on a bad or missing file (nothing written), 3 without matplotlib.
"""
import base64
import html
import json
import os
import sys


from .files import read_frf, read_model


def _row(k, v):
    return f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(str(v))}</td></tr>"


def _fmt(x):
    if isinstance(x, float):
        return f"{x:.6g}"
    if isinstance(x, (list, dict)):
        return json.dumps(x)
    return x


def _frf_table(frf):
    m = frf.meta
    f, unit = frf.hz_axis()
    rows = [("estimator", m.get("method", "periodic")), ("inputs x outputs", f"{frf.n_inputs} x {frf.n_outputs}"),
            ("experiments", m.get("n_experiments")), ("lines", f"{frf.n_lines} ({f.min():.6g} .. {f.max():.6g} {unit})"),
            ("periods used / rejected", f"{m.get('periods_used')} / {m.get('periods_rejected')}")]
    if frf.dof is not None:
        rows.append(("dof (complex)", f"{frf.dof.min():.4g} .. {frf.dof.max():.4g}"))
    if m.get("incomplete") is not None:
        rows.append(("incomplete", _fmt(m.get("incomplete"))))
    acq = m.get("acquisition")
    if isinstance(acq, dict):
        for k in ("transport", "endpoint", "interface", "samples", "samples_lost", "frames_missing", "retries",
                  "timeouts", "kernel_drops", "bus_state"):
            if k in acq:
                rows.append((f"acquisition {k}", _fmt(acq[k])))
    nl = m.get("nonlinear_distortion")
    if isinstance(nl, dict):
        rows.append(("nonlinear distortion", f"p = {_fmt(nl.get('p_value'))}, detected {nl.get('distortion_detected')}"))
    return rows


def _model_table(model):
    d = model.doc
    rows = [("method", d.get("method")), ("order", model.order), ("domain", d.get("domain")),
            ("stable", d.get("stable"))]
    c = d.get("cost") or {}
    if c:
        rows.append(("weighted cost", f"{_fmt(c.get('value'))} (expected {_fmt(c.get('expected'))}, "
                                       f"p = {_fmt(c.get('p_value'))})"))
    if "converged" in d:
        rows.append(("converged", d["converged"]))
    modes = (d.get("modes") or {}).get("modes") or []
    unit = (d.get("modes") or {}).get("frequency_unit", "")
    for k, md in enumerate(modes):
        sd = md.get("sd_fn")
        rows.append((f"mode {k + 1}", f"fn {md['fn']:.6g} {unit}" + (f" +- {sd:.3g}" if sd is not None else "") +
                     f", zeta {100 * md['zeta']:.4g}%"))
    return rows


def write_report(outdir):
    """Write OUTDIR/bode.png, OUTDIR/bode.svg and OUTDIR/report.html; returns the report's path."""
    from . import plot
    frf_path = os.path.join(outdir, "frf.json")
    model_path = os.path.join(outdir, "model.json")
    frf = read_frf(frf_path)
    model = read_model(model_path) if os.path.exists(model_path) else None
    fig = plot.bode(frf, model)
    plot.save(fig, os.path.join(outdir, "bode.svg"))
    plot.save(fig, os.path.join(outdir, "bode.png"))
    with open(os.path.join(outdir, "bode.png"), "rb") as fh:
        png = fh.read()
    rows = "".join(_row(k, _fmt(v)) for k, v in _frf_table(frf))
    mrows = "".join(_row(k, _fmt(v)) for k, v in _model_table(model)) if model is not None else ""
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>msid report: {html.escape(os.path.abspath(outdir))}</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:1em auto}} th{{text-align:left;padding-right:1em}}
img{{max-width:100%}} td,th{{font-size:90%}}</style></head><body>
<h1>msid report</h1>
<p>FRF <code>frf.json</code>{' and model <code>model.json</code>' if model is not None else ''} in
<code>{html.escape(os.path.abspath(outdir))}</code>. Shaded bands: exact 95% regions from the file's covariance and
degrees of freedom (F(2, 2 dof), docs/statistics.md){'; red: the model, with the residuals in standard deviations' if model is not None else ''}.
Plot files: <a href="bode.png">bode.png</a>, <a href="bode.svg">bode.svg</a>.</p>
<h2>FRF</h2><table>{rows}</table>
{'<h2>Model</h2><table>' + mrows + '</table>' if model is not None else ''}
<h2>Bode plot</h2>
<img alt="Bode plot with 95% regions" src="data:image/png;base64,{base64.b64encode(png).decode()}">
</body></html>
"""
    out = os.path.join(outdir, "report.html")
    tmp = out + f".{os.getpid()}.tmp"
    try:
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(page)
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return out


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 1 or argv[0] in ("-h", "--help"):
        print(__doc__.strip().split("\n\n")[1].strip(), file=sys.stdout if argv[:1] in (["-h"], ["--help"]) else sys.stderr)
        return 0 if argv[:1] in (["-h"], ["--help"]) else 2
    from .plot import run_cli
    return run_cli("msid.report", lambda: write_report(argv[0]))


if __name__ == "__main__":
    sys.exit(main())
