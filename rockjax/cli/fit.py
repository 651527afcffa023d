"""`rockjax fit`: fit k_f, r (or the 2-DOF body's dashpots c_f), u0 and t0 to a measured
free-vibration decay trace, with any model of the ladder, and check the fit's residuals.

`identification` (optax and the fit's JAX code) is imported inside the functions that need
it, so that `rockjax --help` and the other commands do not pay for it.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import warnings

from rockjax._plotting import plot_fit, plot_joint_fit

from ._common import (
    add_model_arguments,
    add_outputs,
    add_plausibility_argument,
    check_outputs,
    CLIError,
    COMMON_FLAGS,
    converter,
    load_structure,
    model_info,
    model_line,
    positive_float,
)

#: the library parameters that the options of `rockjax fit` set (errors name the option)
FLAGS = {**COMMON_FLAGS, "structure": "--structure", "columns": "--columns",
         "units": "--units", "drop_nan": "--drop-nan", "contact": "--contact", "c_f": "--c-f",
         "starts": "--starts", "params": "--params", "offset": "--offset", "drift": "--drift"}
_PARAMS = ("k_f", "r", "u0", "t0", "c_f")
_CONTACTS = ("impact", "continuous")  # identification.CONTACTS (not imported: heavy)
_CHANNELS = ("t", "u", "uplift", "theta")
#: --offset -> fit_decay's offset=: where the trace pins it (None), always, never
_OFFSET = {"auto": None, "yes": True, "no": False}
AUTO = "auto"  # --model auto: every rung of the ladder fitted and ranked (identification._auto)


def _channel_map(option):
    """--columns / --units: "t=NAME,u=NAME[,uplift=NAME]" -> dict."""

    def conv(text):
        out = {}
        for item in text.split(","):
            key, sep, value = (x.strip() for x in item.partition("="))
            if not sep or not value or key not in _CHANNELS:
                raise argparse.ArgumentTypeError(
                    f"{option} takes CHANNEL=VALUE pairs separated by commas, channels "
                    f"{', '.join(_CHANNELS)}, such as t=time_s,u=disp_mm; got {text!r}")
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
        "what was read. --model auto fits the rungs of the ladder and keeps the one the "
        "trace requires (the ranking is printed). The 2-DOF body's fits take minutes.",
    )
    f.add_argument("trace", metavar="TRACE.csv", nargs="+",
                   help="decay trace (time, displacement, optional uplift); several traces "
                   "of one structure are fitted jointly: k_f and r (or c_f) shared, u0 and "
                   "t0 of each trace")
    f.add_argument("--structure", metavar="FILE.toml",
                   help="structure file (default: Table 1); its k_f and Eq 3 r are the start")
    add_plausibility_argument(f)
    f.add_argument(
        "--params", nargs="+", choices=list(_PARAMS), metavar="P",
        help="parameters to fit, from k_f r u0 t0 c_f (default: k_f r u0 t0, less what does "
        "not act in the model: with --contact continuous, c_f in place of r; with housner, "
        "no k_f); the others are held at the structure's values (k_f, Eq 3 r or --r, --c-f) "
        "and the detected release (u0, t0); c_f only with two_spring_2dof")
    add_model_arguments(f, "model of the ladder (default simplified): the SDOF laws, "
                        "rigid_body, or two_spring_2dof, the 2-DOF body on its springs (see "
                        "--contact); or auto: the rungs simplified, rigid_body and "
                        "two_spring_2dof with impact and with continuous contact, each fitted "
                        "with its default parameters and ranked (residuals that are noise "
                        "first, then by AIC), the table printed (minutes: every rung is a "
                        "full fit)", fidelity=False)
    model_action = next(a for a in f._actions if a.dest == "model")
    model_action.choices = [*model_action.choices, AUTO]
    f.add_argument(
        "--contact", choices=list(_CONTACTS),
        help="contact law of the 2-DOF body (two_spring_2dof only): impact (its default: a "
        "landing corner is Housner's impact, r) or continuous (the springs and dashpots "
        "carry the impacts: r does not act, c_f is fitted in its place)")
    f.add_argument(
        "--c-f", dest="c_f", type=positive_float("--c-f"), metavar="C",
        help="dashpot coefficient c_f of the 2-DOF body [N s/m]: the start when c_f is "
        "fitted (default 5 %% of critical of the vertical mode, 0.05 sqrt(2 k_f (m_e + "
        "m_b))), else the value held (default 0: no dashpots)")
    f.add_argument(
        "--offset", choices=list(_OFFSET), default="auto",
        help="fit the sensor's zero of each channel (offset, offset_uplift [m]) as nuisance "
        "parameters: auto (default: where the trace pins it, i.e. two cycles of motion "
        "after the release or a rest at the end), yes (always) or no (never)")
    f.add_argument("--drift", action="store_true",
                   help="also fit a linear drift of the displacement sensor [m/s]")
    f.add_argument("--columns", type=_channel_map("--columns"),
                   metavar="t=NAME,u=NAME[,uplift=NAME]",
                   help="the columns to read, by header name (other columns are ignored)")
    f.add_argument("--units", type=_channel_map("--units"), metavar="t=UNIT,u=UNIT[,uplift=UNIT]",
                   help="units of columns whose header states none, such as u=mm (default SI)")
    f.add_argument("--drop-nan", action="store_true",
                   help="drop rows with missing (NaN) values, with a warning (default: refuse)")
    f.add_argument("--starts", type=converter("--starts", int, lambda n: n >= 1, "be at least 1"),
                   metavar="N", help="number of optimiser starts, run in parallel (default: "
                   "fit_decay's)")
    add_outputs(f, "write measured vs fitted traces and residuals")
    _add_posterior_arguments(f)
    f.set_defaults(func=run)
    return f


def _add_posterior_arguments(f):
    g = f.add_argument_group(
        "posterior", "sample the posterior of the fitted parameters by NUTS (blackjax) after "
        "the fit (one trace, or the joint fit of several: every fitted parameter, u0[i] and "
        "t0[i] of each trace; identification.sample_posterior): its report (mean, sd, 90 % "
        "interval, R-hat, ESS beside the Laplace values; a WARNING line first when the "
        "diagnostics fail) is printed after the fit's, and --json gains a 'posterior' block")
    g.add_argument("--posterior", action="store_true", help="sample the posterior")
    count = converter("--chains", int, lambda n: n >= 1, "be at least 1")
    g.add_argument("--chains", type=count, default=4, metavar="N",
                   help="chains, run together (default 4)")
    g.add_argument("--draws", type=converter("--draws", int, lambda n: n >= 4,
                                             "be at least 4"),
                   default=1000, metavar="N", help="draws kept per chain (default 1000)")
    g.add_argument("--warmup", type=converter("--warmup", int, lambda n: n >= 0,
                                              "be at least 0"),
                   default=500, metavar="N", help="warmup transitions per chain (default 500)")
    g.add_argument("--prior", action="append", metavar="NAME=KIND(...)",
                   help="prior of a fitted parameter, repeatable: k_f=lognormal(2e6,1), "
                   "r=uniform(0.5,1), u0=normal(0.1,0.01), c_f=halfnormal(500), t0=flat "
                   "(default: k_f, c_f lognormal(start, 2), r uniform(0, 1), the others "
                   "flat; each channel's noise level integrated out)")
    g.add_argument("--draws-out", metavar="FILE.csv",
                   help="write the posterior draws as CSV (a '# units:' line, then one "
                   "column per parameter: what rockjax fragility/spectrum --draws read)")


def _check_posterior_options(args):
    """--chains/--draws/--warmup/--prior/--draws-out need --posterior."""
    given = [flag for flag, on in (("--prior", args.prior), ("--draws-out", args.draws_out))
             if on]
    if given and not args.posterior:
        raise CLIError(f"{given[0]} needs --posterior")
    if not args.posterior:
        return
    if args.draws_out is not None:
        p = pathlib.Path(args.draws_out)
        if p.is_dir() or not p.parent.is_dir():
            raise CLIError(f"--draws-out: not a file in an existing folder: {args.draws_out}")
    for text in args.prior or ():
        if "=" not in text:
            raise CLIError(f"--prior {text}: expected NAME=KIND(numbers), such as "
                           "k_f=lognormal(2e6,1)")


def _posterior(args, fit):
    """The posterior of the fit (--posterior), its CSV written (--draws-out)."""
    import identification

    priors = None
    if args.prior:
        priors = {}
        for text in args.prior:
            name, _, kind = text.partition("=")
            priors[name.strip()] = kind
    try:
        pb = fit.posterior_problem(priors)
    except ValueError as e:
        raise CLIError(f"--prior: {e}") from None
    post = identification.sample_posterior(pb, chains=args.chains, draws=args.draws,
                                           warmup=args.warmup,
                                           progress=False if args.json else None)
    if args.draws_out:
        post.to_csv(args.draws_out)
    return post


def fit_trace(trace, structure, params, *, model="simplified", impact="paper", r=None,
              starts=None, progress=None, contact=None, c_f=None, offset=None, drift=False):
    """`identification.fit_decay` from the structure's k_f and Eq 3 r (`r`: the start, also
    the held value when r is not fitted; `c_f`: the start or held value of c_f; `offset`,
    `drift`: fit_decay's).
    IdentifiabilityWarnings (LackOfFitWarnings included) and OutlierWarnings are captured
    (their messages are in `fit.warnings`, printed by the caller), other warnings are
    passed on. `params` None: the model's default parameters."""
    import identification  # heavy (optax, the fit's JAX code): only when a fit runs

    initial = {k: float(v) for k, v in (("r", r), ("c_f", c_f)) if v is not None}
    kwargs = {} if starts is None else {"starts": starts}
    shown = (identification.IdentifiabilityWarning, identification.OutlierWarning,
             identification.ConvergenceWarning)
    with warnings.catch_warnings(record=True) as caught:
        for cls in shown:
            warnings.simplefilter("always", cls)
        fit = identification.fit_decay(
            trace, structure, params=None if params is None else tuple(params), model=model,
            impact=impact, contact=contact, initial=initial, progress=progress,
            offset=offset, drift=drift, **kwargs)
    for w in caught:
        if not issubclass(w.category, shown):  # those are printed from fit.warnings
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return fit


# ------------------------------------------------------------------------------ text
def _print_traces(traces):
    for tr in traces:
        lines = tr.report()
        print(f"trace         {lines[0]}", *(f"              {ln}" for ln in lines[1:]), sep="\n")


def _print_report(args, s, traces, fit, info, read_warnings):
    """The text report of one trace's fit."""
    _print_traces(traces)
    print(f"release       {fit.release_text()}")
    extra = f"; contact {info['contact']}, c_f {info['c_f']}" if "c_f" in info else ""
    print(f"model         {model_line(info)}{extra}; start k_f = {float(s.k_f):.6g} N/m\n")
    print(fit.report(read_warnings=read_warnings))
    if "u0" not in fit.names:
        print(f"note: u0 held at {fit.fixed['u0']:.6g} m (the first sample, or the level of "
              "the hold); for noisy traces fit it (the default --params)")


def _print_joint(args, s, traces, fit, info, read_warnings):
    """The text report of a joint fit: shared values, then u0, t0 and rms of each trace."""
    _print_traces(traces)
    print(f"model         {model_line(info)}; start k_f = {float(s.k_f):.6g} N/m; joint fit "
          f"of {len(traces)} traces (shared: {', '.join(fit.names)})\n")
    print(fit.report(read_warnings=read_warnings))


# ------------------------------------------------------------------------------- run
def _read(args, path):
    """The trace at `path`, and the messages of the warnings of reading it (a TraceError
    names the option that fixes it in `main`)."""
    import identification

    for ch, unit in (args.units or {}).items():
        table = identification.TIME_UNITS if ch == "t" else identification.LENGTH_UNITS
        if unit.lower() not in table:
            raise CLIError(f"--units {ch}={unit}: unknown unit; expected one of "
                           f"{', '.join(table)}")
    dropped = identification.DroppedRowsWarning
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", dropped)
        trace = identification.read_trace(path, columns=args.columns, units=args.units,
                                          drop_nan=args.drop_nan,
                                          check_plausible=args.check_plausible)
    for w in caught:
        if not issubclass(w.category, dropped):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return trace, [str(w.message) for w in caught if issubclass(w.category, dropped)]


def _check_auto(args):
    """--model auto against the options that name one model's parameters or contact law."""
    for given, flag, why in (
            (args.params is not None, "--params", "each rung is fitted with its own default "
             "parameters"),
            (args.contact is not None, "--contact", "both contact laws of the 2-DOF body are "
             "rungs"),
            (args.c_f is not None, "--c-f", "c_f would be held in the impact rung"),
            (len(args.trace) > 1, "several traces", "it ranks the rungs on one trace; fit "
             "each trace with --model auto, then the traces jointly with the model chosen")):
        if given:
            raise CLIError(f"--model auto does not take {flag}: {why}")


def _check_model_options(args, identification):
    """--params, --contact, --c-f and --r against the model, in the command line's terms
    (None for --model auto)."""
    if args.params is not None and len(set(args.params)) != len(args.params):
        raise CLIError(f"--params: each parameter at most once, got {' '.join(args.params)}")
    if args.r is not None and not 0.0 < args.r < 1.0:
        raise CLIError(f"--r must lie strictly inside (0, 1) for a fit, got {args.r}")
    if args.model == AUTO:
        _check_auto(args)
        return None
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
    return fm


def _fit_model_info(args, s, fit, fm):
    """`model_info(args)` for a fit: r is fitted (from Eq 3 or --r), held, or not used
    (continuous contact); for the 2-DOF body, its contact law and c_f."""
    info = model_info(args)
    if getattr(args, "chosen_by", None):
        info["chosen_by"] = f"--model {args.chosen_by}"
    r0 = float(s.restitution) if args.r is None else float(args.r)
    src = "Eq 3" if args.r is None else "--r"
    if "r" in fit.names:
        info["r"] = f"fitted, start {r0:.4g} ({src})"
    elif "r" in fit.fixed:
        info["r"] = f"held at {r0:.4g} ({src})"
    else:  # continuous contact: no impacts, the springs and dashpots carry the landings
        info["r"] = "not used (contact continuous)"
        info["impact"] = "none: the springs and dashpots carry the landings"
    info["start_k_f_N_m"], info["start_r"] = float(s.k_f), r0
    if "c_f" in fit.names or "c_f" in fit.fixed:  # the 2-DOF body
        info["contact"] = fm.contact
        src = "--c-f" if args.c_f is not None else "default"
        info["c_f"] = (f"fitted, start {fit.start['c_f']:.4g} N s/m ({src})"
                       if "c_f" in fit.names else
                       f"held at {fit.fixed['c_f']:.4g} N s/m ({src})")
    return info


def _chosen(args, fit, identification):
    """(args as if the rung `--model auto` chose had been named, its FitModel)."""
    model, contact = fit.ranking[0]["rung"]
    chosen = argparse.Namespace(**{**vars(args), "model": model, "contact": contact,
                                   "chosen_by": AUTO})
    return chosen, identification.resolve_model(model, args.impact, contact)


def ranking_lines(fit):
    """The ranking of `--model auto` as text: the table, then the rung chosen and why."""
    best = fit.ranking[0]
    why = ("its residuals are noise and its AIC is the lowest of those" if not
           best["lack_of_fit"] and best["converged"] else "no rung's residuals are noise "
           "(or no such fit converged): the lowest AIC; see the lack-of-fit line above")
    return (f"\nmodel auto    the rungs of the ladder, best first (AIC = n ln(RSS/n) + 2k):\n"
            f"{fit.ranking_text()}\nchosen        {best['model']}: {why}")


def run(args):
    """One trace, or several fitted jointly (shared k_f, r or c_f; u0, t0 of each trace)."""
    import identification  # heavy (optax, the fit's JAX code): only when a fit runs

    check_outputs(args, r=False)
    _check_posterior_options(args)
    fm = _check_model_options(args, identification)
    s = load_structure(args.structure, args.check_plausible)
    joint = len(args.trace) > 1
    traces, read_warnings = [], []
    for path in args.trace:
        trace, msgs = _read(args, path)
        traces.append(trace)
        read_warnings += [f"{path}: {m}" for m in msgs] if joint else msgs
    fit = fit_trace(traces if joint else traces[0], s, args.params, model=args.model,
                    impact=args.impact, r=args.r, starts=args.starts,
                    progress=False if args.json else None, contact=args.contact, c_f=args.c_f,
                    offset=_OFFSET[args.offset], drift=args.drift)
    if args.model == AUTO:  # the report is the chosen rung's, with the ranking beside it
        args, fm = _chosen(args, fit, identification)
    info = _fit_model_info(args, s, fit, fm)
    post = _posterior(args, fit) if args.posterior else None
    if args.plot:
        fig = (plot_joint_fit(traces, fit, title=f"joint fit of {len(traces)} traces, "
                              f"{model_line(info)}") if joint else
               plot_fit(traces[0], fit, title=f"fit of {pathlib.Path(args.trace[0]).name}, "
                        f"{model_line(info)}"))
        fig.savefig(args.plot, dpi=150)
    if args.json:
        summary = fit.summary()
        summary["warnings"] = read_warnings + summary["warnings"]
        if joint:
            for d, tr in zip(summary["traces"], traces):
                d["trace"] = tr.info()
            out = {"files": [str(p) for p in args.trace], "model": info, **summary}
        else:
            out = {"file": str(args.trace[0]), "model": info, "trace": traces[0].info(),
                   **summary, "t0_used_s": fit.values.get("t0", fit.fixed.get("t0"))}
        if post is not None:
            out["posterior"] = {**post.summary(), "draws_out": args.draws_out}
        print(json.dumps(out))
        return 0
    (_print_joint if joint else _print_report)(args, s, traces, fit, info, read_warnings)
    if getattr(fit, "ranking", None):  # --model auto (one trace; a joint fit has none)
        print(ranking_lines(fit))
    if post is not None:
        print("\n" + post.report())
        if args.draws_out:
            print(f"posterior draws written to {args.draws_out}")
    if args.plot:
        print(f"plot written to {args.plot}")
    return 0
