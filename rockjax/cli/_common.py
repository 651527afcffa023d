"""Shared pieces of the `rockjax` command line: the one-line-error parser, `CLIError`, the
argument converters, the shared arguments, output checks, CSV writing and the library's
errors in the command's terms."""

from __future__ import annotations

import argparse
import math
import pathlib

import numpy as np

import rockjax
from rockjax._cache import compile_cache_dir, COMPILE_CACHE_ENV  # noqa: F401 (re-exported)
from rockjax._checks import check_r
from rockjax._fidelity import sdof_lift_off_message
from rockjax._report import model_info as _model_info, model_line  # noqa: F401 (re-exported)
from rockjax._suite import split_record_units  # noqa: F401 (re-exported)

EXIT_USAGE = 2
#: the longest run the CLI accepts, in output samples or record steps
MAX_STEPS = 10_000_000
#: the most scale factors a START:STOP:N range may give
_MAX_SCALES = 1_000_000
#: where the --model help sends the user
MODEL_GUIDE = ("which model for which scene: docs/models.md (the paper's SDOF models "
               "over-predict a body rocking under ground motion; rigid_body does not)")
#: the library parameters that most commands set, and the option that sets each; a command
#: adds its own (`FLAGS` in its module)
COMMON_FLAGS = {"r": "--r", "impact": "--impact", "model": "--model", "t1": "--t1",
                "method": "--method", "substeps": "--substeps",
                "check_plausible": "--no-plausibility-check"}
#: the options of a ground-motion record (read_record's and GroundMotion's parameters)
RECORD_FLAGS = {"units": "--units", "dt": "--record-dt", "scale": "--scale",
                "time_tolerance": "--time-tolerance"}
#: the units of acceleration a record may be in (`rockjax.UNITS`), for --units' help
RECORD_UNITS_METAVAR = "{" + ",".join(rockjax.UNITS["acceleration"]) + "}"
#: the fidelity warning's advice in CLI syntax
_FIDELITY_ADVICE = ("use --model rigid_body (the body's own one-DOF equation, about as fast) "
                    "or two_spring_2dof. See docs/models.md; silence with "
                    "--no-fidelity-warning")


class CLIError(Exception):
    """A user-facing error: printed as one line, exit code 2."""


class Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, no usage dump
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


def first_line(e):
    """The first line of an exception's message, or its type's name when it has none."""
    return str(e).splitlines()[0] if str(e) else type(e).__name__


# ------------------------------------------------------------------ argument converters
def converter(option, kind=float, test=None, must=None, noun=None):
    """The one factory of argparse types: the text as `kind` (float, int, or a parser that
    raises ValueError), which must pass `test` (else "OPTION must MUST, got X": the integer
    read, or the text); text that `kind` refuses: "OPTION must be NOUN, got TEXT" (default
    "an integer" or "a number"; a parser's own message when it has no `noun`)."""
    if noun is None and kind in (int, float):
        noun = "an integer" if kind is int else "a number"

    def conv(text):
        try:
            x = kind(text)
        except ValueError as e:
            raise argparse.ArgumentTypeError(
                str(e) if noun is None else f"{option} must be {noun}, got {text!r}") from None
        if test is not None and not test(x):
            got = x if kind is int else repr(text)
            raise argparse.ArgumentTypeError(f"{option} must {must}, got {got}")
        return x

    return conv


def positive_float(option):
    return converter(option, float, lambda x: math.isfinite(x) and x > 0, "be a positive number")


def finite_float(option):
    return converter(option, float, math.isfinite, "be finite")


def positive_int(option):
    return converter(option, int, lambda n: n >= 1, "be a positive integer")


def _range(text, parts):
    """START, STOP and N of a "START:STOP:N" range (N checked, START and STOP not yet)."""
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"a range is START:STOP:N, got {text!r}")
    try:
        a, b = float(parts[0]), float(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"START and STOP of START:STOP:N must be numbers, got {text!r}") from None
    try:
        n = int(parts[2])
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"N of START:STOP:N must be an integer, got {text!r}") from None
    if not 1 <= n <= _MAX_SCALES:
        bound = "at least 1" if n < 1 else f"at most {_MAX_SCALES}"
        raise argparse.ArgumentTypeError(f"N of START:STOP:N must be {bound}, got {n}")
    return a, b, n


def number_list(subject):
    """A comma list "0.5,1,1.5" or a range "START:STOP:N" (N values, ends included, to 12
    significant digits: 0.8, not linspace's 0.7999999999999999) of positive finite
    numbers; `subject` names them in the error."""

    def conv(text):
        t = text.strip()
        if ":" in t:
            a, b, n = _range(text, t.split(":"))
            ends = [a, b]
        else:
            try:
                ends = [float(item) for item in t.split(",")]
            except ValueError:
                raise argparse.ArgumentTypeError(
                    f"expected a comma list of numbers such as 0.5,1,1.5 or a range "
                    f"START:STOP:N, got {text!r}") from None
        if not all(math.isfinite(x) and x > 0 for x in ends):
            raise argparse.ArgumentTypeError(f"{subject} must be positive and finite, got {text!r}")
        return [float(f"{x:.12g}") for x in np.linspace(a, b, n)] if ":" in t else ends

    return conv


#: --scales: a comma list "0.5,1,1.5" or a range "START:STOP:N"
scale_list = number_list("scale factors")


def record_units(text):
    """--units: a unit of acceleration in any spelling of `rockjax.UNITS` (``g``, ``m/s2``,
    ``cm/s^2``, ``Gal``, ...) -> its canonical name; an unknown unit is an argparse error
    that names it and lists the known ones."""
    try:
        return rockjax.UNITS.normalize(text, "acceleration")
    except rockjax.UnitError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


# ----------------------------------------------------------------- shared arguments
def add_model_arguments(parser, model_help, fidelity=True):
    """--model (every model of the ladder, from `rockjax.MODELS`), --r and --impact, and
    (`fidelity`) --no-fidelity-warning."""
    parser.add_argument("--model", choices=list(rockjax.MODELS), default="simplified",
                        help=f"{model_help}; {MODEL_GUIDE}")
    if fidelity:
        parser.add_argument(
            "--no-fidelity-warning", dest="fidelity_warning", action="store_false",
            help="do not warn when the paper's SDOF model lifts the structure off by more "
            "than 3 u_crit under ground motion")
    parser.add_argument("--r", type=finite_float("--r"), metavar="R",
                        help="coefficient of restitution in [0, 1] (default: Eq 3)")
    parser.add_argument("--impact", choices=list(rockjax.IMPACT_RULES), default="paper",
                        help="impact rule (default paper: every crossing of u = 0)")


def add_outputs(parser, plot, out=None, json="print one JSON object and nothing else",
                out_default=None):
    """--plot FILE.png, --out FILE.csv (when `out` is its help) and --json, with these helps."""
    if out is not None:
        parser.add_argument("--out", default=out_default, metavar="FILE.csv", help=out)
    parser.add_argument("--plot", metavar="FILE.png", help=plot)
    parser.add_argument("--json", action="store_true", help=json)


def add_structure_argument(parser):
    """--structure FILE.toml (one; default Table 1) and --no-plausibility-check."""
    parser.add_argument("--structure", metavar="FILE.toml",
                        help="structure file (default: Table 1)")
    add_plausibility_argument(parser)


# ------------------------------------------------------------------------ input checks
def load_structure(path, check_plausible=True):
    """The structure of a TOML file, or the Table 1 McManus column when `path` is None."""
    if path is None:
        return rockjax.mcmanus_column()
    return rockjax.RockingStructure.from_toml(path, check_plausible=check_plausible)


#: the option that turns off the readers' plausibility checks (check_plausible=False)
PLAUSIBILITY_FLAG = "--no-plausibility-check"


def add_time_tolerance_argument(parser):
    """--time-tolerance: how far a record's time column may jitter (`read_record`)."""
    parser.add_argument(
        "--time-tolerance", type=positive_float("--time-tolerance"), default=1e-3,
        metavar="FRACTION", help="a two-column record whose time steps differ from their "
        "median by at most this fraction of the step is resampled onto a uniform step, with "
        "a warning; beyond it, refused (default 0.001)")


def add_plausibility_argument(parser):
    """--no-plausibility-check: read inputs that look like wrong units as they are (a PGA
    over 5 g, a decay trace sampled in seconds, a structure a kilometre tall)."""
    parser.add_argument(
        PLAUSIBILITY_FLAG, dest="check_plausible", action="store_false",
        help="read inputs that look like wrong units as they are (a PGA over 5 g, a decay "
        "trace with a time step of seconds, a structure wider than 100 m or taller than "
        "500 m); default: refuse them with a hint on the units")


def check_outputs(args, r=True):
    """--plot's suffix, the folders of --out and --plot, and (`r`) --r in [0, 1]
    (`rockjax._checks.check_r`: its `ParameterError` names r, which `main` reports as --r)."""
    plot, out = getattr(args, "plot", None), getattr(args, "out", None)
    if plot is not None and pathlib.Path(plot).suffix.lower() not in (".png", ".pdf", ".svg"):
        raise CLIError(f"--plot must end in .png, .pdf or .svg, got {plot}")
    if r:
        check_r(args.r)
    for option, path in (("--out", out), ("--plot", plot)):
        if path is None:
            continue
        p = pathlib.Path(path)
        if p.is_dir():
            raise CLIError(f"{option} is a directory: {path}")
        if not p.parent.is_dir():
            raise CLIError(f"{option}: directory not found: {p.parent}")


def write_columns(path, columns, units):
    """Columns as CSV; `units` maps each column name to its unit, written into the header
    as a suffix (``u_m``, ``theta_rad``)."""
    data = np.column_stack([np.asarray(columns[k]) for k in units])
    header = ",".join(f"{k}_{u}" for k, u in units.items())
    np.savetxt(path, data, delimiter=",", header=header, comments="", fmt="%.10g")


def save(fig, path, **kw):
    """Write a matplotlib Figure (150 dpi), every title wrapped inside it
    (`rockjax._plotting.fit_titles`), and return `path`."""
    from rockjax._plotting import fit_titles

    fit_titles(fig).savefig(path, dpi=150, **kw)
    return path


# ------------------------------------------------------------------ what produced a number
def fidelity_note(args, structure, forced, peak_u):
    """The fidelity warning of `rockjax.simulate` in CLI syntax, or None (also when
    --no-fidelity-warning was given)."""
    if not getattr(args, "fidelity_warning", True):
        return None
    model = rockjax.get_model(args.model, args.impact)
    return sdof_lift_off_message(model, structure, forced, peak_u, model_name=args.model,
                                 advice=_FIDELITY_ADVICE)


def model_info(args):
    """`rockjax._report.model_info` of --model, --impact and --r."""
    return _model_info(args.model, args.impact, args.r)


# ------------------------------------------------------- library errors in CLI syntax
def _argument(flag, value):
    """A parameter with its value in the command line's syntax: the flag alone (True or no
    value), CHANNEL=VALUE pairs (a mapping), else the flag and the value."""
    if isinstance(value, dict):
        return f"{flag} " + ",".join(f"{k}={v}" for k, v in value.items())
    # a boolean's option is a flag (--no-plausibility-check for False)
    return flag if value is None or isinstance(value, bool) else f"{flag} {value}"


def parameter_message(e, flags):
    """A library error that names its parameter (`e.param`) in the command's terms, `flags`
    mapping the library's parameter names to the command's options: a
    `rockjax.ParameterError` as "--flag: message; pass --flag value" ("--flag VALUE:
    message" when it names the value at fault; the message alone, no advice in Python
    syntax, when no option sets that parameter); an error with its own
    `advice_for` (`identification.TraceError`) as its message with the advice in CLI
    syntax."""
    flag = flags.get(e.param)
    if not isinstance(e, rockjax.ParameterError):
        return (first_line(e) if flag is None
                else e.message + e.advice_for(_argument(flag, e.value)))
    message = e.message.splitlines()[0] if e.message else type(e).__name__
    if flag is None:
        return message if e.value is None else str(e).splitlines()[0]
    where = flag if e.value is None else f"{flag} {e.value}"
    return f"{where}: {message}{e.advice_for(flag)}"


def error_text(e, flags):
    """One line for an exception: `parameter_message` for an error that names its
    parameter, else its first line."""
    if isinstance(e, rockjax.ParameterError) or hasattr(e, "advice_for"):
        return parameter_message(e, flags)
    return first_line(e)
