"""JAX's persistent compilation cache for the `rockjax` command line: where it lives
(`compile_cache_dir`) and turning it on for a process (`enable_compile_cache`). `import
rockjax` does not turn it on; `rockjax.cli.main` does, for the command's own process.
"""

from __future__ import annotations

import os
import pathlib

import jax

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
    env = os.environ.get(COMPILE_CACHE_ENV, "").strip()
    no = os.environ.get("ROCKJAX_NO_COMPILE_CACHE", "").strip().lower()
    if disabled or env.lower() in _OFF or no not in ("",) + _OFF[1:]:
        return None
    if env:
        return pathlib.Path(env).expanduser()
    from . import datasets

    return datasets.cache_dir() / "jax"


def enable_compile_cache(disabled: bool = False) -> pathlib.Path | None:
    """Turn on JAX's persistent compilation cache (`compile_cache_dir`) for this process:
    every compiled program is written there and read back by the next process with the
    same program, JAX version and machine, so that a second `rockjax fit` skips the XLA
    compile (JAX does not cache tracing; `identification` keeps the fit's traced programs
    in `<dir>/identification` when the cache is on). Returns the directory, None when
    turned off. A directory that cannot be created turns the cache off (no error). The
    command line calls it (`rockjax.cli.main`); `import rockjax` does not."""
    path = compile_cache_dir(disabled)
    if path is None:
        return None
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    jax.config.update("jax_compilation_cache_dir", str(path))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return path
