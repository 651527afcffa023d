r"""Closed-form restoring forces $k(u)$ of the SDOF Eq. 1 (paper §3.3, Eqs 13–20).

Each law is an equinox Module: abstract `AbstractRestoringForce`, final `Simplified`,
`Exact`, `Smooth` and `Housner`. All are odd in $u$, vectorised over $u$ and
differentiable with respect to $u$ and every structure field. A law is only $k(u)$; the
SDOF rocking model (`rockjax.models.SDOF`) adds the impact rule and the events.
"""

from __future__ import annotations

import abc
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .._kinematics import theta_from_u
from .._pushover import pushover


def _is_traced(x):
    return isinstance(x, jax.core.Tracer)


def _rocking_force(structure, theta):
    r"""Eq. 18: $P = W \frac{R_c \sin(\alpha_c - \theta)}{R_e \cos(\alpha_e - \theta)}$ [N]."""
    s = structure
    return s.W * s.R_c * jnp.sin(s.alpha_c - theta) / (s.R_e * jnp.cos(s.alpha_e - theta))


def _simplified_post(structure, a):
    r"""Eq. 20 on $a = |u|$: $P_{crit2}(a - u_{ot})/(u_{crit} - u_{ot})$ [N]."""
    s = structure
    return (a - s.u_overturn) * (s.P_crit2 / (s.u_crit - s.u_overturn))


class AbstractRestoringForce(eqx.Module):
    """A restoring-force law $k(u)$ [N] of the SDOF equation of motion (Eq. 1).

    `rigid` (class variable) is True for a rigid interface, which has no pre-uplift phase.
    """

    rigid: ClassVar[bool] = False

    @abc.abstractmethod
    def __call__(self, structure, u):
        """The restoring force [N] at top displacement `u` [m] (any shape)."""

    def branch(self, structure, u, sign, lifted):
        """k(u) [N] on one smooth branch, continued smoothly past the branch's ends.

        The branch is the side `sign` (+1 or -1) of $u = 0$ and before (`lifted` False) or
        after lift-off. The integrators stop at every lift-off, landing and impact, so no
        step straddles a kink or the jump at $u_{crit}$, and trial steps that overshoot an
        event see a smooth force. Default: `self(structure, u)` (a law smooth everywhere).
        """
        return self(structure, u)


class Simplified(AbstractRestoringForce):
    r"""The paper's piecewise-linear $k(u)$: Eq. 13 before lift-off, Eq. 20 after.

    $$k(u) = K_1 u \quad (|u| \le u_{crit}), \qquad
    k(u) = \operatorname{sign}(u)\, P_{crit2}\frac{|u| - u_{overturn}}{u_{crit} - u_{overturn}}
    \quad (|u| > u_{crit}).$$

    There is a small jump at $u_{crit}$ from $P_{crit}$ (Eq. 14) to $P_{crit2}$ (Eq. 19).
    Past $u_{overturn}$ the force is negative: the structure overturns.
    """

    def branch(self, structure, u, sign, lifted):
        post = sign * _simplified_post(structure, sign * u)
        return jnp.where(lifted, post, structure.K1 * u)

    def __call__(self, structure, u):
        u = jnp.asarray(u)
        sign = jnp.where(u < 0, -1.0, 1.0)
        return self.branch(structure, u, sign, jnp.abs(u) > structure.u_crit)


class Exact(AbstractRestoringForce):
    r"""Eq. 13 before lift-off, the trigonometric Eq. 18 after it.

    After lift-off $k(u) = \operatorname{sign}(u)\, W \frac{R_c\sin(\alpha_c - \theta)}
    {R_e\cos(\alpha_e - \theta)}$ with $\theta = \theta(|u|)$ from the exact uplift mapping
    (`rockjax.theta_from_u`). Use it for large rotations and near overturning.
    """

    def branch(self, structure, u, sign, lifted):
        s = structure
        # the after-lift-off mapping theta(u), continued below u_crit
        tu = jnp.arcsin(jnp.clip(s.delta_0 / s.B, -1.0, 1.0))
        arg = jnp.sin(s.alpha_e - tu) + (s.u_crit - sign * u) / s.R_e
        theta = s.alpha_e - jnp.arcsin(jnp.clip(arg, -1.0, 1.0))
        return jnp.where(lifted, sign * _rocking_force(s, theta), s.K1 * u)

    def __call__(self, structure, u):
        u = jnp.asarray(u)
        sign = jnp.where(u < 0, -1.0, 1.0)
        return self.branch(structure, u, sign, jnp.abs(u) > structure.u_crit)


def _smootherstep(t):
    """$6t^5 - 15t^4 + 10t^3$ on [0, 1], clipped: C2 (zero first and second derivatives)."""
    t = jnp.clip(t, 0.0, 1.0)
    return t**3 * (t * (6.0 * t - 15.0) + 10.0)


class Smooth(AbstractRestoringForce):
    r"""A C2 blend of `Simplified` across lift-off, for gradient-based identification.

    With $w$ = `width` $\times\, u_{crit}$ and $s(a)$ the quintic smoothstep rising from 0 at
    $a = u_{crit} - w$ to 1 at $a = u_{crit} + w$,

    $$k(u) = (1 - s)\,K_1 u + s\,\operatorname{sign}(u)\,P_{crit2}
    \frac{|u| - u_{overturn}}{u_{crit} - u_{overturn}}.$$

    Outside the window it equals `Simplified` exactly, and it converges to it as
    `width` → 0. **Arguments:** `width`, the half-width of the window as a fraction of
    $u_{crit}$ (dimensionless, in (0, 1); default 0.2).
    """

    width: float | jnp.ndarray = 0.2

    def __check_init__(self):
        w = self.width
        if not _is_traced(w):
            wa = np.asarray(w, dtype=float)
            if not np.all((wa > 0.0) & (wa < 1.0)):
                raise ValueError(f"width must be in (0, 1) (a fraction of u_crit), got {wa}")

    def __call__(self, structure, u):
        s = structure
        u = jnp.asarray(u)
        a = jnp.abs(u)
        w = self.width * s.u_crit
        blend = _smootherstep((a - (s.u_crit - w)) / (2.0 * w))
        post = jnp.sign(u) * _simplified_post(s, a)
        return (1.0 - blend) * s.K1 * u + blend * post


class Housner(AbstractRestoringForce):
    r"""The rigid-interface limit $k_f \to \infty$: rocking about the corners only.

    $k(u) = \operatorname{sign}(u)\, W \frac{R_c\sin(\alpha_c - \theta)}{R_e\cos(\alpha_e -
    \theta)}$ with $u = R_e[\sin\alpha_e - \sin(\alpha_e - \theta)]$. The force jumps from
    $-WB/H_e$ to $+WB/H_e$ at $u = 0$. This is the limit of `Exact` within the paper's SDOF
    reduction (inertia $m_e + m_b$), not Housner's rotational equation of motion.
    """

    rigid: ClassVar[bool] = True

    def __call__(self, structure, u):
        s = structure
        u = jnp.asarray(u)
        theta = theta_from_u(s, jnp.abs(u), rigid=True)
        return jnp.sign(u) * _rocking_force(s, theta)

    def branch(self, structure, u, sign, lifted):
        s = structure
        # u = R_e [sin(alpha_e) - sin(alpha_e - theta)] on the side `sign`, continued past 0
        theta = s.alpha_e - jnp.arcsin(jnp.clip(jnp.sin(s.alpha_e) - sign * u / s.R_e, -1.0, 1.0))
        return sign * _rocking_force(s, theta)


def restoring_force(structure, u, model="simplified"):
    r"""The restoring force $k(u)$ [N] of Eq. 1 at top displacement `u` [m].

    **Arguments:**

    - `structure`: a `rockjax.RockingStructure`.
    - `u`: top displacement [m], any shape (vectorised).
    - `model`: `"simplified"` (Eqs 13, 20; default), `"exact"` (Eqs 13, 18), `"smooth"`
      (C2 blend of simplified, `rockjax.Smooth(width=...)` to set the width) or
      `"housner"` (rigid limit), `"two_spring_2dof"` or `"rigid_body"` (the body's
      pushover, `rockjax.pushover`), or an `AbstractRestoringForce` instance.

    **Returns:** the force [N], same shape as `u`, odd in `u`.

    **Example:**

    ```python
    s = rockjax.mcmanus_column()
    rockjax.restoring_force(s, jnp.linspace(0, 0.3, 5), model="exact")
    ```
    """
    if isinstance(model, str) and model in ("two_spring_2dof", "rigid_body"):
        # the body models' static force is the body's pushover
        return pushover(structure, u).P
    if isinstance(model, str):
        if model not in LAWS:
            raise ValueError(
                f"model must be one of {', '.join(repr(m) for m in LAWS)} or an "
                f"AbstractRestoringForce instance, got {model!r}"
            )
        model = LAWS[model]()
    if not isinstance(model, AbstractRestoringForce):
        raise ValueError(
            f"model must be one of {', '.join(repr(m) for m in LAWS)}, 'two_spring_2dof', "
            f"'rigid_body' or an AbstractRestoringForce instance, got {model!r}"
        )
    return model(structure, u)


LAWS = {"simplified": Simplified, "exact": Exact, "smooth": Smooth, "housner": Housner}
