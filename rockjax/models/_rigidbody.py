r"""The one-DOF equation of the rigid body itself on its two springs (`model="rigid_body"`).

The paper reduces the rocking body to Eq. 1, a lateral SDOF of mass $m_e + m_b$. This
module keeps the body's own rotational equation, one degree of freedom $\theta$ with the
body's rotary inertia, on the same kinematics as the paper (and `rockjax.pushover`):
rotation about the base centre, held, until lift-off; then about the corner in contact,
fixed. Its rigid limit ($k_f \to \infty$) is Housner's rocking block. The derivation is in
`docs/rigid_body.md`.

Notation: $M = m_e + m_b$, $W = Mg$, $M H_c = m_e H_e + m_b H_b$, clockwise $\theta$ (the
top moves to $+x$ for $\theta > 0$), $\sigma = \mathrm{sign}\,\theta$,
$\theta_u = \arcsin(\delta_0/B)$ the lift-off rotation,
$I_c = I_{eg} + I_{bg} + m_eH_e^2 + m_bH_b^2$ the inertia about the base centre and
$I_P = I_{eg} + I_{bg} + m_eR_e^2 + m_bR_b^2$ (`I_O`) about a base corner. `a_g` [m/s²] is
the ground acceleration (positive: the ground accelerates to $+x$).

- $|\theta| \le \theta_u$ (both springs in contact):
  $I_c\ddot\theta = -(2k_fB^2\cos\theta - WH_c)\sin\theta - a_g MH_c\cos\theta$.
- $|\theta| > \theta_u$ (on one corner):
  $I_P\ddot\theta = -\sigma WR_c\sin(\alpha_c - |\theta|) - a_g MR_c\cos(\alpha_c - |\theta|)$.

Events, in the order of `RigidBody.conditions`:

0. lift-off and landing, $|\theta|$ crossing $\theta_u$. Lift-off:
   $\dot\theta \leftarrow \sqrt{I_c/I_P}\,\dot\theta$; landing (a rocking impact, Eqs 2–3):
   $\dot\theta \leftarrow \sqrt{r\,I_P/I_c}\,\dot\theta$. The inertia changes with the pivot;
   the switch keeps the kinetic energy (the springs carry the transition elastically), so
   a cycle of landing and lift-off loses exactly the factor $r$ of Eq. 2, as Housner's
   block does. A landing that leaves too little energy to lift off again settles the
   body on its springs (`SETTLE`).
1. overturning, $|\theta|$ reaching $\alpha_c$.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp

from .._kinematics import _lift_off_rotation, theta_from_u, u_from_theta, uplift, uplift_from_theta
from ._base import AbstractRockingModel, Flags, Observed
from ._sdof import nonzero_sign

#: a landing that leaves the body too little energy to swing more than this fraction of
#: theta_u past theta_u (were it elastic) settles it: it then vibrates on both springs,
#: amplitude theta_u, until a ground motion takes it SETTLE theta_u past theta_u
SETTLE = 1e-3


class RigidBodyMode(eqx.Module):
    """The discrete mode of the rigid-body model (scalars).

    `sign` (+1/-1): the side of the pivot corner (the side of the last lift-off); `lifted`:
    on one corner ($|\\theta| > \\theta_u$); `settled`: on both springs without the energy
    to lift off (see `SETTLE`): it lifts off again only at $|\\theta| = (1 +
    \\mathrm{SETTLE})\\,\\theta_u$.
    """

    sign: jnp.ndarray
    lifted: jnp.ndarray
    settled: jnp.ndarray


#: Coefficients of sin x / x and cos x in t = x² (nine each): their Taylor series (to x^58)
#: economised by Chebyshev on |x| <= pi/2 (written in Chebyshev polynomials of t over
#: [0, (pi/2)²] in exact rational arithmetic, truncated at degree 8, and back; the
#: truncation is below 4e-18, under the rounding of float64): three fewer multiply-adds
#: each than the Taylor polynomials to x^23 and x^22 used before, in what the batched
#: stepper evaluates five times per RK4 step (`benchmarks/results.md` (g)).
_SIN = (1.0, -0.16666666666666666, 0.008333333333333186, -0.0001984126984120872,
        2.755731921123654e-06, -2.5052106891168703e-08, 1.6058940907182887e-10,
        -7.643027273612204e-13, 2.7215821926997076e-15)
_COS = (1.0, -0.4999999999999997, 0.04166666666666388, -0.0013888888888773081,
        2.4801587277429444e-05, -2.755731639228085e-07, 2.087656190004232e-09,
        -1.1462903400770852e-11, 4.608992189914223e-14)


def sincos(x):
    r"""$(\sin x, \cos x)$ by polynomials (Horner in $x^2$, nine terms each: `_SIN`,
    `_COS`), exact to rounding for $|x| \le \pi/2$ (within 4e-16 of the library's; the
    body overturns at $\alpha_c < \pi/2$) and within 1e-12 up to $|x| = 2$ (a step's
    stages may pass $\alpha_c$ before the overturning is located; beyond, the error grows
    as $x^{18}$: 1e-8 at $|x| = 3$).

    The rotation of the body is bounded, so the polynomials replace the library's sin and
    cos in the flow: under the batched stepper they vectorise (a few multiply-adds for
    both, about 20x cheaper than `jnp.sin` plus `jnp.cos` on a CPU), and the flow
    evaluates them four times per RK4 step. Differentiable (the derivative of one is the
    other to the same accuracy)."""
    x2 = x * x
    s = jnp.full_like(x, _SIN[-1])
    c = jnp.full_like(x, _COS[-1])
    for a, b in zip(_SIN[-2::-1], _COS[-2::-1]):
        s = s * x2 + a
        c = c * x2 + b
    return x * s, c


def centre_inertia(s):
    """$I_c$ [kg m²]: rotary inertia of the body about the centre of its base."""
    return s.I_eg + s.I_bg + s.m_e * s.H_e**2 + s.m_b * s.H_b**2


def _mass(s):
    return s.m_e + s.m_b


def rotational_stiffness(s):
    """$2k_fB^2 - WH_c$ [N m/rad]: the stiffness of the rotation before lift-off."""
    return 2.0 * s.k_f * s.B**2 - s.W * s.H_c


def top_displacement(s, theta, sign, lifted):
    r"""$u$ [m] of the top mass $m_e$ at rotation `theta` [rad] in the mode (`sign`,
    `lifted`): $H_e\sin\theta$ before lift-off, $\sigma\{u_{crit} + R_e[\sin(\alpha_e -
    \theta_u) - \sin(\alpha_e - \sigma\theta)]\}$ after; `rockjax.u_from_theta` in each
    branch, continued smoothly past $\theta_u$ (for event location). With
    $R_e\sin(\alpha_e - x) = B\cos x - H_e\sin x$ it needs only $\sin\theta$, $\cos\theta$."""
    sn, c = sincos(theta)
    d0 = s.delta_0
    # R_e sin(alpha_e - theta_u) with sin(theta_u) = delta_0 / B
    at_lift = s.B * jnp.sqrt(1.0 - (d0 / s.B) ** 2) - s.H_e * d0 / s.B
    post = sign * (s.u_crit + at_lift - (s.B * c - sign * s.H_e * sn))
    return jnp.where(lifted, post, s.H_e * sn)


def lever(s, theta, sign, lifted):
    r"""$du/d\theta$ [m/rad]: $H_e\cos\theta$ before lift-off, $R_e\cos(\alpha_e -
    |\theta|) = H_e\cos\theta + \sigma B\sin\theta$ after."""
    sn, c = sincos(theta)
    return jnp.where(lifted, s.H_e * c + sign * s.B * sn, s.H_e * c)


def energy(s, theta, theta_dot, sign, lifted):
    r"""Mechanical energy [J] above the body at rest ($\theta = 0$ on both springs).

    Before lift-off $\tfrac12 I_c\dot\theta^2 + WH_c(\cos\theta - 1) + k_fB^2\sin^2\theta$;
    after it $\tfrac12 I_P\dot\theta^2 + W[R_c\cos(\alpha_c - |\theta|) - H_c - \delta_0/2]$
    (the contact spring carries $W$, compressed $2\delta_0$). Continuous at $\theta_u$.
    """
    pre = (0.5 * centre_inertia(s) * theta_dot**2 + s.W * s.H_c * (jnp.cos(theta) - 1.0)
           + s.k_f * (s.B * jnp.sin(theta)) ** 2)
    post = (0.5 * s.I_O * theta_dot**2
            + s.W * (s.R_c * jnp.cos(s.alpha_c - sign * theta) - s.H_c - 0.5 * s.delta_0))
    return jnp.where(lifted, post, pre)


def angular_acceleration(s, theta, theta_dot, sign, lifted, a_g):
    r"""$\ddot\theta$ [rad/s²] in the mode (`sign`, `lifted`) under ground acceleration
    `a_g` [m/s²] (the equations of the module docstring). With $R_c\sin\alpha_c = B$ and
    $R_c\cos\alpha_c = H_c$, $R_c\sin(\alpha_c - \sigma\theta) = B\cos\theta -
    \sigma H_c\sin\theta$ and $R_c\cos(\alpha_c - \sigma\theta) = H_c\cos\theta +
    \sigma B\sin\theta$: one sine and one cosine for both branches, and one expression,
    $-[(k_1\cos\theta + k_2)\sin\theta + k_3\cos\theta + a_g(k_4\cos\theta +
    k_5\sin\theta)]$, whose coefficients the mode selects (the batched fast path evaluates
    this four times per RK4 step: selecting five coefficients costs less than both
    branches; the inertias divide the structure's constants, not the batch's arrays)."""
    M = _mass(s)
    sn, c = sincos(theta)
    ic, io = 1.0 / centre_inertia(s), 1.0 / s.I_O
    inv = jnp.where(lifted, io, ic)  # k2 = -W H_c / I, k4 = M H_c / I with I the pivot's
    k1 = jnp.where(lifted, 0.0, 2.0 * s.k_f * s.B**2 * ic)
    k3 = jnp.where(lifted, sign * (s.W * s.B * io), 0.0)
    k5 = jnp.where(lifted, sign * (M * s.B * io), 0.0)
    return -((k1 * c - s.W * s.H_c * inv) * sn + k3 * c
             + a_g * ((M * s.H_c * inv) * c + k5 * sn))


class RigidBody(AbstractRockingModel):
    r"""The rigid body on two springs as one rotational DOF: pivots, inertia, impacts.

    Use it as `model="rigid_body"` (or `rockjax.RigidBody()`) in `rockjax.simulate` and
    `rockjax.simulate_batch`, on every integrator. The state is `y = (theta [rad],
    theta_dot [rad/s])`; `u` [m] is the horizontal displacement of the top mass $m_e$
    (`rockjax.u_from_theta`, the SDOF models' kinematics exactly), `v = du/dθ θ'` [m/s].

    Before lift-off ($|\theta| \le \theta_u = \arcsin(\delta_0/B)$) the body rotates about
    its base centre on both springs, inertia $I_c = I_{eg} + I_{bg} + m_eH_e^2 + m_bH_b^2$
    [kg m²]:

    $$I_c\ddot\theta = -(2k_fB^2\cos\theta - WH_c)\sin\theta - \ddot u_g MH_c\cos\theta;$$

    after it about the corner in contact, inertia $I_P$ (`structure.I_O`):

    $$I_P\ddot\theta = -\sigma WR_c\sin(\alpha_c - |\theta|)
    - \ddot u_g MR_c\cos(\alpha_c - |\theta|),\qquad \sigma = \mathrm{sign}\,\theta,$$

    the moment form of the paper's Eq. 18 (the inertial force $-m_j\ddot u_g$ acts at each
    mass's own height). The moment is continuous at $\theta_u$. At lift-off
    $\dot\theta \leftarrow \sqrt{I_c/I_P}\,\dot\theta$ and at landing
    $\dot\theta \leftarrow \sqrt{r\,I_P/I_c}\,\dot\theta$: the pivot switch keeps the energy,
    and the landing is the rocking impact of Eq. 2 (one impact per landing; small
    vibrations that never lift off have none). The body overturns when $|\theta|$ reaches
    $\alpha_c$, i.e. $|u|$ reaches `u_overturn` = `u_from_theta(s, alpha_c)`.

    As $k_f \to \infty$ it is Housner's rocking block: $\theta_u \to 0$, the two switch
    factors cancel, and a block at rest starts rocking at $|\ddot u_g| = g(B/H_c -
    \tan\theta_u) \to g\tan\alpha_c$.

    A landing that leaves the body too little energy to swing more than `SETTLE` (1e-3) of
    $\theta_u$ past $\theta_u$ settles it: without this, the rocking energy would decay
    geometrically ($r$ per landing) but never vanish, every later swing grazing $\theta_u$
    at the integrator's rounding. A settled body vibrates on both springs (undamped, so a
    free vibration ends as a vibration of amplitude $u_{crit}$, status completed) and lifts
    off again only past $(1 + \mathrm{SETTLE})\,\theta_u$. A free release on both springs
    that could not swing that far past $\theta_u$ (e.g. at rest at $u_{crit}$) starts
    settled. The impact rule `impact` of `get_model` does not apply.
    """

    #: a landing and the lift-off on the other corner may share a step (stiff springs)
    recrossing_conditions: ClassVar[bool] = True
    kinematics_of_u: ClassVar[bool] = True
    # a landing and the next lift-off may share a step when theta_u is small: 4 pieces
    # hold landing, lift-off and a third event (as for the SDOF models)
    contacts: ClassVar[int] = 1
    peak_from_state: ClassVar[bool] = True
    impacts_accumulate: ClassVar[bool] = False

    def init(self, structure, u0, v0, first, forced):
        s = structure
        tu = _lift_off_rotation(s)
        lifted = jnp.abs(u0) > s.u_crit  # the branch of theta_from_u
        th0 = theta_from_u(s, u0)
        th0 = jnp.where(lifted, th0, jnp.clip(th0, -tu, tu))
        sign = nonzero_sign(th0, nonzero_sign(v0, first))
        w0 = v0 / lever(s, th0, sign, lifted)
        # a free release on both springs that cannot swing SETTLE theta_u past theta_u
        # starts settled (released at rest at u_crit it would graze theta_u every swing)
        excess = energy(s, th0, w0, sign, False) - energy(s, tu, 0.0 * w0, sign, False)
        settled = (not forced) & ~lifted & (excess <= SETTLE * rotational_stiffness(s) * tu**2)
        mode = RigidBodyMode(sign=sign, lifted=lifted, settled=settled)
        return jnp.stack([th0, w0]), mode

    def start(self, structure, y, mode, a_g):
        return y, mode  # on its springs from the start: no rest state to leave

    def vector_field(self, structure, y, mode, a_g):
        acc = angular_acceleration(structure, y[0], y[1], mode.sign, mode.lifted, a_g)
        return jnp.stack([y[1], acc])

    def conditions(self, structure, y, mode, a_g):
        s = structure
        th = y[0]
        tu = _lift_off_rotation(s)
        lift = jnp.where(mode.settled, (1.0 + SETTLE) * tu, tu) - jnp.abs(th)
        contact = jnp.where(mode.lifted, mode.sign * th - tu, lift)
        return jnp.stack([contact, s.alpha_c - jnp.abs(th)])

    def jump(self, structure, y, mode, which, r, a_g):
        # lambdas, not bound methods: lax.switch hashes its branches
        branches = [lambda *a: self._contact(*a), lambda *a: self._overturn(*a)]
        return jax.lax.switch(jnp.minimum(which, 1), branches, structure, y, mode, r)

    def _contact(self, s, y, mode, r):
        """Lift-off (pivot to the corner) or landing (impact, pivot to the centre)."""
        landing = mode.lifted
        side = jnp.where(landing, mode.sign, nonzero_sign(y[0], mode.sign))
        Ic, Ip = centre_inertia(s), s.I_O
        tu = _lift_off_rotation(s)
        w = jnp.where(landing, jnp.sqrt(r * Ip / Ic), jnp.sqrt(Ic / Ip)) * y[1]
        # settled: too little energy left to swing SETTLE theta_u past theta_u
        settle = landing & (0.5 * Ic * w**2 <= SETTLE * rotational_stiffness(s) * tu**2)
        w = jnp.where(settle, 0.0, w)
        # on the contact surface exactly (a settled body lifts off at (1 + SETTLE) theta_u)
        th = side * jnp.where(mode.settled & ~landing, (1.0 + SETTLE) * tu, tu)
        new = RigidBodyMode(sign=side, lifted=~landing, settled=settle)
        f = jnp.zeros((), bool)
        return jnp.stack([th, w]), new, Flags(landing, f, f)

    def _overturn(self, s, y, mode, r):
        f = jnp.zeros((), bool)
        side = nonzero_sign(y[0], mode.sign)
        return jnp.stack([side * s.alpha_c, y[1]]), mode, Flags(f, ~f, f)

    def observe(self, structure, y, mode):
        s = structure
        th = y[0]
        return Observed(
            u=top_displacement(s, th, mode.sign, mode.lifted),
            v=lever(s, th, mode.sign, mode.lifted) * y[1],
            theta=th,
            uplift=uplift_from_theta(s, th),
        )

    def theta_uplift_of_u(self, structure, u):
        return theta_from_u(structure, u), uplift(structure, u)

    def frequency(self, structure):
        s = structure
        centre = jnp.sqrt(rotational_stiffness(s) / centre_inertia(s))
        return jnp.maximum(centre, jnp.sqrt(s.W * s.R_c / s.I_O))

    def u_overturn(self, structure):
        s = structure
        tu = _lift_off_rotation(s)
        return s.u_crit + s.R_e * (jnp.sin(s.alpha_e - tu) - jnp.sin(s.alpha_e - s.alpha_c))

    def peak_coordinate(self, structure, y, mode):
        # theta and its rate: |u| increases with |theta| up to alpha_c, and observing u
        # would take a sine and a cosine at both ends of every step
        return y[0], y[1]

    def peak_limit(self, structure):
        return structure.alpha_c

    def u_of_peak(self, structure, q):
        return jnp.where(q >= structure.alpha_c, self.u_overturn(structure),
                         u_from_theta(structure, q))

    def tracked_uplift(self, structure, y, mode):
        return jnp.zeros_like(y[0])  # the peak uplift follows from the peak |u|

    def peak_uplift(self, structure, peak_u, tracked):
        return uplift(structure, peak_u)
