"""`rockjax fit-outcomes`: fit a rocking specimen to a table of pass/fail runs (toppled or
stood under commanded pulses): a block's slenderness and size, or a known structure's k_f
and r, and the dispersion beta of a probit link on rockjax's own overturning threshold.

`identification` is imported inside `run`, so that `rockjax --help` does not pay for it.
"""

from __future__ import annotations

import json
import pathlib
import warnings

from ._common import (
    add_outputs,
    add_plausibility_argument,
    check_outputs,
    CLIError,
    COMMON_FLAGS,
    converter,
    load_structure,
)

COMMAND = "fit-outcomes"  # the sub-command's name (the module's is `outcomes`)
#: the library parameters that the options of `rockjax fit-outcomes` set
FLAGS = {"model": COMMON_FLAGS["model"], "check_plausible": COMMON_FLAGS["check_plausible"],
         "structure": "--structure",
         "drop_unknown_labels": "--drop-unknown-labels", "kind": "--pulse",
         "amplitude_unit": "--amplitude-unit", "free": "--params"}
_PARAMS = ("alpha", "R", "beta", "k_f", "r")
_MODELS = ("rigid_body", "simplified")


def add_parser(subparsers):
    f = subparsers.add_parser(
        "fit-outcomes",
        help="fit a specimen to pass/fail runs (toppled or stood under pulses)",
        description="Fit a rocking specimen to a table of pass/fail runs: a CSV file with a "
        "header naming the pulse (period [s] or PGV/PGA [s]), the commanded amplitude (PGA "
        "with its unit: PGA_g, PGA_m/s2, or --amplitude-unit) and the outcome (Y/N, yes/no, "
        "true/false, 1/0, toppled/stood). The ShakeBot layout 'Date & Time, PGV/PGA, PGA, "
        "Rock Status' reads as one-cosine pulses, T = 2 pi PGV/PGA, PGA in g. The model: "
        "P(topple) = Phi(ln(A / A_c(T)) / beta), A_c the lowest amplitude of the pulse "
        "that overturns the specimen on rockjax's model (rigid_body by default), for a "
        "uniform block of unknown slenderness alpha and half-diagonal R, or for the "
        "structure of --structure (k_f, r). A_c is computed on a grid of overturning "
        "spectra (one to two minutes on 2 cores, once per run of the command) and "
        "interpolated smoothly. Prints the estimates with 90 % intervals and the "
        "negative log-likelihood beside a three-parameter probit in (ln PGA, ln PGV/PGA) "
        "and a constant.",
    )
    f.add_argument("table", metavar="TABLE.csv", help="the runs: pulse, amplitude, outcome")
    f.add_argument("--structure", metavar="FILE.toml",
                   help="a structure of known geometry: fit its k_f, r and beta (default: a "
                   "uniform block of unknown shape: alpha, R and beta)")
    add_plausibility_argument(f)
    f.add_argument("--params", nargs="+", choices=list(_PARAMS), metavar="P",
                   help="the parameters to fit (default alpha R beta for a block, k_f r "
                   "beta for a structure); a structure's others keep its values")
    f.add_argument("--model", choices=list(_MODELS), default="rigid_body",
                   help="rockjax model of the thresholds (default rigid_body)")
    f.add_argument("--pulse", choices=["one_cosine", "one_sine", "rectangular"],
                   help="the pulse of every run when the table does not say (the ShakeBot "
                   "layout: one_cosine)")
    f.add_argument("--amplitude-unit", choices=["g", "m/s2"],
                   help="the unit of an amplitude column whose name gives none")
    f.add_argument("--drop-unknown-labels", action="store_true",
                   help="drop rows whose outcome is neither toppled nor stood (blanks, "
                   "notes), reporting each; default: refuse them, naming the line")
    f.add_argument("--cv", type=converter("--cv", int, lambda n: n >= 2, "be at least 2"),
                   metavar="K", help="also K-fold cross-validation: the held-out log loss "
                   "of the physics model, the probit and the constant")
    f.add_argument("--grid", metavar="FILE.npz",
                   help="the threshold grid: read from FILE if it exists (it must be of "
                   "the same pulse, model and specimen kind), else built and written there, "
                   "so that a later run skips the build")
    add_outputs(f, "draw the runs with the fitted boundary and its band (PGA against "
                "PGV/PGA)")
    f.set_defaults(func=run)
    return f


def _grid(args, identification, table, structure, free):
    """The grid of --grid when its file exists (checked against the run), else None."""
    if not args.grid or not pathlib.Path(args.grid).exists():
        return None
    g = identification.ThresholdGrid.load(args.grid)
    block = "alpha" in g.axes
    if g.kind != table.kind or g.model != args.model or block != (structure is None):
        raise CLIError(f"--grid {args.grid}: a grid of {g.kind} pulses, model {g.model}, "
                       f"for {'a block' if block else 'a structure'}; this run needs "
                       f"{table.kind}, {args.model}, "
                       f"{'a block' if structure is None else 'a structure'}")
    if structure is not None and g.settings.get("structure") != structure.to_dict():
        raise CLIError(f"--grid {args.grid}: built for another structure")
    return g


def run(args):
    """Read the table, fit, print the report (or one JSON object), draw the figure."""
    import identification

    check_outputs(args, r=False)
    structure = (load_structure(args.structure, args.check_plausible)
                 if args.structure else None)
    free = tuple(args.params) if args.params else None
    if free is not None:
        allowed = ("alpha", "R", "beta") if structure is None else ("k_f", "r", "beta")
        bad = [p for p in free if p not in allowed]
        if bad:
            raise CLIError(f"--params {' '.join(bad)}: "
                           f"{'a block (no --structure)' if structure is None else '--structure'}"
                           f" has the parameters {' '.join(allowed)}")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        table = identification.read_outcomes(args.table, kind=args.pulse,
                                             amplitude_unit=args.amplitude_unit,
                                             drop_unknown_labels=args.drop_unknown_labels)
        grid = _grid(args, identification, table, structure, free)
        fit = identification.fit_outcomes(table, structure, free=free, model=args.model,
                                          grid=grid)
        if args.grid and not pathlib.Path(args.grid).exists():
            fit.grid.save(args.grid)
    notes = [str(w.message) for w in caught
             if not isinstance(w.message, identification.IdentifiabilityWarning)]
    cv = fit.cross_validate(args.cv) if args.cv else None
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        ax = fit.plot()
        ax.figure.savefig(args.plot, dpi=150, bbox_inches="tight")
    if args.json:
        out = {"file": args.table, **fit.summary(cv)}
        out["warnings"] = notes + out["warnings"]
        print(json.dumps(out))
        return 0
    print(fit.report(cv))
    for n in notes:
        print(f"note: {n}")
    if args.plot:
        print(f"plot written to {args.plot}")
    return 0
