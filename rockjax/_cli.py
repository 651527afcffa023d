"""The `rockjax` command line: `rockjax demo`, `rockjax pushover`, ...

Every bad input ends with a non-zero exit code and a one-line message on stderr, never a
traceback.
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import sys

EXIT_USAGE = 2


class CLIError(Exception):
    """A user-facing error: printed as one line, exit code 2."""


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, no usage dump
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


def _positive_float(name):
    def conv(text):
        try:
            x = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not math.isfinite(x) or x <= 0:
            raise argparse.ArgumentTypeError(f"{name} must be a positive number, got {text!r}")
        return x

    return conv


def _points(text):
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--points must be an integer, got {text!r}") from None
    if n < 2:
        raise argparse.ArgumentTypeError(f"--points must be at least 2, got {n}")
    return n


def _load_structure(path):
    from ._structure import mcmanus_column, RockingStructure

    if path is None:
        return mcmanus_column()
    return RockingStructure.from_toml(path)


def _check_png(path):
    if path is not None and pathlib.Path(path).suffix.lower() not in (".png", ".pdf", ".svg"):
        raise CLIError(f"--plot must end in .png, .pdf or .svg, got {path}")


# ---------------------------------------------------------------------- pushover
def cmd_pushover(args):
    from ._plotting import plot_pushover, pushover_curves

    s = _load_structure(args.structure)
    umax = args.umax if args.umax is not None else 0.99 * float(s.u_overturn)
    _check_png(args.plot)
    curves = pushover_curves(s, umax=umax, n=args.points)
    derived = s.derived()
    if args.plot:
        fig = plot_pushover(s, curves)
        fig.savefig(args.plot, dpi=150)
    if args.out:
        _write_csv(args.out, curves, ("u", "simplified", "exact", "numerical", "theta", "uplift"))
    if args.json:
        out = {
            "derived": derived,
            "curve": {k: curves[k].tolist() for k in ("u", "simplified", "exact", "numerical")},
            "converged": curves["converged"],
        }
        print(json.dumps(out))
        return 0
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
    if args.plot:
        print(f"plot written to {args.plot}")
    return 0


def _lin(a, b, n):
    return [a + (b - a) * i / (n - 1) for i in range(n)]


def _write_csv(path, columns, names):
    import numpy as np

    data = np.column_stack([np.asarray(columns[k]) for k in names])
    np.savetxt(path, data, delimiter=",", header=",".join(names), comments="", fmt="%.10g")


_UNITS = {
    "W": "N",
    "H_c": "m",
    "R_c": "m",
    "alpha_c": "rad",
    "R_e": "m",
    "alpha_e": "rad",
    "R_b": "m",
    "alpha_b": "rad",
    "delta_0": "m",
    "theta_crit": "rad",
    "u_crit": "m",
    "K1": "N/m",
    "P_crit": "N",
    "P_crit2": "N",
    "u_overturn": "m",
    "restitution": "-",
}


def _derived_table(derived):
    lines = [f"{'quantity':<14}{'value':>14}  unit"]
    for k, unit in _UNITS.items():
        v = derived[k]
        extra = f"  ({derived[k + '_deg']:.4f} deg)" if k + "_deg" in derived else ""
        lines.append(f"{k:<14}{v:>14.6g}  {unit}{extra}")
    return "\n".join(lines)



# ---------------------------------------------------------------------- simulate
def _nonneg_float(name):
    def conv(text):
        try:
            x = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got {text!r}") from None
        if not math.isfinite(x):
            raise argparse.ArgumentTypeError(f"{name} must be finite, got {text!r}")
        return x

    return conv


def _build_excitation(args):
    from ._excitation import FreeVibration, GroundMotion

    if args.record is not None and args.u0 is not None:
        raise CLIError("give either --u0 (free vibration) or --record (ground motion), not both")
    if args.record is None:
        if args.u0 is None:
            raise CLIError("give --u0 M (free vibration) or --record FILE (ground motion)")
        return FreeVibration(args.u0, args.v0), None
    units = {"m/s2": "m/s2", "g": "g", None: None}[args.units]
    gm = GroundMotion.from_file(args.record, units=units, scale=args.scale, dt=args.record_dt)
    return gm, gm


def cmd_simulate(args):
    import numpy as np

    from ._simulate import simulate

    s = _load_structure(args.structure)
    _check_png(args.plot)
    excitation, gm = _build_excitation(args)
    if args.t1 is not None:
        t1 = args.t1
    elif gm is not None:
        t1 = float(gm.duration)
    else:
        t1 = 4.0
    if args.r is not None and not 0.0 <= args.r <= 1.0:
        raise CLIError(f"--r must lie in [0, 1], got {args.r}")
    if gm is None:
        ts = np.linspace(0.0, t1, max(2, int(round(t1 / 0.002)) + 1))
    else:
        ts = None
    res = simulate(s, excitation, t1, ts=ts, model=args.model, r=args.r, impact=args.impact)
    summary = res.summary()
    if args.out:
        cols = {k: np.asarray(getattr(res, k)) for k in ("ts", "u", "v", "theta", "uplift")}
        cols["t"] = cols.pop("ts")
        _write_csv(args.out, cols, ("t", "u", "v", "theta", "uplift"))
    if args.plot:
        from ._plotting import plot_response

        rec = pathlib.Path(args.record).name if gm is not None else ""
        what = f"release u0 = {args.u0} m" if gm is None else f"{rec} x {args.scale}"
        fig = plot_response(s, res, ground_motion=gm, title=f"{args.model} model, {what}")
        fig.savefig(args.plot, dpi=150)
    if args.json:
        print(json.dumps(summary))
        return 0
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
    return 0

# -------------------------------------------------------------------------- demo
def _demo_ground_motion():
    """El Centro 1940 NS if cached, local (ROCKJAX_EL_CENTRO) or downloadable; else synthetic."""
    from . import datasets
    from ._excitation import GroundMotion

    try:
        rec = datasets.el_centro()
        return GroundMotion.from_record(rec), "1940 El Centro NS (IELC180)"
    except (OSError, RuntimeError, ValueError) as e:
        print(f"El Centro unavailable ({str(e).splitlines()[0]}); using a SYNTHETIC motion")
        rec = datasets.synthetic_ground_motion()
        return GroundMotion.from_record(rec), "SYNTHETIC motion (no El Centro)"


def cmd_demo(args):
    import numpy as np

    from ._excitation import FreeVibration
    from ._plotting import plot_pushover, plot_response, pushover_curves
    from ._simulate import simulate
    from ._structure import mcmanus_column

    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    s = mcmanus_column()
    curves = pushover_curves(s)
    fig = plot_pushover(s, curves, title="McManus column (Table 1): pushover, cf. Figs 6 and 8")
    path = out / "pushover.png"
    fig.savefig(path, dpi=150)
    d = s.derived()
    u = curves["u"]
    mask = (u >= 1.2 * d["u_crit"]) & (u <= 0.95 * d["u_overturn"])
    err_exact = np.max(np.abs(curves["exact"] - curves["numerical"])[mask]) / d["P_crit"]
    err_simpl = np.max(np.abs(curves["simplified"] - curves["numerical"])[mask]) / d["P_crit"]
    print("rockjax demo: McManus (1980) column of the paper's Table 1")
    print()
    print(_derived_table(d))
    print()
    print("closed forms against the numerical pushover, over [1.2 u_crit, 0.95 u_overturn]:")
    print(f"  exact (Eq 18)      max |error| = {100 * err_exact:.2e} % of P_crit")
    print(f"  simplified (Eq 20) max |error| = {100 * err_simpl:.3f} % of P_crit")
    written = [path]

    # Fig 9: free vibration from u0 = 0.10 m with the theoretical r (Eq 3)
    ts = np.linspace(0.0, 4.0, 2001)
    free = simulate(s, FreeVibration(0.10), 4.0, ts=ts)
    free_exact = simulate(s, FreeVibration(0.10), 4.0, ts=ts, model="exact")
    fig = plot_response(
        s, free, label="simplified", overlay=[("exact", free_exact)],
        title=f"Free vibration from u0 = 0.10 m, r = {d['restitution']:.3f} (Eq 3), cf. Fig 9",
    )
    written.append(out / "free_vibration.png")
    fig.savefig(written[-1], dpi=150)

    # Fig 10: earthquake response
    gm, name = _demo_ground_motion()
    quake = simulate(s, gm, float(gm.duration))
    fig = plot_response(s, quake, ground_motion=gm, title=f"{name}, scale 1.0, cf. Fig 10")
    written.append(out / "earthquake.png")
    fig.savefig(written[-1], dpi=150)

    print()
    print(f"{'run':<34}{'peak |u| [mm]':>14}{'peak uplift [mm]':>18}{'impacts':>9}  status")
    for label, res in (
        ("free vibration, simplified", free),
        ("free vibration, exact", free_exact),
        (name[:33], quake),
    ):
        sm = res.summary()
        print(f"{label:<34}{1e3 * sm['peak_u']:>14.2f}{1e3 * sm['peak_uplift']:>18.2f}"
              f"{sm['n_impacts']:>9d}  {sm['status']}")
    print()
    for p in written:
        print(f"wrote {p}")
    return 0


# --------------------------------------------------------------------------- main
def build_parser():
    p = _Parser(
        prog="rockjax",
        description="Differentiable simulator of rigid structures rocking on a two-spring "
        "foundation (SI units throughout).",
    )
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    d = sub.add_parser("demo", help="run the demonstration and write plots into ./rockjax-demo/")
    d.add_argument("--out", default="rockjax-demo", help="output folder (default ./rockjax-demo)")
    d.set_defaults(func=cmd_demo)

    q = sub.add_parser(
        "pushover",
        help="derived quantities and pushover curves (closed forms and numerical)",
        description="Print the derived quantities of a structure and its pushover curves: "
        "the simplified (Eqs 13, 20) and exact (Eqs 13, 18) closed forms and the numerical "
        "pushover of the rigid body on two springs.",
    )
    q.add_argument("--structure", metavar="FILE.toml", help="structure file (default: Table 1)")
    q.add_argument(
        "--umax",
        type=_positive_float("--umax"),
        metavar="M",
        help="largest displacement [m] (default 0.99 u_overturn)",
    )
    q.add_argument("--points", type=_points, default=201, help="number of points (default 201)")
    q.add_argument("--plot", metavar="FILE.png", help="write a Fig 8-style plot")
    q.add_argument("--out", metavar="FILE.csv", help="write the curves as CSV")
    q.add_argument("--json", action="store_true", help="print one JSON object and nothing else")
    q.set_defaults(func=cmd_pushover)

    m = sub.add_parser(
        "simulate",
        help="time history of a free-vibration release or a ground-motion record (Eq 1)",
        description="Integrate Eq 1 with impacts at u = 0 (velocity scaled by sqrt(r)). "
        "Free vibration: --u0 [--v0]. Ground motion: --record FILE (PEER AT2, two columns "
        "t a, or one column with --record-dt) [--units g|m/s2] [--scale S].",
    )
    m.add_argument("--structure", metavar="FILE.toml", help="structure file (default: Table 1)")
    m.add_argument("--u0", type=_nonneg_float("--u0"), metavar="M", help="release displacement [m]")
    m.add_argument("--v0", type=_nonneg_float("--v0"), default=0.0, metavar="V",
                   help="release velocity [m/s] (default 0)")
    m.add_argument("--record", metavar="FILE", help="ground-motion record file")
    m.add_argument("--units", choices=["g", "m/s2"], help="units of the record's values")
    m.add_argument("--scale", type=_nonneg_float("--scale"), default=1.0,
                   help="scale factor on the record (default 1)")
    m.add_argument("--record-dt", type=_positive_float("--record-dt"), metavar="DT",
                   help="sample step [s] of a one-column record")
    m.add_argument("--t1", type=_positive_float("--t1"), metavar="T",
                   help="end time [s] (default: 4 s, or the record's length)")
    m.add_argument("--model", choices=["simplified", "exact", "smooth", "housner"],
                   default="simplified", help="restoring-force model (default simplified)")
    m.add_argument("--r", type=_nonneg_float("--r"), metavar="R",
                   help="coefficient of restitution in [0, 1] (default: Eq 3)")
    m.add_argument("--impact", choices=["paper", "after_uplift"], default="paper",
                   help="impact rule (default paper: every crossing of u = 0)")
    m.add_argument("--out", metavar="FILE.csv", help="write t, u, v, theta, uplift as CSV")
    m.add_argument("--plot", metavar="FILE.png", help="write a Fig 9/10-style plot")
    m.add_argument("--json", action="store_true", help="print a JSON summary and nothing else")
    m.set_defaults(func=cmd_simulate)
    return p


def main(argv=None):
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return EXIT_USAGE
    try:
        return args.func(args)
    except (CLIError, ValueError, FileNotFoundError, IsADirectoryError, PermissionError) as e:
        msg = str(e).splitlines()[0] if str(e) else type(e).__name__
        print(f"rockjax {args.command}: error: {msg}", file=sys.stderr)
        return EXIT_USAGE
    except OSError as e:
        print(f"rockjax {args.command}: error: {e}", file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
