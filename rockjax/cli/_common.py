"""Shared pieces of the `rockjax` command line: the one-line-error parser, `CLIError`,
argument converters, structure loading, output checks and CSV writing."""

from __future__ import annotations

import argparse
import math
import pathlib

import numpy as np

import rockjax
from rockjax._checks import check_r
from rockjax._fidelity import sdof_lift_off_message

EXIT_USAGE = 2

#: the longest run the CLI accepts, in output samples or record steps
_MAX_STEPS = 10_000_000
#: the most scale factors a START:STOP:N range may give
_MAX_SCALES = 1_000_000


class CLIError(Exception):
    """A user-facing error: printed as one line, exit code 2."""


#: where the --model help sends the user
MODEL_GUIDE = ("which model for which scene: docs/models.md (the paper's SDOF models "
               "over-predict a body rocking under ground motion; rigid_body does not)")


def add_model_arguments(parser, model_help, fidelity=True):
    """--model (every model of the ladder, from `rockjax.MODELS`), --r and --impact, and
    (`fidelity`) --no-fidelity-warning."""
    parser.add_argument(
        "--model", choices=list(rockjax.MODELS), default="simplified",
        help=f"{model_help}; {MODEL_GUIDE}",
    )
    if fidelity:
        parser.add_argument(
            "--no-fidelity-warning", dest="fidelity_warning", action="store_false",
            help="do not warn when the paper's SDOF model lifts the structure off by more "
            "than 3 u_crit under ground motion",
        )
    parser.add_argument(
        "--r",
        type=_finite_float("--r"),
        metavar="R",
        help="coefficient of restitution in [0, 1] (default: Eq 3)",
    )
    parser.add_argument(
        "--impact",
        choices=list(rockjax.IMPACT_RULES),
        default="paper",
        help="impact rule (default paper: every crossing of u = 0)",
    )


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, no usage dump
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


def _first_line(e):
    """The first line of an exception's message, or its type's name when it has none."""
    return str(e).splitlines()[0] if str(e) else type(e).__name__


# ------------------------------------------------------------------ argument converters
def converter(option, kind=float, test=None, must=None):
    """The one factory of argparse types: the text as `kind` (float or int), which must pass
    `test` (else "OPTION must MUST, got X": the integer read, or the text of a number)."""
    noun = "an integer" if kind is int else "a number"

    def conv(text):
        try:
            x = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{option} must be {noun}, got {text!r}") from None
        if test is not None and not test(x):
            got = x if kind is int else repr(text)
            raise argparse.ArgumentTypeError(f"{option} must {must}, got {got}")
        return x

    return conv


def _positive_float(option):
    return converter(option, float, lambda x: math.isfinite(x) and x > 0, "be a positive number")


def _finite_float(option):
    return converter(option, float, math.isfinite, "be finite")


def _positive_int(option):
    return converter(option, int, lambda n: n >= 1, "be a positive integer")


_points = converter("--points", int, lambda n: n >= 2, "be at least 2")
_starts = converter("--starts", int, lambda n: n >= 1, "be at least 1")


def _scale_range(text, parts):
    """START, STOP and N of a "START:STOP:N" range (N checked, START and STOP not yet)."""
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(f"a range is START:STOP:N, got {text!r}")
    try:
        a, b = float(parts[0]), float(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"START and STOP of START:STOP:N must be numbers, got {text!r}"
        ) from None
    try:
        n = int(parts[2])
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"N of START:STOP:N must be an integer, got {text!r}"
        ) from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"N of START:STOP:N must be at least 1, got {n}")
    if n > _MAX_SCALES:
        raise argparse.ArgumentTypeError(
            f"N of START:STOP:N must be at most {_MAX_SCALES}, got {n}"
        )
    return a, b, n


def _scale_list(text, t):
    """The numbers of a comma list "0.5,1,1.5" (not yet checked for sign or finiteness)."""
    values = []
    for item in t.split(","):
        try:
            values.append(float(item))
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected a comma list of numbers such as 0.5,1,1.5 or a range "
                f"START:STOP:N, got {text!r}"
            ) from None
    return values


def _scales(text):
    """--scales: a comma list "0.5,1,1.5" or a range "START:STOP:N" (N points, inclusive)."""
    t = text.strip()
    if ":" in t:
        a, b, n = _scale_range(text, t.split(":"))
        values = [a, b]
    else:
        values = _scale_list(text, t)
    for x in values:
        if not math.isfinite(x) or x <= 0:
            raise argparse.ArgumentTypeError(
                f"scale factors must be positive and finite, got {text!r}"
            )
    if ":" in t:
        # 12 significant digits: 0.8, not linspace's 0.7999999999999999
        return [float(f"{x:.12g}") for x in np.linspace(values[0], values[1], n)]
    return values


# ------------------------------------------------------------------------ input checks
def _load_structure(path, check_plausible=True):
    """The structure of a TOML file, or the Table 1 McManus column when `path` is None."""
    if path is None:
        return rockjax.mcmanus_column()
    return rockjax.RockingStructure.from_toml(path, check_plausible=check_plausible)


#: the option that turns off the readers' plausibility checks (check_plausible=False)
PLAUSIBILITY_FLAG = "--no-plausibility-check"


def add_plausibility_argument(parser):
    """--no-plausibility-check: read inputs that look like wrong units as they are (a PGA
    over 5 g, a decay trace sampled in seconds, a structure a kilometre tall)."""
    parser.add_argument(
        PLAUSIBILITY_FLAG, dest="check_plausible", action="store_false",
        help="read inputs that look like wrong units as they are (a PGA over 5 g, a decay "
        "trace with a time step of seconds, a structure wider than 100 m or taller than "
        "500 m); default: refuse them with a hint on the units",
    )


def _check_r(r):
    """--r in [0, 1] (`rockjax._checks.check_r`, the library's own check; its
    `ParameterError` names the parameter, which `main` reports as --r)."""
    check_r(r)


def _check_t1_steps(t1, dt, what):
    """A one-line error naming --t1, rather than numpy's size error, for absurd run lengths."""
    n = t1 / dt
    if not n <= _MAX_STEPS:
        raise CLIError(
            f"--t1 {t1:g} s is {n:.3g} {what} of {dt:g} s, more than {_MAX_STEPS:,}; shorten --t1"
        )


# ----------------------------------------------------------------------------- outputs
def _check_png(path):
    if path is not None and pathlib.Path(path).suffix.lower() not in (".png", ".pdf", ".svg"):
        raise CLIError(f"--plot must end in .png, .pdf or .svg, got {path}")


def _check_out_dir(option, path):
    if path is None:
        return
    p = pathlib.Path(path)
    if p.is_dir():
        raise CLIError(f"{option} is a directory: {path}")
    if not p.parent.is_dir():
        raise CLIError(f"{option}: directory not found: {p.parent}")


def _write_csv(path, columns, units):
    """Columns as CSV; `units` maps each column name to its unit, written into the header
    as a suffix (``u_m``, ``theta_rad``)."""
    data = np.column_stack([np.asarray(columns[k]) for k in units])
    header = ",".join(f"{k}_{u}" for k, u in units.items())
    np.savetxt(path, data, delimiter=",", header=header, comments="", fmt="%.10g")


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


# ------------------------------------------------------------------ what produced a number
def fidelity_note(args, structure, forced, peak_u):
    """The fidelity warning of `rockjax.simulate` in CLI syntax, or None (also when
    --no-fidelity-warning was given)."""
    if not getattr(args, "fidelity_warning", True):
        return None
    model = rockjax.get_model(args.model, args.impact)
    return sdof_lift_off_message(model, structure, forced, peak_u, model_name=args.model,
                                 advice=_FIDELITY_ADVICE)


#: the fidelity warning's advice in CLI syntax
_FIDELITY_ADVICE = ("use --model rigid_body (the body's own one-DOF equation, about as fast) "
                    "or two_spring_2dof. See docs/models.md; silence with "
                    "--no-fidelity-warning")


#: the models whose impacts are their landings, not the SDOF impact rule
BODY_MODELS = ("rigid_body", "two_spring_2dof")


def model_info(args):
    """The model, impact rule and restitution behind a CLI result (for text and JSON); the
    body models impact at their landings (`--impact` does not apply to them)."""
    impact = "landings" if args.model in BODY_MODELS else args.impact
    return {"model": args.model, "impact": impact, "r": "Eq 3" if args.r is None else args.r}


def model_line(info):
    """`model_info` as one line of text."""
    r = info["r"] if isinstance(info["r"], str) else f"{info['r']:g}"
    if info["impact"] == "landings":
        return f"{info['model']} model, impacts at landings (Eqs 2-3), r {r}"
    return f"{info['model']} model, impact rule {info['impact']}, r {r}"


def record_info(record, scale=1.0):
    """What was read from a record: file, units (and where they came from), dt, points,
    duration, PGA and the scale applied, as plain Python (SI units, PGA also in g)."""
    pga = float(record.pga)
    return {
        "file": str(record.source),
        "units_in_file": record.units_in_file,
        "units_from": getattr(record, "units_source", None),
        "dt_s": float(record.dt),
        "n_points": int(record.npts),
        "duration_s": float(record.dt * (record.npts - 1)),
        "pga_m_s2": pga,
        "pga_g": pga / rockjax.G_STANDARD,
        "scale": float(scale),
        "scaled_pga_g": float(scale) * pga / rockjax.G_STANDARD,
    }


def record_line(info):
    """`record_info` as one line of text."""
    src = f" ({info['units_from']})" if info.get("units_from") else ""
    return (
        f"{pathlib.Path(info['file']).name}: units {info['units_in_file']}{src}, "
        f"dt {info['dt_s']:g} s, {info['n_points']} points, {info['duration_s']:g} s, "
        f"PGA {info['pga_g']:.4g} g x scale {info['scale']:g} = {info['scaled_pga_g']:.4g} g"
    )


# ------------------------------------------------------- API errors in CLI syntax
#: the library parameters that most commands set, and the option that sets each; a command
#: adds its own (`FLAGS` in its module)
COMMON_FLAGS = {"r": "--r", "impact": "--impact", "model": "--model", "t1": "--t1",
                "method": "--method", "substeps": "--substeps",
                "check_plausible": PLAUSIBILITY_FLAG}
#: the options of a ground-motion record (read_record's and GroundMotion's parameters)
RECORD_FLAGS = {"units": "--units", "dt": "--record-dt", "scale": "--scale"}


def parameter_message(e, flags):
    """A `rockjax.ParameterError` in the command's terms: "--flag: message; pass --flag
    value", `flags` mapping the library's parameter names to the command's options; the
    message alone (no advice in Python syntax) when no option sets that parameter."""
    message = e.message.splitlines()[0] if e.message else type(e).__name__
    flag = flags.get(e.param)
    if flag is None:
        return message
    return f"{flag}: {message}{e.advice_for(flag)}"


def error_text(e, flags):
    """One line for an exception: `parameter_message` for a `ParameterError`, else its
    first line."""
    if isinstance(e, rockjax.ParameterError):
        return parameter_message(e, flags)
    return _first_line(e)


#: the units of acceleration a record may be in (`rockjax.UNITS`), for --units' help
RECORD_UNITS = tuple(rockjax.UNITS["acceleration"])
RECORD_UNITS_METAVAR = "{" + ",".join(RECORD_UNITS) + "}"


def record_units(text):
    """--units: a unit of acceleration in any spelling of `rockjax.UNITS` (``g``, ``m/s2``,
    ``cm/s^2``, ``Gal``, ...) -> its canonical name; an unknown unit is an argparse error
    that names it and lists the known ones."""
    try:
        return rockjax.UNITS.normalize(text, "acceleration")
    except rockjax.UnitError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def split_record_units(text):
    """(path, units or None) of a `--record` value: a trailing `:UNIT` naming a unit of
    acceleration of `rockjax.UNITS` (`:g`, `:m/s2`, `:cm/s2`, `:gal`, also `:m/s^2`,
    `:mps2`, ...) names the record's units (canonical name); any other colon belongs to the
    path, and so does the suffix when the whole text names an existing file."""
    head, sep, tail = str(text).rpartition(":")
    units = None
    if sep and rockjax.UNITS.kind_of(tail) == "acceleration":
        units = rockjax.UNITS.normalize(tail, "acceleration")
    if units is None or not head or pathlib.Path(text).exists():
        return str(text), None
    return head, units


def _derived_table(derived):
    """The derived quantities of a structure as a text table (angles also in degrees)."""
    lines = [f"{'quantity':<14}{'value':>14}  unit"]
    for k, unit in _UNITS.items():
        v = derived[k]
        extra = f"  ({derived[k + '_deg']:.4f} deg)" if k + "_deg" in derived else ""
        lines.append(f"{k:<14}{v:>14.6g}  {unit}{extra}")
    return "\n".join(lines)


# ------------------------------------------------------------ persistent compile cache
#: environment variable: a directory for the compile cache, or off / 0 / no / false
COMPILE_CACHE_ENV = "ROCKJAX_COMPILE_CACHE"
_OFF = ("off", "0", "no", "false", "none")


def compile_cache_dir(disabled: bool = False) -> pathlib.Path | None:
    """The directory of JAX's persistent compilation cache for the command line, or None
    when it is turned off (`disabled`, i.e. `--no-compile-cache`, or
    `ROCKJAX_COMPILE_CACHE=off`, or `ROCKJAX_NO_COMPILE_CACHE=1`).

    `$ROCKJAX_COMPILE_CACHE` when it names a directory, else `rockjax.datasets.cache_dir()
    / "jax"` (`$ROCKJAX_CACHE/jax`, `$XDG_CACHE_HOME/rockjax/jax` or
    `~/.cache/rockjax/jax`)."""
    import os

    env = os.environ.get(COMPILE_CACHE_ENV, "").strip()
    no = os.environ.get("ROCKJAX_NO_COMPILE_CACHE", "").strip().lower()
    if disabled or env.lower() in _OFF or no not in ("",) + _OFF[1:]:
        return None
    if env:
        return pathlib.Path(env).expanduser()
    from rockjax import datasets

    return datasets.cache_dir() / "jax"


def enable_compile_cache(disabled: bool = False) -> pathlib.Path | None:
    """Turn on JAX's persistent compilation cache (`compile_cache_dir`) for this process:
    every compiled program is written there and read back by the next process with the
    same program, JAX version and machine, so that a second `rockjax fit` skips the XLA
    compile (JAX does not cache tracing; `identification` keeps the fit's traced programs
    in `<dir>/identification` when the cache is on). Returns the directory, None when
    turned off. A directory that cannot be created turns the cache off (no error)."""
    path = compile_cache_dir(disabled)
    if path is None:
        return None
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    import jax

    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return path
