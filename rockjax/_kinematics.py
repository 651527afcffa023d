r"""The uplift mapping $u \to \theta \to$ uplift (paper §4).

The body first rotates about its centreline at the settled base plane (both springs in
contact, Eq. 6: $u = H_e \sin\theta$). Lift-off happens when the lighter spring unloads,
at $\sin\theta_u = \delta_0 / B$, i.e. exactly at $u_{crit}$ of Eq. 11. After lift-off it
rotates about the corner still in contact, which stays at a fixed position (no sliding):

$$u(\theta) = u_{crit} + R_e\left[\sin(\alpha_e - \theta_u) - \sin(\alpha_e - \theta)\right],
\qquad \theta > \theta_u.$$

The lifted corner then rises above the unloaded spring top by
$2(B\sin\theta - \delta_0)$, because the contact spring carries the whole weight (its
compression is $2\delta_0$). These are the kinematics of the rigid body on two springs; the
numerical pushover (`rockjax.pushover`) uses the same contact and no-slip rules.
"""

from __future__ import annotations

import jax.numpy as jnp


def _lift_off_rotation(structure, rigid: bool = False):
    """Exact lift-off rotation $\\theta_u = \\arcsin(\\delta_0/B)$ [rad] (0 if rigid)."""
    if rigid:
        return jnp.zeros_like(structure.B)
    return jnp.arcsin(jnp.clip(structure.delta_0 / structure.B, -1.0, 1.0))


def theta_from_u(structure, u, *, rigid: bool = False):
    r"""Rotation $\theta$ [rad] of the body for a top displacement `u` [m]; odd in `u`.

    Before lift-off $\theta = \arcsin(u/H_e)$ (Eq. 6). After it, the inverse of
    $u = u_{crit} + R_e[\sin(\alpha_e - \theta_u) - \sin(\alpha_e - \theta)]$.
    With `rigid=True` the foundation is rigid ($k_f \to \infty$, Housner's limit): the body
    rotates about a corner from the start, $u = R_e[\sin\alpha_e - \sin(\alpha_e - \theta)]$.

    **Example:** `theta_from_u(rockjax.mcmanus_column(), 0.1)` → 0.0993 rad.
    """
    s = structure
    u = jnp.asarray(u)
    a = jnp.abs(u)
    tu = _lift_off_rotation(s, rigid)
    uc = jnp.zeros_like(s.B) if rigid else s.u_crit
    pre = jnp.arcsin(jnp.clip(jnp.minimum(a, uc) / s.H_e, -1.0, 1.0))
    arg = jnp.sin(s.alpha_e - tu) + (uc - jnp.maximum(a, uc)) / s.R_e
    post = s.alpha_e - jnp.arcsin(jnp.clip(arg, -1.0, 1.0))
    return jnp.sign(u) * jnp.where(a <= uc, pre, post)


def u_from_theta(structure, theta, *, rigid: bool = False):
    r"""Top displacement $u$ [m] for a rotation `theta` [rad]; the inverse of `theta_from_u`."""
    s = structure
    theta = jnp.asarray(theta)
    t = jnp.abs(theta)
    tu = _lift_off_rotation(s, rigid)
    uc = jnp.zeros_like(s.B) if rigid else s.u_crit
    pre = s.H_e * jnp.sin(t)
    post = uc + s.R_e * (jnp.sin(s.alpha_e - tu) - jnp.sin(s.alpha_e - t))
    return jnp.sign(theta) * jnp.where(t <= tu, pre, post)


def uplift_from_theta(structure, theta, *, rigid: bool = False):
    r"""Uplift [m] of the lifted corner above the unloaded spring top.

    $\mathrm{uplift} = 2(B\sin|\theta| - \delta_0)^+$.
    Zero until lift-off. For a rigid foundation ($\delta_0 = 0$) it is $2B\sin|\theta|$.
    """
    s = structure
    d0 = jnp.zeros_like(s.B) if rigid else s.delta_0
    return 2.0 * jnp.maximum(s.B * jnp.sin(jnp.abs(theta)) - d0, 0.0)


def uplift(structure, u, *, rigid: bool = False):
    """Uplift [m] of the lifted corner for a top displacement `u` [m] (paper §4)."""
    return uplift_from_theta(structure, theta_from_u(structure, u, rigid=rigid), rigid=rigid)
