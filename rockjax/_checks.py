"""The one home of the library's argument checks (`simulate`, `simulate_batch`, `sweep`,
`overturning_spectrum`, and the command line, which calls the same checks).

Each raises `rockjax.ParameterError` (a `ValueError`) whose `param` names the parameter at
fault; nothing here integrates.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from ._errors import ParameterError
from ._excitation import AbstractExcitation, FreeVibration, GroundMotion
from ._structure import FIELDS, RockingStructure

METHODS = ("diffrax", "rk4", "dopri5")


def is_traced(x) -> bool:
    return isinstance(x, jax.core.Tracer)


def check_scene(structure, excitation) -> None:
    if not isinstance(structure, RockingStructure):
        raise ParameterError(
            f"structure must be a RockingStructure, got {type(structure).__name__}",
            param="structure")
    if not isinstance(excitation, AbstractExcitation):
        raise ParameterError(
            f"excitation must be a FreeVibration or GroundMotion, got {type(excitation).__name__}",
            param="excitation"
        )
    if not isinstance(excitation, (FreeVibration, GroundMotion)):
        raise ParameterError("rockjax integrates FreeVibration and GroundMotion excitations",
                             param="excitation")


def check_t1(t1):
    """The largest end time [s] as a float (None if traced)."""
    if is_traced(t1):
        return None
    try:
        t1a = np.asarray(t1, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(f"t1 must be a positive, finite number of seconds, got {t1!r}",
                             param="t1") from None
    if t1a.size < 1:
        raise ParameterError("t1 must be a positive, finite number of seconds, got an empty array",
                             param="t1")
    t1f = float(np.max(t1a))
    if not np.isfinite(t1f) or not float(np.min(t1a)) > 0:
        raise ParameterError(f"t1 must be positive and finite, got {t1a}", param="t1")
    return t1f


def check_end_time(t1) -> float:
    """The end time [s] of a batch: a positive, finite scalar that must be given."""
    if t1 is None:
        raise ParameterError(
            "t1 must be given: the end time [s] of a single excitation (only a sequence of "
            "records has a default end, each record's end plus tail)", param="t1")
    t1f = np.asarray(t1, dtype=float)
    if t1f.ndim != 0 or not np.isfinite(t1f) or not t1f > 0:
        raise ParameterError(f"t1 must be a positive, finite scalar, got {t1f}", param="t1")
    return float(t1f)


def check_ts(ts, t1f, summary_only=False) -> None:
    """Output times: a 1-D, finite, strictly increasing array within [0, t1]; none with
    `summary_only`."""
    if ts is None or is_traced(ts):
        return
    if summary_only:
        raise ParameterError("ts applies to full responses, not with summary_only=True",
                             param="ts")
    tsn = np.asarray(ts, dtype=float)
    if tsn.ndim != 1 or tsn.size < 1:
        raise ParameterError("ts must be a 1-D array of output times", param="ts")
    if not np.all(np.isfinite(tsn)):
        raise ParameterError("ts must be finite", param="ts")
    if tsn.size > 1 and not np.all(np.diff(tsn) > 0):
        raise ParameterError("ts must be strictly increasing", param="ts")
    if tsn[0] < 0 or (t1f is not None and tsn[-1] > t1f * (1 + 1e-12)):
        raise ParameterError(f"ts must lie within [0, t1] = [0, {t1f}]", param="ts")


def check_r(r) -> None:
    if r is None or is_traced(r):
        return
    rr = np.asarray(r)
    if not np.all(np.isfinite(rr)) or np.any(rr < 0) or np.any(rr > 1):
        raise ParameterError(f"r must lie in [0, 1], got {rr}", param="r")


def check_one_structure(structure, advice) -> None:
    """A `RockingStructure` of scalar fields (one structure); `advice` ends the error, e.g.
    "sweep one structure at a time"."""
    if not isinstance(structure, RockingStructure):
        raise ParameterError(
            f"structure must be a RockingStructure, got {type(structure).__name__}",
            param="structure")
    batched = [f for f in FIELDS if np.ndim(getattr(structure, f)) != 0]
    if batched:
        raise ParameterError(f"structure: one structure (scalar fields), got arrays in "
                             f"{', '.join(batched)}; {advice}", param="structure")


def check_scales(scales) -> np.ndarray:
    """Scale factors: a non-empty 1-D list of positive, finite numbers, as a float array."""
    try:
        sc = np.array(scales, dtype=float).reshape(-1) if np.ndim(scales) <= 1 else None
    except (TypeError, ValueError):
        raise ParameterError(f"scales must be positive numbers, got {scales!r}",
                             param="scales") from None
    if sc is None or sc.size == 0 or not np.all(np.isfinite(sc)) or np.any(sc <= 0):
        raise ParameterError(f"scales must be a non-empty 1-D list of positive finite numbers, "
                             f"got {scales!r}", param="scales")
    return sc


def check_periods(periods) -> np.ndarray:
    """Periods [s]: a number or a non-empty 1-D array of positive, finite numbers."""
    T = np.asarray(periods, dtype=float)
    if T.ndim == 0:
        T = T[None]
    if T.ndim != 1 or T.size == 0:
        raise ParameterError(f"periods must be a non-empty 1-D array [s], got shape {T.shape}",
                             param="periods")
    if not np.all(np.isfinite(T) & (T > 0)):
        raise ParameterError(f"periods must be positive and finite [s], got {T}", param="periods")
    return T


def check_settings(*, method, rtol, atol, max_impacts, dt, substeps, max_steps=1) -> None:
    """Checks of the solver settings common to both entry points."""
    if method not in METHODS:
        raise ParameterError(f"method must be 'diffrax', 'rk4' or 'dopri5', got {method!r}",
                             param="method")
    for name, val in (("rtol", rtol), ("atol", atol)):
        if not (isinstance(val, (int, float)) and val > 0):
            raise ParameterError(f"{name} must be a positive number, got {val!r}", param=name)
    if not (isinstance(max_impacts, int) and max_impacts >= 1):
        raise ParameterError(f"max_impacts must be a positive integer, got {max_impacts!r}",
                             param="max_impacts")
    if dt is not None and not (isinstance(dt, (int, float)) and np.isfinite(dt) and dt > 0):
        raise ParameterError(f"dt must be a positive number of seconds (finite), got {dt!r}",
                             param="dt")
    if not (isinstance(max_steps, int) and max_steps >= 1):
        raise ParameterError(f"max_steps must be a positive integer, got {max_steps!r}",
                             param="max_steps")
    if substeps is not None and not (isinstance(substeps, int) and substeps >= 1):
        raise ParameterError(f"substeps must be a positive integer, got {substeps!r}",
                             param="substeps")


def check_float64(method, dtype) -> None:
    if method == "diffrax" and dtype != np.float64:
        fix = ("structure.astype(jnp.float64)" if jax.config.jax_enable_x64 else
               "rockjax.configure() (float64 on; you opted out with configure(x64=False) "
               "or JAX_ENABLE_X64) before building the structure")
        raise ParameterError(
            f"method 'diffrax' runs in float64; this structure is {dtype}: use "
            f"method='rk4' or 'dopri5' for float32 (see docs/batches.md), or {fix}",
            param="method",
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
        raise ParameterError(
            "dt applies to a free vibration; a ground motion is integrated on "
            "its record's samples (use substeps to refine)", param="dt"
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
