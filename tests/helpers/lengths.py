"""The length of a function in lines of code, over rockjax/ and identification/.

A function's length is the number of lines in its span (decorators through its last line)
that are neither blank nor comment-only and are not part of a docstring. A nested
function's lines count inside its parent too, since the parent's span contains them.

This is the one place that measure is defined: tests/test_architecture.py checks it, and
`python benchmarks/longest_functions.py` prints the longest functions with it. Standard
library only.
"""

from __future__ import annotations

import ast
import io
import pathlib
import tokenize
from collections.abc import Iterable, Iterator
from typing import NamedTuple

REPO = pathlib.Path(__file__).resolve().parents[2]
SOURCE_ROOTS = ("rockjax", "identification")
MAX_FUNCTION_LINES = 80


class FunctionLength(NamedTuple):
    path: str  # as given (repository-relative for the real tree)
    lineno: int  # the `def` line
    qualname: str  # Outer.method.inner
    lines: int  # lines of code, as defined above

    def __str__(self) -> str:
        return f"{self.path}:{self.lineno} {self.qualname}() has {self.lines} lines"


def iter_python_files(
    repo: pathlib.Path = REPO, roots: Iterable[str] = SOURCE_ROOTS
) -> Iterator[pathlib.Path]:
    """Every .py file under the given top-level folders (recursively, sorted, no caches)."""
    for root in roots:
        base = repo / root
        if not base.is_dir():
            continue
        for path in sorted(base.rglob("*.py")):
            parts = path.relative_to(repo).parts
            if any(p == "__pycache__" or p.startswith(".") for p in parts):
                continue
            yield path


def _docstring_lines(tree: ast.AST) -> set[int]:
    """Lines taken by the docstrings of the module and of every class and function."""
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if (
                body
                and isinstance(body[0], ast.Expr)
                and isinstance(body[0].value, ast.Constant)
                and isinstance(body[0].value.value, str)
            ):
                lines.update(range(body[0].lineno, body[0].end_lineno + 1))
    return lines


def _comment_only_lines(source: str) -> set[int]:
    """Lines with a comment and no other token (a `#` inside a string literal is no comment)."""
    comments: set[int] = set()
    code: set[int] = set()
    skip = (tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT, tokenize.ENCODING)
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            comments.add(tok.start[0])
        elif tok.type not in skip:
            code.update(range(tok.start[0], tok.end[0] + 1))  # a string may span lines
    return comments - code


def code_lines(source: str, tree: ast.AST | None = None) -> set[int]:
    """The 1-based line numbers of `source` that count as code."""
    tree = ast.parse(source) if tree is None else tree
    text = source.splitlines()
    not_code = _docstring_lines(tree) | _comment_only_lines(source)
    return {i for i, line in enumerate(text, start=1) if line.strip() and i not in not_code}


def function_lengths(source: str, path: str = "<string>") -> list[FunctionLength]:
    """The length of every function and method in `source`, in source order."""
    tree = ast.parse(source, filename=path)
    code = code_lines(source, tree)
    out: list[FunctionLength] = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                first = min([child.lineno] + [d.lineno for d in child.decorator_list])
                n = sum(1 for i in range(first, child.end_lineno + 1) if i in code)
                out.append(FunctionLength(path, child.lineno, prefix + child.name, n))
                visit(child, prefix + child.name + ".")
            elif isinstance(child, ast.ClassDef):
                visit(child, prefix + child.name + ".")
            else:
                visit(child, prefix)

    visit(tree, "")
    return out


def all_function_lengths(
    repo: pathlib.Path = REPO, roots: Iterable[str] = SOURCE_ROOTS
) -> list[FunctionLength]:
    """`function_lengths` over every .py file under `roots`, longest first."""
    out: list[FunctionLength] = []
    for path in iter_python_files(repo, roots):
        rel = path.relative_to(repo).as_posix()
        out.extend(function_lengths(path.read_text(encoding="utf-8"), rel))
    return sorted(out, key=lambda f: (-f.lines, f.path, f.lineno))
