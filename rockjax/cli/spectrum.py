"""`rockjax spectrum`: the overturning spectrum of a structure under a pulse."""

from __future__ import annotations

import json

import numpy as np

import rockjax
from rockjax._plotting import new_figure
from rockjax._spectrum import periods_at

from ._common import (
    add_model_arguments,
    add_outputs,
    add_structure_argument,
    check_outputs,
    CLIError,
    COMMON_FLAGS,
    converter,
    load_structure,
    model_info,
    number_list,
    save,
    write_columns,
)
from .fragility import add_draws_arguments, read_draws_option

#: the library parameters that the options of `rockjax spectrum` set (errors name them)
FLAGS = {**COMMON_FLAGS, "periods": "--periods", "rtol": "--rtol", "kind": "--pulse",
         "structure": "--structure", "draws": "--draws", "confidence": "--confidence"}
#: --pulse names and the `rockjax.pulses` kinds
PULSES = {"rectangular": "rectangular", "sine": "one_sine", "cosine": "one_cosine"}


def add_parser(subparsers):
    q = subparsers.add_parser(
        "spectrum",
        help="overturning spectrum: the smallest pulse amplitude that overturns, per period",
        description="For each period of a pulse (a rectangular pulse: its duration), the "
        "smallest amplitude that overturns the structure (overturning after impacts or "
        "without), found by batches of runs and multisection to --rtol. Plotted as the "
        "literature does: a / (g tan alpha) against omega_p / p (p t1 for a rectangular "
        "pulse), p = sqrt(W R / I_O).",
    )
    q.add_argument("--pulse", required=True, choices=list(PULSES),
                   help="rectangular (Housner), sine (one-sine, Zhang & Makris type A) or "
                   "cosine (one-cosine, type B)")
    which = q.add_mutually_exclusive_group(required=True)
    which.add_argument("--periods", type=number_list("--periods"), metavar="T",
                       help="pulse periods [s] (rectangular: durations), a list 0.2,0.5,1 "
                       "or a range START:STOP:N")
    which.add_argument("--ratios", type=number_list("--ratios"), metavar="X",
                       help="the same as omega_p / p (rectangular: p t1), a list or a range")
    add_structure_argument(q)
    add_model_arguments(q, "model (default rigid_body, the body's own equation)",
                        fidelity=False)
    q.set_defaults(model="rigid_body")
    q.add_argument("--rtol", type=float, default=1e-3,
                   help="relative width of each final bracket (default 1e-3)")
    add_draws_arguments(q, "the threshold amplitude per period for every draw, its median "
                        "and --confidence band, beside the spectrum of the structure as given")
    q.add_argument("--confidence", default=0.9, metavar="C",
                   type=converter("--confidence", float, lambda c: 0 < c < 1, "lie in (0, 1)"),
                   help="confidence of the band over the --draws (default 0.9)")
    add_outputs(q, "write the spectrum plot", out="write the spectrum as CSV (SI units)")
    q.set_defaults(func=run)
    return q


def run(args):
    s = load_structure(args.structure, args.check_plausible)
    check_outputs(args)
    if not 1e-8 <= args.rtol <= 0.1:
        raise CLIError(f"--rtol must lie in [1e-8, 0.1], got {args.rtol}")
    T = (np.asarray(args.periods) if args.periods is not None
         else periods_at(s, PULSES[args.pulse], args.ratios))
    if args.draws is not None:
        return _run_band(args, s, T)
    if args.draws_ignore is not None:
        raise CLIError("--draws-ignore: applies to --draws")
    sp = rockjax.overturning_spectrum(s, PULSES[args.pulse], T, model=args.model,
                                      impact=args.impact, r=args.r, rtol=args.rtol,
                                      progress=None if not args.json else False)
    info = model_info(args)
    if args.plot:
        fig = new_figure(figsize=(6, 4))
        sp.plot(fig.subplots())
        save(fig, args.plot, bbox_inches="tight")
    if args.out:
        sp.to_csv(args.out)
    if args.json:
        print(json.dumps({**sp.to_dict(), "model_info": info, "plot": args.plot,
                          "csv": args.out}))
        return 0
    print(sp.report())
    for what, path in (("plot", args.plot), ("CSV", args.out)):
        if path:
            print(f"{what} written to {path}")
    return 0



def _run_band(args, s, T):
    """--draws: `rockjax.spectrum_band`: text, --json, --plot, --out."""
    draws = read_draws_option(args)
    band = rockjax.spectrum_band(
        s, PULSES[args.pulse], T, draws,
        model=args.model if args.impact == "paper" else rockjax.get_model(args.model, args.impact),
        r=args.r, amplitude_rtol=args.rtol, confidence=args.confidence,
        execution=rockjax.Execution(progress=None if not args.json else False))
    if args.plot:
        fig = new_figure(figsize=(6, 4))
        band.plot(fig.subplots())
        save(fig, args.plot, bbox_inches="tight")
    if args.out:
        write_columns(args.out, {"period": band.periods, "x": band.x,
                                 "point": band.point.amplitude, "median": band.median,
                                 "lower": band.band[0], "upper": band.band[1],
                                 "n_none": band.n_none},
                      {"period": "s", "x": "-", "point": "m/s2", "median": "m/s2",
                       "lower": "m/s2", "upper": "m/s2", "n_none": "-"})
    if args.json:
        print(json.dumps({"spectrum_band": band.summary(), "draws_file": args.draws,
                          "model_info": model_info(args), "plot": args.plot,
                          "csv": args.out}))
        return 0
    print(band.report())
    for what, path in (("plot", args.plot), ("CSV", args.out)):
        if path:
            print(f"{what} written to {path}")
    return 0
