"""Levenberg-Marquardt as an optax transformation.

Least-squares fits of oscillatory decay traces converge in a few Gauss-Newton steps where
first-order optimisers need hundreds. `levenberg_marquardt()` is an
`optax.GradientTransformationExtraArgs`: its `update` takes the gradient $J^T r$ as
`updates`, and the extra arguments `value` (the loss $\\tfrac12\\|r\\|^2$) and `jtj`
($J^T J$). It keeps the damping $\\lambda$ and the last accepted point in its state: a step
that raised the loss is undone and $\\lambda$ grows; an accepted one shrinks it. Any other
optax optimiser (e.g. `optax.adam(1e-2)`) can be used in its place by `fit_decay`.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import optax


class LMState(NamedTuple):
    damping: jax.Array  # lambda, relative to diag(J^T J)
    best_value: jax.Array  # loss at the last accepted point
    best_params: jax.Array  # last accepted point
    best_grad: jax.Array  # J^T r there
    best_jtj: jax.Array  # J^T J there
    started: jax.Array  # False until the first update


def levenberg_marquardt(
    damping: float = 1e-3,
    up: float = 4.0,
    down: float = 3.0,
    max_damping: float = 1e12,
    max_step: float = 1.0,
) -> optax.GradientTransformationExtraArgs:
    r"""Levenberg-Marquardt steps $\delta = -(J^TJ + \lambda\,\mathrm{diag}(J^TJ))^{-1} J^Tr$.

    A point whose loss is higher than the last accepted one is rejected: the next step is
    taken from the accepted point (whose $J^Tr$, $J^TJ$ the state keeps) with a larger
    $\lambda$. **Arguments:** `damping`, the initial $\lambda$; `up` / `down`, its factors
    after a rejected / accepted step; `max_step`, a trust-region radius on the step's
    2-norm (in the unconstrained coordinates: 1.0 changes k_f by at most a factor e). Params
    must be a flat 1-D array.
    """

    def init(params):
        z = jnp.zeros((), params.dtype)
        n = params.shape[0]
        return LMState(z + damping, z + jnp.inf, params, jnp.zeros_like(params),
                       jnp.zeros((n, n), params.dtype), jnp.zeros((), bool))

    def update(updates, state, params=None, *, value=None, jtj=None, **extra):
        del extra
        if params is None or value is None or jtj is None:
            raise ValueError("levenberg_marquardt needs params, value= and jtj=")
        accept = (value <= state.best_value) | ~state.started
        lam = jnp.where(
            state.started,
            jnp.where(accept, state.damping / down, jnp.minimum(state.damping * up, max_damping)),
            state.damping,
        )
        base = jnp.where(accept, params, state.best_params)
        grad = jnp.where(accept, updates, state.best_grad)
        h = jnp.where(accept, jtj, state.best_jtj)
        diag = jnp.diag(h)
        a = h + lam * jnp.diag(jnp.maximum(diag, 1e-12 * jnp.max(diag) + 1e-300))
        step = -jnp.linalg.solve(a, grad)
        step = jnp.where(jnp.all(jnp.isfinite(step)), step, 0.0)
        norm = jnp.sqrt(jnp.sum(step**2))
        step = step * jnp.minimum(1.0, max_step / jnp.maximum(norm, 1e-300))
        new_state = LMState(lam, jnp.where(accept, value, state.best_value), base, grad, h,
                            jnp.ones((), bool))
        return base + step - params, new_state

    return optax.GradientTransformationExtraArgs(init, update)
