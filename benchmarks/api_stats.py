"""Acceptance figures of issue 23: the most parameters of the public functions (not counting
``**keywords``), and private names imported across packages and modules (an AST scan).

    python benchmarks/api_stats.py
"""

from __future__ import annotations

import ast
import inspect
import pathlib

import identification
import rockjax
import rockjax.datasets
import rockjax.integrators
import rockjax.models
import rockjax.pulses

ROOT = pathlib.Path(__file__).resolve().parents[1]
MODULES = (rockjax, identification, rockjax.integrators, rockjax.models, rockjax.pulses,
           rockjax.datasets)


def parameter_counts():
    """[(parameters, qualified name)] of the public functions, most first."""
    rows = set()
    for mod in MODULES:
        for name in dir(mod):
            obj = getattr(mod, name)
            if name.startswith("_") or not inspect.isfunction(obj):
                continue
            params = inspect.signature(obj).parameters.values()
            n = sum(p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL) for p in params)
            rows.add((n, f"{mod.__name__}.{name}"))
    return sorted(rows, reverse=True)


def private_imports():
    """(between packages, within a package): `from X import ...` lines that take a private
    module or name of the other package, or a private name of another module."""
    between, within = [], []
    for pkg in ("rockjax", "identification"):
        for f in sorted((ROOT / pkg).rglob("*.py")):
            for node in ast.walk(ast.parse(f.read_text())):
                if not isinstance(node, ast.ImportFrom) or not node.module:
                    continue
                names = [a.name for a in node.names]
                private = [n for n in names if n.startswith("_") and not n.startswith("__")]
                top = node.module.split(".")[0]
                private_module = any(p.startswith("_") and p != "__future__"
                                     for p in node.module.split("."))
                line = f"{f.relative_to(ROOT)}: from {'.' * node.level}{node.module} import "
                if (node.level == 0 and top in ("rockjax", "identification") and top != pkg
                        and (private_module or private)):
                    between.append(line + ", ".join(names))
                if private:
                    within.append(line + ", ".join(private))
    return between, within


if __name__ == "__main__":
    for n, name in parameter_counts()[:6]:
        print(f"{n:3d}  {name}")
    between, within = private_imports()
    print(f"private names between packages: {len(between)}")
    print(*between, sep="\n")
    print(f"private names imported from another module of the same package: {len(within)}")
    print(*within, sep="\n")
