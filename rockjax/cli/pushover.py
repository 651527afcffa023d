"""`rockjax pushover`: derived quantities and pushover curves (closed forms and numerical)."""

from __future__ import annotations

import json
import math

from rockjax._plotting import plot_pushover, pushover_curves
from rockjax._report import DERIVED_UNITS, pushover_table

from ._common import (
    add_outputs,
    add_structure_argument,
    check_outputs,
    CLIError,
    converter,
    load_structure,
    positive_float,
    write_columns,
)

_CURVES = ("u", "simplified", "exact", "numerical")
#: the --out CSV columns and their units (header u_m,simplified_N,...,uplift_m)
CSV_COLUMNS = {"u": "m", "simplified": "N", "exact": "N", "numerical": "N", "theta": "rad",
               "uplift": "m"}
#: the library parameters that the options of `rockjax pushover` set (errors name them)
FLAGS = {"u": "--umax", "structure": "--structure",
         "check_plausible": "--no-plausibility-check"}


def add_parser(subparsers):
    q = subparsers.add_parser(
        "pushover",
        help="derived quantities and pushover curves (closed forms and numerical)",
        description="Print the derived quantities of a structure and its pushover curves: "
        "the simplified (Eqs 13, 20) and exact (Eqs 13, 18) closed forms and the numerical "
        "pushover of the rigid body on two springs.",
    )
    add_structure_argument(q)
    q.add_argument("--umax", type=positive_float("--umax"), metavar="M",
                   help="largest displacement [m] (default 0.99 u_overturn)")
    q.add_argument("--points", type=converter("--points", int, lambda n: n >= 2, "be at least 2"),
                   default=201, help="number of points (default 201)")
    add_outputs(q, "write a Fig 8-style plot", out="write the curves as CSV, header u_m,"
                "simplified_N,exact_N,numerical_N,theta_rad,uplift_m")
    q.set_defaults(func=run)
    return q


def _umax(s, umax):
    """--umax, or 0.99 u_overturn; below the body's reach, where the pushover ends."""
    umax = umax if umax is not None else 0.99 * float(s.u_overturn)
    reach = float(s.R_e * (1.0 + math.sin(float(s.alpha_e))))
    if umax >= reach:
        raise CLIError(f"--umax must be below the body's reach R_e (1 + sin alpha_e) = "
                       f"{reach:.6g} m, got {umax}")
    return umax


def run(args):
    s = load_structure(args.structure, args.check_plausible)
    umax = _umax(s, args.umax)
    check_outputs(args, r=False)
    curves = pushover_curves(s, umax=umax, n=args.points)
    if args.plot:
        plot_pushover(s, curves).savefig(args.plot, dpi=150)
    if args.out:
        write_columns(args.out, curves, CSV_COLUMNS)
    if args.json:
        print(json.dumps({
            "derived": s.derived(), "curve": {k: curves[k].tolist() for k in _CURVES},
            "converged": curves["converged"],
            "units": {"u": "m", "simplified": "N", "exact": "N", "numerical": "N",
                      "angles": "rad (and deg in *_deg)", "derived": DERIVED_UNITS}}))
        return 0
    print(pushover_table(s.derived(), curves))
    print(f"({len(curves['u'])} points; --json or --out FILE.csv for all of them)")
    if args.plot:
        print(f"plot written to {args.plot}")
    return 0
