"""`rockjax simulate`: the time history of a free-vibration release or a ground motion."""

from __future__ import annotations

import json
import pathlib
import sys

import numpy as np

import rockjax
from rockjax._plotting import plot_response
from rockjax._report import record_info, record_line

from ._common import (
    add_model_arguments,
    add_outputs,
    add_structure_argument,
    add_time_tolerance_argument,
    check_outputs,
    CLIError,
    COMMON_FLAGS,
    fidelity_note,
    finite_float,
    load_structure,
    MAX_STEPS,
    model_info,
    model_line,
    positive_float,
    RECORD_FLAGS,
    record_units,
    RECORD_UNITS_METAVAR,
)

#: the library parameters that the options of `rockjax simulate` set (errors name the option)
FLAGS = {**COMMON_FLAGS, **RECORD_FLAGS, "u0": "--u0", "v0": "--v0"}
#: output step [s] of a free-vibration run (a ground-motion run uses the record's step)
_FREE_DT = 0.002


def add_parser(subparsers):
    m = subparsers.add_parser(
        "simulate",
        help="time history of a free-vibration release or a ground-motion record (Eq 1)",
        description="Integrate Eq 1 with impacts at u = 0 (velocity scaled by sqrt(r)). "
        "Free vibration: --u0 [--v0]. Ground motion: --record FILE (PEER AT2, two columns "
        "t a, or one column with --record-dt) [--units g|m/s2|cm/s2|gal|...] [--scale S].",
    )
    add_structure_argument(m)
    m.add_argument("--u0", type=finite_float("--u0"), metavar="M", help="release displacement [m]")
    m.add_argument("--v0", type=finite_float("--v0"), default=0.0, metavar="V",
                   help="release velocity [m/s] (default 0)")
    m.add_argument("--record", metavar="FILE", help="ground-motion record file")
    m.add_argument("--units", type=record_units, metavar=RECORD_UNITS_METAVAR,
                   help="units of the record's values (other spellings: m/s^2, Gal, ...)")
    m.add_argument("--scale", type=finite_float("--scale"), default=1.0,
                   help="scale factor on the record (default 1)")
    m.add_argument("--record-dt", type=positive_float("--record-dt"), metavar="DT",
                   help="sample step [s] of a one-column record")
    add_time_tolerance_argument(m)
    m.add_argument("--t1", type=positive_float("--t1"), metavar="T",
                   help="end time [s] (default: 4 s, or the record's length)")
    add_model_arguments(m, "model of the fidelity ladder (default simplified)")
    add_outputs(m, "write a Fig 9/10-style plot", out="write the time history as CSV, header "
                "t_s,u_m,v_m_s,theta_rad,uplift_m", json="print a JSON summary and nothing else")
    m.set_defaults(func=run)
    return m


def _build_excitation(args, s):
    """(excitation, ground motion or None, what was read) from --u0/--v0 or --record."""
    if args.record is not None and args.u0 is not None:
        raise CLIError("give either --u0 (free vibration) or --record (ground motion), not both")
    if args.record is None:
        if args.u0 is None:
            raise CLIError("give --u0 M (free vibration) or --record FILE (ground motion)")
        if abs(args.u0) > (uo := float(s.u_overturn)):
            raise CLIError(f"--u0 {args.u0:g} m is beyond u_overturn = {uo:.4g} m: the structure "
                           "would overturn at once (--u0 is in metres: 100 mm is --u0 0.1)")
        return (rockjax.FreeVibration(args.u0, args.v0), None,
                {"type": "free_vibration", "u0": args.u0, "v0": args.v0})
    rec = rockjax.read_record(args.record, units=args.units, dt=args.record_dt,
                              check_plausible=args.check_plausible,
                              time_tolerance=args.time_tolerance)
    gm = rockjax.GroundMotion.from_record(rec, scale=args.scale)
    return gm, gm, {"type": "ground_motion", **record_info(rec, args.scale)}


def _end_time(args, gm):
    """--t1, else the record's length or 4 s; a one-line error naming --t1, rather than
    numpy's size error, for absurd run lengths."""
    t1 = args.t1 if args.t1 is not None else 4.0 if gm is None else float(gm.duration)
    dt = _FREE_DT if gm is None else float(gm.dt)
    if not t1 / dt <= MAX_STEPS:
        raise CLIError(f"--t1 {t1:g} s is {t1 / dt:.3g} output samples of {dt:g} s, more than "
                       f"{MAX_STEPS:,}; shorten --t1")
    return t1


def _write_plot(args, s, res, gm, read):
    what = (f"release u0 = {args.u0} m" if gm is None else
            f"{pathlib.Path(read['file']).name} x {args.scale:g} "
            f"(PGA {read['scaled_pga_g']:.3g} g)")
    plot_response(s, res, ground_motion=gm, title=f"{model_line(model_info(args))}; {what}"
                  ).savefig(args.plot, dpi=150)


#: units of the JSON result's values
UNITS = {
    "peak_u": "m", "t_peak": "s", "peak_theta": "rad", "peak_theta_over_alpha_c": "-",
    "peak_uplift": "m", "impact_times": "s", "t_overturn": "s", "t_end": "s",
    "residual_u": "m", "u0": "m", "v0": "m/s", "dt_s": "s", "duration_s": "s",
    "pga_m_s2": "m/s2", "pga_g": "g", "t1": "s", "r": "-",
}


def _result(args, s, res, t1, read):
    """The JSON result: what produced it, what was read, and the response (SI units)."""
    theta = res.peak_theta(s, rockjax.get_model(args.model, args.impact))
    return {**model_info(args), "r": float(s.restitution) if args.r is None else args.r,
            "r_from": "Eq 3" if args.r is None else "--r", "excitation": read, "t1": t1,
            **res.summary(), "peak_theta": theta,
            "peak_theta_over_alpha_c": theta / float(s.alpha_c), "message": res.message,
            "units": UNITS}


def _print_summary(args, s, res, out):
    read = out["excitation"]
    print(f"record        {record_line(read)}" if read["type"] == "ground_motion" else
          f"release       u0 = {read['u0']:g} m, v0 = {read['v0']:g} m/s")
    print(f"model         {model_line(model_info(args))} (= {out['r']:.4g}), t1 = {out['t1']:g} s")
    print(res.report(s, rockjax.get_model(args.model, args.impact)))
    for what, path in (("time history", args.out), ("plot", args.plot)):
        if path:
            print(f"{what} written to {path}")


def run(args):
    s = load_structure(args.structure, args.check_plausible)
    check_outputs(args)
    excitation, gm, read = _build_excitation(args, s)
    t1 = _end_time(args, gm)
    ts = None if gm is not None else np.linspace(0.0, t1, max(2, int(round(t1 / _FREE_DT)) + 1))
    res = rockjax.simulate(s, excitation, t1, ts=ts, model=args.model, r=args.r,
                           impact=args.impact, fidelity_warning=False)
    out = _result(args, s, res, t1, read)
    out["fidelity_warning"] = fidelity_note(args, s, excitation.forced, res.peak_u)
    if out["fidelity_warning"]:
        print(f"warning: {out['fidelity_warning']}", file=sys.stderr)
    if args.out:
        res.to_csv(args.out)
    if args.plot:
        _write_plot(args, s, res, gm, read)
    if args.json:
        print(json.dumps(out))
        return 0
    _print_summary(args, s, res, out)
    return 0
