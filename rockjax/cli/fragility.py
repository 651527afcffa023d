"""`rockjax fragility`: a lognormal fragility curve fitted to a sweep of records x scales.

Built on `rockjax sweep`: the same record, scale and run arguments (`sweep`'s argument
groups) and the same engine (`rockjax.sweep`, one process), then
`rockjax.fragility` on the result: the median and beta by maximum likelihood with a
bootstrap band over the records, reported as text, --json and a --plot (docs/fragility.md).
"""

from __future__ import annotations

import argparse
import json
import sys
import warnings

import numpy as np

import rockjax
from rockjax import _plotting
from rockjax._fragility import parse_im, parse_limit

from . import sweep
from ._common import (
    _check_out_dir,
    _check_png,
    _check_r,
    CLIError,
    converter,
    model_info,
    model_line,
)

#: the library parameters that the options of `rockjax fragility` set (errors name them)
FLAGS = {**sweep.FLAGS, "im": "--im", "limit": "--limit", "n_bootstrap": "--bootstrap",
         "confidence": "--confidence", "seed": "--seed"}

#: standard normal quantiles of the probabilities the text report gives the IM at
_Z = {0.1: -1.2815515655446004, 0.5: 0.0, 0.9: 1.2815515655446004}


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
    w.set_defaults(inputs=None)
    sweep._add_input_arguments(w)
    for action in w._actions:  # the sweep's arguments, as one curve needs them
        if action.dest == "structure":
            action.help = "structure file (default: Table 1); one per fragility curve"
        elif action.dest == "scales":
            action.required, action.default = True, None
            action.help = ('scale factors on every record: a comma list such as "0.5,1,1.5" '
                           'or a range "START:STOP:N" of N evenly spaced values, ends included')
    sweep._add_run_arguments(w)
    _add_fit_arguments(w)
    _add_output_arguments(w)
    w.set_defaults(func=run)
    return w


def _im(text):
    try:
        parse_im(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
    return text


def _limit(text):
    try:
        parse_limit(text)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--limit must be overturned, uplift=METRES or rotation=RADIANS (a positive "
            f"threshold), got {text!r}"
        ) from None
    return text


_bootstrap = converter("--bootstrap", int, lambda n: n >= 0, "be >= 0")
_confidence = converter("--confidence", float, lambda c: 0 < c < 1, "lie in (0, 1)")


def _add_fit_arguments(w):
    """--im, --limit, --bootstrap, --confidence, --seed."""
    w.add_argument(
        "--im",
        type=_im,
        default="PGA",
        metavar="IM",
        help="intensity measure: PGA [g] (default), PGV [m/s], PGD [m], Sa(T) [g] (5 %%-damped "
        "pseudo-spectral acceleration at the period T in s, e.g. 'Sa(1.0)'), or scale",
    )
    w.add_argument(
        "--limit",
        type=_limit,
        default="overturned",
        metavar="LIMIT",
        help="limit state: overturned (default), uplift=M (peak corner uplift >= M metres) or "
        "rotation=RAD (peak rotation >= RAD radians); an overturned run exceeds every limit",
    )
    w.add_argument(
        "--bootstrap",
        type=_bootstrap,
        default=1000,
        metavar="N",
        help="bootstrap resamples of the records (default 1000; 0: no band)",
    )
    w.add_argument(
        "--confidence",
        type=_confidence,
        default=0.9,
        metavar="C",
        help="confidence of the band and the intervals (default 0.9)",
    )
    w.add_argument("--seed", type=int, default=0, help="seed of the bootstrap (default 0)")


def _add_output_arguments(w):
    """--plot, --json, --out."""
    w.add_argument(
        "--plot",
        metavar="FILE.png",
        help="plot the fitted curve, its band and the observed fractions against the IM",
    )
    w.add_argument(
        "--json",
        action="store_true",
        help="print one JSON object and nothing else (no progress bar)",
    )
    w.add_argument(
        "--out",
        metavar="FILE.csv",
        help="also write the sweep's CSV, one row per run (the columns of rockjax sweep)",
    )


# --------------------------------------------------------------------------------- run
def _check_args(args):
    if args.structure is not None and len(args.structure) > 1:
        raise CLIError(
            f"--structure: one structure per fragility curve, got {len(args.structure)}"
        )
    _check_png(args.plot)
    _check_r(args.r)
    _check_out_dir("--plot", args.plot)
    _check_out_dir("--out", args.out)


def _fit(args, result):
    """`rockjax.fragility` with its warnings collected; errors in CLI syntax."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fit = rockjax.fragility(result, im=args.im, limit=args.limit,
                                n_bootstrap=args.bootstrap, confidence=args.confidence,
                                seed=args.seed)  # a ParameterError names its option in main
    return fit, [str(w.message) for w in caught]


def _plot(args, sw, fit):
    fig = _plotting.new_figure(figsize=(7.5, 5), layout="constrained")
    ax = fit.plot(fig.subplots())
    ax.set_title(
        f"{sw.runs}: {len(sw.rec_labels)} record(s) x {len(sw.scales)} scale(s), "
        f"{model_line(model_info(args))}",
        fontsize=9,
    )
    fig.savefig(args.plot, dpi=150)


def run(args):
    """The sweep (records x scales, one structure), then the fit: text, --json, --plot."""
    _check_args(args)
    sw = sweep._read_sweep(args)
    sweep._run_batches(args, sw)
    fit, notes = _fit(args, sw.results[0])
    for note in notes:
        if not args.json:
            print(f"warning: {note}", file=sys.stderr)
    if args.out:
        sweep._write_sweep_csv(args, sw)
    if args.plot:
        _plot(args, sw, fit)
    if args.json:
        _print_json(args, sw, fit, notes)
    else:
        _print_report(args, sw, fit)
    return 0


# ----------------------------------------------------------------------------- outputs
#: the keys of the sweep's JSON that `--json` shows under "sweep"
_SWEEP_KEYS = ("n_runs", "n_records", "n_scales", "status_counts", "wall_time_s", "tail_s",
               "t1", "grid_dt_s", "model", "model_info", "method", "substeps", "records",
               "record_info", "skipped_files", "scales")


def _print_json(args, sw, fit, notes):
    info = sweep.sweep_json(args, sw)
    print(json.dumps({"fragility": fit.to_dict(), "sweep": {k: info[k] for k in _SWEEP_KEYS},
                      "plot": args.plot, "csv": args.out, "warnings": sw.warnings + notes}))


def _interval(fit, ci, unit=""):
    if ci is None:
        return ""
    return f"  ({fit.confidence:.0%} interval {ci[0]:.4g} to {ci[1]:.4g}{unit})"


def _print_report(args, sw, fit):
    sweep._print_inputs(args, sw)
    print(
        f"sweep         {sw.runs}: {len(sw.rec_labels)} record(s) x {len(sw.scales)} scale(s), "
        f"{sw.wall:.3g} s ({sw.n_runs / sw.wall:.3g} runs/s, compilation included)"
    )
    counts = sw.status_counts()
    print("status        " + ", ".join(f"{k} {v}" for k, v in counts.items() if v))
    failed = {k: v for k, v in fit.n_failed.items() if v}
    left = ", ".join(f"{k} {v}" for k, v in failed.items())
    print(
        f"fit           P({fit.limit} | {fit.im}) = Phi(ln({fit.im}/median)/beta), maximum "
        f"likelihood over the {fit.n_used} runs that completed or overturned "
        f"({fit.n_exceeded} reached the limit); "
        + (f"{sum(failed.values())} failed runs left out ({left})" if failed else
           "no failed runs")
    )
    unit = f" {fit.im_unit}" if fit.im_unit != "-" else ""
    print(f"median        {fit.median:.4g}{unit}{_interval(fit, fit.median_ci, unit)}")
    beta = "0 (separated: a step at the median)" if fit.separated else f"{fit.beta:.4g}"
    print(f"beta          {beta}{_interval(fit, fit.beta_ci)}")
    at = [fit.median * np.exp(fit.beta * z) for z in _Z.values()]
    print(f"quantiles     {fit.im} at P = 10, 50, 90 %: " + ", ".join(f"{v:.4g}" for v in at)
          + unit)
    if fit.n_bootstrap:
        kinds = ", ".join(f"{k} {v}" for k, v in fit.bootstrap_counts.items() if v)
        print(f"bootstrap     {fit.n_bootstrap} resamples of the {fit.resampled} (seed "
              f"{fit.seed}): {kinds}")
    if args.out:
        print(f"results written to {args.out}")
    if args.plot:
        print(f"plot written to {args.plot}")
