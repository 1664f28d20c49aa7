"""One-page HTML report of a measurement directory (docs/python.md).

    python3 -m msid.report OUTDIR [--command "msid measure ..."]

reads OUTDIR/frf.json (msid-frf/1) and, when present, OUTDIR/model.json (msid-model/1), writes the Bode
plot (msid.plot.bode: 95% regions, model overlay, residuals, stabilisation diagram) as OUTDIR/bode.png
and OUTDIR/bode.svg, and OUTDIR/report.html: a self-contained page (the PNG embedded as data) with the
plot and the figures of the files: when and by which msid the FRF was written, the command line (given
by `msid measure`), the design (OUTDIR/design.json: period, rate, lines, amplitudes), the channels
with their names and units, lines, periods, dof, acquisition counters, model cost, stability and modes.
An interrupted run ("complete": false) says INCOMPLETE in the title, a banner and the plot title.
Exit status 0, 1 with one message on a bad or missing file (nothing written), 3 without matplotlib.
"""
import base64
import datetime
import html
import json
import os
import sys
from typing import Optional, Sequence, Union

import numpy as np

from .files import read_frf, read_model
from .types import Model
from .plot import incomplete_note

PathLike = Union[str, "os.PathLike[str]"]


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
    if incomplete_note(frf):
        rows.insert(0, ("complete", incomplete_note(frf)))
    acq = m.get("acquisition")
    if isinstance(acq, dict):
        for k in ("transport", "endpoint", "interface", "samples", "samples_lost", "frames_missing", "retries",
                  "timeouts", "kernel_drops", "bus_state"):
            if k in acq:
                rows.append((f"acquisition {k}", _fmt(acq[k])))
    nl = m.get("nonlinear_distortion")
    if isinstance(nl, dict) and nl.get("noise_separated") is False:
        rows.append(("nonlinear distortion", f"{nl.get('realisations')} realisations of one period: not separated "
                     "from the noise (cov is their total)"))
    elif isinstance(nl, dict):
        rows.append(("nonlinear distortion", f"p = {_fmt(nl.get('p_value'))}, detected {nl.get('distortion_detected')}"))
    return rows


def format_bins(bins: Sequence[int]) -> str:
    """1,3,5:2:11 - a bin list in msid's --lines syntax (runs of three or more as a:step:b)."""
    b = [int(x) for x in bins]
    out, i = [], 0
    while i < len(b):
        j = i + 1
        if j < len(b):
            st = b[j] - b[i]
            while j + 1 < len(b) and b[j + 1] - b[j] == st:
                j += 1
            if j - i >= 2:
                out.append(f"{b[i]}:{b[j]}" if st == 1 else f"{b[i]}:{st}:{b[j]}")
                i = j + 1
                continue
        out.append(str(b[i]))
        i += 1
    return ",".join(out)


def _when(path):
    t = datetime.datetime.fromtimestamp(os.path.getmtime(path), datetime.timezone.utc)
    return t.strftime("%Y-%m-%d %H:%M:%S UTC")


def _run_table(outdir, frf, model, command):
    """When, by what and how: the provenance rows of the report."""
    from . import __version__
    m = frf.meta
    rows = [("FRF written", _when(os.path.join(outdir, "frf.json"))),
            ("report written", datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")),
            ("msid", f"{m.get('generator', 'unknown')} (FRF)"
                     + (f", {model.doc['generator']} (model)" if model is not None and model.doc.get("generator") else "")
                     + f", Python package {__version__}"),
            ("command line", command or "not recorded (msid measure passes it)")]
    if m.get("source"):
        rows.append(("source", m["source"]))
    return rows


def _design_table(outdir, frf):
    """Period, rate, lines and amplitudes: from OUTDIR/design.json when present, else from the FRF."""
    m = frf.meta
    rows = []
    design = None
    dp = os.path.join(outdir, "design.json")
    if os.path.exists(dp):
        try:
            with open(dp, encoding="utf-8") as fh:
                design = json.load(fh)
        except (OSError, ValueError):
            design = None
    P = (design or {}).get("period_samples", m.get("period_samples"))
    rows.append(("period", f"{P} samples" if P is not None else "unknown"))
    h = frf.sample_time
    if h:
        rows.append(("sample rate", f"{1.0 / h:.6g} Hz" + (f" (period {P * h:.6g} s)" if P else "")))
    else:
        rows.append(("sample rate", "unknown (frequencies in cycles/sample)"))
    if design and isinstance(design.get("lines"), list) and design["lines"]:
        lines = design["lines"]
        rows.append(("excited lines (bins)", f"{format_bins([ln['bin'] for ln in lines])} ({len(lines)} lines)"))
        amp = np.array([ln.get("amplitude", []) for ln in lines], dtype=float)
        if amp.size:
            lo, hi = float(amp.min()), float(amp.max())
            rows.append(("amplitudes (peak)", f"{lo:.6g}" + (f" .. {hi:.6g}" if hi > lo else " (every line and input)")))
        rows.append(("inputs x experiments", f"{design.get('n_inputs')} x {design.get('n_experiments')}, "
                                             f"{design.get('phase_mode', '?')} phases"
                                             + (f", seed {design['seed']}" if "seed" in design else "")))
    elif frf.bins is not None:
        rows.append(("lines (bins)", format_bins(frf.bins) + " (no design.json: the FRF's lines)"))
    return rows


def _channel_table(frf):
    """One row per input and output: its name and unit when the file carries them."""
    ins, outs = frf.signal_names()
    m = frf.meta
    rows = []
    for kind, names, ukey in (("input", ins, "input_units"), ("output", outs, "output_units")):
        units = m.get(ukey) if isinstance(m.get(ukey), list) and len(m.get(ukey)) == len(names) else None
        for k, n in enumerate(names):
            rows.append((f"{kind} {k + 1}", f"{n}" + (f" [{units[k]}]" if units and units[k] else " (unit not recorded)")))
    return rows


def stability_text(model: Model) -> str:
    """One unambiguous sentence on the model's poles: stable, or how many are unstable, with the bound."""
    ev = np.linalg.eigvals(model.A) if model.order else np.zeros(0)
    n = len(ev)
    if model.domain == "ct":
        bad = int(np.sum(ev.real >= 0))
        worst = f"largest real part {ev.real.max():.4g} rad/s" if n else ""
        region = "in the left half plane"
    else:
        bad = int(np.sum(np.abs(ev) >= 1))
        worst = f"largest |pole| {np.abs(ev).max():.6g}" if n else ""
        region = "inside the unit circle"
    if n == 0:
        return "stable (no poles: a static gain)"
    if bad == 0:
        return f"stable: all {n} poles {region} ({worst})"
    return f"UNSTABLE: {bad} of {n} poles not {region} ({worst})"


def _model_table(model):
    d = model.doc
    rows = [("method", d.get("method")), ("order", model.order), ("domain", d.get("domain")),
            ("stability of the model", stability_text(model))]
    if (d.get("stability") or {}).get("enforced"):
        rows.append(("stability enforced", "yes (--stable)"))
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


def write_report(outdir: PathLike, command: Optional[str] = None) -> str:
    """Write OUTDIR/bode.png, OUTDIR/bode.svg and OUTDIR/report.html; returns the report's path.
    `command`: the command line that made OUTDIR (msid measure passes it), shown in the report."""
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
    run_rows = "".join(_row(k, _fmt(v)) for k, v in _run_table(outdir, frf, model, command))
    design_rows = "".join(_row(k, _fmt(v)) for k, v in _design_table(outdir, frf))
    channel_rows = "".join(_row(k, _fmt(v)) for k, v in _channel_table(frf))
    mrows = "".join(_row(k, _fmt(v)) for k, v in _model_table(model)) if model is not None else ""
    inc = incomplete_note(frf)
    flag = "INCOMPLETE " if inc else ""
    banner = (f'<p class="incomplete"><strong>{html.escape(inc)}</strong>: the measurement was stopped before its '
              'end; the FRF holds the complete periods acquired until then.</p>' if inc else "")
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{flag}msid report: {html.escape(os.path.abspath(outdir))}</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:1em auto}} th{{text-align:left;padding-right:1em}}
img{{max-width:100%}} td,th{{font-size:90%}} .incomplete{{color:#a00;border:2px solid #a00;padding:.5em}}</style>
</head><body>
<h1>{flag}msid report</h1>
{banner}
<p>FRF <code>frf.json</code>{' and model <code>model.json</code>' if model is not None else ''} in
<code>{html.escape(os.path.abspath(outdir))}</code>. Shaded bands: exact 95% regions from the file's covariance and
degrees of freedom (F(2, 2 dof), docs/statistics.md){'; red: the model, with the residuals in standard deviations' if model is not None else ''}.
Plot files: <a href="bode.png">bode.png</a>, <a href="bode.svg">bode.svg</a>.</p>
<h2>Run</h2><table>{run_rows}</table>
<h2>Design</h2><table>{design_rows}</table>
<h2>Channels</h2><table>{channel_rows}</table>
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


def main(argv: Optional[Sequence[str]] = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    usage = __doc__.strip().split("\n\n")[1].strip()
    if argv[:1] in (["-h"], ["--help"]):
        print(usage)
        return 0
    command = None
    if len(argv) == 3 and argv[1] == "--command":
        command = argv[2]
        argv = argv[:1]
    if len(argv) != 1 or argv[0].startswith("-"):
        print(usage, file=sys.stderr)
        return 2
    from .plot import run_cli
    return run_cli("msid.report", lambda: write_report(argv[0], command))


if __name__ == "__main__":
    sys.exit(main())
