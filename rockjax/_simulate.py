r"""`rockjax.simulate`: one run of a rocking model, checked, then handed to an integrator.

$$(m_e + m_b)\,\ddot u + k(u) = -(m_e + m_b)\,\ddot u_g(t) \qquad \text{(Eq. 1)}$$

The model (`rockjax.models`) gives the physics; the integrator (`rockjax.integrators`, an
object holding its settings) the time stepping: `EventRestart` restarts a diffrax solve at
every event, `RK4` and `Dopri5` run the batched stepper with events located inside its
steps.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from ._checks import (
    check_float64,
    check_r,
    check_scene,
    check_t1,
    check_ts,
    is_traced,
    strong,
)
from ._config import ensure_x64
from ._excitation import AbstractExcitation, GroundMotion
from ._fidelity import warn_sdof_lift_off
from ._records import Record
from ._response import Response
from .integrators import AbstractIntegrator, Dopri5, EventRestart, from_keywords, RK4
from .models import get_model, IMPACT_RULES

__all__ = ["simulate", "IMPACT_RULES", "DEFAULT_INTEGRATORS"]

#: `simulate`'s integrator for each `method=` of the keyword form: `EventRestart` at
#: rtol 1e-10 by default (and `Dopri5` at the same tolerances)
DEFAULT_INTEGRATORS = {
    "diffrax": EventRestart(),
    "rk4": RK4(),
    "dopri5": Dopri5(rtol=1e-10, atol=1e-12),
}


def simulate(
    structure,
    excitation: AbstractExcitation,
    t1,
    *,
    model="simplified",
    integrator: AbstractIntegrator | None = None,
    ts=None,
    r=None,
    impact: str = "paper",
    fidelity_warning: bool = True,
    **keywords,
) -> Response:
    r"""Integrate Eq. 1 from $t = 0$ to `t1` with impacts at $u = 0$ (Eqs 1–3).

    $(m_e+m_b)\ddot u + k(u) = -(m_e+m_b)\ddot u_g(t)$; at each crossing of $u = 0$ the run
    stops and restarts with $\dot u \leftarrow \sqrt{r}\,\dot u$ (Eq. 2, same sign).

    **Arguments:**

    - `structure`: a `RockingStructure` (SI units).
    - `excitation`: `FreeVibration(u0 [m], v0 [m/s])`, `GroundMotion(dt [s], accel [m/s²],
      scale)`, or a `Record` (e.g. `rockjax.datasets.el_centro()`; scale 1, use
      `GroundMotion.from_record(record, scale=...)` to scale it).
    - `t1`: end time [s], > 0.
    - `ts`: output times [s], increasing, within [0, t1]. Default: the record's samples for a
      ground motion, else 1001 points.
    - `model`: a model of the fidelity ladder: `"simplified"` (default), `"exact"`,
      `"smooth"`, `"housner"` (the SDOF Eq. 1 with that restoring force), or
      `"two_spring_2dof"` (the 2-DOF body on its springs); or an `AbstractRestoringForce`
      (e.g. `rockjax.Smooth(width=0.1)`) or an `AbstractRockingModel` instance (e.g.
      `rockjax.TwoSpring2DOF(damping=...)`), or `"rigid_body"` (the body's own one-DOF
      equation, `rockjax.RigidBody`). Every model runs on every `method`. Which model
      for which scene: `docs/models.md`.
    - `r`: coefficient of restitution in [0, 1] (Eq. 2); default `structure.restitution`
      (Eq. 3).
    - `impact` (SDOF models): `"paper"` (default): an impact at every crossing of $u = 0$,
      as in the paper. `"after_uplift"`: a crossing is an impact only if the structure has
      lifted off ($|u| > u_{crit}$) since the last impact; small oscillations on the springs before
      lift-off then lose no energy, which is more physical.
    - `integrator`: how to integrate, an object of `rockjax.integrators` holding its own
      settings. Default `EventRestart()`: one diffrax solve per mode restarted at every
      event, adaptive steps to rtol 1e-10, atol 1e-12 (`jax.grad` works; `t1` may be
      traced). `RK4(substeps=...)`: the fast path of `rockjax.simulate_batch`, fixed RK4
      steps on the record's samples (`substeps` per interval, default 4; for a free
      vibration steps of `dt`, default min(t1/4000, 10 ms)) with each event located
      inside its step; `jax.grad` and `jax.jacfwd` work. `Dopri5(rtol=..., atol=...)`:
      the same loop with adaptive Dormand–Prince 5(4) steps (`jax.jacfwd` only). Both
      steppers need a concrete `t1`; outputs are computed on their grid and interpolated
      (cubic Hermite) to `ts`. Every model runs on every integrator
      (`benchmarks/results.md` for speed).
    - `**keywords`: the keyword form of earlier versions, still accepted: `method=`
      (`"diffrax"`, `"rk4"`, `"dopri5"`) with `solver`, `rtol`, `atol`, `max_steps`,
      `max_impacts`, `adjoint`, `jump_ts`, `dt`, `substeps`, `max_pieces`: they build the
      integrator (`method="dopri5"` at rtol 1e-10, atol 1e-12); one that contradicts
      `integrator=` raises `ValueError` naming it.
    - `fidelity_warning`: warn (`rockjax.FidelityWarning`) when the paper's SDOF model
      (`"simplified"`, `"exact"`, `"smooth"`, `"housner"`) lifts the structure off by more
      than 3 u_crit under a ground motion, a scene where it over-predicts the rocking
      body (`benchmarks/fidelity.md`; default True; never inside `jit`, `grad`, `vmap`).

    **Returns:** a `Response` (see its docstring). Runtime failures come back as
    `Response.status`, never as NaN: completed, overturned, max_impacts, solver_failure.

    **Example:**

    ```python
    s = rockjax.mcmanus_column()
    res = rockjax.simulate(s, rockjax.FreeVibration(0.10), 4.0)
    res.n_impacts, res.peak_u
    fast = rockjax.simulate(s, rockjax.FreeVibration(0.10), 4.0,
                            integrator=rockjax.integrators.RK4(substeps=2))
    ```
    """
    ensure_x64()
    if isinstance(excitation, Record):  # e.g. rockjax.datasets.el_centro(): scale 1
        excitation = GroundMotion.from_record(excitation)
    check_scene(structure, excitation)
    integrator = from_keywords(integrator, keywords, defaults=DEFAULT_INTEGRATORS,
                               default="diffrax", where="simulate")
    t1f = check_t1(t1)
    ts = _default_ts(excitation, ts, t1f)
    check_ts(ts, t1f)
    check_r(r)
    model = get_model(model, impact)
    check_float64(integrator.method, jnp.result_type(structure.B))
    r = structure.restitution if r is None else r
    structure, excitation = strong(structure), strong(excitation)
    res = Response(**integrator.solve(model, structure, excitation, t1, ts, r))
    warn_sdof_lift_off(model, structure, excitation.forced, res.peak_u, fidelity_warning)
    return res


def _default_ts(excitation, ts, t1f):
    """Output times: the record's samples for a ground motion, else 1001 points."""
    if ts is not None:
        return ts
    if t1f is None:
        raise ValueError("ts must be given when t1 is traced")
    if excitation.forced and not is_traced(excitation.dt):
        rec_dt = float(excitation.dt)
        ts = np.arange(0.0, t1f + 0.5 * rec_dt, rec_dt)
        return ts[ts <= t1f]
    return np.linspace(0.0, t1f, 1001)
