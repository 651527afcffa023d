"""`rockjax simulate`: the time history of a free-vibration release or a ground motion."""

from __future__ import annotations

import json
import pathlib

import numpy as np

import rockjax
from rockjax import _plotting

from ._common import (
    _check_png,
    _check_r,
    _check_t1_steps,
    _finite_float,
    _load_structure,
    _positive_float,
    _write_csv,
    add_model_arguments,
    CLIError,
)

#: output step [s] of a free-vibration run (a ground-motion run uses the record's step)
_FREE_DT = 0.002


def add_parser(subparsers):
    m = subparsers.add_parser(
        "simulate",
        help="time history of a free-vibration release or a ground-motion record (Eq 1)",
        description="Integrate Eq 1 with impacts at u = 0 (velocity scaled by sqrt(r)). "
        "Free vibration: --u0 [--v0]. Ground motion: --record FILE (PEER AT2, two columns "
        "t a, or one column with --record-dt) [--units g|m/s2] [--scale S].",
    )
    m.add_argument("--structure", metavar="FILE.toml", help="structure file (default: Table 1)")
    m.add_argument("--u0", type=_finite_float("--u0"), metavar="M", help="release displacement [m]")
    m.add_argument(
        "--v0",
        type=_finite_float("--v0"),
        default=0.0,
        metavar="V",
        help="release velocity [m/s] (default 0)",
    )
    m.add_argument("--record", metavar="FILE", help="ground-motion record file")
    m.add_argument("--units", choices=["g", "m/s2"], help="units of the record's values")
    m.add_argument(
        "--scale",
        type=_finite_float("--scale"),
        default=1.0,
        help="scale factor on the record (default 1)",
    )
    m.add_argument(
        "--record-dt",
        type=_positive_float("--record-dt"),
        metavar="DT",
        help="sample step [s] of a one-column record",
    )
    m.add_argument(
        "--t1",
        type=_positive_float("--t1"),
        metavar="T",
        help="end time [s] (default: 4 s, or the record's length)",
    )
    add_model_arguments(m, "model of the fidelity ladder (default simplified)")
    m.add_argument("--out", metavar="FILE.csv", help="write t, u, v, theta, uplift as CSV")
    m.add_argument("--plot", metavar="FILE.png", help="write a Fig 9/10-style plot")
    m.add_argument("--json", action="store_true", help="print a JSON summary and nothing else")
    m.set_defaults(func=run)
    return m


def _build_excitation(args):
    """(excitation, ground motion or None) from --u0/--v0 or --record."""
    if args.record is not None and args.u0 is not None:
        raise CLIError("give either --u0 (free vibration) or --record (ground motion), not both")
    if args.record is None:
        if args.u0 is None:
            raise CLIError("give --u0 M (free vibration) or --record FILE (ground motion)")
        return rockjax.FreeVibration(args.u0, args.v0), None
    gm = rockjax.GroundMotion.from_file(
        args.record, units=args.units, scale=args.scale, dt=args.record_dt
    )
    return gm, gm


def _end_time(args, gm):
    if args.t1 is not None:
        return args.t1
    if gm is not None:
        return float(gm.duration)
    return 4.0


def _write_plot(args, s, res, gm):
    rec = pathlib.Path(args.record).name if gm is not None else ""
    what = f"release u0 = {args.u0} m" if gm is None else f"{rec} x {args.scale}"
    fig = _plotting.plot_response(s, res, ground_motion=gm, title=f"{args.model} model, {what}")
    fig.savefig(args.plot, dpi=150)


def _print_summary(args, summary):
    print(f"status        {summary['status']}")
    print(f"peak |u|      {summary['peak_u']:.6g} m")
    print(f"peak uplift   {summary['peak_uplift']:.6g} m")
    print(f"impacts       {summary['n_impacts']}")
    if summary["t_overturn"] is not None:
        print(f"t_overturn    {summary['t_overturn']:.6g} s")
    if args.out:
        print(f"time history written to {args.out}")
    if args.plot:
        print(f"plot written to {args.plot}")


def run(args):
    s = _load_structure(args.structure)
    _check_png(args.plot)
    excitation, gm = _build_excitation(args)
    t1 = _end_time(args, gm)
    _check_r(args.r)
    _check_t1_steps(t1, _FREE_DT if gm is None else float(gm.dt), "output samples")
    if gm is None:
        ts = np.linspace(0.0, t1, max(2, int(round(t1 / _FREE_DT)) + 1))
    else:
        ts = None
    res = rockjax.simulate(s, excitation, t1, ts=ts, model=args.model, r=args.r, impact=args.impact)
    summary = res.summary()
    if args.out:
        cols = {k: np.asarray(getattr(res, k)) for k in ("ts", "u", "v", "theta", "uplift")}
        cols["t"] = cols.pop("ts")
        _write_csv(args.out, cols, ("t", "u", "v", "theta", "uplift"))
    if args.plot:
        _write_plot(args, s, res, gm)
    if args.json:
        print(json.dumps(summary))
        return 0
    _print_summary(args, summary)
    return 0
