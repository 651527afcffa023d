"""Argument checks shared by `rockjax.simulate` and `rockjax.simulate_batch`.

Each raises `ValueError` naming the parameter at fault; nothing here integrates.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from ._excitation import AbstractExcitation, FreeVibration, GroundMotion
from ._structure import RockingStructure

METHODS = ("diffrax", "rk4", "dopri5")


def is_traced(x) -> bool:
    return isinstance(x, jax.core.Tracer)


def check_scene(structure, excitation) -> None:
    if not isinstance(structure, RockingStructure):
        raise ValueError(f"structure must be a RockingStructure, got {type(structure).__name__}")
    if not isinstance(excitation, AbstractExcitation):
        raise ValueError(
            f"excitation must be a FreeVibration or GroundMotion, got {type(excitation).__name__}"
        )
    if not isinstance(excitation, (FreeVibration, GroundMotion)):
        raise ValueError("rockjax integrates FreeVibration and GroundMotion excitations")


def check_t1(t1):
    """The largest end time [s] as a float (None if traced)."""
    if is_traced(t1):
        return None
    try:
        t1a = np.asarray(t1, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"t1 must be a positive, finite number of seconds, got {t1!r}") from None
    if t1a.size < 1:
        raise ValueError("t1 must be a positive, finite number of seconds, got an empty array")
    t1f = float(np.max(t1a))
    if not np.isfinite(t1f) or not float(np.min(t1a)) > 0:
        raise ValueError(f"t1 must be positive and finite, got {t1a}")
    return t1f


def check_ts(ts, t1f) -> None:
    if is_traced(ts):
        return
    tsn = np.asarray(ts, dtype=float)
    if tsn.ndim != 1 or tsn.size < 1:
        raise ValueError("ts must be a 1-D array of output times")
    if not np.all(np.isfinite(tsn)):
        raise ValueError("ts must be finite")
    if tsn.size > 1 and not np.all(np.diff(tsn) > 0):
        raise ValueError("ts must be strictly increasing")
    if tsn[0] < 0 or (t1f is not None and tsn[-1] > t1f * (1 + 1e-12)):
        raise ValueError(f"ts must lie within [0, t1] = [0, {t1f}]")


def check_r(r) -> None:
    if r is None or is_traced(r):
        return
    rr = np.asarray(r)
    if not np.all(np.isfinite(rr)) or np.any(rr < 0) or np.any(rr > 1):
        raise ValueError(f"r must lie in [0, 1], got {rr}")


def check_settings(*, method, rtol, atol, max_impacts, dt, substeps, max_steps=1) -> None:
    """Checks of the solver settings common to both entry points."""
    if method not in METHODS:
        raise ValueError(f"method must be 'diffrax', 'rk4' or 'dopri5', got {method!r}")
    for name, val in (("rtol", rtol), ("atol", atol)):
        if not (isinstance(val, (int, float)) and val > 0):
            raise ValueError(f"{name} must be a positive number, got {val!r}")
    if not (isinstance(max_impacts, int) and max_impacts >= 1):
        raise ValueError(f"max_impacts must be a positive integer, got {max_impacts!r}")
    if dt is not None and not (isinstance(dt, (int, float)) and np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive number of seconds (finite), got {dt!r}")
    if not (isinstance(max_steps, int) and max_steps >= 1):
        raise ValueError(f"max_steps must be a positive integer, got {max_steps!r}")
    if substeps is not None and not (isinstance(substeps, int) and substeps >= 1):
        raise ValueError(f"substeps must be a positive integer, got {substeps!r}")


def check_float64(method, dtype) -> None:
    if method == "diffrax" and dtype != np.float64:
        raise ValueError(
            f"method 'diffrax' runs in float64; this structure is {dtype}: use "
            "method='rk4' or 'dopri5' for float32 (see docs/batches.md), or "
            "structure.astype(jnp.float64)"
        )


def default_substeps(substeps, free, method) -> int:
    """RK4 steps per record interval (4), per free-vibration step (1); dopri5: 1 (it
    chooses its own steps, substeps only caps them)."""
    if substeps is not None:
        return substeps
    return 1 if (free or method != "rk4") else 4


def free_vibration_dt(t1f, dt) -> float:
    """The grid step [s] of a free vibration on the stepper: min(t1/4000, 10 ms)."""
    return min(t1f / 4000, 0.01) if dt is None else float(dt)


def stepper_grid_step(excitation, t1f, dt):
    """(grid step [s], number of steps to t1) of the stepper: the record's samples for a
    ground motion (then `dt` must not be given), `free_vibration_dt` otherwise."""
    if not excitation.forced:
        step = free_vibration_dt(t1f, dt)
    elif dt is not None:
        raise ValueError(
            "dt applies to a free vibration; a ground motion is integrated on "
            "its record's samples (use substeps to refine)"
        )
    else:
        step = float(np.asarray(excitation.dt))
    return step, int(math.ceil(t1f / step - 1e-9))


def strong(tree):
    """Strip weak types from the array leaves of a pytree (no copy for strong arrays), so
    that new values never trigger a recompile (eqx.tree_at, for one, can insert weakly
    typed leaves)."""

    def fix(x):
        if isinstance(x, jax.Array) and getattr(x, "weak_type", False):
            return jnp.asarray(x, dtype=x.dtype)
        return x

    return jax.tree_util.tree_map(fix, tree)
