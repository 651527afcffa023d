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


# -------------------------------------------------------------------------- demo
def cmd_demo(args):
    from ._plotting import plot_pushover, pushover_curves
    from ._structure import mcmanus_column

    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    s = mcmanus_column()
    curves = pushover_curves(s)
    fig = plot_pushover(
        s, curves, title="McManus column (Table 1): pushover, cf. paper Figs 6 and 8"
    )
    path = out / "pushover.png"
    fig.savefig(path, dpi=150)
    d = s.derived()
    import numpy as np

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
    print()
    print(f"wrote {path}")
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
