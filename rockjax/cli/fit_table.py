"""`rockjax fit-table`: fit k_f, r (the 2-DOF body's c_f) and the clock offset to
shake-table runs: a table motion and the structure's response (one file, or a response
file and its table record on their own clocks), one run or several jointly.

`identification` is imported inside `run`, so that `rockjax --help` does not pay for it.
"""

from __future__ import annotations

import json
import textwrap
import warnings

from ._common import (
    add_model_arguments,
    add_outputs,
    add_plausibility_argument,
    check_outputs,
    CLIError,
    COMMON_FLAGS,
    converter,
    load_structure,
    model_line,
    positive_float,
)
from .fit import (
    _add_posterior_arguments,
    _channel_map,
    _check_posterior_options,
    _CONTACTS,
    _fit_model_info,
    _posterior,
)

FLAGS = {**COMMON_FLAGS, "structure": "--structure", "units": "--units",
         "table_units": "--table-units", "table_start": "--table-start",
         "contact": "--contact", "c_f": "--c-f", "starts": "--starts", "params": "--params",
         "offset": "--offset", "drift": "--drift", "table": "--table"}
_PARAMS = ("k_f", "r", "u0", "t0", "c_f")
_OFFSET = {"yes": True, "no": False}


def add_parser(subparsers):
    f = subparsers.add_parser(
        "fit-table",
        help="fit k_f, r (or c_f) and the clock offset to shake-table runs",
        description="Fit the foundation stiffness k_f, the coefficient of restitution r "
        "(the 2-DOF body's dashpot coefficient c_f with --params), the clock offset between "
        "the table and the response channels (t0: the time of the table's first sample on "
        "the response's clock) and each channel's sensor zero to a shake-table run: the "
        "model of the ladder driven by the table's acceleration, compared with the response "
        "channels (u relative to the table, theta, uplift). A RUN is one CSV file with "
        "every channel (header such as 't,ag_g,u_mm,theta' or 't,table_disp_mm,u_mm'), or "
        "a response trace with --table giving its table record (AT2, two columns t,a, ...; "
        "each on its own clock and rate). Several runs of one specimen are fitted jointly "
        "(k_f, r, c_f shared; t0 and the sensor zeros of each run). Each channel is "
        "weighted by its noise level, estimated from the residuals.",
    )
    f.add_argument("runs", metavar="RUN.csv", nargs="+",
                   help="a one-file run, or (with --table) a response trace; several are "
                   "fitted jointly")
    f.add_argument("--table", action="append", metavar="TABLE",
                   help="the table record of each RUN (repeat it once per RUN, in order): "
                   "read with rockjax's record reader (AT2, two columns t,a, ESM, ...)")
    f.add_argument("--table-units", metavar="UNIT",
                   help="units of the table records that state none (g, m/s2, cm/s2, gal)")
    f.add_argument("--table-start", type=converter("--table-start", float), metavar="T",
                   help="time [s] of the table's first sample on the response's clock "
                   "(default: the table file's first time stamp, else the response's first "
                   "time); the fit adjusts it (the clock offset)")
    f.add_argument("--units", type=_channel_map("--units"), metavar="u=UNIT[,theta=UNIT]",
                   help="units of response columns whose header states none, such as u=mm")
    f.add_argument("--structure", metavar="FILE.toml",
                   help="structure file (default: Table 1); its k_f and Eq 3 r are the start")
    add_plausibility_argument(f)
    f.add_argument("--params", nargs="+", choices=list(_PARAMS), metavar="P",
                   help="parameters to fit, from k_f r u0 t0 c_f (default: k_f r t0, less "
                   "what does not act in the model)")
    add_model_arguments(f, "model of the ladder (default simplified)", fidelity=False)
    f.add_argument("--contact", choices=list(_CONTACTS),
                   help="contact law of the 2-DOF body (two_spring_2dof only)")
    f.add_argument("--c-f", dest="c_f", type=positive_float("--c-f"), metavar="C",
                   help="dashpot coefficient c_f of the 2-DOF body [N s/m]: the start when "
                   "fitted, else the value held")
    f.add_argument("--offset", choices=list(_OFFSET), default="yes",
                   help="fit each channel's sensor zero (default yes)")
    f.add_argument("--drift", action="store_true",
                   help="also fit a linear drift of the displacement sensor [m/s]")
    f.add_argument("--starts", type=converter("--starts", int, lambda n: n >= 1,
                                              "be at least 1"),
                   metavar="N", help="number of optimiser starts (default: the model's)")
    add_outputs(f, "plot the measured and fitted response channels and the table motion")
    _add_posterior_arguments(f)
    f.set_defaults(func=run)
    return f


def _read_runs(args, identification):
    tables = args.table or []
    if tables and len(tables) != len(args.runs):
        raise CLIError(f"--table: {len(tables)} table record(s) for {len(args.runs)} run(s); "
                       "give one --table per RUN, in order (or none: one-file runs)")
    if args.table_units is not None and not tables:
        raise CLIError("--table-units: only with --table (a one-file run states its table "
                       "unit in its header, such as ag_g)")
    if args.table_start is not None and not tables:
        raise CLIError("--table-start: only with --table (a one-file run has one clock)")
    runs = []
    for i, path in enumerate(args.runs):
        if tables:
            run = identification.read_shake_table(
                table=tables[i], response=path, units=args.units,
                table_units=args.table_units, table_start=args.table_start,
                check_plausible=args.check_plausible)
        else:
            run = identification.read_shake_table(path, units=args.units,
                                                  check_plausible=args.check_plausible)
        runs.append(run)
    return runs


def _plot(path, runs, fit):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    responses = fit.responses if hasattr(fit, "responses") else (fit.response,)
    chans = runs[0].response.channels
    fig, axes = plt.subplots(len(chans) + 1, len(runs), squeeze=False, sharex="col",
                             figsize=(6 * len(runs), 2.2 * (len(chans) + 1)))
    for j, (run, res) in enumerate(zip(runs, responses)):
        t0 = (fit.values["t0"] if "t0" in fit.values else
              fit.per_trace[j]["values"].get("t0", run.table_start)
              if hasattr(fit, "per_trace") else fit.fixed.get("t0", run.table_start))
        ax = axes[0, j]
        ax.plot(t0 + run.table.time, run.table.accel, lw=0.7, color="0.3")
        ax.set_ylabel("table acc. [m/s²]")
        title = (run.description.splitlines() or [""])[0] or run.response.source
        ax.set_title("\n".join(textwrap.wrap(title[:200], 95)) or f"run {j}", fontsize=7)
        for k, ch in enumerate(chans, 1):
            ax = axes[k, j]
            ax.plot(run.response.t, getattr(run.response, ch), ".", ms=1.5, color="0.6",
                    label="measured")
            ax.plot(run.response.t, np.asarray(getattr(res, ch)), lw=0.9, color="C3",
                    label="fitted")
            ax.set_ylabel(f"{ch} [{'rad' if ch == 'theta' else 'm'}]")
        axes[-1, j].set_xlabel("t [s] (response clock)")
    axes[1, 0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=150)


def run(args):
    import identification

    check_outputs(args, r=False)
    _check_posterior_options(args)
    s = load_structure(args.structure, args.check_plausible)
    runs = _read_runs(args, identification)
    if args.r is not None and not 0.0 < args.r < 1.0:
        raise CLIError(f"--r must lie strictly inside (0, 1) for a fit, got {args.r}")
    try:
        fm = identification.resolve_model(args.model, args.impact, args.contact)
    except ValueError as e:
        raise CLIError(f"--contact: {e}") from None
    initial = {k: float(v) for k, v in (("r", args.r), ("c_f", args.c_f)) if v is not None}
    schedule = None if args.starts is None else identification.Schedule(starts=args.starts)
    shown = (identification.IdentifiabilityWarning, identification.ConvergenceWarning)
    with warnings.catch_warnings(record=True) as caught:
        for cls in shown:
            warnings.simplefilter("always", cls)
        fit = identification.fit_shake_table(
            runs if len(runs) > 1 else runs[0], s,
            None if args.params is None else tuple(args.params), model=args.model,
            impact=args.impact, contact=args.contact, initial=initial or None,
            offset=_OFFSET[args.offset], drift=args.drift, schedule=schedule,
            progress=False if args.json else None)
    for w in caught:
        if not issubclass(w.category, shown):
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    info = _fit_model_info(args, s, fit, fm)  # r (and c_f) fitted or held, and their starts
    post = _posterior(args, fit) if args.posterior else None
    if args.plot:
        _plot(args.plot, runs, fit)
    if args.json:
        out = {"files": list(args.runs), "tables": list(args.table or []), "model": info,
               "runs": [r.info() for r in runs], **fit.summary()}
        if len(runs) > 1:
            for d, r in zip(out["traces"], runs):
                t0 = d["values"].get("t0", d["fixed"].get("t0"))
                d["clock_offset"] = t0 - r.table_start
        if post is not None:
            out["posterior"] = {**post.summary(), "draws_out": args.draws_out}
        print(json.dumps(out))
        return 0
    for r in runs:
        lines = r.report()
        print(f"run           {lines[0]}", *(f"              {ln}" for ln in lines[1:]),
              sep="\n")
    print(f"model         {model_line(info)}; start k_f = {float(s.k_f):.6g} N/m\n")
    print(fit.report())
    if len(runs) > 1:
        for i, r in enumerate(runs):
            d = fit.per_trace[i]
            t0 = d["values"].get("t0", d["fixed"].get("t0"))
            print(f"run {i}: clock offset {1e3 * (t0 - r.table_start):+.4g} ms")
    if post is not None:
        print("\n" + post.report())
        if args.draws_out:
            print(f"posterior draws written to {args.draws_out}")
    if args.plot:
        print(f"plot written to {args.plot}")
    return 0
