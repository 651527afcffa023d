r"""The reference model: the rigid body itself on two compression-only springs (2 DOF).

The paper reduces the rocking body to the SDOF Eq. 1 with inertia $(m_e + m_b)$. This
module integrates the body it came from, geometrically exactly, so that the reduction can
be checked (the fidelity study in `benchmarks/fidelity.md`). It is what an engineer would
otherwise build in OpenSees from compression-only zeroLength springs and a corotational
rigid body.

**Kinematics** (the same as `rockjax.pushover`): base centre $(x_o, y_o)$, clockwise
rotation $\theta$; a body point $(b_x, b_y)$ sits at $(x_o + b_x\cos\theta + b_y\sin\theta,\;
y_o - b_x\sin\theta + b_y\cos\theta)$. The masses $m_e$, $m_b$ (rotary inertias $I_{eg}$,
$I_{bg}$) sit at $(0, H_e)$ and $(0, H_b)$; the springs at the corners $(\pm B, 0)$.

**Degrees of freedom** $q = (y_o, \theta)$. The horizontal position follows from the no-slip
rule: while both springs are in contact the base centre is held ($x_o$ constant, rotation
about the centreline); while one spring is in contact that corner keeps its horizontal
position $X$, so $x_o = X \mp B\cos\theta$.

**Equations of motion**: Lagrange's equations $M(q)\ddot q = Q + \partial T/\partial q -
(\partial p/\partial q)\dot q$, with $p = \partial T/\partial \dot q$, written out in
`accelerations` (and checked against their automatic differentiation from the kinetic
energy $T$ in the tests); $Q$ holds gravity, the springs
$f_i = \max(0, k_f\delta_i + c_f\dot\delta_i)$ while compressed ($\delta_i > 0$; optional
compression-only dashpots $c_f$) and the ground acceleration, $-\ddot u_g \sum_j m_j
\partial x_j/\partial q$.

**Contact changes** are events. A change of the no-slip pivot changes the velocity
constraint on $x_o$; the friction impulse that enforces the new one is applied as a
perfectly inelastic projection of the velocities (it removes a fraction of order
$(\delta_0 / H)^2$ of the kinetic energy). With `contact="continuous"`, the springs and
dashpots alone carry the landings.

**The landing law** (`contact="impact"`, default). The mode remembers the rocking *side*,
the corner the body last rocked about. A corner that lands on the other side is Housner's
rocking impact (Eqs 2–3): the rotation rate drops to $\sqrt r$ of its value and the
landing corner stops, so the body turns about it. After that impact the corner, stopped
at the unloaded spring top, takes the whole weight, sinks and may bounce off its spring
for a few tens of microseconds (the vertical period $2\pi\sqrt{M/2k_f}$). Its re-landing
is about the same side, so it is a plastic impact of that corner alone (`corner_stop`):
the corner's vertical velocity goes, angular momentum about it is conserved, and nothing
else. So the body has one rocking impact per crossing and tends to Housner's rigid block
as $k_f \to \infty$ (tested in `tests/test_twospring.py`). Without dashpots it does so
slowly and irregularly: the vertical vibration that each rocking impact starts (the
landing corner, stopped on its unloaded spring, must take the weight) is never damped,
and its velocity, about $g\sqrt{m/k_f}$, meets the next impact with a changing phase
(errors $\sim k_f^{-1/2}$ that grow or shrink from one impact to the next: 1.3e-3 in
the crossing times at $10^{10}$ N/m). Dashpots of a few per cent of critical for the
vertical mode damp it between impacts, and the errors fall as $1/k_f$ (3e-4 at $10^{10}$
N/m; `benchmarks/housner_2dof.md`).

**Ringing below lift-off.** Impacts are the only dissipation of the undamped model, and
they happen only at landings. Once the rocking amplitude falls to about $u_{crit}$ the
corners barely lift off, the impacts take almost nothing, and the body vibrates
elastically on its springs at the pre-uplift frequency (`linearised_frequency`), at an
amplitude of about $u_{crit}$ (5.5 mm for Table 1), indefinitely. That is the physics of
undamped springs, not a numerical artefact; the paper's SDOF does not show it because its
impact rule `"paper"` charges an impact at every crossing of $u = 0$. Dashpots
(`damping`, $c_f$) damp it.
"""

from __future__ import annotations

from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp

from ._base import AbstractRockingModel, Flags, Observed

CONTACTS = ("impact", "continuous")


class TwoSpringMode(eqx.Module):
    """The discrete mode of the 2-DOF body: the no-slip `pivot` (-1 left corner, 0 the
    centre, +1 right corner), its horizontal position `X` [m], the contact flags `cl`,
    `cr` of the left and right springs (1.0 in contact, 0.0 lifted), and the rocking
    `side`: the corner (-1 left, +1 right) the body last rocked about, 0 before it has
    lifted off (a landing is a rocking impact only when it changes the side)."""

    pivot: jnp.ndarray
    X: jnp.ndarray
    cl: jnp.ndarray
    cr: jnp.ndarray
    side: jnp.ndarray


class TwoSpring2DOF(AbstractRockingModel):
    r"""The rigid body on two compression-only springs, integrated as a 2-DOF system.

    Use it as `model="two_spring_2dof"` (or `rockjax.TwoSpring2DOF(damping=..., contact=...)`)
    in `rockjax.simulate` and `rockjax.simulate_batch`; `u` is then the horizontal
    displacement of the top mass $m_e$. Its static limit is `rockjax.pushover`.

    The state is `y = (y_left, y_right, y_left', y_right')`, the corner heights [m] above
    the unloaded spring tops and their rates; events, in the order of `conditions`: the
    left and right corners reaching their springs (landing or lift-off), and overturning.

    **Arguments:**

    - `damping`: $c_f$, the coefficient of each compression-only dashpot [N s/m]
      (default 0).
    - `contact`: `"impact"` (default): a landing corner is a plastic impact, velocities
      scaled by $\sqrt r$ (Eqs 2–3); `"continuous"`: no velocity jump, the springs and
      dashpots dissipate.
    """

    damping: float | jnp.ndarray = 0.0
    contact: str = eqx.field(static=True, default="impact")

    def __check_init__(self):
        if self.contact not in CONTACTS:
            raise ValueError(f"contact must be one of {CONTACTS}, got {self.contact!r}")
        c = self.damping
        if isinstance(c, (int, float)) and not (c >= 0 and c < float("inf")):
            raise ValueError(f"damping (dashpot coefficient c_f) must be >= 0, got {c}")

    kinematics_of_u: ClassVar[bool] = False  # theta, uplift: of both corners, not u
    recrossing_conditions: ClassVar[bool] = False
    contacts: ClassVar[int] = 2  # two corners, each lifting off and landing on its own
    peak_from_state: ClassVar[bool] = False  # u is the top mass's, from the geometry
    impacts_accumulate: ClassVar[bool] = False

    def peak_coordinate(self, structure, y, mode):
        obs = self.observe(structure, y, mode)
        return obs.u, obs.v

    def peak_limit(self, structure):
        return self.u_overturn(structure)

    def u_of_peak(self, structure, q):
        return q

    def tracked_uplift(self, structure, y, mode):
        return self.observe(structure, y, mode).uplift

    def peak_uplift(self, structure, peak_u, tracked):
        return tracked

    def theta_uplift_of_u(self, structure, u):
        raise NotImplementedError(
            "the 2-DOF body's theta and uplift are not functions of u (kinematics_of_u)"
        )

    def init(self, structure, u0, v0, first, forced):
        return _initial_state(structure, u0, v0)

    def start(self, structure, y, mode, a_g):
        return y, mode  # on its springs from the start: no rest state to leave

    def vector_field(self, structure, y, mode, a_g):
        q, qd = y[:2], y[2:]
        qdd = accelerations(structure, self, q, qd, mode.pivot, mode.cl > 0, mode.cr > 0, a_g)
        return jnp.concatenate([qd, qdd])

    def conditions(self, structure, y, mode, a_g):
        q = y[:2]
        sl = jnp.where(mode.cl > 0, -1.0, 1.0)
        sr = jnp.where(mode.cr > 0, -1.0, 1.0)
        xe = top_x(structure, q, mode.pivot, mode.X)
        return jnp.stack([sl * q[0], sr * q[1], structure.u_overturn - jnp.abs(xe)])

    def jump(self, structure, y, mode, which, r, a_g):
        # lambdas, not bound methods: lax.switch hashes its branches, and a bound method
        # hashes the model, whose damping may be a tracer
        branches = [lambda *a: self._contact(*a, left=True),
                    lambda *a: self._contact(*a, left=False),
                    lambda *a: self._overturn(*a)]
        return jax.lax.switch(jnp.minimum(which, 2), branches, structure, y, mode, r)

    def _contact(self, s, y, mode, r, *, left):
        """A corner reaches its spring: new contact flags, the pivot and its friction
        impulse, and (contact="impact") the landing law: Housner's rocking impact when
        the rocking side changes, a plastic impact of the corner alone when it re-lands
        after a hop about the same side."""
        c = -1.0 if left else 1.0  # the corner that reaches its spring
        q = y[:2].at[0 if left else 1].set(0.0)  # on the contact surface exactly
        qd = y[2:]
        cl = jnp.where(left, 1.0 - mode.cl, mode.cl)
        cr = jnp.where(left, mode.cr, 1.0 - mode.cr)
        pivot = mode.pivot
        new_pivot = _pivot_from(cl > 0, cr > 0, pivot)
        changed = new_pivot != pivot
        qd_new = jnp.where(changed, switch_pivot(s, q, qd, pivot, new_pivot), qd)
        _, th = geometry(s, q)
        x_o = x_base(s, th, pivot, mode.X)
        X_new = jnp.where(new_pivot == 0, x_o, x_o + new_pivot * s.B * jnp.cos(th))
        X_new = jnp.where(changed, X_new, mode.X)
        landing = (cl if left else cr) > 0
        impact_law = self.contact == "impact"
        rocking = landing & (c != mode.side)
        # Housner's rocking impact (Eqs 2-3): the rotation rate drops to sqrt(r) of its
        # value and the landing corner stops (no rebound): y_o' = -/+ B cos(theta) theta'.
        w = jnp.sqrt(r) * (qd[0] - qd[1])  # = 2 B cos(theta) theta'
        qd_imp = jnp.stack([0.0 * w, -w]) if left else jnp.stack([w, 0.0 * w])
        # A re-landing after a hop about the same side: the corner alone stops (plastic),
        # angular momentum about it is conserved, only the hop's vertical energy goes.
        qd_hop = corner_stop(s, q, qd, pivot, 0 if left else 1)
        qd_new = jnp.where(impact_law & landing, jnp.where(rocking, qd_imp, qd_hop), qd_new)
        # The side becomes the corner that landed at a rocking impact. At a lift-off that
        # leaves the other corner alone in contact, it becomes that corner if the body
        # turns about it (the lifting corner rises faster than the one in contact); if
        # the corner in contact rises faster, the lifting corner only hops.
        other = jnp.where(left, cr, cl) > 0
        turns = c * (qd[1] - qd[0]) > 0  # corner c rises relative to the other one
        side = jnp.where(landing, jnp.where(rocking, c, mode.side),
                         jnp.where(other & turns, -c, mode.side))
        f = jnp.zeros((), bool)
        new = TwoSpringMode(pivot=new_pivot, X=X_new, cl=cl, cr=cr, side=side)
        return jnp.concatenate([q, qd_new]), new, Flags(rocking & impact_law, f, f)

    def _overturn(self, s, y, mode, r):
        f = jnp.zeros((), bool)
        return y, mode, Flags(f, ~f, f)

    def observe(self, structure, y, mode):
        q, qd = y[:2], y[2:]
        return Observed(
            u=top_x(structure, q, mode.pivot, mode.X),
            v=top_xd(structure, q, qd, mode.pivot),
            theta=geometry(structure, q)[1],
            uplift=jnp.maximum(jnp.max(q), 0.0),
        )

    def frequency(self, structure):
        s = structure
        vertical = jnp.sqrt(2.0 * s.k_f / (s.m_e + s.m_b))
        return jnp.maximum(vertical, linearised_frequency(s))

    def u_overturn(self, structure):
        return structure.u_overturn


# ---------------------------------------------------------------------------- kinematics
#
# The generalised coordinates are the corner heights q = (y_left, y_right) [m] above the
# unloaded spring tops (y_o = mean, sin(theta) = (y_left - y_right) / 2B): a spring's
# contact condition is then a state component itself, computed without cancellation, which
# keeps contact events clean when a corner lands with zero velocity.


def geometry(s, q):
    """(y_o [m], theta [rad]) of the base centre from the corner heights q."""
    return 0.5 * (q[0] + q[1]), jnp.arcsin((q[0] - q[1]) / (2.0 * s.B))


def coords(s, y_o, theta):
    """Corner heights q from (y_o, theta)."""
    return jnp.stack([y_o + s.B * jnp.sin(theta), y_o - s.B * jnp.sin(theta)])


def x_base(s, theta, pivot, X):
    """Horizontal position of the base centre for the no-slip pivot (-1, 0 or +1)."""
    return jnp.where(pivot == 0, X, X - pivot * s.B * jnp.cos(theta))


def _rates(s, q, qd):
    (y_o, theta), (yd, thd) = jax.jvp(lambda qq: geometry(s, qq), (q,), (qd,))
    return y_o, theta, yd, thd


def kinetic(s, q, qd, pivot):
    """Kinetic energy T [J] of the two masses and their rotary inertias."""
    _, theta, y_d, th_d = _rates(s, q, qd)
    dx_o = pivot * s.B * jnp.sin(theta) * th_d
    T = 0.5 * (s.I_eg + s.I_bg) * th_d**2
    for m, H in ((s.m_e, s.H_e), (s.m_b, s.H_b)):
        xd = dx_o + H * jnp.cos(theta) * th_d
        yd = y_d - H * jnp.sin(theta) * th_d
        T = T + 0.5 * m * (xd**2 + yd**2)
    return T


def gravity_potential(s, q):
    y_o, theta = geometry(s, q)
    return s.g * (s.m_e * (y_o + s.H_e * jnp.cos(theta)) + s.m_b * (y_o + s.H_b * jnp.cos(theta)))


def potential(s, q):
    """Gravity + spring energy [J] (the springs' compression-only strain energy)."""
    return gravity_potential(s, q) + 0.5 * s.k_f * jnp.sum(jnp.maximum(-q, 0.0) ** 2)


def top_x(s, q, pivot, X):
    """Horizontal displacement u [m] of the top mass m_e."""
    _, theta = geometry(s, q)
    return x_base(s, theta, pivot, X) + s.H_e * jnp.sin(theta)


def top_xd(s, q, qd, pivot):
    _, theta, _, th_d = _rates(s, q, qd)
    return (pivot * s.B * jnp.sin(theta) + s.H_e * jnp.cos(theta)) * th_d


def _horizontal_moment(s, q, pivot, X):
    """sum_j m_j x_j: its gradient is the ground motion's generalised force per unit accel."""
    _, theta = geometry(s, q)
    x_o = x_base(s, theta, pivot, X)
    return s.m_e * (x_o + s.H_e * jnp.sin(theta)) + s.m_b * (x_o + s.H_b * jnp.sin(theta))


def _inertia(s):
    """(m, m h, I_h): total mass [kg], first moment sum m_j H_j [kg m] and rotary inertia
    about the base centre I_eg + I_bg + sum m_j H_j^2 [kg m^2]."""
    m = s.m_e + s.m_b
    return m, s.m_e * s.H_e + s.m_b * s.H_b, s.I_eg + s.I_bg + s.m_e * s.H_e**2 + s.m_b * s.H_b**2


def _mass_y_theta(s, theta, pivot):
    """Mass matrix in (y_o, theta) and d I_theta / d theta, with x_o' = pivot B sin(theta)
    theta' substituted: T = m y'^2/2 - mh sin(theta) y' theta' + I_theta theta'^2 / 2."""
    m, mh, Ih = _inertia(s)
    sn, c = jnp.sin(theta), jnp.cos(theta)
    pB = pivot * s.B
    I_th = Ih + m * pB**2 * sn**2 + 2.0 * pB * mh * sn * c
    dI = 2.0 * m * pB**2 * sn * c + 2.0 * pB * mh * (c**2 - sn**2)
    return m, mh, I_th, dI


def mass_matrix(s, q, pivot):
    """The generalised mass matrix M(q) [kg] of the corner heights q (T = qd' M qd / 2)."""
    _, theta = geometry(s, q)
    m, mh, I_th, _ = _mass_y_theta(s, theta, pivot)
    sn = jnp.sin(theta)
    M_yt = jnp.stack([jnp.stack([m, -mh * sn]), jnp.stack([-mh * sn, I_th])])
    a = 1.0 / (2.0 * s.B * jnp.cos(theta))
    J = jnp.stack([jnp.stack([0.5 + 0.0 * a, 0.5 + 0.0 * a]), jnp.stack([a, -a])])
    return J.T @ M_yt @ J


def accelerations(s, model, q, qd, pivot, contact_l, contact_r, ag):
    r"""q'' from Lagrange's equations, for the current contact state and ground accel ag.

    In $(y_o, \theta)$, with $x_o' = pB\sin\theta\,\theta'$ ($p$ the pivot), $s, c$ the sine
    and cosine of $\theta$, $m h = m_eH_e + m_bH_b$ and
    $I_\theta = I_h + m p^2B^2 s^2 + 2pB\,mh\,sc$:

    $$m\ddot y_o - mh\,s\,\ddot\theta = Q_y + mh\,c\,\dot\theta^2, \qquad
    -mh\,s\,\ddot y_o + I_\theta\ddot\theta = Q_\theta - \tfrac12 I_\theta'\dot\theta^2,$$

    $Q_y = f_l + f_r - mg$, $Q_\theta = (f_l - f_r)Bc + mh\,g\,s - \ddot u_g(m pBs + mh\,c)$;
    then $\ddot q_{l,r} = \ddot y_o \pm B(c\ddot\theta - s\dot\theta^2)$. Written out (no
    autodiff: the fast path evaluates it 16 times a record step); `tests/test_twospring.py`
    checks it against Lagrange's equations formed by automatic differentiation of `kinetic`.
    """
    _, theta, _, thd = _rates(s, q, qd)
    m, mh, I_th, dI = _mass_y_theta(s, theta, pivot)
    sn, c = jnp.sin(theta), jnp.cos(theta)
    # Springs (and dashpots) push up at the corners. In contact the force is continued
    # smoothly past its end (the contact event ends the segment there); a dashpot cannot
    # pull, so with damping the force is clipped.
    f = -s.k_f * q - model.damping * qd
    f = jnp.where(model.damping > 0, jnp.maximum(f, 0.0), f)
    f = jnp.where(jnp.stack([contact_l, contact_r]), f, 0.0)
    Qy = f[0] + f[1] - m * s.g + mh * c * thd**2
    Qt = ((f[0] - f[1]) * s.B * c + mh * s.g * sn - ag * (m * pivot * s.B * sn + mh * c)
          - 0.5 * dI * thd**2)
    det = m * I_th - (mh * sn) ** 2
    ydd = (I_th * Qy + mh * sn * Qt) / det
    thdd = (mh * sn * Qy + m * Qt) / det
    a = s.B * (c * thdd - sn * thd**2)
    return jnp.stack([ydd + a, ydd - a])


def energy(s, q, qd, pivot):
    """Total mechanical energy T + V [J] (gravity from the base plane, springs)."""
    return kinetic(s, q, qd, pivot) + potential(s, q)


def switch_pivot(s, q, qd, old, new):
    """Velocities after the no-slip pivot changes from `old` to `new` (inelastic projection).

    Physical velocities V = (x_o', y_o', theta'); before, x_o' = old B sin(theta) theta'.
    The friction impulse L acts horizontally at the new restraint point; it makes
    x_o' = new B sin(theta) theta' hold afterwards: M3 (V+ - V-) = G^T L, G V+ = 0.
    """
    _, theta, y_d, th_d = _rates(s, q, qd)
    sn, c = jnp.sin(theta), jnp.cos(theta)
    V = jnp.stack([old * s.B * sn * th_d, y_d, th_d])
    m = s.m_e + s.m_b
    mh = s.m_e * s.H_e + s.m_b * s.H_b
    Ih = s.I_eg + s.I_bg + s.m_e * s.H_e**2 + s.m_b * s.H_b**2
    M3 = jnp.stack([jnp.stack([m, 0.0 * m, mh * c]), jnp.stack([0.0 * m, m, -mh * sn]),
                    jnp.stack([mh * c, -mh * sn, Ih])])
    G = jnp.stack([1.0, 0.0, -new * s.B * sn])
    MiG = jnp.linalg.solve(M3, G)
    Vp = V + MiG * (-(G @ V) / (G @ MiG))
    return jnp.stack([Vp[1] + s.B * c * Vp[2], Vp[1] - s.B * c * Vp[2]])


def corner_stop(s, q, qd, pivot, i):
    """Velocities after a plastic impact of corner `i` (0 left, 1 right) alone.

    A vertical impulse J at the corner stops it: M(q) (qd+ - qd-) = J e_i with qd+_i = 0,
    M the generalised mass matrix of the corner heights q. The impulse acts at the corner,
    so angular momentum about it is conserved; the kinetic energy lost is that of the
    corner's vertical velocity, (qd-_i)^2 / (2 (M^-1)_ii).
    """
    col = jnp.linalg.solve(mass_matrix(s, q, pivot), jnp.eye(2, dtype=qd.dtype)[i])
    return qd - col * (qd[i] / col[i])


# ---------------------------------------------------------------------------- statics


def static_state(s, a):
    """Static equilibrium at top displacement a >= 0 under a lateral load P at m_e.

    Virtual work with the 2-DOF potential: dV/dy_o = 0, dV/dtheta = P dx_e/dtheta, and
    x_e(theta) = a (the pushover kinematics: centre held before lift-off, corner after).
    Returns (q, P, pivot, X).
    """
    def pieces(s, theta):
        theta_u = jnp.arcsin(s.delta_0 / s.B)  # the left spring unloads (exact, Eq. 5)
        lifted = theta > theta_u
        # the right corner's x once it is the pivot
        return jnp.where(lifted, 1.0, 0.0), jnp.where(lifted, s.B * jnp.cos(theta_u), 0.0)

    def fn(z, args):
        s, a = args
        y_o, theta, P = z[0] * s.B, z[1], z[2] * s.W
        pivot, X = pieces(s, theta)
        dVy, dVt = jax.grad(lambda y, t: potential(s, coords(s, y, t)), argnums=(0, 1))(
            y_o, theta)
        dxe = pivot * s.B * jnp.sin(theta) + s.H_e * jnp.cos(theta)
        xe = x_base(s, theta, pivot, X) + s.H_e * jnp.sin(theta)
        return jnp.stack([dVy / s.W, (dVt - P * dxe) / (s.W * s.B), (xe - a) / s.H_e])

    z0 = jnp.stack([-s.delta_0 / s.B, jnp.arcsin(jnp.clip(a / s.R_e, 0.0, 1.0)),
                    jnp.zeros_like(a)])
    z = _newton(fn, z0, (s, a))
    pivot, X = pieces(s, z[1])
    return coords(s, z[0] * s.B, z[1]), z[2] * s.W, pivot, X


def _newton(fn, z0, args, max_steps=64, tol=1e-13):
    r"""The root of `fn(z, args)` by Newton's method from `z0`, with the derivative of the
    implicit function theorem.

    Written out rather than `optimistix.root_find`, whose closure conversion fails inside
    `jax.shard_map` (a batch split over devices). The iteration runs on stopped values (no
    derivatives); one last Newton step from its result carries them: at the root its
    derivative is $-J^{-1}\,\partial f/\partial p$, the implicit one, in forward and reverse
    mode.
    """
    stopped = jax.tree_util.tree_map(jax.lax.stop_gradient, args)

    def step(z, p):
        return z - jnp.linalg.solve(jax.jacfwd(fn)(z, p), fn(z, p))

    def cond(c):
        z, dz, k = c
        return (k < max_steps) & (jnp.max(jnp.abs(dz) - tol * (1 + jnp.abs(z))) > 0)

    def body(c):
        z, _, k = c
        z1 = step(z, stopped)
        return z1, z1 - z, k + 1

    init = (jax.lax.stop_gradient(z0), jnp.full_like(z0, jnp.inf), 0)
    zs, _, _ = jax.lax.while_loop(cond, body, init)
    return step(zs, args)


def static_pushover(structure, u):
    """P(u) [N] from the 2-DOF static equilibrium (virtual work), for checking."""
    u = jnp.asarray(u, jnp.result_type(structure.B))

    def one(ui):
        _, P, _, _ = static_state(structure, jnp.abs(ui))
        return jnp.sign(ui) * P

    return jax.vmap(one)(jnp.ravel(u)).reshape(jnp.shape(u))


def linearised_frequency(structure):
    r"""Small-amplitude rocking frequency [rad/s] of the 2-DOF body on both springs.

    $\omega^2 = (2k_fB^2 - g(m_eH_e + m_bH_b)) / (I_{eg} + I_{bg} + m_eH_e^2 + m_bH_b^2)$,
    rotation about the base centre; the SDOF counterpart is $\sqrt{K_1/(m_e+m_b)}$ (Eq. 15).
    """
    s = structure
    k = 2 * s.k_f * s.B**2 - s.g * (s.m_e * s.H_e + s.m_b * s.H_b)
    return jnp.sqrt(k / (s.I_eg + s.I_bg + s.m_e * s.H_e**2 + s.m_b * s.H_b**2))


# ---------------------------------------------------------------------------- dynamics


def _initial_state(s, u0, v0):
    """(y, mode): the static configuration at top displacement u0 (a release from the
    pushover), with the top mass moving at v0 as a rotation about the pivot."""
    q, _, pivot, X = static_state(s, jnp.abs(u0))
    neg = u0 < 0
    q = jnp.where(neg, q[::-1], q)  # the mirror image swaps the corners
    sg = jnp.where(neg, -1.0, 1.0)
    pivot, X = sg * pivot, sg * X
    _, th0 = geometry(s, q)
    lever = pivot * s.B * jnp.sin(th0) + s.H_e * jnp.cos(th0)
    bc = s.B * jnp.cos(th0) * v0 / lever
    # the pivot corner stays put (both corners move symmetrically about a centre pivot)
    qd = jnp.where(pivot > 0, jnp.stack([2 * bc, 0.0 * bc]),
                   jnp.where(pivot < 0, jnp.stack([0.0 * bc, -2 * bc]), jnp.stack([bc, -bc])))
    mode = TwoSpringMode(pivot=pivot, X=X, cl=(q[0] <= 0).astype(q.dtype),
                         cr=(q[1] <= 0).astype(q.dtype), side=pivot)
    return jnp.concatenate([q, qd]), mode


def _pivot_from(cl, cr, old):
    return jnp.where(cl & cr, 0.0, jnp.where(cr, 1.0, jnp.where(cl, -1.0, old)))


