"""Bode plots of an msid FRF with its exact 95% regions, a model overlay, normalised residuals and the
stabilisation diagram (matplotlib; docs/python.md).

    python3 -m msid.plot FRF.json [--model MODEL.json] [--level 0.95] [--known-input] -o OUT.png|OUT.svg|OUT.pdf

Per output/input pair (column = input, rows per output): magnitude (dB) and phase (degrees) of the
estimate with the band the `level` confidence disc of radius r sweeps (docs/statistics.md: r^2 = v q,
q the quantile of F(2, 2 dof), F(1, dof) on DC lines; chi2 only when the file has no dof):
magnitude |G| -/+ r, phase -/+ asin(r/|G|) (all phases once r >= |G|). With a model: its response on a
dense grid, and the residual |Ghat - G_model| / sqrt(v) per line against the `level` threshold sqrt(q).
A model file with an `order_selection` block adds the stabilisation diagram (pole frequency vs order).

Noise-dominated lines (the `level` region covers the origin, r >= |G|: the phase is unknown there) are
drawn as open markers without joining the phase line, and the phase is unwrapped across the other
lines only, so one such line cannot shift every later line by 360 degrees. An ETFE file
(`msid frf --method etfe`) also gets the band of its finite-sample bound (Tsiamis et al. 2024
Theorem 1): `||Ghat - G||_2 <= bound` for all lines jointly with probability 1 - delta, so every
element lies within `bound` of its estimate (|G| -/+ bound, phase -/+ asin(bound/|G|)).

The figures are plain matplotlib Figure objects (no pyplot state): `bode(frf, model)` returns one.
"""
import argparse
import os
import sys
from typing import Any, Callable, Optional, Sequence, Union

import numpy as np

from . import regions
from .files import FRF, Model, FormatError, read_frf, read_model

PathLike = Union[str, "os.PathLike[str]"]

REGION_LABEL = "95% region"
BOUND_LABEL = "ETFE bound"
NOISE_LABEL = "noise-dominated line"
FLAG_STYLE = {  # stabilisation flags of docs/fitting.md: s stabilised pole, d damping, f frequency, o new
    # "stabilised": the pole repeats from the order below; it says nothing of the system's stability
    "s": ("o", "tab:green", "f, zeta stabilised"),
    "d": ("D", "tab:blue", "f stabilised, zeta moved"),
    "f": ("s", "tab:orange", "f moved"),
    "o": ("+", "tab:red", "new pole"),
}


def _db(x):
    with np.errstate(divide="ignore"):
        return 20 * np.log10(x)


def _model_axis_points(frf, f_axis):
    """Complex points where the model is evaluated for plot-axis frequencies f_axis (Hz or cycles/sample)."""
    _, unit = frf.hz_axis()
    if frf.domain == "ct":
        return 1j * 2 * np.pi * f_axis
    h = frf.sample_time if (unit == "Hz" and frf.sample_time) else 1.0
    return np.exp(2j * np.pi * f_axis * h)


def unwrap_phase(G: np.ndarray, noisy: Optional[np.ndarray] = None) -> np.ndarray:
    """Phase (radians) of G along axis 0, unwrapped across the lines where `noisy` is False only: each
    such line takes the branch nearest the previous one (np.unwrap where nothing is noisy); a noisy
    line takes the branch nearest the last line before it (the first clean line after it at the start),
    and never moves the lines after it."""
    G = np.asarray(G)
    ang = np.angle(G)
    if noisy is None:
        return np.unwrap(ang, axis=0)
    noisy = np.broadcast_to(np.asarray(noisy, bool), ang.shape)
    out = np.array(ang, float)
    flat_a, flat_n, flat_o = (x.reshape(len(ang), -1) for x in (ang, noisy, out))
    two_pi = 2 * np.pi
    for c in range(flat_a.shape[1]):
        a, nz, o = flat_a[:, c], flat_n[:, c], flat_o[:, c]
        clean = np.flatnonzero(~nz)
        ref = None
        for k in range(len(a)):
            if nz[k]:
                r = ref if ref is not None else (a[clean[0]] if len(clean) else a[k])
                o[k] = a[k] + two_pi * np.round((r - a[k]) / two_pi)
                continue
            o[k] = a[k] if ref is None else a[k] + two_pi * np.round((ref - a[k]) / two_pi)
            ref = o[k]
        # the first clean line keeps its principal value; noisy lines before it were placed near it
    return flat_o.reshape(ang.shape)


def etfe_bound(frf: FRF) -> Optional[np.ndarray]:
    """The per-line ETFE bound (L,) of an `msid frf --method etfe` file, or None."""
    if frf.meta.get("method") != "etfe" or not frf.line_extra or not all("bound" in e for e in frf.line_extra):
        return None
    b = np.array([float(e["bound"]) for e in frf.line_extra])
    return b if np.all(np.isfinite(b)) else None


def _disc_band(am, ap, f, m, ph, rad, color, alpha, label):
    """The band a disc of radius `rad` around each estimate sweeps: |G| -/+ rad on the magnitude axes
    `am` (the lower edge at a floor where the disc covers the origin), phase -/+ asin(rad/|G|) on `ap`
    (all phases once rad >= |G|)."""
    lo = np.where(rad < m, m - rad, np.nan)
    floor = np.nanmin(np.concatenate([lo, m])) / 10 if np.any(m > 0) else 1e-12
    lo = np.where(np.isnan(lo), floor, lo)
    am.fill_between(f, _db(lo), _db(m + rad), color=color, alpha=alpha, linewidth=0, label=label)
    half = np.degrees(np.arcsin(np.clip(rad / np.where(m > 0, m, 1), 0, 1)))
    half = np.where(rad >= m, 180.0, half)
    ap.fill_between(f, ph - half, ph + half, color=color, alpha=alpha, linewidth=0, label=label)


def _grid(f):
    f = np.asarray(f, float)
    lo, hi = f.min(), f.max()
    if lo > 0 and hi > lo:
        return np.geomspace(lo, hi, 600)
    return np.linspace(lo, hi if hi > lo else lo + 1, 600)


def bode(frf: Union[FRF, PathLike], model: Union[Model, PathLike, None] = None, level: float = 0.95,
         which: str = "cov", title: Optional[str] = None) -> Any:
    """A matplotlib Figure: Bode magnitude/phase with `level` regions for every output/input pair of `frf`
    (an FRF or a path), the model overlay and residual rows when `model` (Model or path) is given, and
    the stabilisation diagram when the model carries one."""
    from matplotlib.figure import Figure

    if not isinstance(frf, FRF):
        frf = read_frf(frf)
    if model is not None and not isinstance(model, Model):
        model = read_model(model)
    if model is not None and (model.n_inputs, model.n_outputs) != (frf.n_inputs, frf.n_outputs):
        raise FormatError(f"the model is {model.n_outputs}x{model.n_inputs} but the FRF is "
                          f"{frf.n_outputs}x{frf.n_inputs}")
    ny, nu = frf.n_outputs, frf.n_inputs
    ins, outs = frf.signal_names()
    f, unit = frf.hz_axis()
    logx = bool(np.all(f > 0))
    r = frf.radius(level, which)
    var = frf.variance(which)
    rows_per_out = 3 if model is not None else 2
    stab = model.stabilisation if model is not None else None
    nrows = ny * rows_per_out + (1 if stab else 0)
    ratios = ([3, 2, 1.4] if model is not None else [3, 2]) * ny + ([3] if stab else [])
    height = 1.35 * sum(ratios) + 0.8
    fig = Figure(figsize=(4.2 * nu + 1.0, height))
    # fixed margins (a constrained layout costs a second draw)
    # the stabilisation diagram's right axis (mode indicator) needs a margin for its labels
    right = 1 - (0.75 if stab else 0.1) / (4.2 * nu + 1.0)
    gs = fig.add_gridspec(nrows, nu, height_ratios=ratios, left=0.9 / (4.2 * nu + 1.0), right=right,
                          bottom=0.55 / height, top=1 - 0.8 / height, hspace=0.45, wspace=0.25)
    mag = np.abs(frf.G)
    noisy = (r >= mag) if r is not None else np.zeros(mag.shape, bool)
    phase = np.degrees(unwrap_phase(frf.G, noisy))
    bound = etfe_bound(frf)
    if model is not None:
        fg = _grid(f)
        Gd = model.response_at(_model_axis_points(frf, fg))
        Gl = model.response(frf)
        thr = regions.radius(1.0, None if (frf._pick(which)[1] is None) else frf._pick(which)[1][:, None, None],
                           level, frf.real[:, None, None]) if var is not None else None
    lev = f"{100 * level:g}%"
    bottom = {}  # input -> the lowest axes of its column
    for i in range(ny):
        for j in range(nu):
            base = i * rows_per_out
            am = fig.add_subplot(gs[base, j])
            ap = fig.add_subplot(gs[base + 1, j], sharex=am)
            g, m, ph, nz = frf.G[:, i, j], mag[:, i, j], phase[:, i, j], noisy[:, i, j]
            if bound is not None:
                _disc_band(am, ap, f, m, ph, bound, "tab:orange", 0.18, BOUND_LABEL)
            if r is not None:
                _disc_band(am, ap, f, m, ph, r[:, i, j], "tab:blue", 0.25, REGION_LABEL.replace("95%", lev))
            am.plot(f, _db(m), "o-", color="tab:blue", ms=3, lw=1, label="estimate")
            # noise-dominated lines: open markers, not joined (the phase line breaks there)
            ap.plot(f, np.where(nz, np.nan, ph), "o-", color="tab:blue", ms=3, lw=1, label="estimate")
            if np.any(nz):
                ap.plot(f[nz], ph[nz], "o", color="tab:blue", ms=3, mfc="none", lw=0, label=NOISE_LABEL)
            if model is not None:
                gd = Gd[:, i, j]
                pd = np.degrees(np.unwrap(np.angle(gd)))
                # put the model's phase on the branch of the estimate at the line nearest the grid start
                cand = np.flatnonzero(~nz) if np.any(~nz) else np.arange(len(f))
                k0 = int(cand[np.argmin(np.abs(f[cand] - fg[0]))])
                pd += 360.0 * np.round((ph[k0] - np.degrees(np.angle(Gl[k0, i, j])) -
                                        (pd[0] - np.degrees(np.angle(gd[0])))) / 360.0)
                am.plot(fg, _db(np.abs(gd)), "-", color="tab:red", lw=1.2, label="model")
                ap.plot(fg, pd, "-", color="tab:red", lw=1.2, label="model")
                ar = fig.add_subplot(gs[base + 2, j], sharex=am)
                if var is not None:
                    nr = regions.normalised_residual(g - Gl[:, i, j], var[:, i, j])
                    ar.stem(f, nr, linefmt="tab:red", markerfmt="o", basefmt=" ", label="|e|/sd")
                    ar.plot(f, thr[:, 0, 0], "--", color="k", lw=0.8, label=f"{lev} limit")
                    ar.set_ylabel("|e|/sd")
                else:
                    ar.stem(f, np.abs(g - Gl[:, i, j]), linefmt="tab:red", markerfmt="o", basefmt=" ")
                    ar.set_ylabel("|e|")
                ar.grid(True, alpha=0.3)
                bottom[j] = ar
            else:
                bottom[j] = ap
            gunit = frf.gain_unit(i, j)
            am.set_ylabel(f"|G| (dB re 1 {gunit})" if gunit else "|G| (dB)")
            ap.set_ylabel("phase (deg)")
            am.set_title(f"{outs[i]} / {ins[j]}", fontsize=10)
            for a in (am, ap):
                a.grid(True, alpha=0.3)
                if logx:
                    a.set_xscale("log")
            if i == 0 and j == 0:
                am.legend(fontsize=7, loc="best")
    for a in bottom.values():
        a.set_xlabel(f"frequency ({unit})")
    if stab:
        stabilisation(stab, fig.add_subplot(gs[-1, :]), model, frf=frf)
    fig.suptitle(title or _title(frf, model), fontsize=10)
    return fig


def mode_indicator(frf: FRF) -> np.ndarray:
    """The complex mode indicator function of an FRF: the singular values of G at every line, (L, min(ny, nu)),
    largest first. Peaks of the first mark the modes (a SISO FRF: |G|)."""
    return np.linalg.svd(frf.G, compute_uv=False)


def stabilisation(block: dict, ax: Any, model: Optional[Model] = None, frf: Optional[FRF] = None) -> None:
    """Draw an `order_selection` block (docs/fitting.md) on `ax`: pole frequency against model order,
    one marker per stabilisation flag, the chosen order marked. With `frf` the axis spans the Bode plot's
    frequency range (poles outside it are counted in the title) and the FRF's mode indicator function
    (singular values of G, dB, right axis) is drawn in grey behind the poles."""
    from matplotlib.ticker import LogFormatter, MaxNLocator, NullFormatter
    orders = block.get("orders", [])
    seen = set()
    f_lo = f_hi = None
    if frf is not None:
        fa, _ = frf.hz_axis()
        f_lo, f_hi = float(np.min(fa)), float(np.max(fa))
    outside = 0
    for o in orders:
        if not o.get("ok"):
            continue
        for p in o.get("poles", []):
            if f_lo is not None and not (f_lo <= p["fn"] <= f_hi):
                outside += 1
                continue
            fl = p.get("flag", "o")
            mk, col, lab = FLAG_STYLE.get(fl, FLAG_STYLE["o"])
            ax.plot(p["fn"], o["order"], mk, color=col, ms=5, mfc="none" if mk != "+" else None,
                    label=None if fl in seen else lab, zorder=3)
            seen.add(fl)
    ch = block.get("chosen")
    if ch is not None:
        ax.axhline(ch, color="k", lw=0.8, ls=":", label=f"chosen order {ch}", zorder=2)
    unit = "Hz"
    if model is not None:
        unit = (model.doc.get("modes") or {}).get("frequency_unit") or ("Hz" if model.sample_time else "cycles/sample")
    logx = any(p["fn"] > 0 for o in orders if o.get("ok") for p in o.get("poles", []))
    if frf is not None:
        logx = f_lo > 0
        # the mode indicator behind the poles, on its own (right) axis
        mif = ax.twinx()
        sv = mode_indicator(frf)
        for k in range(sv.shape[1]):
            mif.plot(fa, _db(sv[:, k]), "-", color="0.55" if k == 0 else "0.8", lw=1.0,
                     label="mode indicator (sv of G)" if k == 0 else None)
        mif.set_ylabel("sv(G) (dB)", color="0.4")
        mif.tick_params(axis="y", colors="0.4", labelsize=8)
        ax.set_zorder(mif.get_zorder() + 1)   # the poles above the grey curves
        ax.patch.set_visible(False)
        ax.set_xlim(f_lo, f_hi)
    ax.set_xlabel(f"pole frequency ({unit})")
    ax.set_ylabel("order")
    title = "stabilisation diagram"
    if outside:
        title += f" ({outside} poles outside the measured band not shown)"
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ok_orders = [o["order"] for o in orders if o.get("ok")]
    if ok_orders:
        lo, hi = min(ok_orders) - 0.5, max(ok_orders) + 0.5
        ax.set_ylim(lo, hi + 0.35 * (hi - lo))   # headroom: the legend sits above the highest order
    if logx:
        ax.set_xscale("log")
        # a band of less than a decade labels its minor ticks: keep the labels apart
        ax.xaxis.set_major_formatter(LogFormatter(labelOnlyBase=False, minor_thresholds=(2, 0.5)))
        ax.xaxis.set_minor_formatter(NullFormatter() if _decades(ax) > 1.5 else
                                     LogFormatter(labelOnlyBase=False, minor_thresholds=(2, 0.5)))
    handles, labels = ax.get_legend_handles_labels()
    if frf is not None:
        h2, l2 = mif.get_legend_handles_labels()
        handles, labels = handles + h2, labels + l2
    ax.legend(handles, labels, fontsize=7, loc="upper left", ncol=2, framealpha=0.85)
    return ax


def _decades(ax):
    lo, hi = ax.get_xlim()
    return np.log10(hi / lo) if lo > 0 and hi > lo else 0.0


def incomplete_note(frf: FRF) -> str:
    """'' for a complete measurement, else 'INCOMPLETE (reason; k of m experiments)': `msid measure`
    writes "complete": false when it was stopped (docs/frf-format.md)."""
    m = frf.meta
    if m.get("complete", True) is not False:
        return ""
    parts = [str(m["incomplete_reason"])] if m.get("incomplete_reason") else []
    if m.get("experiments_planned") is not None:
        parts.append(f"{m.get('experiments_completed', '?')} of {m['experiments_planned']} experiments complete")
    return "INCOMPLETE" + (f" ({'; '.join(parts)})" if parts else "")


def _title(frf, model):
    inc = incomplete_note(frf)
    nl = frf.meta.get("nonlinear_distortion") or {}
    what = f"{frf.meta.get('method', 'periodic')} FRF"
    if int(nl.get("realisations", 1) or 1) >= 2:   # the regions are of the total (noise + distortion) covariance
        what = f"BLA of {nl['realisations']} realisations" + \
            (" (one period each: total covariance only)" if nl.get("noise_separated") is False else "")
    t = ("INCOMPLETE: " if inc else "") + f"{what}, {frf.n_outputs}x{frf.n_inputs}, {frf.n_lines} lines"
    if frf.dof is not None:
        t += f", dof {np.min(frf.dof):.3g}" + (f"..{np.max(frf.dof):.3g}" if np.ptp(frf.dof) > 0 else "")
    if model is not None:
        t += f"; model: {model.doc.get('method', '?')} order {model.order}"
    return t


def save(fig: Any, path: PathLike) -> None:
    """Save a figure (format from the extension: png, svg, pdf) atomically and reproducibly."""
    ext = os.path.splitext(path)[1].lower().lstrip(".")
    if ext not in ("png", "svg", "pdf"):
        raise ValueError(f"'{path}': the output must end in .png, .svg or .pdf")
    d = os.path.dirname(os.path.abspath(path))
    tmp = os.path.join(d, f".{os.path.basename(path)}.{os.getpid()}.tmp")
    import matplotlib
    # determinism: no dates in SVG/PDF, fixed SVG id salt: the same files give the same bytes
    md = {"svg": {"Date": None}, "pdf": {"CreationDate": None}}.get(ext, {})
    try:
        with matplotlib.rc_context({"svg.hashsalt": "msid"}):
            fig.savefig(tmp, format=ext, dpi=110, metadata=md)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python3 -m msid.plot",
                                 description="Bode plot of an msid-frf/1 file with exact 95%% regions, "
                                             "a model overlay and normalised residuals")
    ap.add_argument("frf", help="msid-frf/1 file")
    ap.add_argument("--model", help="msid-model/1 file to overlay")
    ap.add_argument("-o", "--output", required=True, help="OUT.png, OUT.svg or OUT.pdf")
    ap.add_argument("--level", type=float, default=0.95, help="confidence level of the regions (default 0.95)")
    ap.add_argument("--known-input", action="store_true", help="regions from cov_known_input instead of cov")
    a = ap.parse_args(argv)
    if not 0 < a.level < 1:
        ap.error("--level must be in (0, 1)")
    if os.path.splitext(a.output)[1].lower() not in (".png", ".svg", ".pdf"):
        ap.error(f"'{a.output}': the output must end in .png, .svg or .pdf")
    return run_cli("msid.plot", lambda: save(bode(a.frf, a.model, level=a.level,
                                                   which="known-input" if a.known_input else "cov"), a.output) or a.output)


def run_cli(prog: str, job: Callable[[], Any]) -> int:
    """The shared end of the plot/report entry points: exit 3 with one message without matplotlib,
    1 with one message on a bad file, else 0 after printing what `job()` wrote."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        print(f"{prog}: error: matplotlib is not installed (Debian: apt-get install python3-matplotlib; "
              "else pip install matplotlib)", file=sys.stderr)
        return 3
    try:
        out = job()
    except (FormatError, ValueError, OSError) as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 1
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
