"""`rockjax fit`: fit k_f and r (and u0, t0) to a measured free-vibration decay trace.

`identification` (optax and the fit's JAX code) is imported inside the functions that need
it, so that `rockjax --help` and the other commands do not pay for it.
"""

from __future__ import annotations

import json
import math
import pathlib
import warnings

import numpy as np

from rockjax import _plotting

from ._common import _check_png, _load_structure, _starts, CLIError

_FIT_UNITS = {"k_f": "N/m", "r": "-", "u0": "m", "t0": "s"}


def add_parser(subparsers):
    f = subparsers.add_parser(
        "fit",
        help="fit k_f and r (and u0, t0) to a measured free-vibration decay trace",
        description="Fit the foundation stiffness k_f and the coefficient of restitution r "
        "(optionally the release displacement u0 and time t0) of a structure to a "
        "free-vibration decay trace: a CSV file with header 't,u' or 't,u,uplift' (SI "
        "units: s, m, m; leading '#' comment lines allowed). The fit starts from the "
        "structure's k_f and its Eq 3 restitution and reports standard errors, the k_f-r "
        "correlation and identifiability warnings.",
    )
    f.add_argument("trace", metavar="TRACE.csv", help="decay trace (t,u[,uplift])")
    f.add_argument(
        "--structure",
        metavar="FILE.toml",
        help="structure file (default: Table 1); its k_f and Eq 3 r are the start",
    )
    f.add_argument(
        "--params",
        nargs="+",
        choices=["k_f", "r", "u0", "t0"],
        default=["k_f", "r"],
        metavar="P",
        help="parameters to fit, from k_f r u0 t0 (default: k_f r)",
    )
    f.add_argument(
        "--model",
        choices=["simplified", "exact", "smooth", "housner"],
        default="simplified",
        help="restoring-force model (default simplified)",
    )
    f.add_argument(
        "--starts",
        type=_starts,
        metavar="N",
        help="number of optimiser starts, run in parallel (default: fit_decay's)",
    )
    f.add_argument(
        "--plot", metavar="FILE.png", help="write measured vs fitted traces and residuals"
    )
    f.add_argument("--json", action="store_true", help="print one JSON object and nothing else")
    f.set_defaults(func=run)
    return f


def _fit_trace(trace, structure, params, *, model="simplified", starts=None, progress=None):
    """`identification.fit_decay` from the structure's k_f and Eq-3 r. IdentifiabilityWarnings
    are captured (their messages are in `fit.warnings`, printed by the caller), other
    warnings are passed on."""
    import identification  # heavy (optax, the fit's JAX code): only when a fit runs

    initial = {"k_f": float(structure.k_f), "r": float(structure.restitution)}
    initial = {k: v for k, v in initial.items() if k in params}
    kwargs = {} if starts is None else {"starts": starts}
    with warnings.catch_warnings(record=True) as caught:
        shown = (identification.IdentifiabilityWarning, identification.OutlierWarning)
        for cls in shown:
            warnings.simplefilter("always", cls)
        fit = identification.fit_decay(
            trace,
            structure,
            params=tuple(params),
            model=model,
            initial=initial,
            progress=progress,
            **kwargs,
        )
    for w in caught:
        if not issubclass(w.category, shown):  # those are printed from fit.warnings
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return fit


def _fit_value_table(fit, truth=None):
    head = f"{'parameter':<10}{'fitted':>14}{'std. error':>14}"
    if truth is not None:
        head += f"{'true':>14}{'error/SE':>10}"
    lines = [head + "  unit"]
    for p in fit.names:
        v, se = fit.values[p], fit.stderr[p]
        row = f"{p:<10}{v:>14.6g}{se:>14.3g}"
        if truth is not None:
            z = (v - truth[p]) / se if se > 0 and math.isfinite(se) else float("nan")
            row += f"{truth[p]:>14.6g}{z:>10.2f}"
        lines.append(row + f"  {_FIT_UNITS[p]}")
    return "\n".join(lines)


def _fit_stats_lines(fit):
    lines = []
    rho = fit.identifiability.get("corr_k_f_r")
    if rho is not None:
        lines.append(f"corr(k_f, r)  {rho:+.4f}")
    lines.append(f"loss          {fit.loss:.6g}  (1/2 sum of squared residuals / scale^2)")
    lines.append(f"rms residual  {fit.rms:.4g} m  (noise sigma estimate {fit.sigma:.3g} m)")
    lines.append(
        f"converged     {'yes' if fit.converged else 'NO'}  ({fit.n_iterations} iterations)"
    )
    for w in fit.warnings:
        lines.append(f"warning: {w}")
    return lines


def plot_fit(trace, fit, *, title=None, measured_label="measured"):
    """Measured and fitted displacement (and uplift, when measured) with a residual panel.
    Returns a matplotlib Figure (no pyplot)."""
    t = np.asarray(trace.t)
    u_fit = np.asarray(fit.response.u)
    has_up = trace.uplift is not None
    panels = 3 if has_up else 2
    fig = _plotting.new_figure(figsize=(9, 2.3 * panels + 0.8))
    axes = fig.subplots(
        panels, 1, sharex=True, gridspec_kw={"height_ratios": [2] * (panels - 1) + [1]}
    )
    ax_u, ax_res = axes[0], axes[-1]
    ax_u.plot(t, 1e3 * np.asarray(trace.u), ".", ms=2, color="0.45", label=measured_label)
    ax_u.plot(t, 1e3 * u_fit, color="C3", lw=1.1, label="fitted")
    ax_u.set_ylabel("displacement u [mm]")
    ax_u.legend(fontsize=8, loc="upper right")
    ax_res.plot(t, 1e3 * (np.asarray(trace.u) - u_fit), color="C0", lw=0.7, label="u")
    if has_up:
        up_fit = np.asarray(fit.response.uplift)
        ax_up = axes[1]
        ax_up.plot(t, 1e3 * np.asarray(trace.uplift), ".", ms=2, color="0.45", label=measured_label)
        ax_up.plot(t, 1e3 * up_fit, color="C3", lw=1.1, label="fitted")
        ax_up.set_ylabel("uplift [mm]")
        ax_res.plot(
            t, 1e3 * (np.asarray(trace.uplift) - up_fit), color="C2", lw=0.7, label="uplift"
        )
        ax_res.legend(fontsize=8, loc="upper right", ncol=2)
    ax_res.axhline(0.0, color="k", lw=0.5)
    ax_res.set_ylabel("residual [mm]")
    ax_res.set_xlabel("time [s]")
    for ax in axes:
        ax.grid(alpha=0.3)
    vals = ", ".join(f"{p} = {fit.values[p]:.4g} ± {fit.stderr[p]:.2g}" for p in fit.names)
    conv = "converged" if fit.converged else "NOT converged"
    axes[0].set_title(
        (title + "\n" if title else "") + f"{vals}; rms residual {1e3 * fit.rms:.3g} mm, {conv}",
        fontsize=10,
    )
    fig.tight_layout()
    return fig


def _print_report(args, s, trace, fit, params):
    print(
        f"trace         {args.trace}: {trace.n} samples over {trace.duration:.4g} s"
        f"{', with uplift' if trace.uplift is not None else ''}"
    )
    print(
        f"model         {args.model}; start k_f = {float(s.k_f):.6g} N/m, "
        f"r = {float(s.restitution):.4f} (Eq 3)"
    )
    print()
    print(_fit_value_table(fit))
    print()
    for line in _fit_stats_lines(fit):
        print(line)
    if "u0" not in params:
        print(
            f"note: u0 held at the first measured sample ({fit.fixed['u0']:.6g} m); "
            "for noisy traces add u0 to --params"
        )
    if args.plot:
        print(f"plot written to {args.plot}")


def run(args):
    import identification  # heavy (optax, the fit's JAX code): only when a fit runs

    _check_png(args.plot)
    params = tuple(args.params)
    if len(set(params)) != len(params):
        raise CLIError(f"--params: each parameter at most once, got {' '.join(params)}")
    s = _load_structure(args.structure)
    trace = identification.read_trace(args.trace)
    fit = _fit_trace(
        trace,
        s,
        params,
        model=args.model,
        starts=args.starts,
        progress=False if args.json else None,
    )
    if args.plot:
        fig = plot_fit(
            trace, fit, title=f"fit of {pathlib.Path(args.trace).name}, {args.model} model"
        )
        fig.savefig(args.plot, dpi=150)
    if args.json:
        print(json.dumps(fit.summary()))
        return 0
    _print_report(args, s, trace, fit, params)
    return 0
