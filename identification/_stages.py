"""The multi-start fit with a growing horizon: the stages of `fit_decay`.

Every start (a row of z) is iterated at once (`jax.vmap`), `CHUNK` optimiser steps per
compiled call (`run_chunk`, one `jax.lax.scan`) between convergence checks. Oscillatory
traces have local minima in phase, so the fit grows its horizon: the first fraction of the
motion after the release (k_f held), then more, then all of it, each stage starting from
the best point of the last (`run_stages`); then, if the fit converged, refits without its
outliers (`identification._outliers`). `best_start` picks the best start and its residuals
and Jacobian on the whole trace. The default optimiser is the one Levenberg-Marquardt
instance `DEFAULT_OPTIMIZER` (its compiled code is reused by every fit). An optimistix
least-squares solver runs each stage with `optimistix.least_squares` instead
(`solve_stage`): the same optimum, at a higher cost (docs/identification.md).
"""

from __future__ import annotations

import dataclasses
import sys
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
import optimistix as optx

from . import _aot
from ._optim import levenberg_marquardt
from ._outliers import check_outliers, gross_spikes
from ._problem import Problem
from ._residuals import compiled, TraceModel
from ._transforms import LINEAR

CHUNK = 4
"""Optimiser steps per compiled call (one `jax.lax.scan`) between convergence checks."""
DEFAULT_OPTIMIZER = levenberg_marquardt()
"""The default optimiser: one instance, so compiled code is reused."""
_aot.name_static(DEFAULT_OPTIMIZER.init, "identification.levenberg_marquardt().init")
_aot.name_static(DEFAULT_OPTIMIZER.update, "identification.levenberg_marquardt().update")


def optimizer_of(optimizer):
    """The optimiser of a fit: the one default instance (its compiled code is reused by
    every fit), an optimistix least-squares solver as it is, or an optax `optimizer` with
    extra-args support."""
    if optimizer is None:
        return DEFAULT_OPTIMIZER
    if is_solver(optimizer):
        return optimizer
    return optax.with_extra_args_support(optimizer)


def is_solver(opt) -> bool:
    """Whether `opt` is an optimistix least-squares solver (`optimistix.least_squares`
    runs each stage), rather than an optax transformation (stepped in chunks)."""
    return isinstance(opt, optx.AbstractLeastSquaresSolver)


@compiled(lambda model, opt, z, opt_state, mask, free:
           jax.tree.structure((z, opt_state, 0, 0, 0)))
def run_chunk(model: TraceModel, opt, z, opt_state, mask, free):
    """`CHUNK` optimiser steps of every start (vmap over the first axis), compiled.

    Returns the new points and states, the loss at each step (starts, CHUNK), and the
    residuals and Jacobian at each step (starts, CHUNK, ...).
    """

    def one(z, opt_state):
        def step(carry, _):
            z, st = carry
            r, J = model.res_jac(z, mask)
            J = J * free  # frozen parameters get a zero column: a zero step
            value = 0.5 * jnp.sum(r**2)
            g = J.T @ r
            upd, st = opt.update(g, st, z, value=value, jtj=J.T @ J)
            return (z + upd, st), (value, r, J)

        (z_new, st), (vals, rs, Js) = jax.lax.scan(step, (z, opt_state), None,
                                                    length=CHUNK)
        return z_new, st, vals, rs, Js

    return jax.vmap(one)(z, opt_state)


@eqx.filter_jit
def init_states(opt, z):
    """The optimiser's state of every start (vmap over the first axis of z), compiled:
    one small program instead of a compile per operation."""
    return jax.vmap(opt.init)(z)


# ----------------------------------------- multi-start run with growing horizon


@compiled(lambda model, solver, z, mask, free, max_steps:
          jax.tree.structure((0, 0, 0, 0)))
def solve_stage(model: TraceModel, solver, z, mask, free, max_steps: int):
    """`optimistix.least_squares` of every start (vmap over the first axis of z) on the
    samples of `mask`, the parameters where `free` is 0 held at their start; compiled.

    Returns the solutions, their losses, the number of steps and whether each converged.
    """

    def one(z0):
        def fn(y, _):
            return model.residuals(jnp.where(free > 0, y, z0), mask)

        sol = optx.least_squares(fn, solver, z0, max_steps=max_steps, throw=False)
        r = sol.state.f_info.residual  # at the solution: no further evaluation of fn
        return (sol.value, 0.5 * jnp.sum(r**2), sol.stats["num_steps"],
                sol.result == optx.RESULTS.successful)

    return jax.vmap(one)(z)


@compiled(lambda model, z, mask: jax.tree.structure((0, 0, 0)))
def evaluate(model: TraceModel, z, mask):
    """The loss, residuals and Jacobian of every start (vmap over the first axis of z)."""

    def one(z):
        r, J = model.res_jac(z, mask)
        return 0.5 * jnp.sum(r**2), r, J

    return jax.vmap(one)(z)


class Progress:
    """A tqdm bar: shown if `progress` is True, or (None) once the fit has taken 3 s and
    stderr is a terminal (no carriage returns in logs)."""

    def __init__(self, progress, total: int):
        self.progress = progress
        self.total = total
        self.bar = None
        self.t_start = time.perf_counter()

    def update(self, n_iter: int, frac: float, best_now: np.ndarray):
        if self.progress is not False and self.bar is None and (
            self.progress
            or (sys.stderr.isatty() and time.perf_counter() - self.t_start > 3.0)
        ):
            from tqdm.auto import tqdm

            self.bar = tqdm(total=self.total, desc="fit_decay", unit="it", leave=False)
            self.bar.update(n_iter)
        elif self.bar is not None:
            self.bar.update(CHUNK)
        if self.bar is not None:
            self.bar.set_postfix(horizon=f"{frac:.2f}", loss=f"{np.nanmin(best_now):.3e}")

    def close(self):
        if self.bar is not None:
            self.bar.close()


@dataclasses.dataclass(eq=False)
class Run:
    """State of the multi-start run, carried from one horizon (stage) to the next."""

    z: object  # (starts, P) current points
    opt_state: object
    lm: bool  # the default optimiser: its state keeps the best point of each start
    keep: np.ndarray  # samples in the fit (False: outliers)
    converged: np.ndarray  # (starts,) converged on the last stage
    history: list = dataclasses.field(default_factory=list)  # losses on the last horizon
    vals: np.ndarray | None = None  # losses of the last chunk (starts, CHUNK)
    n_iter: int = 0
    n_refits: int = 0
    tracked: dict | None = None  # the LM's best point of the last stage: loss, r, J, mask

    def best_params(self):
        return self.opt_state.best_params if self.lm else self.z


def run_horizon(problem: Problem, model: TraceModel, opt, run: Run, stage: int, frac: float,
                 progress: Progress):
    """Iterate every start on the first `frac` of the trace until all of them stall (no
    relative improvement of the best loss over two chunks) or `max_iter` iterations."""
    params, horizons = problem.params, problem.horizons
    mask = jnp.asarray(problem.within(frac) & run.keep, dtype=float)
    # On the first (short) horizon k_f and r are nearly collinear (the early cycles
    # depend on r, the phase and u0); k_f is held there and freed afterwards. Without r
    # (continuous contact) the first bounces on the springs pin k_f: it is free throughout.
    freeze_kf = (stage == 0 and len(horizons) > 1 and "k_f" in params and len(params) > 1
                 and "r" in problem.fit_model.acting)
    # The sensor's offsets and drift are held (at their start, 0) on the first horizon too:
    # free there, they trade with the phase and the decay while k_f is held, and a wrong
    # start (spikes) can end in another minimum. They are freed with k_f.
    first = stage == 0 and len(horizons) > 1
    # A problem may hold more on the first horizon (a shake-table run: t0, which the quiet
    # start of a record does not inform)
    held = getattr(problem, "hold_first", ()) if first else ()
    free = jnp.asarray([0.0 if ((p == "k_f" and freeze_kf) or (p in LINEAR and first)
                                or p.split("[")[0] in held) else 1.0 for p in params])
    if is_solver(opt):
        _solve_horizon(problem, model, opt, run, frac, mask, free, progress)
        return
    best_prev = np.full(problem.starts, np.inf)
    stall = np.zeros(problem.starts, int)
    stage_iter = 0
    while stage_iter < problem.max_iter:
        run.z, run.opt_state, vals, rs, Js = run_chunk(model, opt, run.z, run.opt_state,
                                                        mask, free)
        vals = np.asarray(vals)  # (starts, chunk)
        if run.lm and frac == horizons[-1]:
            track_best(run, vals, rs, Js, np.asarray(mask) > 0, first=stage_iter == 0)
        run.vals = vals
        run.n_iter += CHUNK
        stage_iter += CHUNK
        if frac == horizons[-1]:
            run.history.append(vals)
        # converged: no relative improvement of the best loss over two chunks
        finite = np.where(np.isfinite(vals), vals, np.inf)
        best_now = np.minimum(best_prev, np.min(finite, 1))
        improved = best_now < best_prev * (1 - problem.tol) - 1e-300
        stall = np.where(improved, 0, stall + 1)
        best_prev = best_now
        run.converged = stall >= 2
        progress.update(run.n_iter, frac, best_now)
        if np.all(run.converged):
            break


def _solve_horizon(problem: Problem, model: TraceModel, solver, run: Run, frac: float,
                   mask, free, progress: Progress):
    """One stage with an optimistix solver: `optimistix.least_squares` of every start to
    its own termination (or `max_iter` steps)."""
    run.z, vals, steps, ok = solve_stage(model, solver, run.z, mask, free, problem.max_iter)
    vals = np.asarray(vals)[:, None]  # (starts, 1)
    run.vals = vals
    run.n_iter += int(np.max(np.asarray(steps)))
    if frac == problem.horizons[-1]:
        run.history.append(vals)
    run.converged = np.asarray(ok) & np.isfinite(vals[:, 0])
    progress.update(run.n_iter, frac, np.where(np.isfinite(vals[:, 0]), vals[:, 0], np.inf))


def track_best(run: Run, vals, rs, Js, mask: np.ndarray, first: bool):
    """Follow the Levenberg-Marquardt state's accepted point through a chunk (the same
    test: a loss at or below the last accepted one, or the stage's first point), keeping
    its residuals and Jacobian: `best_start` needs them, and would otherwise evaluate
    them again (a chunk)."""
    t = run.tracked
    if first or t is None:
        t = run.tracked = {"value": np.full(vals.shape[0], np.inf), "r": None, "J": None,
                           "started": np.zeros(vals.shape[0], bool), "mask": mask}
    rs, Js = np.asarray(rs), np.asarray(Js)
    if t["r"] is None:
        t["r"], t["J"] = rs[:, 0].copy(), Js[:, 0].copy()
    for c in range(vals.shape[1]):
        acc = (vals[:, c] <= t["value"]) | ~t["started"]
        t["value"] = np.where(acc, vals[:, c], t["value"])
        t["r"][acc], t["J"][acc] = rs[acc, c], Js[acc, c]
        t["started"][:] = True


def run_stages(problem: Problem, model: TraceModel, opt, z_start, lm: bool,
               outliers: bool = True) -> Run:
    """The multi-start fit: each horizon in turn, then (`outliers`) refits of the whole
    trace without its outliers (if any)."""
    z = jnp.asarray(z_start)
    state = None if is_solver(opt) else init_states(opt, z)
    keep = problem.samples()
    if outliers:  # gross spikes are left out from the start (`_outliers.gross_spikes`)
        keep = keep & ~gross_spikes(problem)
    run = Run(z=z, opt_state=state, lm=lm, keep=keep,
              converged=np.zeros(problem.starts, bool))
    progress = Progress(problem.progress, problem.max_iter * len(problem.horizons))
    # Growing horizon: fit the first quarter of the trace, then half, then all of it. Early
    # cycles fix r and the phase; later ones refine k_f. Masks keep every shape, so nothing
    # recompiles between stages.
    plan = list(problem.horizons)  # the outlier check appends refits of the whole trace
    for stage, frac in enumerate(plan):
        if stage > 0:
            run.z = run.best_params()
            run.opt_state = None if is_solver(opt) else init_states(opt, run.z)
        run_horizon(problem, model, opt, run, stage, frac, progress)
        if stage == len(plan) - 1 and outliers and check_outliers(problem, model, run):
            plan.append(problem.horizons[-1])
    progress.close()
    return run


def _evaluate(problem: Problem, model: TraceModel, opt, run: Run, z):
    """(losses, residuals, Jacobians) of every start at `z` on the whole trace (outliers,
    if any, left out): `evaluate`, or with an optax optimiser one chunk from there (a
    program already compiled)."""
    full = jnp.asarray(run.keep, dtype=float)
    if is_solver(opt):
        vals, r, J = evaluate(model, jnp.asarray(z), full)
        return np.asarray(vals), r, J
    _, _, vals, r, J = run_chunk(model, opt, z, init_states(opt, z), full,
                                 jnp.ones(len(problem.params)))
    return np.asarray(vals)[:, 0], np.asarray(r)[:, 0], np.asarray(J)[:, 0]


@dataclasses.dataclass(frozen=True, eq=False)
class Best:
    """The best start, evaluated on the whole trace (outliers left out)."""

    index: int  # of the start
    z: np.ndarray
    r: np.ndarray  # residuals
    J: np.ndarray  # their Jacobian d r / d z
    loss: float
    start_losses: np.ndarray  # final loss of every start
    history: np.ndarray  # its loss at each iteration on the last horizon


def best_start(problem: Problem, model: TraceModel, opt, run: Run) -> Best:
    # best point of every start, and r, J there: those the LM's last stage evaluated there
    # (on the same samples), else one more chunk evaluates them
    z_best = run.best_params()
    t = run.tracked
    if (run.lm and t is not None and np.array_equal(t["mask"], run.keep)
            and np.array_equal(t["value"], np.asarray(run.opt_state.best_value))):
        final_losses, r_b, J_b = t["value"], t["r"], t["J"]
    else:
        final_losses, r_b, J_b = _evaluate(problem, model, opt, run, z_best)
    i_best = int(np.nanargmin(np.where(np.isfinite(final_losses), final_losses, np.inf)))
    return Best(
        index=i_best,
        z=np.asarray(z_best)[i_best],
        r=np.asarray(r_b)[i_best],
        J=np.asarray(J_b)[i_best],
        loss=float(final_losses[i_best]),
        start_losses=final_losses,
        history=np.concatenate(run.history, axis=1)[i_best],
    )


# ------------------------------------------------------------------ uncertainty
