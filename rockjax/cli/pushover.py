"""`rockjax pushover`: derived quantities and pushover curves (closed forms and numerical)."""

from __future__ import annotations

import json
import math

from rockjax import _plotting

from ._common import (
    _check_out_dir,
    _check_png,
    _derived_table,
    _load_structure,
    _points,
    _positive_float,
    _UNITS,
    _write_csv,
    add_plausibility_argument,
    CLIError,
    PLAUSIBILITY_FLAG,
)

_CURVES = ("u", "simplified", "exact", "numerical")
#: the --out CSV columns and their units (header u_m,simplified_N,...,uplift_m)
CSV_COLUMNS = {"u": "m", "simplified": "N", "exact": "N", "numerical": "N", "theta": "rad",
               "uplift": "m"}


#: the library parameters that the options of `rockjax pushover` set (errors name them)
FLAGS = {"u": "--umax", "structure": "--structure", "check_plausible": PLAUSIBILITY_FLAG}

def add_parser(subparsers):
    q = subparsers.add_parser(
        "pushover",
        help="derived quantities and pushover curves (closed forms and numerical)",
        description="Print the derived quantities of a structure and its pushover curves: "
        "the simplified (Eqs 13, 20) and exact (Eqs 13, 18) closed forms and the numerical "
        "pushover of the rigid body on two springs.",
    )
    q.add_argument("--structure", metavar="FILE.toml", help="structure file (default: Table 1)")
    add_plausibility_argument(q)
    q.add_argument(
        "--umax",
        type=_positive_float("--umax"),
        metavar="M",
        help="largest displacement [m] (default 0.99 u_overturn)",
    )
    q.add_argument("--points", type=_points, default=201, help="number of points (default 201)")
    q.add_argument("--plot", metavar="FILE.png", help="write a Fig 8-style plot")
    q.add_argument(
        "--out",
        metavar="FILE.csv",
        help="write the curves as CSV, header u_m,simplified_N,exact_N,numerical_N,theta_rad,"
        "uplift_m",
    )
    q.add_argument("--json", action="store_true", help="print one JSON object and nothing else")
    q.set_defaults(func=run)
    return q


def _umax(s, umax):
    """--umax, or 0.99 u_overturn; below the body's reach, where the pushover ends."""
    umax = umax if umax is not None else 0.99 * float(s.u_overturn)
    reach = float(s.R_e * (1.0 + math.sin(float(s.alpha_e))))
    if umax >= reach:
        raise CLIError(
            f"--umax must be below the body's reach R_e (1 + sin alpha_e) = "
            f"{reach:.6g} m, got {umax}"
        )
    return umax


def _lin(a, b, n):
    return [a + (b - a) * i / (n - 1) for i in range(n)]


def _print_table(derived, curves):
    print(_derived_table(derived))
    print()
    print(f"{'u [m]':>10} {'simplified [N]':>15} {'exact [N]':>12} {'numerical [N]':>14}")
    idx = sorted(set(int(round(i)) for i in _lin(0, len(curves["u"]) - 1, 21)))
    for i in idx:
        print(
            f"{curves['u'][i]:10.5f} {curves['simplified'][i]:15.3f} "
            f"{curves['exact'][i]:12.3f} {curves['numerical'][i]:14.3f}"
        )
    print(f"({len(curves['u'])} points; --json or --out FILE.csv for all of them)")


def run(args):
    s = _load_structure(args.structure, args.check_plausible)
    umax = _umax(s, args.umax)
    _check_png(args.plot)
    _check_out_dir("--out", args.out)
    _check_out_dir("--plot", args.plot)
    curves = _plotting.pushover_curves(s, umax=umax, n=args.points)
    derived = s.derived()
    if args.plot:
        fig = _plotting.plot_pushover(s, curves)
        fig.savefig(args.plot, dpi=150)
    if args.out:
        _write_csv(args.out, curves, CSV_COLUMNS)
    if args.json:
        out = {
            "derived": derived,
            "curve": {k: curves[k].tolist() for k in _CURVES},
            "converged": curves["converged"],
            "units": {"u": "m", "simplified": "N", "exact": "N", "numerical": "N",
                      "angles": "rad (and deg in *_deg)", "derived": _UNITS},
        }
        print(json.dumps(out))
        return 0
    _print_table(derived, curves)
    if args.plot:
        print(f"plot written to {args.plot}")
    return 0
