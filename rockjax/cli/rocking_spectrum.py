"""`rockjax rocking-spectrum`: the rocking spectrum of a record (peak theta / alpha of
uniform blocks across sizes) with the equivalent-linear estimate beside it."""

from __future__ import annotations

import json
import pathlib

import numpy as np

import rockjax
from rockjax._plotting import new_figure
from rockjax._records import RECORD_UNITS
from rockjax._rocking_spectrum import MODELS

from ._common import (
    add_outputs,
    check_outputs,
    CLIError,
    COMMON_FLAGS,
    converter,
    number_list,
    positive_float,
    record_units,
    RECORD_UNITS_METAVAR,
    save,
    write_columns,
)
from .sweep import split_record_units

COMMAND = "rocking-spectrum"
#: the library parameters that the options set (errors name them)
FLAGS = {**COMMON_FLAGS, "p": "--p", "alpha": "--alpha", "record": "--record",
         "scale": "--scale", "tail": "--tail", "model": "--model", "r": "--r"}


def add_parser(subparsers):
    q = subparsers.add_parser(
        COMMAND,
        help="rocking spectrum of a record: peak theta/alpha of uniform blocks across sizes",
        description="For one ground-motion record and one slenderness alpha, the peak "
        "rotation theta/alpha (or overturning) of uniform rigid blocks across a range of "
        "sizes, given by Housner's frequency parameter p = sqrt(3 g / (4 R)) (R: the "
        "half-diagonal), in one batch of runs (rockjax.rocking_spectrum; Makris & "
        "Konstantinidis 2003), with the equivalent-linear-oscillator estimate of Priestley, "
        "Evison & Carr (1978) / FEMA 356 beside it: a linear SDOF of period "
        "T = 4/p acosh(1/(1 - theta/alpha)) and damping -ln(r)/(2 pi), iterated on the "
        "record's elastic displacement spectrum (docs/spectra.md).",
    )
    q.add_argument("--record", required=True, metavar="FILE[:UNITS]",
                   help="ground-motion record (PEER AT2, two columns t a, ...); FILE:g "
                   "states its units")
    q.add_argument("--units", type=record_units, metavar=RECORD_UNITS_METAVAR,
                   help="units of the record when its file states none")
    q.add_argument("--alpha", type=converter("--alpha", float, lambda a: 0 < a < 0.785,
                                             "lie in (0, pi/4)"),
                   action="append", required=True, metavar="RAD",
                   help="slenderness alpha [rad], repeatable (one spectrum each)")
    q.add_argument("--p", type=number_list("--p"), default=None, metavar="LIST|START:STOP:N",
                   help="frequency parameters p [rad/s]: a list or a range (default "
                   "0.5:5:19)")
    q.add_argument("--model", choices=list(MODELS), default="rigid_body",
                   help="rigid_body (default: the body's own equation on stiff springs, "
                   "Housner's block) or housner (the paper's SDOF with the rigid law)")
    q.add_argument("--k-f", dest="k_f", type=positive_float("--k-f"), default=1e10,
                   metavar="N/M", help="rigid_body's springs for the 1000-kg blocks "
                   "(default 1e10)")
    q.add_argument("--r", type=converter("--r", float, lambda r: 0 <= r <= 1, "lie in [0, 1]"),
                   default=None, help="restitution (squared angular speeds after/before an "
                   "impact; default Housner's (1 - 1.5 sin^2 alpha)^2)")
    q.add_argument("--scale", type=positive_float("--scale"), default=1.0,
                   help="factor on the record (default 1)")
    q.add_argument("--tail", type=converter("--tail", float, lambda x: x >= 0, "be >= 0"),
                   default=5.0, metavar="S", help="free rocking after the record's end "
                   "(default 5 s)")
    add_outputs(q, "write the spectrum plot (theta/alpha against p)",
                out="write the spectra as CSV (one row per alpha and p)")
    q.set_defaults(func=run)
    return q


def run(args):
    check_outputs(args, r=False)
    path, units = split_record_units(args.record)
    if units is not None and units not in RECORD_UNITS:
        raise CLIError(f"--record: unknown units {units}")
    record = rockjax.read_record(path, units=units or args.units)
    p = np.asarray(args.p if args.p is not None else np.linspace(0.5, 5.0, 19), float)
    spectra = [rockjax.rocking_spectrum(record, a, p, model=args.model, r=args.r,
                                        scale=args.scale, k_f=args.k_f, tail=args.tail)
               for a in args.alpha]
    if args.plot:
        fig = new_figure(figsize=(6, 4))
        ax = fig.subplots()
        for sp in spectra:
            sp.plot(ax)
        ax.set_title(f"rocking spectrum of {pathlib.Path(record.source).name} x {args.scale:g}",
                     fontsize=9)
        save(fig, args.plot, bbox_inches="tight")
    if args.out:
        write_columns(args.out, {
            "alpha": np.concatenate([np.full(sp.p.size, sp.alpha) for sp in spectra]),
            "p": np.concatenate([sp.p for sp in spectra]),
            "R": np.concatenate([sp.R for sp in spectra]),
            "theta_over_alpha": np.concatenate([sp.theta_over_alpha for sp in spectra]),
            "overturned": np.concatenate([sp.overturned for sp in spectra]).astype(int),
            "eq_theta_over_alpha": np.concatenate([sp.eq_theta_over_alpha for sp in spectra]),
            "eq_overturned": np.concatenate([sp.eq_overturned for sp in spectra]).astype(int),
        }, {"alpha": "rad", "p": "rad/s", "R": "m", "theta_over_alpha": "-",
            "overturned": "-", "eq_theta_over_alpha": "-", "eq_overturned": "-"})
    if args.json:
        print(json.dumps({"spectra": [sp.to_dict() for sp in spectra], "plot": args.plot,
                          "csv": args.out}))
        return 0
    print("\n\n".join(sp.report() for sp in spectra))
    for what, where in (("plot", args.plot), ("CSV", args.out)):
        if where:
            print(f"{what} written to {where}")
    return 0
