r"""Numerical pushover of the actual rigid body on two compression-only springs (Fig. 8).

For each top displacement $u$ the static equilibrium of the rigid body is solved with
optimistix (Newton), geometrically exactly and independently of the closed forms:

- the body is rigid, with base centre at $(x_o, y_o)$ and clockwise rotation $\theta$;
  a body point $(b_x, b_y)$ sits at $(x_o + b_x\cos\theta + b_y\sin\theta,\;
  y_o - b_x\sin\theta + b_y\cos\theta)$;
- each spring is vertical and compression-only, $f_i = k_f \max(0, -y_i)$, with $y_i$ the
  height of the corner $(\pm B, 0)$ above the unloaded spring top;
- horizontal restraint (no sliding): while both springs are in contact the base centre is
  held horizontally ($x_o = 0$; rotation about the centreline); after lift-off the corner in
  contact keeps the horizontal position it had at lift-off;
- the lateral load $P$ acts horizontally at the effective mass, the weights $m_e g$ and
  $m_b g$ at the two mass centroids.

Unknowns $(y_o, \theta, P)$; equations: vertical force balance, moment balance about the
horizontal restraint point (so that the unknown friction force drops out), and the
displacement control $x_{top} = u$.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, Float

from ._config import ensure_x64
from ._errors import ParameterError


class PushoverResult(eqx.Module):
    """Result of `rockjax.pushover`, each field with the shape of `u`.

    - `u`: top displacement [m]; `P`: lateral force [N]; `theta`: rotation [rad];
    - `uplift`: uplift of the lifted corner above the unloaded spring top [m];
    - `f_left`, `f_right`: spring forces at $x = -B$ and $x = +B$ [N];
    - `converged`: whether Newton converged.
    """

    u: Float[Array, "..."]
    P: Float[Array, "..."]
    theta: Float[Array, "..."]
    uplift: Float[Array, "..."]
    f_left: Float[Array, "..."]
    f_right: Float[Array, "..."]
    converged: Array


def _body_point(x_o, y_o, theta, bx, by):
    c, s = jnp.cos(theta), jnp.sin(theta)
    return x_o + bx * c + by * s, y_o - bx * s + by * c


def _spring_forces(s, y_o, theta):
    _, y_left = _body_point(0.0, y_o, theta, -s.B, 0.0)
    _, y_right = _body_point(0.0, y_o, theta, s.B, 0.0)
    return s.k_f * jnp.maximum(-y_left, 0.0), s.k_f * jnp.maximum(-y_right, 0.0), y_left


def lift_off_rotation(s):
    """Solve for the rotation at which the left spring unloads (both springs in contact)."""

    def fn(z, _):
        y_o, theta = z
        _, y_left = _body_point(0.0, y_o, theta, -s.B, 0.0)
        _, y_right = _body_point(0.0, y_o, theta, s.B, 0.0)
        # Linear springs (contact assumed), vertical balance and zero left compression.
        return jnp.stack([s.k_f * (-y_left - y_right) - s.W, -y_left])

    z0 = jnp.stack([-s.delta_0, jnp.zeros_like(s.B)])
    sol = optx.root_find(fn, optx.Newton(rtol=1e-13, atol=1e-15), z0, max_steps=32, throw=False)
    return sol.value[1]


def _equilibrium(s, a, theta_lift):
    """Solve the statics at top displacement a >= 0; returns (y_o, theta, P), success."""

    def x_base(theta):
        lifted = theta > theta_lift
        return jnp.where(lifted, s.B * (jnp.cos(theta_lift) - jnp.cos(theta)), 0.0)

    def fn(z, _):
        # Dimensionless unknowns (y_o / B, theta, P / W), so that one tolerance fits all.
        y_o, theta, P = z[0] * s.B, z[1], z[2] * s.W
        x_o = x_base(theta)
        f_left, f_right, _ = _spring_forces(s, y_o, theta)
        xl, yl = _body_point(x_o, y_o, theta, -s.B, 0.0)
        xr, yr = _body_point(x_o, y_o, theta, s.B, 0.0)
        xe, ye = _body_point(x_o, y_o, theta, 0.0, s.H_e)
        xb, _ = _body_point(x_o, y_o, theta, 0.0, s.H_b)
        lifted = theta > theta_lift
        px = jnp.where(lifted, xr, x_o)
        py = jnp.where(lifted, yr, y_o)
        # z-moment about the restraint point of all forces except the restraint's own
        moment = (
            (xl - px) * f_left
            + (xr - px) * f_right
            - (xe - px) * s.m_e * s.g
            - (xb - px) * s.m_b * s.g
            - (ye - py) * P
        )
        return jnp.stack([(f_left + f_right - s.W) / s.W, moment / (s.W * s.B), (xe - a) / s.H_e])

    z0 = jnp.stack([-s.delta_0 / s.B, jnp.arcsin(jnp.clip(a / s.R_e, 0.0, 1.0)), jnp.zeros_like(a)])
    sol = optx.root_find(fn, optx.Newton(rtol=1e-12, atol=1e-12), z0, max_steps=64, throw=False)
    z = sol.value
    return (z[0] * s.B, z[1], z[2] * s.W), sol.result == optx.RESULTS.successful


@eqx.filter_jit
def _pushover(structure, u):
    s = structure
    theta_lift = lift_off_rotation(s)

    def one(ui):
        a = jnp.abs(ui)
        (y_o, theta, P), ok = _equilibrium(s, a, theta_lift)
        f_left, f_right, y_left = _spring_forces(s, y_o, theta)
        sign = jnp.where(ui < 0, -1.0, 1.0)
        # Mirror for negative u: P and theta odd, spring forces swap.
        fl = jnp.where(ui < 0, f_right, f_left)
        fr = jnp.where(ui < 0, f_left, f_right)
        return sign * P, sign * theta, jnp.maximum(y_left, 0.0), fl, fr, ok

    flat = jnp.ravel(u)
    P, theta, up, fl, fr, ok = jax.vmap(one)(flat)
    shape = jnp.shape(u)
    r = lambda x: jnp.reshape(x, shape)  # noqa: E731
    return PushoverResult(u, r(P), r(theta), r(up), r(fl), r(fr), r(ok))


def pushover(structure, u) -> PushoverResult:
    r"""Numerical pushover of the rigid body on two compression-only springs.

    Solves, for each top displacement `u` [m], the geometrically exact static equilibrium
    (vertical force balance, moment balance, no sliding at the spring in contact) with
    optimistix's Newton solver. This is the "complicated pushover analysis" the paper's
    closed forms (Eqs 13–20) were checked against (Fig. 8), for any structure.

    **Arguments:** `structure`, a `RockingStructure`; `u`, top displacements [m] (any shape).

    **Returns:** a `PushoverResult` with `P` [N], `theta` [rad], `uplift` [m], `f_left`,
    `f_right` [N] and `converged`.

    **Example:**

    ```python
    s = rockjax.mcmanus_column()
    res = rockjax.pushover(s, jnp.linspace(0.0, 0.3, 200))
    ```
    """
    ensure_x64()
    if not isinstance(u, jax.core.Tracer):
        ua = np.asarray(u, dtype=float)
        if not np.all(np.isfinite(ua)):
            raise ParameterError(f"u must be finite, got {ua}", param="u")
        reach = np.asarray(structure.R_e * (1.0 + jnp.sin(structure.alpha_e)))
        if np.any(np.abs(ua) >= reach):
            raise ParameterError(
                f"u must be smaller than the body's reach R_e (1 + sin alpha_e) = "
                f"{float(np.max(reach)):.6g} m (the rigid body cannot move its top further), "
                f"got |u| up to {float(np.max(np.abs(ua))):.6g} m", param="u"
            )
    u = jnp.asarray(u, dtype=jnp.result_type(structure.B))
    return _pushover(structure, u)


def overturn_displacement(structure):
    r"""The displacement [m] where the numerical pushover force returns to zero.

    Found by bisection on $P(u) = 0$ between $u_{crit}$ and $R_e$; compare with the closed
    form `structure.u_overturn`.
    """
    s = structure
    theta_lift = lift_off_rotation(s)

    def fn(a, _):
        (_, _, P), _ = _equilibrium(s, a, theta_lift)
        return P / s.W

    solver = optx.Bisection(rtol=1e-13, atol=1e-14)
    sol = optx.root_find(
        fn,
        solver,
        0.5 * (s.u_crit + s.R_e),
        options=dict(lower=1.01 * s.u_crit, upper=0.999 * s.R_e),
        max_steps=200,
        throw=False,
    )
    return sol.value
