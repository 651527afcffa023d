"""`rockjax fragility`: a lognormal fragility curve fitted to a sweep of records x scales.

Built on `rockjax sweep`: the same record, scale and run arguments (`sweep`'s argument
groups) and the same engine (`rockjax.sweep`, one process), then
`rockjax.fragility` on the result: the median and beta by maximum likelihood with a
bootstrap band over the records, reported as text, --json and a --plot (docs/fragility.md).
"""

from __future__ import annotations

import json
import sys
import warnings

import rockjax
from rockjax._draws import NUISANCE
from rockjax._fragility import parse_im, parse_limit
from rockjax._plotting import new_figure
from rockjax._report import status_line
from rockjax._sweep import status_totals, write_csv

from . import sweep
from ._common import (
    add_outputs,
    check_outputs,
    CLIError,
    converter,
    first_line,
    model_info,
    model_line,
    save,
)

#: the library parameters that the options of `rockjax fragility` set (errors name them)
FLAGS = {**sweep.FLAGS, "im": "--im", "limit": "--limit", "n_bootstrap": "--bootstrap",
         "confidence": "--confidence", "seed": "--seed", "draws": "--draws"}
#: the keys of the sweep's JSON that `--json` shows under "sweep"
_SWEEP_KEYS = ("n_runs", "n_records", "n_scales", "status_counts", "wall_time_s", "tail_s",
               "t1", "grid_dt_s", "model", "model_info", "method", "substeps", "records",
               "record_info", "skipped_files", "suites", "suite_notes", "scales")


# ------------------------------------------------------------------------------ parser
def add_parser(subparsers):
    w = subparsers.add_parser(
        "fragility",
        help="a lognormal fragility curve (median, beta, bootstrap band) from a sweep of "
        "records x scales",
        description="Run every ground-motion record at every scale factor, as `rockjax "
        "sweep` does, and fit a lognormal fragility curve P(limit | IM) = "
        "Phi(ln(IM/median)/beta) by maximum likelihood: each run that completed or "
        "overturned is one Bernoulli trial at its intensity measure (the scale times its "
        "record's PGA, PGV, PGD or Sa(T)); runs that ended as max_impacts or "
        "solver_failure are left out and counted. The band and the intervals come from a "
        "bootstrap over the records (resampled with replacement, each resample refitted). "
        "Use --model rigid_body for fragility (docs/models.md); method: docs/fragility.md.",
    )
    sweep.add_input_arguments(
        w, structure="structure file (default: Table 1); one per fragility curve",
        scales='scale factors on every record: a comma list such as "0.5,1,1.5" or a range '
        '"START:STOP:N" of N evenly spaced values, ends included')
    sweep.add_run_arguments(w)
    w.add_argument("--im", type=converter("--im", _valid(parse_im)), default="PGA",
                   metavar="IM",
                   help="intensity measure: PGA [g] (default), PGV [m/s], PGD [m], Sa(T) [g] "
                   "(5 %%-damped pseudo-spectral acceleration at the period T in s, e.g. "
                   "'Sa(1.0)'), or scale")
    w.add_argument("--limit", default="overturned", metavar="LIMIT", type=converter(
        "--limit", _valid(parse_limit), noun="overturned, uplift=METRES or rotation=RADIANS "
        "(a positive threshold)"), help="limit state: overturned (default), uplift=M (peak corner "
        "uplift >= M metres) or rotation=RAD (peak rotation >= RAD radians); an overturned run "
        "exceeds every limit")
    w.add_argument("--bootstrap", type=converter("--bootstrap", int, lambda n: n >= 0, "be >= 0"),
                   default=1000, metavar="N",
                   help="bootstrap resamples of the records (default 1000; 0: no band)")
    w.add_argument("--confidence", default=0.9, metavar="C",
                   type=converter("--confidence", float, lambda c: 0 < c < 1, "lie in (0, 1)"),
                   help="confidence of the band and the intervals (default 0.9)")
    w.add_argument("--seed", type=int, default=0, help="seed of the bootstrap (default 0)")
    add_draws_arguments(w, "a fragility curve per draw (each refitted, no bootstrap), their "
                        "median curve, --confidence band and pooled (mean) curve, beside the "
                        "curve of the structure as given")
    add_outputs(w, "plot the fitted curve, its band and the observed fractions against the IM",
                out="also write the sweep's CSV, one row per run (the columns of rockjax sweep)",
                json="print one JSON object and nothing else (no progress bar)")
    sweep.add_store_arguments(w)
    w.set_defaults(func=run)
    return w


def add_draws_arguments(w, what):
    """--draws FILE.csv and --draws-ignore NAMES (also `rockjax spectrum`'s)."""
    w.add_argument("--draws", metavar="FILE.csv",
                   help=f"posterior draws of the parameters (rockjax fit ... --draws-out): "
                   f"{what}. CSV: a line '# units: k_f N/m, r -', a header of names (fields "
                   "of the structure, r, c_f), one row per draw in SI units")
    w.add_argument("--draws-ignore", type=lambda t: [n.strip() for n in t.split(",") if n.strip()],
                   metavar="NAMES", default=None,
                   help="columns of --draws to leave out, a comma list (default: a fit's "
                   "nuisance parameters, " + ", ".join(NUISANCE) + ")")


def read_draws_option(args):
    """The draws of --draws (errors name --draws)."""
    ignore = NUISANCE if args.draws_ignore is None else args.draws_ignore
    try:
        return rockjax.read_draws(args.draws, ignore=ignore)
    except (ValueError, OSError) as e:
        raise CLIError(f"--draws: {first_line(e)}") from None


def _valid(parse):
    """The text itself, once `parse` accepts it (a `converter` kind)."""
    return lambda text: (parse(text), text)[1]


# --------------------------------------------------------------------------------- run
def run(args):
    """The sweep (records x scales, one structure), then the fit: text, --json, --plot."""
    if args.structure is not None and len(args.structure) > 1:
        raise CLIError(f"--structure: one structure per fragility curve, got "
                       f"{len(args.structure)}")
    check_outputs(args)
    sweep.check_store_arguments(args)
    if args.draws is not None:
        return _run_band(args)
    if args.draws_ignore is not None:
        raise CLIError("--draws-ignore: applies to --draws")
    sw = sweep.read_sweep(args)
    sweep.run_batches(args, sw, full=True)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fit = rockjax.fragility(sw.results[0], im=args.im, limit=args.limit,
                                n_bootstrap=args.bootstrap, confidence=args.confidence,
                                seed=args.seed)  # a ParameterError names its option in main
    notes = [str(w.message) for w in caught]
    for note in notes:
        if not args.json:
            print(f"warning: {note}", file=sys.stderr)
    if args.out:
        write_csv(args.out, sw.results, sw.struct_labels)
    if args.plot:
        fig = new_figure(figsize=(7.5, 5), layout="constrained")
        fit.plot(fig.subplots()).set_title(
            f"{sw.runs}: {len(sw.rec_labels)} record(s) x {len(sw.scales)} scale(s), "
            f"{model_line(model_info(args))}", fontsize=9)
        save(fig, args.plot)
    if args.json:
        info = sweep.sweep_json(args, sw)
        print(json.dumps({"fragility": fit.to_dict(), "sweep": {k: info[k] for k in _SWEEP_KEYS},
                          "plot": args.plot, "csv": args.out, "store": args.store,
                          "runs_found_done": sw.found, "warnings": sw.warnings + notes}))
    else:
        _print_report(args, sw, fit)
    return 0


def _run_band(args):
    """--draws: `rockjax.fragility_band` over the draws: text, --json, --plot."""
    for option, value in (("--out", args.out), ("--store", args.store)):
        if value:
            raise CLIError(f"{option}: the sweep's results are written without --draws only")
    draws = read_draws_option(args)
    sw = sweep.read_sweep(args)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        band = rockjax.fragility_band(
            sw.structures[0], sw.records, sw.scales, draws, im=args.im, limit=args.limit,
            model=args.model, confidence=args.confidence, labels=sw.rec_labels, tail=sw.tail,
            t1=sw.t1, r=args.r, impact=args.impact, method=args.method,
            substeps=args.substeps, progress=False if args.json else None)
    notes = [str(w.message) for w in caught]
    if args.plot:
        fig = new_figure(figsize=(7.5, 5), layout="constrained")
        band.plot(fig.subplots()).set_title(
            f"{band.n_draws} draws of {', '.join(band.draws)} x {len(sw.rec_labels)} "
            f"record(s) x {len(sw.scales)} scale(s), model {args.model}", fontsize=9)
        save(fig, args.plot)
    if args.json:
        print(json.dumps({"fragility_band": band.summary(), "draws_file": args.draws,
                          "model_info": model_info(args), "plot": args.plot,
                          "warnings": notes}))
        return 0
    for note in notes:
        print(f"warning: {note}", file=sys.stderr)
    print(f"records       {', '.join(sw.rec_labels)} (each on its own time step, to its end "
          f"+ {sw.tail:g} s)\n{band.report()}")
    if args.plot:
        print(f"plot written to {args.plot}")
    return 0


# ----------------------------------------------------------------------------- outputs
def _print_report(args, sw, fit):
    sweep.print_inputs(sw)
    print(f"sweep         {sw.runs}: {len(sw.rec_labels)} record(s) x {len(sw.scales)} scale(s), "
          f"{sw.wall:.3g} s ({(sw.n_runs - sw.found) / sw.wall:.3g} runs/s, compilation "
          f"included{f'; {sw.found} runs found done in the store' if sw.found else ''})\n"
          f"status        {status_line(status_totals(sw.results))}\n{fit.report()}")
    sweep.print_store(args, sw)
    for what, path in (("results", args.out), ("plot", args.plot)):
        if path:
            print(f"{what} written to {path}")
