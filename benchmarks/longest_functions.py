"""The longest functions in rockjax/ and identification/, by lines of code.

    python benchmarks/longest_functions.py [--top N] [--limit L]

The measure (lines of code of a function's span, docstrings, blank and comment-only lines
left out) is defined in tests/helpers/lengths.py, which tests/test_architecture.py checks
with; this script prints the longest functions with it. Standard library only.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))
from helpers.lengths import all_function_lengths, MAX_FUNCTION_LINES  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--top", type=int, default=10, help="how many to print (default 10)")
    parser.add_argument(
        "--limit",
        type=int,
        default=MAX_FUNCTION_LINES,
        help=f"mark functions over this length (default {MAX_FUNCTION_LINES})",
    )
    args = parser.parse_args(argv)
    lengths = all_function_lengths()
    for f in lengths[: args.top]:
        flag = " *" if f.lines > args.limit else ""
        print(f"{f.lines:5d}  {f.path}:{f.lineno}  {f.qualname}{flag}")
    over = sum(f.lines > args.limit for f in lengths)
    print(f"{over} of {len(lengths)} functions have more than {args.limit} lines of code (*)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
