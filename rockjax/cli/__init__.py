"""The `rockjax` command line: `rockjax demo`, `rockjax pushover`, `rockjax sweep`, ...

One module per command, each with `add_parser(subparsers)` and `run(args)`; shared pieces
are in `_common`. Every bad input ends with a non-zero exit code and a one-line message on
stderr, never a traceback.
"""

from __future__ import annotations

import sys

import rockjax
from rockjax._cache import enable_compile_cache
from rockjax._config import stack_versions

from . import (
    demo,
    fit,
    fit_table,
    fragility,
    outcomes,
    pushover,
    rocking_spectrum,
    simulate,
    spectrum,
    sweep,
)
from ._common import CLIError, COMMON_FLAGS, error_text, EXIT_USAGE, Parser

#: the sub-commands, in the order `rockjax --help` lists them
COMMANDS = (demo, pushover, simulate, fit, fit_table, outcomes, sweep, fragility, spectrum,
            rocking_spectrum)


def flags(command):
    """The library parameter -> option map of a command (its module's `FLAGS`, else the
    options most commands share)."""
    module = next((c for c in COMMANDS if getattr(
        c, "COMMAND", c.__name__.rsplit(".", 1)[-1].replace("_", "-")) == command), None)
    return getattr(module, "FLAGS", COMMON_FLAGS)


def build_parser():
    p = Parser(prog="rockjax", description="Differentiable simulator of rigid structures "
               "rocking on a two-spring foundation (SI units throughout).")
    p.add_argument("--version", action="version",
                   version=f"rockjax {rockjax.__version__} ({stack_versions()})")
    p.add_argument(
        "--no-compile-cache", dest="compile_cache", action="store_false",
        help="do not use JAX's persistent compilation cache (default: on, in "
        "$ROCKJAX_COMPILE_CACHE or ~/.cache/rockjax/jax; ROCKJAX_COMPILE_CACHE=off also "
        "turns it off): a second run of a command skips most of its compile time",
    )
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    for command in COMMANDS:
        command.add_parser(sub)
    return p


def main(argv=None, *, compile_cache=None):
    """Run the `rockjax` command with the arguments `argv` (default: `sys.argv[1:]`) and
    return its exit code.

    `compile_cache`: whether to turn on JAX's persistent compilation cache for this
    process (`_common.enable_compile_cache`). The default, None, turns it on only when
    `argv` is None, i.e. when this process *is* the command (the `rockjax` script,
    `python -m rockjax.cli`): a call `main([...])` from a notebook, a script or a test
    leaves the caller's JAX configuration as it is. `--no-compile-cache` and
    `ROCKJAX_COMPILE_CACHE=off` turn it off in any case."""
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)  # the command, for provenance
    if not getattr(args, "command", None):
        parser.print_help()
        return EXIT_USAGE
    # float64 and every core, before any computation (a no-op for the device count when
    # the caller's JAX has already run, e.g. main([...]) in a notebook)
    rockjax.configure()
    if compile_cache is None:
        compile_cache = argv is None
    if compile_cache:  # before any computation: a later run reads the programs back
        enable_compile_cache(disabled=not args.compile_cache)
    try:
        return args.func(args)
    except (CLIError, ValueError, FileNotFoundError, IsADirectoryError, PermissionError) as e:
        # a library error that names its parameter reads with the command's option for it
        print(f"rockjax {args.command}: error: {error_text(e, flags(args.command))}",
              file=sys.stderr)
    except OSError as e:
        print(f"rockjax {args.command}: error: {e}", file=sys.stderr)
    return EXIT_USAGE


__all__ = ["build_parser", "CLIError", "COMMANDS", "EXIT_USAGE", "main"]
