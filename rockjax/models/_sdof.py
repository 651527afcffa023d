r"""The paper's SDOF rocking model: Eq. 1 with a restoring-force law and an impact rule.

$$(m_e + m_b)\,\ddot u + k(u) = -(m_e + m_b)\,\ddot u_g(t) \qquad \text{(Eq. 1)}$$

Modes: the side of $u = 0$ (`sign`), before or after lift-off (`branch`), and, for the
rigid `Housner` law under a ground motion, resting on the ground. Events, in the order of
`SDOF.conditions`:

0. impact, $u$ reaching 0: $v \leftarrow \sqrt r\, v$, same sign (Eqs 2–3);
1. overturning, $|u|$ reaching $u_{overturn}$;
2. lift-off and landing, $|u|$ crossing $u_{crit}$ (not for the rigid law);
3. and 4. the release of a resting rigid block, $|\ddot u_g|$ reaching $k(0^+)/M$.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp

from .._kinematics import theta_from_u, uplift
from ._base import AbstractRockingModel, Flags, Observed
from ._laws import AbstractRestoringForce

IMPACT_RULES = ("paper", "after_uplift")


class SDOFMode(eqx.Module):
    """The discrete mode of the SDOF model (scalars).

    `sign` (+1/-1): the side of u = 0; `branch`: on the after-lift-off branch of k(u);
    `lifted`: lifted off since the last impact; `resting`: a rigid block at rest on the
    ground; `forced`: a ground motion acts; `E0` [J]: the energy scale of the release (a
    free vibration comes to rest when its energy falls below 1e-14 of it).
    """

    sign: jnp.ndarray
    branch: jnp.ndarray
    lifted: jnp.ndarray
    resting: jnp.ndarray
    forced: jnp.ndarray
    E0: jnp.ndarray


def nonzero_sign(x, fallback):
    """+1 or -1 from the sign of `x`, `fallback` where x == 0."""
    return jnp.where(x > 0, 1.0, jnp.where(x < 0, -1.0, fallback))


class SDOF(AbstractRockingModel):
    r"""Eq. 1 with the restoring force `law` and the impact rule `impact` (Eqs 1–3).

    - `law`: an `AbstractRestoringForce` (`Simplified`, `Exact`, `Smooth`, `Housner`).
    - `impact`: `"paper"`: an impact at every crossing of $u = 0$; `"after_uplift"`: only
      if the structure has lifted off ($|u| > u_{crit}$) since the last impact.

    A rigid block (`Housner`) under a ground motion rests on the ground until
    $|\ddot u_g|$ exceeds its uplift threshold $k(0^+)/M$ (Eq. 1 alone, whose force jumps at
    $u = 0$, would chatter through infinitely many impacts from rest), and comes to rest
    again when its impacts converge.
    """

    law: AbstractRestoringForce
    impact: str = eqx.field(static=True, default="paper")

    def __check_init__(self):
        if self.impact not in IMPACT_RULES:
            raise ValueError(f"impact must be one of {IMPACT_RULES}, got {self.impact!r}")
        if not isinstance(self.law, AbstractRestoringForce):
            raise ValueError(f"law must be an AbstractRestoringForce, got {self.law!r}")

    @property
    def rigid(self) -> bool:
        return self.law.rigid

    kinematics_of_u: ClassVar[bool] = True
    recrossing_conditions: ClassVar[bool] = False
    contacts: ClassVar[int] = 1
    peak_from_state: ClassVar[bool] = True

    @property
    def impacts_accumulate(self) -> bool:
        # a settling rigid block has many impacts per step; the others a few at most
        return self.rigid

    def _u_lift(self, s):
        return jnp.zeros_like(s.u_crit) if self.rigid else s.u_crit

    def _a_up(self, s):
        """Uplift threshold of a rigid block, k(0+)/M [m/s²]."""
        one = jnp.ones_like(s.B)
        return self.law.branch(s, 0.0 * one, one, one > 0) / s.mass

    def init(self, structure, u0, v0, first, forced):
        s = structure
        sign = nonzero_sign(u0, nonzero_sign(v0, first))
        a = jnp.abs(u0)
        # a rigid block released at rest on the ground stays there (until a ground motion
        # lifts it): Eq. 1 alone, whose force jumps at u = 0, would chatter from rest
        resting = self.rigid & (u0 == 0) & (v0 == 0) & (a < s.u_overturn)
        E0 = 0.5 * s.mass * v0**2 + a * jnp.abs(self.law(s, u0))
        mode = SDOFMode(
            sign=sign,
            branch=(a >= self._u_lift(s)) | self.rigid,
            lifted=(a > self._u_lift(s)) | self.rigid,
            resting=jnp.asarray(resting),
            forced=jnp.asarray(forced),
            E0=E0,
        )
        return jnp.stack([u0, v0]), mode

    def start(self, structure, y, mode, a_g):
        """A rigid block at rest is released at t = 0 if the ground acceleration already
        exceeds k(0+)/M there (a pulse that starts with a jump: rectangular, one-cosine);
        its release events fire only when |a_g| reaches the threshold later."""
        if not self.rigid:
            return y, mode
        go = mode.resting & (jnp.abs(a_g) > self._a_up(structure))
        new = eqx.tree_at(lambda m: (m.sign, m.resting), mode,
                          (jnp.where(go, jnp.where(a_g > 0, -1.0, 1.0).astype(mode.sign.dtype),
                                     mode.sign), mode.resting & ~go))
        return y, new

    def vector_field(self, structure, y, mode, a_g):
        s = structure
        u, v = y[0], y[1]
        acc = -self.law.branch(s, u, mode.sign, mode.branch) * (1.0 / s.mass) - a_g
        if not self.rigid:  # only a rigid block rests (`init`): nothing to select
            return jnp.stack([v, acc])
        return jnp.where(mode.resting, 0.0, jnp.stack([v, acc]))

    def conditions(self, structure, y, mode, a_g):
        s = structure
        a = mode.sign * y[0]
        vals = [jnp.where(mode.resting, 1.0, a) if self.rigid else a, s.u_overturn - a]
        if self.rigid:
            up = self._a_up(s)
            vals += [jnp.where(mode.resting, up - a_g, 1.0), jnp.where(mode.resting, up + a_g, 1.0)]
        else:
            ul = self._u_lift(s)
            vals.append(jnp.where(mode.branch, a - ul, ul - a))
        return jnp.stack(vals)

    def jump(self, structure, y, mode, which, r, a_g):
        # lambdas, not bound methods: lax.switch hashes its branches, and a bound method
        # hashes the model, whose fields may be tracers (e.g. a traced Smooth width)
        impact, overturn = (lambda *a: self._impact(*a)), (lambda *a: self._overturn(*a))
        if self.rigid:
            release = lambda *a: self._release(*a)  # noqa: E731
            branches = [impact, overturn, release, release]
        else:
            branches = [impact, overturn, lambda *a: self._lift(*a)]
        return jax.lax.switch(which, branches, structure, y, mode, r, a_g)

    def _impact(self, s, y, mode, r, a_g):
        real = mode.lifted if self.impact == "after_uplift" else jnp.ones((), bool)
        v = jnp.where(real, jnp.sqrt(r) * y[1], y[1])
        if self.rigid:
            # the impacts of a settling block converge (infinitely many in a finite time):
            # below this speed it has come to rest, on the ground until a ground motion
            # lifts it again
            settle = real & (0.5 * v**2 <= 1e-8 * self._a_up(s) * s.B)
        else:
            settle = jnp.zeros((), bool)
        # a free vibration that has run out of energy rests at u = 0 for good
        rest = ~mode.forced & ((0.5 * s.mass * v**2 <= 1e-14 * mode.E0) | settle)
        v = jnp.where(settle | rest, 0.0, v)
        new = SDOFMode(
            sign=-mode.sign,
            branch=jnp.asarray(self.rigid),
            lifted=jnp.asarray(self.rigid),
            resting=mode.resting | settle,
            forced=mode.forced,
            E0=mode.E0,
        )
        return jnp.stack([0.0 * v, v]), new, Flags(real, jnp.zeros((), bool), rest)

    def _overturn(self, s, y, mode, r, a_g):
        f = jnp.zeros((), bool)
        return jnp.stack([mode.sign * s.u_overturn, y[1]]), mode, Flags(f, ~f, f)

    def _lift(self, s, y, mode, r, a_g):
        f = jnp.zeros((), bool)
        new = eqx.tree_at(lambda m: (m.branch, m.lifted), mode,
                          (~mode.branch, mode.lifted | ~mode.branch))
        return jnp.stack([mode.sign * self._u_lift(s), y[1]]), new, Flags(f, f, f)

    def _release(self, s, y, mode, r, a_g):
        f = jnp.zeros((), bool)
        new = eqx.tree_at(lambda m: (m.sign, m.resting), mode,
                          (jnp.where(a_g > 0, -1.0, 1.0).astype(mode.sign.dtype), f))
        return y, new, Flags(f, f, f)

    def observe(self, structure, y, mode):
        u = y[0]
        return Observed(
            u=u,
            v=y[1],
            theta=theta_from_u(structure, u, rigid=self.rigid),
            uplift=uplift(structure, u, rigid=self.rigid),
        )

    def theta_uplift_of_u(self, structure, u):
        return (theta_from_u(structure, u, rigid=self.rigid),
                uplift(structure, u, rigid=self.rigid))

    def frequency(self, structure):
        if self.rigid:
            return jnp.zeros_like(structure.B)
        return jnp.sqrt(jnp.abs(structure.K1) / structure.mass)

    def u_overturn(self, structure):
        return structure.u_overturn

    def peak_coordinate(self, structure, y, mode):
        return y[0], y[1]  # (u, v)

    def peak_limit(self, structure):
        return self.u_overturn(structure)

    def u_of_peak(self, structure, q):
        return q

    def tracked_uplift(self, structure, y, mode):
        return jnp.zeros_like(y[0])  # the peak uplift follows from the peak |u|

    def peak_uplift(self, structure, peak_u, tracked):
        return uplift(structure, peak_u, rigid=self.rigid)
