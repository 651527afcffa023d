"""`rockjax fit`: fit k_f, r (or the 2-DOF body's dashpots c_f), u0 and t0 to a measured
free-vibration decay trace, with any model of the ladder, and check the fit's residuals.

`identification` (optax and the fit's JAX code) is imported inside the functions that need
it, so that `rockjax --help` and the other commands do not pay for it.
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import warnings

import numpy as np

from rockjax import _plotting

from ._common import (
    _check_png,
    _load_structure,
    _positive_float,
    _starts,
    add_model_arguments,
    CLIError,
    model_info,
    model_line,
)

_FIT_UNITS = {"k_f": "N/m", "r": "-", "u0": "m", "t0": "s", "c_f": "N s/m",
              "offset": "m", "offset_uplift": "m", "drift": "m/s"}  # + the sensor's
_SENSOR = ("offset", "offset_uplift", "drift")
_PARAMS = ("k_f", "r", "u0", "t0", "c_f")
_CONTACTS = ("impact", "continuous")  # identification.CONTACTS (not imported: heavy)
_CHANNELS = ("t", "u", "uplift")


def _channel_map(option):
    """--columns / --units: "t=NAME,u=NAME[,uplift=NAME]" -> dict."""

    def conv(text):
        out = {}
        for item in text.split(","):
            key, sep, value = item.partition("=")
            key, value = key.strip(), value.strip()
            if not sep or not value or key not in _CHANNELS:
                raise argparse.ArgumentTypeError(
                    f"{option} takes CHANNEL=VALUE pairs separated by commas, channels "
                    f"{', '.join(_CHANNELS)}, such as t=time_s,u=disp_mm; got {text!r}"
                )
            if key in out:
                raise argparse.ArgumentTypeError(f"{option}: {key} given twice in {text!r}")
            out[key] = value
        return out

    return conv


def add_parser(subparsers):
    f = subparsers.add_parser(
        "fit",
        help="fit k_f, r (or c_f), u0 and t0 to a measured free-vibration decay trace",
        description="Fit the foundation stiffness k_f, the coefficient of restitution r "
        "(with --model two_spring_2dof --contact continuous: the dashpot coefficient c_f "
        "instead), the release displacement u0 and the release time t0 of a structure to a "
        "free-vibration decay trace: a CSV file with a header such as 't,u', 't,u,uplift', "
        "'time_s,disp_mm' or 't [s],u [mm],uplift [mm]' (units s, ms, us, min; m, cm, mm, "
        "um, in; none: SI; leading '#' comment lines allowed). The trace may start before "
        "the release (a hold at u0, or any clock): the release is detected and t0 fitted "
        "from there. The fit starts from the structure's k_f and its Eq 3 restitution and "
        "reports standard errors, the k_f-r correlation, identifiability warnings, a "
        "lack-of-fit check (residuals that are not noise: the model cannot represent the "
        "trace, the standard errors do not hold, and the next model up the ladder), and "
        "what was read. The 2-DOF body's fits take minutes.",
    )
    f.add_argument("trace", metavar="TRACE.csv", nargs="+",
                   help="decay trace (time, displacement, optional uplift); several traces "
                   "of one structure are fitted jointly: k_f and r (or c_f) shared, u0 and "
                   "t0 of each trace")
    f.add_argument(
        "--structure",
        metavar="FILE.toml",
        help="structure file (default: Table 1); its k_f and Eq 3 r are the start",
    )
    f.add_argument(
        "--params",
        nargs="+",
        choices=list(_PARAMS),
        metavar="P",
        help="parameters to fit, from k_f r u0 t0 c_f (default: k_f r u0 t0, less what does "
        "not act in the model: with --contact continuous, c_f in place of r; with housner, "
        "no k_f); the others are held at the structure's values (k_f, Eq 3 r or --r, --c-f) "
        "and the detected release (u0, t0); c_f only with two_spring_2dof",
    )
    add_model_arguments(f, "model of the ladder (default simplified): the SDOF laws, "
                        "rigid_body, or two_spring_2dof, the 2-DOF body on its springs (see "
                        "--contact)", fidelity=False)
    _add_2dof_arguments(f)
    f.add_argument(
        "--columns",
        type=_channel_map("--columns"),
        metavar="t=NAME,u=NAME[,uplift=NAME]",
        help="the columns to read, by header name (other columns are ignored)",
    )
    f.add_argument(
        "--units",
        type=_channel_map("--units"),
        metavar="t=UNIT,u=UNIT[,uplift=UNIT]",
        help="units of columns whose header states none, such as u=mm (default SI)",
    )
    f.add_argument("--drop-nan", action="store_true",
                   help="drop rows with missing (NaN) values, with a warning (default: refuse)")
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


def _add_2dof_arguments(f):
    f.add_argument(
        "--contact",
        choices=list(_CONTACTS),
        help="contact law of the 2-DOF body (two_spring_2dof only): impact (its default: a "
        "landing corner is Housner's impact, r) or continuous (the springs and dashpots "
        "carry the impacts: r does not act, c_f is fitted in its place)",
    )
    f.add_argument(
        "--c-f",
        dest="c_f",
        type=_positive_float("--c-f"),
        metavar="C",
        help="dashpot coefficient c_f of the 2-DOF body [N s/m]: the start when c_f is "
        "fitted (default 5 %% of critical of the vertical mode, 0.05 sqrt(2 k_f (m_e + "
        "m_b))), else the value held (default 0: no dashpots)",
    )


def _fit_trace(trace, structure, params, *, model="simplified", impact="paper", r=None,
               starts=None, progress=None, contact=None, c_f=None):
    """`identification.fit_decay` from the structure's k_f and r (Eq 3, or `r`: also its
    held value when r is not fitted; `c_f`: the start or held value of c_f).
    IdentifiabilityWarnings (LackOfFitWarnings included) and OutlierWarnings are captured
    (their messages are in `fit.warnings`, printed by the caller), other warnings are
    passed on. `params` None: the model's default parameters."""
    import identification  # heavy (optax, the fit's JAX code): only when a fit runs

    fitted = (identification.default_params(model, impact=impact, contact=contact)
              if params is None else tuple(params))
    initial = {"k_f": float(structure.k_f),
               "r": float(structure.restitution) if r is None else float(r)}
    if r is None:
        initial = {k: v for k, v in initial.items() if k in fitted}
    if c_f is not None:
        initial["c_f"] = float(c_f)
    kwargs = {} if starts is None else {"starts": starts}
    with warnings.catch_warnings(record=True) as caught:
        shown = (identification.IdentifiabilityWarning, identification.OutlierWarning,
                 identification.ConvergenceWarning)
        for cls in shown:
            warnings.simplefilter("always", cls)
        fit = identification.fit_decay(
            trace,
            structure,
            params=None if params is None else tuple(params),
            model=model,
            impact=impact,
            contact=contact,
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
            tv = truth.get(p, 0.0) if p in _SENSOR else truth[p]  # synthetic: no offset
            z = (v - tv) / se if se > 0 and math.isfinite(se) else float("nan")
            row += f"{tv:>14.6g}{z:>10.2f}"
        lines.append(row + f"  {_FIT_UNITS[p]}")
    return "\n".join(lines)


def _fit_stats_lines(fit):
    lines = []
    for other in ("r", "c_f"):
        rho = fit.identifiability.get(f"corr_k_f_{other}")
        if rho is not None:
            lines.append(f"{f'corr(k_f, {other})':<13} {rho:+.4f}")
    lines.append(f"loss          {fit.loss:.6g}  (1/2 sum of squared residuals / scale^2)")
    lines.append(f"rms residual  {fit.rms:.4g} m  (noise sigma estimate {fit.sigma:.3g} m)")
    lines.append(
        f"converged     {'yes' if fit.converged else 'NO'}  ({fit.n_iterations} iterations)"
    )
    lines.append(lack_of_fit_line(fit.lack_of_fit))
    for note in fit.notes:
        lines.append(f"note: {note}")
    for w in fit.warnings:
        lines.append(f"warning: {w}")
    return lines


def lack_of_fit_line(lack):
    """The lack-of-fit check in one line: its statistics, thresholds and verdict."""
    if not lack:
        return "lack of fit   not checked"
    th = lack["thresholds"]
    diag = lack.get("diagnosis") or {}
    cause = ("the model cannot represent the trace" if diag.get("cause", "model") == "model"
             else f"the residuals look like {diag['message']}")
    verdict = (f"FIRES: {cause}, standard errors do not hold"
               if lack["fires"] else "no (residuals consistent with noise)")
    return (f"lack of fit   {verdict}; lag-1 autocorrelation "
            f"{lack['lag1_autocorrelation']:+.3f} (limit {th['lag1_autocorrelation']:g}), "
            f"runs z {lack['runs_z']:+.1f} (limit {th['runs_z']:g})")


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


def _fit_model_info(args, s, fit):
    """`model_info(args)` for a fit: r is fitted (from Eq 3 or --r), held, or not used
    (continuous contact); for the 2-DOF body, its contact law and c_f."""
    info = model_info(args)
    r0 = float(s.restitution) if args.r is None else float(args.r)
    src = "Eq 3" if args.r is None else "--r"
    if "r" in fit.names:
        info["r"] = f"fitted, start {r0:.4g} ({src})"
    elif "r" in fit.fixed:
        info["r"] = f"held at {r0:.4g} ({src})"
    else:  # continuous contact: no impacts, the springs and dashpots carry the landings
        info["r"] = "not used (contact continuous)"
        info["impact"] = "none: the springs and dashpots carry the landings"
    info["start_k_f_N_m"] = float(s.k_f)
    info["start_r"] = r0
    if "c_f" in fit.names or "c_f" in fit.fixed:  # the 2-DOF body
        import identification

        info["contact"] = identification.resolve_model(args.model, args.impact,
                                                       args.contact).contact
        src = "--c-f" if args.c_f is not None else "default"
        info["c_f"] = (f"fitted, start {fit.start['c_f']:.4g} N s/m ({src})"
                       if "c_f" in fit.names else
                       f"held at {fit.fixed['c_f']:.4g} N s/m ({src})")
    return info


def trace_lines(info):
    """`DecayTrace.info()` as lines of text: the columns and units read, dt, points,
    duration, amplitude, rows dropped."""
    chans = ", ".join(
        f"{ch} = column {info['columns'].get(ch, ch)!r} in {unit} ({info['units_from'][ch]})"
        for ch, unit in info["units_in_file"].items()
    )
    out = [
        f"{info['file']}: {chans}",
        f"dt {info['dt_s']:.6g} s, {info['n_points']} points, {info['duration_s']:.6g} s "
        f"(t = {info['t_start_s']:.6g} .. {info['t_end_s']:.6g} s), "
        f"max |u| {info['max_abs_u_m']:.4g} m",
    ]
    if info["dropped_nan_rows"]:
        out.append(f"{info['dropped_nan_rows']} row(s) with missing values dropped (--drop-nan)")
    return out


def release_line(fit):
    """Where the release was found, and the t0 the fit used."""
    rel = fit.release
    if rel["held"]:
        found = (f"detected at t = {rel['release_time_s']:.6g} s, after a hold at "
                 f"u = {rel['level_m']:.6g} m (noise sigma {rel['noise_sigma_m']:.3g} m)")
    else:
        found = (f"at the first sample, t = {rel['release_time_s']:.6g} s (no hold before "
                 "the motion)")
    if "t0" in fit.values:
        used = f"t0 fitted from there: {fit.values['t0']:.6g} s"
    else:
        used = f"t0 held there: {fit.fixed['t0']:.6g} s"
    return f"{found}; {used}"


def _print_report(args, s, trace, fit, info, read_warnings):
    lines = trace_lines(trace.info())
    print(f"trace         {lines[0]}")
    for line in lines[1:]:
        print(f"              {line}")
    print(f"release       {release_line(fit)}")
    extra = (f"; contact {info['contact']}, c_f {info['c_f']}" if "c_f" in info else "")
    print(f"model         {model_line(info)}{extra}; start k_f = {float(s.k_f):.6g} N/m")
    print()
    print(_fit_value_table(fit))
    print()
    for w in read_warnings:
        print(f"warning: {w}")
    for line in _fit_stats_lines(fit):
        print(line)
    if "u0" not in fit.names:
        print(
            f"note: u0 held at {fit.fixed['u0']:.6g} m (the first sample, or the level of "
            "the hold); for noisy traces fit it (the default --params)"
        )
    if args.plot:
        print(f"plot written to {args.plot}")


def _read(args, path):
    """The trace at `path`, and the messages of the warnings of reading it; TraceErrors in
    the command line's terms."""
    import identification

    units = args.units or {}
    for ch, unit in units.items():
        table = identification.TIME_UNITS if ch == "t" else identification.LENGTH_UNITS
        if unit.lower() not in table:
            raise CLIError(f"--units {ch}={unit}: unknown unit; expected one of "
                           f"{', '.join(table)}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", identification.DroppedRowsWarning)
        try:
            trace = identification.read_trace(path, columns=args.columns,
                                              units=args.units, drop_nan=args.drop_nan)
        except identification.TraceError as e:
            raise CLIError(e.cli_message) from None
    for w in caught:
        if not issubclass(w.category, identification.DroppedRowsWarning):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return trace, [str(w.message) for w in caught
                   if issubclass(w.category, identification.DroppedRowsWarning)]


def run(args):
    import identification  # heavy (optax, the fit's JAX code): only when a fit runs

    _check_png(args.plot)
    params = None if args.params is None else tuple(args.params)
    if params is not None and len(set(params)) != len(params):
        raise CLIError(f"--params: each parameter at most once, got {' '.join(params)}")
    if args.r is not None and not 0.0 < args.r < 1.0:
        raise CLIError(f"--r must lie strictly inside (0, 1) for a fit, got {args.r}")
    _check_model_options(args, identification)
    s = _load_structure(args.structure)
    if len(args.trace) > 1:
        return _run_joint(args, s, params, identification)
    trace, read_warnings = _read(args, args.trace[0])
    try:
        fit = _fit_trace(trace, s, params, model=args.model, impact=args.impact, r=args.r,
                         starts=args.starts, progress=False if args.json else None,
                         contact=args.contact, c_f=args.c_f)
    except identification.TraceError as e:
        raise CLIError(e.cli_message) from None
    info = _fit_model_info(args, s, fit)
    if args.plot:
        fig = plot_fit(
            trace, fit, title=f"fit of {pathlib.Path(args.trace[0]).name}, {model_line(info)}"
        )
        fig.savefig(args.plot, dpi=150)
    if args.json:
        summary = fit.summary()
        summary["warnings"] = read_warnings + summary["warnings"]
        t0 = fit.values.get("t0", fit.fixed.get("t0"))
        print(json.dumps({"file": str(args.trace[0]), "model": info, "trace": trace.info(),
                          **summary, "t0_used_s": t0}))
        return 0
    _print_report(args, s, trace, fit, info, read_warnings)
    return 0


def _check_model_options(args, identification):
    """--contact, --c-f and --r against the model, in the command line's terms."""
    try:
        fm = identification.resolve_model(args.model, args.impact, args.contact)
    except ValueError as e:  # --model and --impact are argparse choices: --contact
        raise CLIError(f"--contact: {e}") from None
    if args.c_f is not None and not fm.has_dashpots:
        raise CLIError(f"--c-f: c_f (the dashpot coefficient of the 2-DOF body) is not a "
                       f"parameter of the {fm.describe()} model; use --model two_spring_2dof")
    if args.r is not None and "r" not in fm.acting:
        raise CLIError("--r does not act with --contact continuous: the springs and dashpots "
                       "carry the impacts (c_f is fitted for the dissipation; --c-f sets its "
                       "start)")


# ------------------------------------------------------------------ several traces


def _run_joint(args, s, params, identification):
    """`rockjax fit A.csv B.csv ...`: the joint fit (shared k_f, r or c_f; u0, t0 of each
    trace)."""
    traces, read_warnings = [], []
    for path in args.trace:
        trace, msgs = _read(args, path)
        traces.append(trace)
        read_warnings += [f"{path}: {m}" for m in msgs]
    try:
        fit = _fit_trace(traces, s, params, model=args.model, impact=args.impact, r=args.r,
                         starts=args.starts, progress=False if args.json else None,
                         contact=args.contact, c_f=args.c_f)
    except identification.TraceError as e:
        raise CLIError(e.cli_message) from None
    info = _fit_model_info(args, s, fit)
    if args.plot:
        plot_joint(traces, fit, title=f"joint fit of {len(traces)} traces, "
                   f"{model_line(info)}").savefig(args.plot, dpi=150)
    if args.json:
        summary = fit.summary()
        summary["warnings"] = read_warnings + summary["warnings"]
        for d, tr in zip(summary["traces"], traces):
            d["trace"] = tr.info()
        print(json.dumps({"files": [str(p) for p in args.trace], "model": info, **summary}))
        return 0
    _print_joint(args, s, traces, fit, info, read_warnings)
    return 0


def _print_joint(args, s, traces, fit, info, read_warnings):
    for tr in traces:
        lines = trace_lines(tr.info())
        print(f"trace         {lines[0]}")
        for line in lines[1:]:
            print(f"              {line}")
    print(f"model         {model_line(info)}; start k_f = {float(s.k_f):.6g} N/m; joint fit "
          f"of {len(traces)} traces (shared: {', '.join(fit.names)})")
    print()
    print(_fit_value_table(fit))
    print()
    print(f"{'trace':<28}{'u0 [m]':>12}{'SE':>10}{'t0 [s]':>12}{'SE':>10}{'rms [m]':>11}"
          "  lack of fit")
    for d in fit.per_trace:
        row = f"{pathlib.Path(d['source']).name[:27]:<28}"
        for p in ("u0", "t0"):
            if p in d["values"]:
                row += f"{d['values'][p]:>12.6g}{d['stderr'][p]:>10.2g}"
            else:
                row += f"{d['fixed'][p]:>12.6g}{'held':>10}"
        row += f"{d['rms']:>11.3g}  {'FIRES' if d['lack_of_fit']['fires'] else 'no'}"
        print(row)
    print()
    for w in read_warnings:
        print(f"warning: {w}")
    for other in ("r", "c_f"):
        if "k_f" in fit.names and other in fit.names:
            rho = fit.correlation[fit.joint_names.index("k_f"), fit.joint_names.index(other)]
            print(f"{f'corr(k_f, {other})':<13} {rho:+.4f}")
    print(f"loss          {fit.loss:.6g}  (1/2 sum of squared residuals / scale^2)")
    print(f"converged     {'yes' if fit.converged else 'NO'}  ({fit.n_iterations} iterations)")
    for note in fit.notes:
        print(f"note: {note}")
    for w in fit.warnings:
        print(f"warning: {w}")
    if args.plot:
        print(f"plot written to {args.plot}")


def plot_joint(traces, fit, *, title=None):
    """Measured and fitted displacement of each trace of a joint fit, one panel each.
    Returns a matplotlib Figure (no pyplot)."""
    fig = _plotting.new_figure(figsize=(9, 2.0 * len(traces) + 0.8))
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
    vals = ", ".join(f"{p} = {fit.values[p]:.4g} ± {fit.stderr[p]:.2g}" for p in fit.names)
    fig.suptitle((title + "\n" if title else "") + vals, fontsize=10)
    fig.tight_layout()
    return fig
