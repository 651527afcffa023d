"""Matplotlib figures in the style of the paper (Figs 6 and 8)."""

from __future__ import annotations

import numpy as np


def new_figure(**kwargs):
    """A matplotlib Figure that needs no pyplot state or backend switch.

    It saves with `fig.savefig(...)` from scripts and the CLI, and shows inline in notebooks.
    """
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def _drawn(fig):
    """Draw `fig` (on an Agg canvas when it has none that renders) and return the renderer,
    so that text extents are those of the saved image."""
    canvas = fig.canvas
    if not hasattr(canvas, "get_renderer"):
        from matplotlib.backends.backend_agg import FigureCanvasAgg

        canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return canvas.get_renderer()


def fit_titles(fig, margin=2.0):
    """Wrap every title (of each axes, and the figure's suptitle) that runs past the
    figure's edges, then lay the figure out again; returns `fig`.

    A title is measured as drawn (its window extent against the figure's box, `margin`
    pixels inside, about its own centre); one too wide is re-wrapped from its original
    text at the width that fits (its own line breaks kept), and a figure without a layout
    engine is laid out again with `tight_layout`, so the title's height is made room for."""
    import textwrap
    import warnings

    original = {}
    for _ in range(4):
        renderer, box, changed = _drawn(fig), fig.bbox, False
        for t in [ax.title for ax in fig.axes] + list(fig.texts):
            if not t.get_text() or not t.get_visible():
                continue
            ext = t.get_window_extent(renderer)
            centre = 0.5 * (ext.x0 + ext.x1)
            room = 2 * min(centre - box.x0, box.x1 - centre) - 2 * margin
            if ext.width <= room:
                continue
            text = original.setdefault(id(t), t.get_text())
            chars = max(len(ln) for ln in t.get_text().split("\n"))
            width = max(10, int(chars * room / ext.width * 0.95))
            t.set_text("\n".join(w for ln in text.split("\n")
                                 for w in (textwrap.wrap(ln, width) or [""])))
            changed = True
        from matplotlib.layout_engine import PlaceHolderLayoutEngine

        if isinstance(fig.get_layout_engine(), (type(None), PlaceHolderLayoutEngine)):
            with warnings.catch_warnings():  # a figure too small for its titles: as it is
                warnings.simplefilter("ignore", UserWarning)
                fig.tight_layout()
        if not changed:
            break
    return fig


def titles_inside(fig, margin=0.5) -> list[str]:
    """The titles (axes titles and suptitle) whose drawn extent leaves the figure, as
    text (empty when every title lies inside); for tests."""
    renderer = _drawn(fig)
    box = fig.bbox
    out = []
    for t in [ax.title for ax in fig.axes] + list(fig.texts):
        if not t.get_text() or not t.get_visible():
            continue
        e = t.get_window_extent(renderer)
        if e.x0 < box.x0 - margin or e.x1 > box.x1 + margin or e.y0 < box.y0 - margin or \
                e.y1 > box.y1 + margin:
            out.append(t.get_text())
    return out


def pushover_curves(structure, umax=None, n=401):
    """The closed-form and numerical pushover curves on u in [0, umax] [m] (numpy arrays)."""
    import jax.numpy as jnp

    from ._pushover import pushover
    from .models import restoring_force

    s = structure
    if umax is None:
        umax = 0.99 * float(s.u_overturn)
    u = jnp.linspace(0.0, umax, n)
    num = pushover(s, u)
    return {
        "u": np.asarray(u),
        "simplified": np.asarray(restoring_force(s, u, "simplified")),
        "exact": np.asarray(restoring_force(s, u, "exact")),
        "numerical": np.asarray(num.P),
        "uplift": np.asarray(num.uplift),
        "theta": np.asarray(num.theta),
        "converged": bool(np.all(np.asarray(num.converged))),
    }


def plot_pushover(structure, curves=None, *, ax=None, title=None):
    """Fig. 6/8-style plot: simplified, exact and numerical k(u), with u_crit, P_crit and
    u_overturn marked. Returns the matplotlib Figure."""
    s = structure
    if curves is None:
        curves = pushover_curves(s)
    if ax is None:
        fig = new_figure(figsize=(7, 4.5))
        ax = fig.add_subplot()
    else:
        fig = ax.figure
    u_mm = 1e3 * curves["u"]
    ax.plot(
        u_mm, 1e-3 * curves["numerical"], color="0.6", lw=4, label="numerical pushover (rigid body)"
    )
    ax.plot(u_mm, 1e-3 * curves["exact"], color="C0", lw=1.5, label="exact: Eqs 13, 18")
    ax.plot(
        u_mm, 1e-3 * curves["simplified"], "--", color="C3", lw=1.5, label="simplified: Eqs 13, 20"
    )
    uc, pc, uo = float(s.u_crit), float(s.P_crit), float(s.u_overturn)
    ax.plot([1e3 * uc], [1e-3 * pc], "ko", ms=5)
    ax.annotate(
        f"$u_{{crit}}$ = {1e3 * uc:.2f} mm\n$P_{{crit}}$ = {pc:.0f} N",
        (1e3 * uc, 1e-3 * pc),
        xytext=(25, -10),
        textcoords="offset points",
        va="top",  # below the peak, which is the top of the frame
        fontsize=9,
    )
    ax.axvline(1e3 * uo, color="k", lw=0.8, ls=":")
    ax.annotate(
        f"$u_{{overturn}}$ = {1e3 * uo:.1f} mm",
        (1e3 * uo, 0.0),
        xytext=(-110, 20),
        textcoords="offset points",
        fontsize=9,
    )
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel("top displacement u [mm]")
    ax.set_ylabel("restoring force k(u) [kN]")
    ax.set_title(title or "Pushover of a rigid rocking structure on two springs")
    ax.legend(fontsize=9)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fit_titles(fig)


def _until_overturn(res):
    """(ts, mask): the output times and the samples up to t_overturn (all if it did not)."""
    ts = np.asarray(res.ts)
    t_ot = float(res.t_overturn)
    return ts, (ts <= t_ot) if np.isfinite(t_ot) else np.ones(ts.shape, bool)


def _ground_panel(ax, ground_motion, ts):
    ag = np.asarray(ground_motion.ground_acceleration(ts))
    ax.plot(ts, ag / 9.80665, color="0.3", lw=0.8)
    ax.set_ylabel("ground accel. [g]")
    ax.grid(alpha=0.3)


def _history_panels(ax_u, ax_up, res, label, overlay):
    """u and uplift [mm] of the main response and the overlays, each cut at its
    t_overturn (the arrays hold the state at overturning after it)."""
    ts, keep = _until_overturn(res)
    ax_u.plot(ts[keep], 1e3 * np.asarray(res.u)[keep], color="C0", lw=1.2, label=label)
    ax_up.plot(ts[keep], 1e3 * np.asarray(res.uplift)[keep], color="C0", lw=1.2, label=label)
    for i, (lab, other) in enumerate(overlay):
        t_o, k_o = _until_overturn(other)
        ax_u.plot(t_o[k_o], 1e3 * np.asarray(other.u)[k_o], lw=1.0, ls="--",
                  color=f"C{i + 1}", label=lab)
        ax_up.plot(t_o[k_o], 1e3 * np.asarray(other.uplift)[k_o], lw=1.0, ls="--",
                   color=f"C{i + 1}", label=lab)


def _marks(ax_u, s, res):
    """±u_crit dotted, impacts, and for an overturned run ±u_overturn and t_overturn."""
    uc = 1e3 * float(s.u_crit)
    for y in (uc, -uc):
        ax_u.axhline(y, color="k", lw=0.5, ls=":")
    imp = np.asarray(res.impact_times)[: int(res.n_impacts)]
    if imp.size and imp.size <= 60:
        ax_u.plot(imp, np.zeros_like(imp), "k|", ms=8, label="impacts")
    ax_u.axhline(0.0, color="k", lw=0.5)
    t_ot = float(res.t_overturn)
    if np.isfinite(t_ot):
        uo = 1e3 * float(s.u_overturn)
        for y in (uo, -uo):
            ax_u.axhline(y, color="C3", lw=0.6, ls="--")
        ax_u.axvline(t_ot, color="C3", lw=0.8, label=f"overturned at {t_ot:.3g} s")


def plot_response(structure, response, *, ground_motion=None, title=None, label=None,
                  overlay=(), note=None):
    """Fig 9/10-style time histories: displacement (impacts marked, ±u_crit dotted) and
    uplift, with the ground acceleration on top when given.

    After overturning the curves stop at `t_overturn` (marked, with ±u_overturn dashed).
    `overlay` is a sequence of `(label, Response)` drawn over the main one; `note` a text
    written in the displacement panel. Returns the Figure.
    """
    s = structure
    res = response
    panels = 3 if ground_motion is not None else 2
    fig = new_figure(figsize=(9, 2.4 * panels + 0.6))
    axes = fig.subplots(panels, 1, sharex=True)
    k = 0
    if ground_motion is not None:
        _ground_panel(axes[0], ground_motion, np.asarray(res.ts))
        k = 1
    ax_u, ax_up = axes[k], axes[k + 1]
    _history_panels(ax_u, ax_up, res, label, overlay)
    _marks(ax_u, s, res)
    ax_u.set_ylabel("displacement u [mm]")
    ax_up.set_ylabel("uplift [mm]")
    ax_up.set_xlabel("time [s]")
    for ax in (ax_u, ax_up):
        ax.grid(alpha=0.3)
    if label or overlay or np.isfinite(float(res.t_overturn)):
        ax_u.legend(fontsize=8, loc="upper right")
    if note:
        ax_u.text(0.99, 0.03, note, transform=ax_u.transAxes, ha="right", va="bottom",
                  fontsize=7, color="0.25", bbox=dict(fc="white", ec="0.8", alpha=0.85))
    status = _status_text(res.status)
    summary = (f"peak |u| = {1e3 * float(res.peak_u):.1f} mm, peak uplift = "
               f"{1e3 * float(res.peak_uplift):.1f} mm, {int(res.n_impacts)} impacts, {status}")
    if overlay:  # several models drawn: the numbers are the main curve's
        summary = f"{label or 'main curve'}: {summary}"
    axes[0].set_title((title + "\n" if title else "") + summary, fontsize=10)
    fig.tight_layout()
    return fit_titles(fig)


def _status_text(code):
    from ._response import STATUS_NAMES

    name = STATUS_NAMES.get(int(code), "?")
    return "OVERTURNED" if name == "overturned" else name.replace("_", " ")


# ------------------------------------------------------------------------------ sweeps
def _sweep_lines(ax_u, xs, order, res, lab_s, many, style):
    """Peak |u| of one sweep, one line per record (overturned runs as x at u_overturn,
    other failures as open squares). Returns (any overturned, any other failure, the
    failed runs as a boolean (n_records, n_scales) array in scale order)."""
    from ._status import STATUS

    status, peak = res.status[:, order], 1e3 * res.peak_u[:, order]
    over = status == STATUS["overturned"]
    other = ~over & (status != STATUS["completed"])
    u_ov = 1e3 * float(res.structure.u_overturn)
    for ri, lab_r in enumerate(res.labels):
        color = f"C{ri % 10}"
        ax_u.plot(xs, np.where(over[ri], np.nan, peak[ri]), style, marker="o", ms=3, lw=1.2,
                  color=color, label=f"{lab_s} / {lab_r}" if many else lab_r)
        if over[ri].any():
            ax_u.plot(xs[over[ri]], np.full(int(over[ri].sum()), u_ov), "x", ms=8, mew=1.6,
                      color=color)
        if other[ri].any():
            ax_u.plot(xs[other[ri]], peak[ri, other[ri]], "s", ms=7, mfc="none", color=color)
    return over.any(), other.any(), other


def _overturn_levels(ax_u, results, labels):
    """One dashed line per distinct u_overturn, labelled with its structures when several."""
    import math

    levels = {}
    for res, lab_s in zip(results, labels):
        u_ov = float(res.structure.u_overturn)
        key = next((k for k in levels if math.isclose(k, u_ov, rel_tol=1e-9)), None)
        levels.setdefault(u_ov if key is None else key, []).append(lab_s)
    for u_ov, labs in levels.items():
        label = "u_overturn" if len(levels) == 1 else f"u_overturn ({', '.join(labs)})"
        ax_u.axhline(1e3 * u_ov, color="0.45", lw=0.9, ls=(0, (5, 3)), label=label)


def _peak_legend(ax_u, any_over, any_other, n_lines):
    """The legend of the peak panel, with the marker keys; none beyond 24 lines."""
    handles, labels = ax_u.get_legend_handles_labels()
    if any_over:
        handles.append(ax_u.plot([], [], "x", color="k", ms=8, mew=1.6)[0])
        labels.append("overturned (at u_overturn)")
    if any_other:
        handles.append(ax_u.plot([], [], "s", color="k", ms=7, mfc="none")[0])
        labels.append("max_impacts / solver_failure")
    if n_lines <= 24:
        ax_u.legend(handles, labels, fontsize=7, ncol=2 if len(labels) > 6 else 1, loc="upper left")


def plot_sweeps(results, labels, *, title=None):
    """Peak |u| against scale (one line per structure x record; overturned runs as x at
    u_overturn) over the fraction overturned against scale (per structure, of the runs
    that completed or overturned; the fraction that failed, left out, as a grey line).

    `results`: `rockjax.SweepResult`s of the same records and scales, one per structure,
    `labels` their names. Returns a matplotlib Figure (no pyplot)."""
    x = np.asarray(results[0].scales, float)
    order = np.argsort(x, kind="stable")
    fig = new_figure(figsize=(8.5, 7.5), layout="constrained")
    ax_u, ax_f = fig.subplots(2, 1, sharex=True)
    styles, many, any_over, any_other = ["-", "--", ":", "-."], len(results) > 1, False, False
    for si, (res, lab_s) in enumerate(zip(results, labels)):
        o, f, other = _sweep_lines(ax_u, x[order], order, res, lab_s, many, styles[si % 4])
        any_over, any_other = any_over or o, any_other or f
        ax_f.plot(x[order], res.fraction_overturned()[order], styles[si % 4], marker="o", ms=4,
                  color=f"C{si % 10}", label=lab_s)
        if other.any():  # the failed runs, left out of the fraction
            ax_f.plot(x[order], np.mean(other, axis=0), styles[si % 4], marker="s", ms=4,
                      mfc="none", lw=0.8, color="0.5", label=f"{lab_s}: fraction failed "
                      "(left out)" if many else "fraction failed (left out)")
    _overturn_levels(ax_u, results, labels)
    _peak_legend(ax_u, any_over, any_other, sum(r.n_records for r in results))
    ax_u.set_ylabel("peak |u| [mm]")
    ax_u.set_title(title or "peak displacement against scale", fontsize=10)
    ax_f.set_ylim(-0.03, 1.03)
    ax_f.set_ylabel(f"fraction overturned (of {results[0].n_records}\nrecord(s), failed runs "
                    "left out)")
    ax_f.set_xlabel("scale factor on the records")
    if many or any_other:
        ax_f.legend(fontsize=8)
    for ax in (ax_u, ax_f):
        ax.grid(alpha=0.3)
    return fit_titles(fig)


# ------------------------------------------------------------------------------- fits
def _fit_values(fit):
    return ", ".join(f"{p} = {fit.values[p]:.4g} ± {fit.stderr[p]:.2g}" for p in fit.names)


def plot_fit(trace, fit, *, title=None, measured_label="measured"):
    """Measured and fitted displacement (and uplift, when measured) of a decay trace and
    its fit (`identification.fit_decay`), with a residual panel. Returns a matplotlib
    Figure (no pyplot)."""
    t = np.asarray(trace.t)
    channels = [(c, label, np.asarray(getattr(trace, c)), np.asarray(getattr(fit.response, c)),
                 color) for c, label, color in (("u", "displacement u [mm]", "C0"),
                                                ("theta", "rotation θ [mrad]", "C1"),
                                                ("uplift", "uplift [mm]", "C2"))
                if getattr(trace, c, None) is not None]  # the channels the trace has
    panels = len(channels) + 1
    fig = new_figure(figsize=(9, 2.3 * panels + 0.8))
    axes = fig.subplots(panels, 1, sharex=True,
                        gridspec_kw={"height_ratios": [2] * (panels - 1) + [1]})
    ax_res = axes[-1]
    for ax, (name, ylabel, measured, fitted, color) in zip(axes, channels):
        ax.plot(t, 1e3 * measured, ".", ms=2, color="0.45", label=measured_label)
        ax.plot(t, 1e3 * fitted, color="C3", lw=1.1, label="fitted")
        ax.set_ylabel(ylabel)
        ax_res.plot(t, 1e3 * (measured - fitted), color=color, lw=0.7, label=name)
    axes[0].legend(fontsize=8, loc="upper right")
    if len(channels) > 1:
        ax_res.legend(fontsize=8, loc="upper right", ncol=2)
    ax_res.axhline(0.0, color="k", lw=0.5)
    units = dict.fromkeys("mrad" if c[0] == "theta" else "mm" for c in channels)
    unit = next(iter(units))  # of fit.rms: the first channel's
    ax_res.set_ylabel(f"residual [{', '.join(units)}]")
    ax_res.set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
    conv = "converged" if fit.converged else "NOT converged"
    axes[0].set_title((title + "\n" if title else "") + f"{_fit_values(fit)}; rms residual "
                      f"{1e3 * fit.rms:.3g} {unit}, {conv}", fontsize=10)
    fig.tight_layout()
    return fit_titles(fig)


def plot_joint_fit(traces, fit, *, title=None):
    """Measured and fitted displacement of each trace of a joint fit, one panel each.
    Returns a matplotlib Figure (no pyplot)."""
    import pathlib

    fig = new_figure(figsize=(9, 2.0 * len(traces) + 0.8))
    axes = np.atleast_1d(fig.subplots(len(traces), 1, sharex=True))
    for ax, tr, resp, d in zip(axes, traces, fit.responses, fit.per_trace):
        ax.plot(tr.t, 1e3 * np.asarray(tr.u), ".", ms=2, color="0.45", label="measured")
        ax.plot(tr.t, 1e3 * np.asarray(resp.u), color="C3", lw=1.1, label="fitted")
        ax.set_ylabel("u [mm]")
        ax.set_title(f"{pathlib.Path(d['source']).name}: rms residual "
                     f"{1e3 * d['rms']:.3g} mm", fontsize=9)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, loc="upper right")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle((title + "\n" if title else "") + _fit_values(fit), fontsize=10)
    fig.tight_layout()
    return fit_titles(fig)


def plot_fragility_band(band, ax=None, n_curves=40):
    """`rockjax.FragilityBand.plot`: the band, the median, pooled and point-estimate curves
    and up to `n_curves` of the draws' curves, against the IM."""
    if ax is None:
        ax = new_figure(figsize=(6.5, 4.5), layout="constrained").subplots()
    g = band.grid
    rows = np.flatnonzero(~np.all(np.isnan(band.curves), axis=1))
    for k, i in enumerate(rows[:: max(1, rows.size // n_curves)][:n_curves]):
        ax.plot(g, band.curves[i], color="0.5", lw=0.5, alpha=0.3,
                label="curves of the draws" if k == 0 else None)
    ax.fill_between(g, band.band[0], band.band[1], color="C0", alpha=0.25, lw=0,
                    label=f"{band.confidence:.0%} band over {band.n_draws} draws")
    ax.plot(g, band.median_curve, color="C0", lw=2, label="median curve")
    ax.plot(g, band.pooled, color="C1", lw=1.5, ls="--",
            label="pooled (mean probability, posterior predictive)")
    if band.point is not None:
        pt = band.point
        ax.plot(g, pt.probability(g), color="k", lw=1.2, ls=":",
                label=f"point estimate: median {pt.median:.4g} {band.im_unit}, β {pt.beta:.3g}")
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel(f"{band.im} [{band.im_unit}]" if band.im_unit != "-" else "scale factor")
    ax.set_ylabel(f"P({band.limit} | {band.im})")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    return ax
