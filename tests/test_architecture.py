"""Structural checks on rockjax/ and identification/: import cycles, layering, function length.

Static only (ast + pathlib, no JAX compile, well under a second). Every .py file under
rockjax/ and identification/ is found by walking the tree, so new subpackages are covered
without touching this file.

Import graph. Nodes are the modules of those two trees (a package is its __init__.py).
Every import statement counts, wherever it is -- module level, inside functions (where
cycles were once hidden), under `if TYPE_CHECKING`, inside try blocks. Relative imports are
resolved against the importing module. For `from P import n`: if `P.n` is a module of the
tree the edge goes to it, otherwise to `P` itself (its __init__.py). Importing `a.b.c` also
runs the __init__ of `a.b`, so an edge goes to every intermediate package too, except the
importer's own enclosing packages (those are already running). External imports are ignored.
All edges count, edges into and out of a package __init__ included: any cycle fails.
An import of a module of ours that does not exist gives no edge; test_internal_imports_resolve
reports it instead.

The function-length measure lives in tests/helpers/lengths.py (`python
benchmarks/longest_functions.py` prints the longest functions with it).
"""

from __future__ import annotations

import ast
import pathlib
import textwrap
from collections import deque
from collections.abc import Callable, Iterable, Mapping
from typing import NamedTuple

import pytest
from helpers import lengths

REPO = pathlib.Path(__file__).resolve().parents[1]
SOURCE_ROOTS = ("rockjax", "identification")


# ------------------------------------------------------------------------------------------
# Modules and their imports


class Module(NamedTuple):
    name: str  # dotted module name; a package is named by its __init__.py
    path: str  # repository-relative, posix
    is_package: bool
    tree: ast.Module


class Import(NamedTuple):
    """One imported name, resolved to an absolute dotted name."""

    path: str
    lineno: int
    module: str  # the module the statement names (`a.b` in `import a.b`, `P` in `from P import n`)
    name: str | None  # `n` in `from P import n`; None for `import a.b` and `from P import *`

    @property
    def dotted(self) -> str:
        return f"{self.module}.{self.name}" if self.name else self.module


def modules_from_sources(sources: Mapping[str, str]) -> dict[str, Module]:
    """Modules from {repository-relative path: source}; paths ending in __init__.py are packages."""
    out: dict[str, Module] = {}
    for path, source in sources.items():
        parts = pathlib.PurePosixPath(path).with_suffix("").parts
        is_package = parts[-1] == "__init__"
        name = ".".join(parts[:-1] if is_package else parts)
        out[name] = Module(name, path, is_package, ast.parse(source, filename=path))
    return out


def modules_from_tree(
    repo: pathlib.Path = REPO, roots: Iterable[str] = SOURCE_ROOTS
) -> dict[str, Module]:
    sources = {
        p.relative_to(repo).as_posix(): p.read_text(encoding="utf-8")
        for p in lengths.iter_python_files(repo, roots)
    }
    return modules_from_sources(sources)


def _resolve_relative(mod: Module, level: int, module: str | None) -> str:
    package = mod.name if mod.is_package else mod.name.rpartition(".")[0]
    parts = package.split(".")
    if level - 1 >= len(parts):
        raise ValueError(f"{mod.path}: relative import beyond the top-level package")
    base = ".".join(parts[: len(parts) - (level - 1)])
    return f"{base}.{module}" if module else base


def imports_of(mod: Module) -> list[Import]:
    """Every import in `mod` (nested ones included), resolved to absolute names."""
    out: list[Import] = []
    for node in ast.walk(mod.tree):
        if isinstance(node, ast.Import):
            out.extend(Import(mod.path, node.lineno, a.name, None) for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = _resolve_relative(mod, node.level, node.module)
            else:
                base = node.module
            for a in node.names:
                name = None if a.name == "*" else a.name
                out.append(Import(mod.path, node.lineno, base, name))
    return sorted(out, key=lambda i: (i.lineno, i.dotted))


def _prefixes(dotted: str) -> list[str]:
    parts = dotted.split(".")
    return [".".join(parts[:k]) for k in range(1, len(parts) + 1)]


def import_targets(importer: Module, imp: Import, known: Mapping[str, Module]) -> list[str]:
    """The modules of the tree that running `imp` inside `importer` imports.

    An import of a module of ours that does not exist (see test_internal_imports_resolve)
    gives no edge.
    """
    if imp.name and imp.dotted in known:
        target = imp.dotted  # `from P import n` with n a submodule
    elif imp.module in known:
        target = imp.module  # `import P`, or `from P import name` with name defined in P
    else:
        return []  # not ours, or dangling
    running = set(_prefixes(importer.name))  # the importer and its enclosing packages
    between = [p for p in _prefixes(target)[:-1] if p in known and p not in running]
    return between + [target]


def dangling_imports(modules: Mapping[str, Module]) -> list[str]:
    """Imports naming a module under one of our top-level packages that does not exist."""
    tops = {name.split(".")[0] for name in modules}
    exists = {p for name in modules for p in _prefixes(name)}  # with folders lacking __init__
    out = []
    for mod in sorted(modules.values(), key=lambda m: m.path):
        for imp in imports_of(mod):
            if imp.module.split(".")[0] in tops and imp.module not in exists:
                line = f"{imp.path}:{imp.lineno} imports {imp.module}"
                if line not in out:
                    out.append(line)
    return out


Graph = dict[str, dict[str, str]]  # importer -> {imported: "path:line" of the first such import}


def import_graph(modules: Mapping[str, Module]) -> Graph:
    graph: Graph = {name: {} for name in modules}
    for mod in modules.values():
        for imp in imports_of(mod):
            for target in import_targets(mod, imp, modules):
                graph[mod.name].setdefault(target, f"{imp.path}:{imp.lineno}")
    return graph


# ------------------------------------------------------------------------------------------
# Cycles


def strongly_connected_components(graph: Graph) -> list[list[str]]:
    """Tarjan's algorithm (iterative), components in sorted order."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[list[str]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    parent = work[-1][0]
                    low[parent] = min(low[parent], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    components.append(sorted(component))
    return sorted(components)


def _shortest_path(graph: Graph, start: str, goal: str, allowed: set[str]) -> list[str]:
    previous: dict[str, str | None] = {start: None}
    queue = deque([start])
    while queue:
        node = queue.popleft()
        if node == goal:
            path = [node]
            while previous[path[-1]] is not None:
                path.append(previous[path[-1]])
            return path[::-1]
        for child in sorted(graph[node]):
            if child in allowed and child not in previous:
                previous[child] = node
                queue.append(child)
    raise AssertionError("unreachable: both ends are in one strongly connected component")


def find_cycles(graph: Graph) -> list[list[str]]:
    """One shortest cycle through every edge that lies on a cycle, deduplicated.

    Each cycle is a closed path [a, b, ..., a], rotated to start at its smallest module.
    No cycles means the graph is acyclic.
    """
    cycles: set[tuple[str, ...]] = set()
    for component in strongly_connected_components(graph):
        members = set(component)
        for u in component:
            for v in graph[u]:
                if v not in members:
                    continue
                path = [u] + _shortest_path(graph, v, u, members)  # u -> v -> ... -> u
                ring = path[:-1]
                k = ring.index(min(ring))
                ring = ring[k:] + ring[:k]
                cycles.add(tuple(ring + [ring[0]]))
    return sorted((list(c) for c in cycles), key=lambda c: (len(c), c))


def format_cycle(graph: Graph, cycle: list[str]) -> str:
    steps = [cycle[0]]
    for a, b in zip(cycle, cycle[1:]):
        steps.append(f"{b} ({graph[a][b]})")
    return " -> ".join(steps)


# ------------------------------------------------------------------------------------------
# Layering contracts


def _under(dotted: str, prefixes: Iterable[str]) -> bool:
    return any(dotted == p or dotted.startswith(p + ".") for p in prefixes)


def _private_rockjax(dotted: str) -> bool:
    """rockjax._x, rockjax.sub._x, `from rockjax import _x`; dunders (__version__) are fine."""
    parts = dotted.split(".")
    return parts[0] == "rockjax" and any(
        p.startswith("_") and not (p.startswith("__") and p.endswith("__")) for p in parts[1:]
    )


class Contract(NamedTuple):
    id: str
    rule: str  # what it says, for the failure message
    sources: tuple[str, ...]  # folders (repository-relative) whose files it constrains
    excluded: tuple[str, ...]  # folders inside `sources` it does not constrain
    forbidden: Callable[[str], bool]  # on the imported absolute dotted name


CONTRACTS = [
    Contract(
        "identification-uses-public-rockjax",
        "identification/ imports only rockjax's public API (rockjax, rockjax.X, "
        "rockjax.datasets), never rockjax._private or rockjax.<subpackage>._private",
        ("identification",),
        (),
        _private_rockjax,
    ),
    Contract(
        "models-never-import-integrators",
        "rockjax/models/ never imports rockjax.integrators, rockjax._simulate, rockjax._batch "
        "or rockjax.cli",
        ("rockjax/models",),
        (),
        lambda d: _under(
            d, ("rockjax.integrators", "rockjax._simulate", "rockjax._batch", "rockjax.cli")
        ),
    ),
    Contract(
        "integrators-never-import-simulate-batch-cli",
        "rockjax/integrators/ never imports rockjax._simulate, rockjax._batch or rockjax.cli",
        ("rockjax/integrators",),
        (),
        lambda d: _under(d, ("rockjax._simulate", "rockjax._batch", "rockjax.cli")),
    ),
    Contract(
        "only-cli-imports-cli-and-identification",
        "nothing in rockjax/ outside rockjax/cli/ imports rockjax.cli or identification",
        ("rockjax",),
        ("rockjax/cli",),
        lambda d: _under(d, ("rockjax.cli", "identification")),
    ),
]


def _in_folder(path: str, folders: Iterable[str]) -> bool:
    return any(path == f or path.startswith(f.rstrip("/") + "/") for f in folders)


def contract_violations(contract: Contract, modules: Mapping[str, Module]) -> list[str]:
    out = []
    for mod in sorted(modules.values(), key=lambda m: m.path):
        if not _in_folder(mod.path, contract.sources) or _in_folder(mod.path, contract.excluded):
            continue
        for imp in imports_of(mod):
            if contract.forbidden(imp.dotted) or contract.forbidden(imp.module):
                out.append(f"{imp.path}:{imp.lineno} imports {imp.dotted}")
    return out


# ------------------------------------------------------------------------------------------
# The checks on the real tree


@pytest.fixture(scope="module")
def modules() -> dict[str, Module]:
    return modules_from_tree()


def test_source_tree_is_found(modules):
    """Guards the checks below against passing vacuously on an empty walk."""
    assert "rockjax" in modules and "identification" in modules, sorted(modules)
    assert modules["rockjax"].path == "rockjax/__init__.py"
    assert len(modules) >= 10, sorted(modules)
    graph = import_graph(modules)
    assert any(graph.values()), "no import edges found between rockjax/identification modules"


def test_internal_imports_resolve(modules):
    """Every import of rockjax.* / identification.* names a module that exists.

    Catches stale imports left inside functions (which only fail when that function runs)
    after a module is moved or renamed.
    """
    dangling = dangling_imports(modules)
    assert not dangling, "imports of modules that do not exist:\n  " + "\n  ".join(dangling)


def test_no_import_cycles(modules):
    graph = import_graph(modules)
    cycles = find_cycles(graph)
    components = [c for c in strongly_connected_components(graph) if len(c) > 1]
    assert not cycles, (
        f"{len(cycles)} import cycle(s) (each edge labelled with the importing file:line):\n  "
        + "\n  ".join(format_cycle(graph, c) for c in cycles)
        + "\nstrongly connected groups:\n  "
        + "\n  ".join(", ".join(c) for c in components)
    )


@pytest.mark.parametrize("contract", [pytest.param(c, id=c.id) for c in CONTRACTS])
def test_layering_contract(contract, modules):
    # A source folder that does not exist (yet) has no files: the contract holds vacuously.
    violations = contract_violations(contract, modules)
    assert not violations, f"contract broken: {contract.rule}:\n  " + "\n  ".join(violations)


def test_function_length():
    limit = lengths.MAX_FUNCTION_LINES
    offenders = [f for f in lengths.all_function_lengths(REPO, SOURCE_ROOTS) if f.lines > limit]
    assert not offenders, (
        f"{len(offenders)} function(s) over {limit} lines of code "
        "(non-blank, non-comment, docstring excluded, nested functions included):\n  "
        + "\n  ".join(str(f) for f in offenders)
    )


# ------------------------------------------------------------------------------------------
# Self-tests: each check can fail


def _synthetic(files: dict[str, str]) -> dict[str, Module]:
    return modules_from_sources({path: textwrap.dedent(src) for path, src in files.items()})


def test_synthetic_paths():
    mods = _synthetic(
        {"pkg/__init__.py": "", "pkg/sub/__init__.py": "", "pkg/sub/mod.py": "", "pkg/_a.py": ""}
    )
    assert {m.name: m.path for m in mods.values()} == {
        "pkg": "pkg/__init__.py",
        "pkg.sub": "pkg/sub/__init__.py",
        "pkg.sub.mod": "pkg/sub/mod.py",
        "pkg._a": "pkg/_a.py",
    }


def test_detects_cycle_hidden_in_a_function():
    mods = _synthetic(
        {
            "pkg/__init__.py": "",
            "pkg/_a.py": "from ._b import g\n",
            "pkg/_b.py": "def g():\n    from . import _a\n    return _a\n",
            "pkg/_c.py": "from ._a import g\n",
        }
    )
    graph = import_graph(mods)
    assert graph["pkg._b"] == {"pkg._a": "pkg/_b.py:2"}
    assert find_cycles(graph) == [["pkg._a", "pkg._b", "pkg._a"]]
    assert format_cycle(graph, ["pkg._a", "pkg._b", "pkg._a"]) == (
        "pkg._a -> pkg._b (pkg/_a.py:1) -> pkg._a (pkg/_b.py:2)"
    )


def test_detects_cycle_through_package_init():
    mods = _synthetic(
        {
            "pkg/__init__.py": "from ._core import f\nfrom . import util\n",
            "pkg/_core.py": "def f():\n    import pkg\n",
            "pkg/util.py": "from pkg import f\n",  # f is no submodule: this imports pkg/__init__
        }
    )
    graph = import_graph(mods)
    assert graph["pkg"].keys() == {"pkg._core", "pkg.util"}
    assert graph["pkg.util"].keys() == {"pkg"}
    assert find_cycles(graph) == [["pkg", "pkg._core", "pkg"], ["pkg", "pkg.util", "pkg"]]
    assert strongly_connected_components(graph) == [["pkg", "pkg._core", "pkg.util"]]


def test_no_cycle_when_acyclic():
    mods = _synthetic(
        {
            "pkg/__init__.py": "from . import models\nfrom .models import Block\nimport numpy\n",
            "pkg/models/__init__.py": "from ._block import Block\n",
            "pkg/models/_block.py": "from .. import _util\nfrom pkg._util import helper\n",
            "pkg/_util.py": "import os\n",
            "app/__init__.py": "import pkg\nfrom pkg.models import _block\n",
        }
    )
    graph = import_graph(mods)
    assert graph["pkg"].keys() == {"pkg.models"}
    assert graph["pkg.models._block"].keys() == {"pkg._util"}
    # from an outside package, importing pkg.models._block runs pkg and pkg.models first
    assert graph["app"].keys() == {"pkg", "pkg.models", "pkg.models._block"}
    assert find_cycles(graph) == []
    assert all(len(c) == 1 for c in strongly_connected_components(graph))


def test_detects_self_import_and_long_cycle():
    mods = _synthetic(
        {
            "p/__init__.py": "",
            "p/a.py": "import p.b\n",
            "p/b.py": "from p import c\n",
            "p/c.py": "from .a import x\n",
            "p/d.py": "import p.d\n",
        }
    )
    cycles = find_cycles(import_graph(mods))
    assert cycles == [["p.d", "p.d"], ["p.a", "p.b", "p.c", "p.a"]]


def test_detects_dangling_imports():
    mods = _synthetic(
        {
            "pkg/__init__.py": "from ._gone import f\nfrom . import here\nimport numpy.linalg\n",
            "pkg/here.py": "def g():\n    from .sub._old import h\n    from pkg import f\n",
            "pkg/ns/a.py": "from pkg.ns import b\nfrom . import c\n",  # folder without __init__
            "pkg/ns/b.py": "",
        }
    )
    assert dangling_imports(mods) == [
        "pkg/__init__.py:1 imports pkg._gone",
        "pkg/here.py:2 imports pkg.sub._old",
    ]
    assert import_graph(mods) == {
        "pkg": {"pkg.here": "pkg/__init__.py:2"},
        "pkg.here": {"pkg": "pkg/here.py:3"},
        "pkg.ns.a": {"pkg.ns.b": "pkg/ns/a.py:1"},
        "pkg.ns.b": {},
    }


def test_contracts_detect_violations():
    mods = _synthetic(
        {
            "rockjax/__init__.py": "from . import cli\n",
            "rockjax/models/__init__.py": "",
            "rockjax/models/block.py": (
                "from .. import integrators\n"
                "def f():\n"
                "    from rockjax._simulate import simulate\n"
                "from rockjax.models import _helpers\n"
            ),
            "rockjax/integrators/__init__.py": "from rockjax.cli import main\n",
            "rockjax/cli/__init__.py": "import identification\n",
            "rockjax/_core.py": "import identification._fit\n",
            "identification/__init__.py": (
                "import rockjax\nfrom rockjax import simulate, __version__, datasets\n"
                "from rockjax import _batch\nfrom rockjax.models._block import X\n"
                "from ._fit import fit\n"
            ),
            "identification/_fit.py": "def g():\n    import rockjax._structure\n",
        }
    )
    found = {c.id: contract_violations(c, mods) for c in CONTRACTS}
    assert found == {
        "identification-uses-public-rockjax": [
            "identification/__init__.py:3 imports rockjax._batch",
            "identification/__init__.py:4 imports rockjax.models._block.X",
            "identification/_fit.py:2 imports rockjax._structure",
        ],
        "models-never-import-integrators": [
            "rockjax/models/block.py:1 imports rockjax.integrators",
            "rockjax/models/block.py:3 imports rockjax._simulate.simulate",
        ],
        "integrators-never-import-simulate-batch-cli": [
            "rockjax/integrators/__init__.py:1 imports rockjax.cli.main",
        ],
        "only-cli-imports-cli-and-identification": [
            "rockjax/__init__.py:1 imports rockjax.cli",
            "rockjax/_core.py:1 imports identification._fit",
            "rockjax/integrators/__init__.py:1 imports rockjax.cli.main",
        ],
    }


def test_line_counter():
    source = textwrap.dedent(
        '''\
        """Module docstring."""
        import functools


        @functools.cache
        def outer(x):  # 1 decorator + 2 def
            """Docstring,

            over several lines."""
            # a comment
            y = x + 1  # 3

            def inner(z):  # 4
                """Inner docstring."""
                text = """  # 5
        # not a comment: inside a string  # 6
                """  # 7
                return z + len(text)  # 8

            return inner(  # 9
                y,  # 10
            )  # 11


        class K:
            def method(self):
                # only a comment
                pass
        '''
    )
    got = {f.qualname: (f.lineno, f.lines) for f in lengths.function_lengths(source, "m.py")}
    assert got == {"outer": (6, 11), "outer.inner": (13, 5), "K.method": (26, 2)}
    assert lengths.function_lengths("def f():\n    '''Only a docstring.'''\n")[0].lines == 1
    assert str(lengths.FunctionLength("m.py", 6, "outer", 11)) == "m.py:6 outer() has 11 lines"


def test_every_package_ships_in_the_wheel():
    """pyproject's explicit package list names every package folder (a subpackage left
    out installs from a checkout but is missing from a wheel)."""
    import tomllib

    listed = set(tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"][
        "packages"])
    found = {
        ".".join(p.parent.relative_to(REPO).parts)
        for root in ("rockjax", "identification")
        for p in (REPO / root).rglob("__init__.py")
    }
    assert found <= listed, f"packages missing from pyproject.toml: {sorted(found - listed)}"
