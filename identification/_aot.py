"""The fit's compiled programs kept on disk, traced once per program: `persisted(fn)`.

JAX's persistent compilation cache (`jax_compilation_cache_dir`, which `rockjax`'s command
line turns on) keeps XLA's compiled code between processes, but not the tracing that
comes before it: for a fit that is the larger part (the `rockjax.simulate` solve, traced
under forward-mode differentiation, `vmap` and `scan`: several seconds). When that cache
is on, `persisted(fn)` therefore also writes each program it traces, as a serialised
`jax.export` module, next to it (in `<cache dir>/identification`), and a later process
reads it back instead of tracing; its compile is then a hit in JAX's cache. When the
cache is off (the default outside the command line) it is `eqx.filter_jit(fn)`.

A program is keyed by its static arguments and the shapes and dtypes of its arrays, the
versions of JAX, jaxlib, equinox, diffrax, optax, lineax and optimistix, and a digest of
the source of `rockjax` and `identification`: any change to them traces again. Static
arguments other than strings, numbers, None and tuples of them (functions, say) must be
named with `name_static` (the default optimiser's), else the call is not persisted. Any failure to
export, read or write falls back to `eqx.filter_jit` silently.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import os
import pathlib

import equinox as eqx
import jax

_TOKENS: dict = {}  # id(static object) -> its name in the key
_KEEP: list = []  # the named objects (so that their ids stay theirs)


def name_static(obj, name: str):
    """Name a static argument (a function) in the keys of persisted programs."""
    _TOKENS[id(obj)] = name
    _KEEP.append(obj)


def store() -> pathlib.Path | None:
    """`<jax_compilation_cache_dir>/identification`, or None when that cache is off."""
    d = jax.config.jax_compilation_cache_dir
    return pathlib.Path(d) / "identification" if d else None


@functools.cache
def _environment() -> str:
    """Versions of the stack and a digest of the source of rockjax and identification."""
    import rockjax

    h = hashlib.sha256()
    for pkg in ("jax", "jaxlib", "equinox", "diffrax", "optax", "lineax", "optimistix"):
        try:
            h.update(f"{pkg}={importlib.metadata.version(pkg)};".encode())
        except importlib.metadata.PackageNotFoundError:  # pragma: no cover
            h.update(f"{pkg}=?;".encode())
    for root in (pathlib.Path(rockjax.__file__).parent, pathlib.Path(__file__).parent):
        for path in sorted(root.rglob("*.py")):
            h.update(path.relative_to(root.parent).as_posix().encode())
            h.update(path.read_bytes())
    h.update(f"x64={jax.config.jax_enable_x64};{jax.default_backend()}".encode())
    return h.hexdigest()


def _static_token(x):
    if x is None or isinstance(x, (bool, int, float, str)):
        return repr(x)
    if isinstance(x, tuple):
        parts = [_static_token(y) for y in x]
        return None if None in parts else "(" + ",".join(parts) + ")"
    return _TOKENS.get(id(x))


class persisted:
    """`eqx.filter_jit(fn)`, whose programs persist on disk when JAX's persistent
    compilation cache is on (see the module docstring). `out_structure(*args)`: the
    pytree structure of `fn(*args)`, found without tracing `fn` (a program read from
    disk has flat outputs)."""

    def __init__(self, fn, out_structure):
        self.fn = fn
        self.out_structure = out_structure
        self.jitted = eqx.filter_jit(fn)
        self.programs = {}  # key -> (compiled call of the flat arrays, output treedef)
        functools.update_wrapper(self, fn)

    def __call__(self, *args):
        where = store()
        if where is None:
            return self.jitted(*args)
        dyn, static = eqx.partition(args, eqx.is_array)
        s_leaves, s_def = jax.tree.flatten(static)
        tokens = tuple(_static_token(x) for x in s_leaves)
        if None in tokens:
            return self.jitted(*args)
        d_leaves, d_def = jax.tree.flatten(dyn)
        avals = tuple((tuple(x.shape), str(x.dtype)) for x in d_leaves)
        key = (str(s_def), tokens, str(d_def), avals)
        program = self.programs.get(key)
        if program is None:
            program = self._program(where, key, args, d_def, static, d_leaves)
            self.programs[key] = program
        if program is False:
            return self.jitted(*args)
        call, out_def = program
        return jax.tree.unflatten(out_def, call(*d_leaves))

    def _program(self, where, key, args, d_def, static, d_leaves):
        digest = hashlib.sha256(repr((key, _environment())).encode()).hexdigest()[:32]
        path = where / f"{self.fn.__name__}-{digest}.export"
        out_def = self.out_structure(*args)
        try:
            return jax.jit(_load(path.read_bytes()).call), out_def
        except Exception:  # absent, or unreadable: trace it
            pass
        out_defs = []

        def flat(*leaves):
            out = self.fn(*eqx.combine(jax.tree.unflatten(d_def, leaves), static))
            o_leaves, o_def = jax.tree.flatten(out)
            out_defs.append(o_def)
            return o_leaves

        try:
            shapes = [jax.ShapeDtypeStruct(x.shape, x.dtype) for x in d_leaves]
            exported = jax.export.export(jax.jit(flat))(*shapes)
            blob = _dump(exported)
        except Exception:  # not exportable: the plain path
            return False
        if out_defs[-1] != out_def:  # out_structure is wrong: do not keep it
            return jax.jit(exported.call), out_defs[-1]
        try:
            where.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(f".tmp{os.getpid()}")
            tmp.write_bytes(blob)
            os.replace(tmp, path)
        except Exception:  # not writable: used in this process only
            pass
        return jax.jit(exported.call), out_defs[-1]


def _dump(exported):
    """An `Exported` as bytes (JAX's own serialisation, with the `flatbuffers` package)."""
    return bytes(exported.serialize())


def _load(blob: bytes):
    return jax.export.deserialize(bytearray(blob))
