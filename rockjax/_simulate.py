r"""`rockjax.simulate`: one run of a rocking model, checked, then handed to an integrator.

$$(m_e + m_b)\,\ddot u + k(u) = -(m_e + m_b)\,\ddot u_g(t) \qquad \text{(Eq. 1)}$$

The model (`rockjax.models`) gives the physics; the integrator (`rockjax.integrators`)
the time stepping: `method="diffrax"` restarts a diffrax solve at every event, `"rk4"`
and `"dopri5"` run the batched stepper with events located inside its steps.
"""

from __future__ import annotations

import diffrax as dfx
import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ._checks import (
    check_float64,
    check_r,
    check_scene,
    check_settings,
    check_t1,
    check_ts,
    default_substeps,
    is_traced,
    stepper_grid_step,
    strong,
)
from ._config import ensure_x64
from ._excitation import AbstractExcitation, GroundMotion
from ._fidelity import warn_sdof_lift_off
from ._records import Record
from ._response import Response
from .integrators import resample, RestartConfig, run, solve, StepperConfig
from .models import get_model, IMPACT_RULES

__all__ = ["simulate", "IMPACT_RULES"]


def simulate(
    structure,
    excitation: AbstractExcitation,
    t1,
    *,
    ts=None,
    model="simplified",
    r=None,
    impact: str = "paper",
    solver=None,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_steps: int = 16384,
    max_impacts: int = 1024,
    adjoint: str = "reverse",
    jump_ts: bool = True,
    dt: float | None = None,
    method: str = "diffrax",
    substeps: int | None = None,
    fidelity_warning: bool = True,
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
    - `solver`: a diffrax solver (default `diffrax.Tsit5()`); `rtol`, `atol`: tolerances of
      the PID step-size controller; `max_steps`: steps per segment between impacts;
      `max_impacts`: bound on the number of impacts (status `max_impacts` when reached).
    - `adjoint`: `"reverse"` (default; `jax.grad` works) or `"forward"` (`jax.jacfwd` with
      `diffrax.ForwardMode`, often cheaper for a few parameters).
    - `jump_ts`: tell the step-size controller where a record's samples are (default True).
    - `dt`: a fixed step [s] instead of adaptive steps (`rtol`, `atol` then unused). The
      result is then a smooth function of every parameter, impact times included.
    - `method`: `"diffrax"` (default): the event-restart diffrax solve described above.
      `"rk4"`: the fast path of `rockjax.simulate_batch`, fixed RK4 steps on the record's
      samples (`substeps` per interval, default 4; for a free vibration, `substeps`, default
      1, steps per `dt`, default min(t1/4000, 10 ms)) with each event located inside its step;
      `jax.grad` and `jax.jacfwd` work.
      `"dopri5"`: the same loop with adaptive Dormand–Prince 5(4) steps to `rtol`, `atol`
      (forward-mode `jax.jacfwd` only). Both need a concrete `t1`; outputs are computed on
      the grid and interpolated (cubic Hermite) to `ts`. Much faster for a full record
      (see `benchmarks/results.md`); `solver`, `max_steps`, `adjoint` and `jump_ts` apply
      to `"diffrax"` only.
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
    ```
    """
    ensure_x64()
    if isinstance(excitation, Record):  # e.g. rockjax.datasets.el_centro(): scale 1
        excitation = GroundMotion.from_record(excitation)
    check_scene(structure, excitation)
    if adjoint not in ("reverse", "forward"):
        raise ValueError(f"adjoint must be 'reverse' or 'forward', got {adjoint!r}")
    t1f = check_t1(t1)
    ts = _default_ts(excitation, ts, t1f)
    check_ts(ts, t1f)
    check_r(r)
    check_settings(method=method, rtol=rtol, atol=atol, max_impacts=max_impacts, dt=dt,
                   substeps=substeps, max_steps=max_steps)
    model = get_model(model, impact)
    check_float64(method, jnp.result_type(structure.B))
    r = structure.restitution if r is None else r
    structure, excitation = strong(structure), strong(excitation)
    if method == "diffrax":
        cfg = RestartConfig(
            solver=dfx.Tsit5() if solver is None else solver, rtol=float(rtol),
            atol=float(atol), max_steps=int(max_steps), max_impacts=int(max_impacts),
            adjoint=adjoint, use_jump_ts=bool(jump_ts), dt=None if dt is None else float(dt),
        )
        dtype = jnp.result_type(structure.B)
        ts = jnp.asarray(ts, dtype)
        out = solve(model, structure, excitation, jnp.asarray(t1, dtype), ts,
                    jnp.asarray(r, dtype), cfg)
        res = Response(ts=ts, **out)
    else:
        res = _simulate_stepper(structure, excitation, t1f, ts, r, model, method=method,
                                substeps=substeps, dt=dt, rtol=rtol, atol=atol,
                                max_impacts=max_impacts)
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


_run_jit = eqx.filter_jit(run)


def stepper_grid(excitation, t1f, dt, method, dtype):
    """(grid step [s], number of steps, padded record table (1, n) [m/s²], scale), in
    `dtype`."""
    if excitation.forced and is_traced(excitation.dt):
        raise ValueError(f"the record's dt must be concrete with method {method!r}")
    dt_rec, n_steps = stepper_grid_step(excitation, t1f, dt)
    if not excitation.forced:
        return dt_rec, n_steps, jnp.zeros((1, 2), dtype), jnp.ones((), dtype)
    acc = jnp.asarray(excitation.accel, dtype)
    pad = max(0, n_steps + 2 - acc.shape[-1])
    table = jnp.concatenate([acc, jnp.zeros((pad,), dtype)])[None]
    return dt_rec, n_steps, table, excitation.scale


def _simulate_stepper(structure, excitation, t1f, ts, r, model, *, method, substeps, dt,
                      rtol, atol, max_impacts):
    """One run on the batched stepper (a batch of one), outputs resampled to ts."""
    if t1f is None:
        raise ValueError(f"t1 must be a concrete number with method {method!r}")
    dtype = jnp.result_type(structure.B)
    dt_rec, n_steps, table, scale = stepper_grid(excitation, t1f, dt, method, dtype)
    cfg = StepperConfig(
        method=method, substeps=default_substeps(substeps, not excitation.forced, method),
        n_steps=n_steps, forced=excitation.forced, full=True, max_impacts=max_impacts,
        max_pieces=model.default_max_pieces() if method == "rk4" else 4096,
        rtol=float(rtol), atol=float(atol),
    )
    u0, v0 = excitation.initial_state()
    # zero forcing right after the record's last sample, as GroundMotion defines it
    lengths = (jnp.asarray([excitation.accel.shape[-1]], jnp.int32) if excitation.forced
               else None)
    out = _run_jit(model, structure, table, jnp.zeros((1,), jnp.int32),
                   jnp.asarray(dt_rec, dtype), jnp.asarray(scale, dtype),
                   jnp.reshape(jnp.asarray(u0, dtype), (1,)),
                   jnp.reshape(jnp.asarray(v0, dtype), (1,)), jnp.asarray(r, dtype),
                   jnp.asarray(t1f, dtype), cfg, lengths)
    out = {k: v[0] for k, v in out.items()}
    out["peak_uplift"] = model.peak_uplift(structure, out["peak_u"], out["peak_uplift"])
    grid = np.minimum(np.arange(n_steps + 1) * dt_rec, t1f)
    ts_n = np.asarray(ts, float) if ts is not None else grid
    out = resample_outputs(grid, out, ts_n, lambda u: model.theta_uplift_of_u(structure, u))
    return Response(ts=jnp.asarray(ts_n, dtype), **out)


def resample_outputs(grid, out, ts, of_u):
    """The stepper's grid outputs at output times `ts` [s] (last axis): u and v by cubic
    Hermite interpolation; theta and uplift from u where the model has them as functions
    of u (`of_u(u)` is not None), else linearly."""
    if ts.shape == grid.shape and np.array_equal(ts, grid):
        return out
    u, v = resample(grid, out["u"], out["v"], ts)
    exact = of_u(u)
    if exact is None:
        i = np.clip(np.searchsorted(grid, ts, side="right") - 1, 0, len(grid) - 2)
        w = (ts - grid[i]) / (grid[i + 1] - grid[i])
        exact = tuple(out[k][..., i] * (1 - w) + out[k][..., i + 1] * w
                      for k in ("theta", "uplift"))
    return dict(out, u=u, v=v, theta=exact[0], uplift=exact[1])
