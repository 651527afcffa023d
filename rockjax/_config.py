"""`rockjax.configure`: the one place where rockjax changes JAX's configuration.

`import rockjax` changes nothing. `configure()` turns on float64 (`jax_enable_x64`) and asks
for one CPU device per usable core (`rockjax/_devices.py`); the command line, the test
suite, the README, the notebooks and the benchmarks call it first. A program that never
calls it still gets float64 from the first computing entry point (`ensure_x64`), with one
`ConfigurationWarning` saying so, unless it opted out: ``configure(x64=False)`` or the
environment variable ``JAX_ENABLE_X64`` set to a false value (0, false, no, off).
"""

from __future__ import annotations

import dataclasses
import os
import warnings

import jax

from ._devices import choose_cpu_devices
from ._errors import ConfigurationWarning, ParameterError

_FALSE = ("0", "false", "no", "off")

#: the process's state: x64 as chosen by configure (None: not chosen), whether warned
_STATE = {"x64": None, "warned": False}


@dataclasses.dataclass(frozen=True)
class Configuration:
    """What `configure` did: `x64` (float64 on), and to the CPU device count: `devices`
    ("set", "left alone", "backend already initialised", "XLA_FLAGS sets the count" or
    "jax_num_cpu_devices set by the user") and `cpu_devices` (the count, None if unknown
    without starting JAX's backend)."""

    x64: bool
    devices: str
    cpu_devices: int | None


def configure(*, x64: bool = True, cpu_devices="all") -> Configuration:
    """Set JAX up for rockjax, explicitly; call it before any JAX computation.

    **Arguments:**

    - `x64`: True (default): turn on float64 (`jax_enable_x64`), the default dtype of every
      result. False: leave it off and opt out of the float64 that the computing entry
      points would otherwise turn on; float32 then runs where supported
      (`method="rk4"` or `"dopri5"`) and `method="diffrax"` raises.
    - `cpu_devices`: `"all"` (default): one JAX CPU device per usable core, so that
      `simulate_batch` uses every core, unless a count was chosen with `XLA_FLAGS`,
      `JAX_NUM_CPU_DEVICES` or `ROCKJAX_CPU_DEVICES`; an int: that many; None: leave the
      count alone. JAX fixes the count when its backend starts: called after a
      computation, `configure` leaves the count as it is and says so in its result.

    **Returns:** a `Configuration`: what it did.

    **Example:**

    ```python
    cfg = rockjax.configure()
    cfg.x64, cfg.devices
    ```
    """
    if not isinstance(x64, bool):
        raise ParameterError(f"x64 must be True or False, got {x64!r}", param="x64")
    choice = choose_cpu_devices(cpu_devices)
    jax.config.update("jax_enable_x64", x64)
    _STATE["x64"] = x64
    return Configuration(x64=bool(jax.config.jax_enable_x64), devices=choice["action"],
                         cpu_devices=choice["count"])


def opted_out() -> bool:
    """Whether the user chose float32: ``configure(x64=False)``, or ``JAX_ENABLE_X64`` set
    to a false value while `configure` was not called."""
    if _STATE["x64"] is not None:
        return not _STATE["x64"]
    return os.environ.get("JAX_ENABLE_X64", "").strip().lower() in _FALSE


def ensure_x64() -> None:
    """Turn float64 on for a computing entry point when it is off and the user has not
    opted out, warning once per process (`ConfigurationWarning`). Cheap when it is on."""
    if jax.config.jax_enable_x64 or opted_out():
        return
    jax.config.update("jax_enable_x64", True)
    if not _STATE["warned"]:
        _STATE["warned"] = True
        warnings.warn(
            "rockjax turned on JAX's float64 mode (jax_enable_x64), which its results "
            "default to; call rockjax.configure() before any computation to do it "
            "explicitly (and silence this warning), or rockjax.configure(x64=False) to "
            "keep float32", ConfigurationWarning, stacklevel=_user_level())


def _user_level() -> int:
    """The `stacklevel` of the first frame outside rockjax, equinox and jax (the user's
    call), so that the warning names the user's line."""
    import sys

    import equinox

    inside = tuple(os.path.dirname(m.__file__) for m in (sys.modules[__package__], equinox, jax))
    frame, level = sys._getframe(1), 1
    while frame is not None and frame.f_code.co_filename.startswith(inside):
        frame, level = frame.f_back, level + 1
    return level


def stack_versions() -> str:
    """The versions of the JAX stack rockjax runs on, as "jax X, diffrax Y, ..." (one line)."""
    from importlib.metadata import PackageNotFoundError, version

    def of(pkg):
        try:
            return version(pkg)
        except PackageNotFoundError:  # pragma: no cover - a broken environment
            return "?"

    return ", ".join(f"{pkg} {of(pkg)}" for pkg in ("jax", "diffrax", "equinox", "optax"))
