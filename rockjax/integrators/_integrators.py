r"""Integrators as objects: each holds its own settings and has one `solve` signature.

- `EventRestart`: one diffrax solve per mode of the model, restarted at every event
  (`_event_restart`); any `diffrax` solver, adaptive or fixed steps, reverse- or
  forward-mode gradients, a traced `t1`.
- `RK4`: the batched stepper with fixed classical Runge–Kutta 4 steps on the record's
  grid, every event located inside its step (`_stepper`); the fast path of batches.
- `Dopri5`: the same loop with adaptive Dormand–Prince 5(4) steps under error control.

`AbstractIntegrator` is abstract, the three integrators final (equinox's pattern): a
caller picks one by building it, e.g. `RK4(substeps=8)` or `EventRestart(rtol=1e-10)`,
and hands it to `rockjax.simulate` or `rockjax.simulate_batch` as `integrator=`.
"""

from __future__ import annotations

import abc
from typing import ClassVar

import diffrax as dfx
import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._checks import default_substeps, is_traced, stepper_grid_step
from .._excitation import as_table
from ._event_restart import RestartConfig, solve as _restart_solve
from ._hermite import resample
from ._stepper import run, StepperConfig

_ADJOINTS = ("reverse", "forward")


def _positive(name, val):
    if not (isinstance(val, (int, float)) and not isinstance(val, bool) and val > 0
            and np.isfinite(val)):
        raise ValueError(f"{name} must be a positive number, got {val!r}")


def _count(name, val, low=1, optional=False):
    if optional and val is None:
        return
    if not (isinstance(val, int) and not isinstance(val, bool) and val >= low):
        raise ValueError(f"{name} must be an integer >= {low}, got {val!r}")


class AbstractIntegrator(eqx.Module):
    """An integrator of rocking models: settings as fields, one `solve`.

    Every integrator runs every model of `rockjax.models`. `method` (a class constant)
    names it in messages and in the keyword form `method="..."`; `batched` says whether it
    advances a whole batch as arrays (the stepper) or one run at a time under `jax.vmap`.
    """

    max_impacts: eqx.AbstractVar[int]
    method: eqx.AbstractClassVar[str]
    batched: eqx.AbstractClassVar[bool]

    @abc.abstractmethod
    def solve(self, model, structure, excitation, t1, ts, r) -> dict:
        """One run of `model` from t = 0 to `t1` [s], outputs on `ts` [s] (the steppers
        also take None: their own grid).

        `structure` is a `RockingStructure`, `excitation` a `FreeVibration` or
        `GroundMotion`, `r` the coefficient of restitution. Returns a dict: `ts`, and u,
        v, theta, uplift on it; impact_times, n_impacts, peak_u, peak_uplift, status,
        t_overturn (the fields of `rockjax.Response`).
        """

    @abc.abstractmethod
    def config(self, model, *, forced: bool, n_steps: int, full: bool):
        """The static settings of the compiled loop for `model` (internal to the batch
        engine): a `RestartConfig` or a `StepperConfig`."""


class EventRestart(AbstractIntegrator):
    r"""The event-restart diffrax integrator: one `diffrax.diffeqsolve` per mode.

    Each segment ends at the first event of the model (located by bisection on the dense
    solution, its time differentiable) or a turning point of $u$; the model's jump is
    applied and the next segment starts, all inside one bounded loop under `jit`.

    **Arguments:**

    - `solver`: a diffrax solver (default `diffrax.Tsit5()`).
    - `rtol`, `atol`: tolerances of the PID step-size controller (default 1e-10, 1e-12).
    - `max_steps`: steps per segment between events (default 16384).
    - `max_impacts`: bound on the number of impacts (status `max_impacts` when reached).
    - `adjoint`: `"reverse"` (default; `jax.grad`) or `"forward"` (`jax.jacfwd`, often
      cheaper for a few parameters), or `diffrax.RecursiveCheckpointAdjoint()` /
      `diffrax.ForwardMode()`.
    - `jump_ts`: tell the step-size controller where a record's samples are (default True).
    - `dt` [s]: fixed steps instead of adaptive ones (`rtol`, `atol` then unused); the
      result is then a smooth function of every parameter, impact times included.
    """

    solver: object = dfx.Tsit5()
    rtol: float = 1e-10
    atol: float = 1e-12
    max_steps: int = 16384
    max_impacts: int = 1024
    adjoint: object = "reverse"
    jump_ts: bool = True
    dt: float | None = None

    method: ClassVar[str] = "diffrax"
    batched: ClassVar[bool] = False

    def __check_init__(self):
        _positive("rtol", self.rtol)
        _positive("atol", self.atol)
        _count("max_steps", self.max_steps)
        _count("max_impacts", self.max_impacts)
        if self.dt is not None:
            _positive("dt", self.dt)
        _adjoint_name(self.adjoint)

    def config(self, model=None, *, forced=True, n_steps=0, full=True):
        return RestartConfig(
            solver=self.solver, rtol=float(self.rtol), atol=float(self.atol),
            max_steps=int(self.max_steps), max_impacts=int(self.max_impacts),
            adjoint=_adjoint_name(self.adjoint), use_jump_ts=bool(self.jump_ts),
            dt=None if self.dt is None else float(self.dt),
        )

    def solve(self, model, structure, excitation, t1, ts, r):
        if ts is None:
            raise ValueError("ts must be given: EventRestart outputs on the times it is given")
        dtype = jnp.result_type(structure.B)
        ts = jnp.asarray(ts, dtype)
        out = _restart_solve(model, structure, excitation, jnp.asarray(t1, dtype), ts,
                             jnp.asarray(r, dtype), self.config())
        return dict(ts=ts, **out)


def _adjoint_name(adjoint) -> str:
    """"reverse" or "forward" from a name or a diffrax adjoint."""
    if isinstance(adjoint, str) and adjoint in _ADJOINTS:
        return adjoint
    if isinstance(adjoint, dfx.ForwardMode):
        return "forward"
    if isinstance(adjoint, dfx.RecursiveCheckpointAdjoint):
        return "reverse"
    raise ValueError(
        "adjoint must be 'reverse' or 'forward' (or diffrax.RecursiveCheckpointAdjoint(), "
        f"diffrax.ForwardMode()), got {adjoint!r}"
    )


def max_pieces_for(model) -> int:
    """RK4's event-located pieces per step for `model`: 32 where a settling body's impacts
    accumulate (Housner's rigid block), else 4 per independent contact (the 2-DOF body's
    two corners: 8)."""
    return 32 if model.impacts_accumulate else 4 * model.contacts


class _AbstractStepper(AbstractIntegrator):
    """The shared part of `RK4` and `Dopri5` (the batched stepper of `_stepper`)."""

    batched: ClassVar[bool] = True
    substeps: eqx.AbstractVar[int | None]
    dt: eqx.AbstractVar[float | None]
    max_pieces: eqx.AbstractVar[int | None]
    grazing_roots: eqx.AbstractVar[bool | None]

    @abc.abstractmethod
    def tolerances(self) -> tuple[float, float]:
        """(rtol, atol) of the error control (unused by fixed steps)."""

    def __check_init__(self):
        for name, val in zip(("rtol", "atol"), self.tolerances()):
            _positive(name, val)
        _count("max_impacts", self.max_impacts)
        _count("substeps", self.substeps, optional=True)
        _count("max_pieces", self.max_pieces, low=2, optional=True)
        if self.dt is not None:
            _positive("dt", self.dt)

    def config(self, model, *, forced, n_steps, full):
        pieces = self.max_pieces
        if pieces is None:
            pieces = max_pieces_for(model) if self.method == "rk4" else 4096
        grazing = (model.recrossing_conditions if self.grazing_roots is None
                   else bool(self.grazing_roots))
        return StepperConfig(
            method=self.method, substeps=default_substeps(self.substeps, not forced,
                                                          self.method),
            n_steps=n_steps, forced=forced, full=full, max_impacts=int(self.max_impacts),
            max_pieces=pieces, rtol=float(self.tolerances()[0]),
            atol=float(self.tolerances()[1]), grazing_roots=grazing,
        )

    def solve(self, model, structure, excitation, t1, ts, r):
        if is_traced(t1):
            raise ValueError(f"t1 must be a concrete number with method {self.method!r}")
        t1f = float(t1)
        dtype = jnp.result_type(structure.B)
        dt_rec, n_steps = _grid(excitation, t1f, self.dt, self.method)
        cfg = self.config(model, forced=excitation.forced, n_steps=n_steps, full=True)
        table = as_table(excitation, dtype, dt=dt_rec, n_min=n_steps + 2)
        out = _run_jit(model, structure, eqx.tree_at(lambda e: e.u0, table, table.u0[None]),
                       jnp.asarray(r, dtype), jnp.asarray(t1f, dtype), cfg)
        out = {k: v[0] for k, v in out.items()}
        out["peak_u"] = model.u_of_peak(structure, out["peak_u"])
        out["peak_uplift"] = model.peak_uplift(structure, out["peak_u"], out["peak_uplift"])
        grid = np.minimum(np.arange(n_steps + 1) * dt_rec, t1f)
        ts_n = np.asarray(ts, float) if ts is not None else grid
        out = resample_outputs(model, grid, out, ts_n,
                               lambda u: model.theta_uplift_of_u(structure, u))
        return dict(ts=jnp.asarray(ts_n, dtype), **out)


class RK4(_AbstractStepper):
    r"""Fixed classical Runge–Kutta 4 steps on the record's samples, events located inside
    each step (cubic Hermite root, then the step redone to it): the fast path of
    `rockjax.simulate_batch`. Reverse- and forward-mode differentiable; needs a concrete
    `t1`. The peak-u error falls about 16x per halving of the step
    (`benchmarks/results.md`).

    **Arguments:**

    - `substeps`: steps per record interval (default 4); for a free vibration, steps per
      `dt` (default 1).
    - `dt` [s]: the grid step of a free vibration (default min(t1 / 4000, 10 ms)); a
      ground motion is integrated on its record's samples.
    - `max_pieces`: event-located pieces per step (default from the model: 4 per
      independent contact, 32 where impacts accumulate, `max_pieces_for`).
    - `max_impacts`: bound on the number of impacts (default 1024).
    - `grazing_roots`: locate a condition that leaves its surface at a jump and crosses
      it again in the same step at that crossing (default: the model's
      `recrossing_conditions`).
    """

    substeps: int | None = None
    dt: float | None = None
    max_pieces: int | None = None
    max_impacts: int = 1024
    grazing_roots: bool | None = None

    method: ClassVar[str] = "rk4"

    def tolerances(self):
        return 1e-8, 1e-10  # fixed steps: no error control (the config's placeholders)


class Dopri5(_AbstractStepper):
    r"""Adaptive Dormand–Prince 5(4) steps under error control (`rtol`, `atol`) inside the
    stepper's loop, events located to the method's order: a full time history at a set
    tolerance. Forward-mode differentiable (`jax.jacfwd`); needs a concrete `t1`.

    **Arguments:**

    - `rtol`, `atol`: tolerances of the error control (default 1e-8, 1e-10).
    - `substeps`: caps the step at the record interval / `substeps` (default 1).
    - `dt` [s], `max_impacts`, `grazing_roots`: as `RK4`.
    - `max_pieces`: steps and pieces per record interval (default 4096).
    """

    rtol: float = 1e-8
    atol: float = 1e-10
    substeps: int | None = None
    dt: float | None = None
    max_pieces: int | None = None
    max_impacts: int = 1024
    grazing_roots: bool | None = None

    method: ClassVar[str] = "dopri5"

    def tolerances(self):
        return self.rtol, self.atol


_run_jit = eqx.filter_jit(run)


def _grid(excitation, t1f, dt, method):
    """(grid step [s], number of steps) of one run on the stepper."""
    if excitation.forced and is_traced(excitation.dt):
        raise ValueError(f"the record's dt must be concrete with method {method!r}")
    return stepper_grid_step(excitation, t1f, dt)


def resample_outputs(model, grid, out, ts, of_u):
    """The stepper's grid outputs at output times `ts` [s] (last axis): u and v by cubic
    Hermite interpolation; theta and uplift from u where the model has them as functions
    of u (`model.kinematics_of_u`; `of_u(u)`), else linearly."""
    if ts.shape == grid.shape and np.array_equal(ts, grid):
        return out
    u, v = resample(grid, out["u"], out["v"], ts)
    if model.kinematics_of_u:
        exact = of_u(u)
    else:
        i = np.clip(np.searchsorted(grid, ts, side="right") - 1, 0, len(grid) - 2)
        w = (ts - grid[i]) / (grid[i + 1] - grid[i])
        exact = tuple(out[k][..., i] * (1 - w) + out[k][..., i + 1] * w
                      for k in ("theta", "uplift"))
    return dict(out, u=u, v=v, theta=exact[0], uplift=exact[1])
