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
(\partial p/\partial q)\dot q$, with $p = \partial T/\partial \dot q$, formed by automatic
differentiation of the kinetic energy $T$; $Q$ holds gravity, the springs
$f_i = \max(0, k_f\delta_i + c_f\dot\delta_i)$ while compressed ($\delta_i > 0$; optional
compression-only dashpots $c_f$) and the ground acceleration, $-\ddot u_g \sum_j m_j
\partial x_j/\partial q$.

**Contact changes** are events. A change of the no-slip pivot changes the velocity
constraint on $x_o$; the friction impulse that enforces the new one is applied as a
perfectly inelastic projection of the velocities (it removes a fraction of order
$(\delta_0 / H)^2$ of the kinetic energy). With `contact="impact"` (default), a lifted corner
landing on its spring is Housner's plastic impact: the velocities are then also scaled by
$\sqrt r$ (Eq. 2, $r$ from Eq. 3). With `contact="continuous"`, the springs and dashpots
alone carry the impact.
"""

from __future__ import annotations

import diffrax as dfx
import equinox as eqx
import equinox.internal as eqxi
import jax
import jax.numpy as jnp
import optimistix as optx

from ._excitation import FreeVibration, GroundMotion
from ._response import Response, STATUS
from ._restoring import AbstractRestoringForce

CONTACTS = ("impact", "continuous")


class TwoSpring2DOF(AbstractRestoringForce):
    r"""The rigid body on two compression-only springs, integrated as a 2-DOF system.

    Use it as `model="two_spring_2dof"` (or `rockjax.TwoSpring2DOF(damping=..., contact=...)`)
    in `rockjax.simulate`; `u` is then the horizontal displacement of the top mass $m_e$.
    As a restoring force $k(u)$ it is the static pushover of the same body
    (`rockjax.pushover`).

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

    @property
    def two_dof(self) -> bool:
        return True

    def __call__(self, structure, u):
        from ._pushover import pushover

        return pushover(structure, u).P


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


def accelerations(s, model, q, qd, pivot, contact_l, contact_r, ag):
    """q'' from Lagrange's equations, for the current contact state and ground accel ag."""
    M = jax.hessian(kinetic, argnums=2)(s, q, jnp.zeros_like(q), pivot)
    dTdq = jax.grad(kinetic, argnums=1)(s, q, qd, pivot)

    def momentum(qq):
        return jax.grad(kinetic, argnums=2)(s, qq, qd, pivot)

    _, dp = jax.jvp(momentum, (q,), (qd,))
    Q = -jax.grad(gravity_potential, argnums=1)(s, q)
    # Springs (and dashpots) push up at the corners: generalised forces on q directly. In
    # contact the force is continued smoothly past its end (the contact event ends the
    # segment there); a dashpot cannot pull, so with damping the force is clipped.
    f = -s.k_f * q - model.damping * qd
    f = jnp.where(model.damping > 0, jnp.maximum(f, 0.0), f)
    f = jnp.where(jnp.stack([contact_l, contact_r]), f, 0.0)
    Q = Q + f - ag * jax.grad(_horizontal_moment, argnums=1)(s, q, pivot, 0.0)
    return jnp.linalg.solve(M, Q + dTdq - dp)


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


# ---------------------------------------------------------------------------- statics


def static_state(s, a):
    """Static equilibrium at top displacement a >= 0 under a lateral load P at m_e.

    Virtual work with the 2-DOF potential: dV/dy_o = 0, dV/dtheta = P dx_e/dtheta, and
    x_e(theta) = a (the pushover kinematics: centre held before lift-off, corner after).
    Returns (q, P, pivot, X).
    """
    from ._pushover import _lift_off

    theta_u = _lift_off(s)
    X_r = s.B * jnp.cos(theta_u)  # the right corner's x once it is the pivot

    def pieces(theta):
        lifted = theta > theta_u
        return jnp.where(lifted, 1.0, 0.0), jnp.where(lifted, X_r, 0.0)

    def V(y_o, theta):
        return potential(s, coords(s, y_o, theta))

    def fn(z, _):
        y_o, theta, P = z[0] * s.B, z[1], z[2] * s.W
        pivot, X = pieces(theta)
        dVy, dVt = jax.grad(V, argnums=(0, 1))(y_o, theta)
        dxe = pivot * s.B * jnp.sin(theta) + s.H_e * jnp.cos(theta)
        xe = x_base(s, theta, pivot, X) + s.H_e * jnp.sin(theta)
        return jnp.stack([dVy / s.W, (dVt - P * dxe) / (s.W * s.B), (xe - a) / s.H_e])

    z0 = jnp.stack([-s.delta_0 / s.B, jnp.arcsin(jnp.clip(a / s.R_e, 0.0, 1.0)),
                    jnp.zeros_like(a)])
    sol = optx.root_find(fn, optx.Newton(rtol=1e-13, atol=1e-13), z0, max_steps=64,
                         throw=False)
    z = sol.value
    pivot, X = pieces(z[1])
    return coords(s, z[0] * s.B, z[1]), z[2] * s.W, pivot, X


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


def _initial_state(s, u0):
    """Static configuration at top displacement u0 (a release from the pushover)."""
    q, _, pivot, X = static_state(s, jnp.abs(u0))
    neg = u0 < 0
    q = jnp.where(neg, q[::-1], q)  # the mirror image swaps the corners
    sg = jnp.where(neg, -1.0, 1.0)
    return q, sg * pivot, sg * X, q[0] <= 0, q[1] <= 0


def _pivot_from(cl, cr, old):
    return jnp.where(cl & cr, 0.0, jnp.where(cr, 1.0, jnp.where(cl, -1.0, old)))


@eqx.filter_jit
def _simulate_2dof(structure, model, excitation, t1, ts, r, cfg):
    from ._simulate import _EventBisection, _PIDController, _WINDOW

    s = structure
    dtype = jnp.result_type(s.B)
    t1 = jnp.asarray(t1, dtype)
    ts = jnp.asarray(ts, dtype)
    n = ts.shape[0]
    sqrt_r = jnp.sqrt(jnp.asarray(r, dtype))
    u_ot = s.u_overturn
    impact_mode = model.contact == "impact"

    def vector_field(t, y, args):
        q, qd = y
        pivot, cl, cr = args[0], args[2], args[3]
        ag = excitation.ground_acceleration(t)
        return qd, accelerations(s, model, q, qd, pivot, cl > 0, cr > 0, ag)

    def conditions(y, args, qdd):
        q, qd = y
        pivot, X, cl, cr, o0, o1, vsign, o3 = args
        sl = jnp.where(cl > 0, -1.0, 1.0)
        sr = jnp.where(cr > 0, -1.0, 1.0)
        xe = top_x(s, q, pivot, X)
        xed = top_xd(s, q, qd, pivot)
        sx = jnp.where(xe >= 0, 1.0, -1.0)
        # turning points of the rotation: theta' = (y_l' - y_r') / (2 B cos theta)
        w, wd = qd[0] - qd[1], qdd[0] - qdd[1]
        vals = jnp.stack([sl * q[0] - o0, sr * q[1] - o1, u_ot - jnp.abs(xe), vsign * w - o3])
        rates = jnp.stack([sl * qd[0], sr * qd[1], -sx * xed, vsign * wd])
        return vals, rates

    def event_cond(t, y, args, **kwargs):
        vals, _ = conditions(y, args, jnp.zeros(2, dtype))
        return jnp.min(vals) + 1e-30

    event = dfx.Event(event_cond, root_finder=_EventBisection(), direction=False)
    term = dfx.ODETerm(vector_field)
    jump_ts = excitation.jump_times() if isinstance(excitation, GroundMotion) else None
    if cfg["dt"] is not None:
        base = (dfx.ConstantStepSize() if jump_ts is None else
                _PIDController(rtol=1.0, atol=1e300, dtmax=cfg["dt"], factormax=1e6))
        dt0 = cfg["dt"]
    else:
        base = _PIDController(rtol=cfg["rtol"], atol=cfg["atol"])
        dt0 = None
    controller = base if jump_ts is None else dfx.ClipStepSizeController(base, jump_ts=jump_ts)
    if cfg["adjoint"] == "forward":
        adjoint, loop_kind = dfx.ForwardMode(), "lax"
    else:
        adjoint, loop_kind = dfx.RecursiveCheckpointAdjoint(), "checkpointed"

    u0, v0 = excitation.initial_state()
    u0 = jnp.asarray(u0, dtype)
    q0, pivot0, X0, cl0, cr0 = _initial_state(s, u0)
    # an initial velocity v0 of the top mass: a rotation rate about the pivot
    _, th0 = geometry(s, q0)
    lever = pivot0 * s.B * jnp.sin(th0) + s.H_e * jnp.cos(th0)
    th_d0 = jnp.asarray(v0, dtype) / lever
    bc = s.B * jnp.cos(th0) * th_d0
    # the pivot corner stays put (both corners move symmetrically about a centre pivot)
    qd0 = jnp.where(pivot0 > 0, jnp.stack([2 * bc, 0.0 * bc]),
                    jnp.where(pivot0 < 0, jnp.stack([0.0 * bc, -2 * bc]), jnp.stack([bc, -bc])))
    if isinstance(excitation, GroundMotion):
        first = excitation.first_direction().astype(dtype)
    else:
        first = jnp.ones((), dtype)
    acc0 = accelerations(s, model, q0, qd0, pivot0, cl0, cr0,
                         excitation.ground_acceleration(jnp.zeros((), dtype)))
    w0, wa0 = qd0[0] - qd0[1], acc0[0] - acc0[1]
    vs0 = jnp.where(w0 > 0, 1.0, jnp.where(w0 < 0, -1.0, jnp.where(
        wa0 > 0, 1.0, jnp.where(wa0 < 0, -1.0, -first))))
    xe0 = top_x(s, q0, pivot0, X0)
    over0 = jnp.abs(xe0) >= u_ot
    ts_pad = jnp.concatenate([ts, jnp.full((_WINDOW,), jnp.inf, dtype)])
    window = jnp.arange(_WINDOW)
    fdt = dtype

    init = dict(
        t=jnp.zeros((), dtype), q=q0, qd=qd0, pivot=pivot0.astype(fdt), X=X0.astype(fdt),
        cl=cl0.astype(fdt), cr=cr0.astype(fdt), o0=jnp.zeros((), fdt), o1=jnp.zeros((), fdt),
        vsign=vs0.astype(fdt), o3=jnp.zeros((), fdt),
        n_impacts=jnp.zeros((), jnp.int32),
        impact_times=jnp.full((cfg["max_impacts"],), jnp.inf, dtype),
        out_u=jnp.zeros((n,), dtype), out_v=jnp.zeros((n,), dtype),
        out_th=jnp.zeros((n,), dtype), out_up=jnp.zeros((n,), dtype),
        peak_u=jnp.minimum(jnp.abs(xe0), u_ot),
        peak_up=jnp.zeros((), dtype),
        status=jnp.where(over0, STATUS["overturned"], STATUS["completed"]).astype(jnp.int32),
        t_overturn=jnp.where(over0, 0.0, jnp.inf).astype(dtype),
        done=over0,
    )

    def body(c):
        t_start = c["t"]
        i0 = jnp.searchsorted(ts, t_start, side="left")
        win = jax.lax.dynamic_slice(ts_pad, (i0,), (_WINDOW,))
        full = i0 + _WINDOW < n
        seg_t1 = jnp.where(full, win[-1], t1)
        args = (c["pivot"], c["X"], c["cl"], c["cr"], c["o0"], c["o1"], c["vsign"], c["o3"])
        sol = dfx.diffeqsolve(
            term, cfg["solver"], t_start, seg_t1, dt0, (c["q"], c["qd"]), args=args,
            saveat=dfx.SaveAt(subs=[dfx.SubSaveAt(ts=jnp.clip(win, t_start, seg_t1)),
                                    dfx.SubSaveAt(t1=True)]),
            stepsize_controller=controller, event=event, max_steps=cfg["max_steps"],
            throw=False, adjoint=adjoint,
        )
        (q_win, qd_win), tend = sol.ys[0], sol.ts[1][-1]
        q_end, qd_end = sol.ys[1][0][-1], sol.ys[1][1][-1]
        # outputs at the segment's end from its final state (diffrax issue #663: inf at an
        # output time equal to t1 when t1 is also a jump time)
        at_end = (jnp.clip(win, t_start, seg_t1) == tend)[:, None]
        q_win = jnp.where(at_end, q_end, q_win)
        qd_win = jnp.where(at_end, qd_end, qd_win)
        ok = (sol.result == dfx.RESULTS.successful) | (sol.result == dfx.RESULTS.event_occurred)
        fired = sol.event_mask & ok
        qdd_end = vector_field(tend, (q_end, qd_end), args)[1]
        vals, rates = conditions((q_end, qd_end), args, qdd_end)
        which = jnp.argmin(jnp.abs(vals) / (jnp.abs(rates) + 1e-300))
        hit_l = fired & (which == 0)
        hit_r = fired & (which == 1)
        hit_ot = fired & (which == 2)
        hit_turn = fired & (which == 3)

        # outputs on this window
        pivot, X = c["pivot"], c["X"]
        u_w = jax.vmap(lambda qq: top_x(s, qq, pivot, X))(q_win)
        v_w = jax.vmap(lambda qq, vv: top_xd(s, qq, vv, pivot))(q_win, qd_win)
        up_w = jnp.maximum(jnp.max(q_win, axis=1), 0.0)
        th_w = jax.vmap(lambda qq: geometry(s, qq)[1])(q_win)
        idx = i0 + window
        valid = (win >= t_start) & (win <= tend) & (idx < n)
        keep = jnp.minimum(idx, n - 1)

        def put(arr, new):
            return arr.at[idx].set(jnp.where(valid, new, arr[keep]), mode="drop")

        xe_end = top_x(s, q_end, pivot, X)
        peak_u = jnp.maximum(c["peak_u"], jnp.minimum(jnp.abs(xe_end), u_ot))
        peak_up = jnp.maximum(c["peak_up"], jnp.maximum(jnp.max(q_end), 0.0))

        # contact changes: new flags, the pivot, the friction impulse, Housner's impact
        cl = jnp.where(hit_l, 1.0 - c["cl"], c["cl"])
        cr = jnp.where(hit_r, 1.0 - c["cr"], c["cr"])
        new_pivot = _pivot_from(cl > 0, cr > 0, pivot)
        changed = (hit_l | hit_r) & (new_pivot != pivot)
        qd_new = jnp.where(changed, switch_pivot(s, q_end, qd_end, pivot, new_pivot), qd_end)
        _, th_end = geometry(s, q_end)
        x_o = x_base(s, th_end, pivot, X)
        X_new = jnp.where(new_pivot == 0, x_o, x_o + new_pivot * s.B * jnp.cos(th_end))
        X_new = jnp.where(changed, X_new, X)
        landing = (hit_l & (cl > 0)) | (hit_r & (cr > 0))
        real = landing & impact_mode
        # Housner's plastic impact (Eqs 2-3): the rotation rate drops to sqrt(r) of its value
        # and the landing corner stops (no rebound): y_o' = -/+ B cos(theta) theta'.
        w = sqrt_r * (qd_end[0] - qd_end[1])  # = 2 B cos(theta) theta'
        qd_imp = jnp.where(hit_l, jnp.stack([0.0 * w, -w]), jnp.stack([w, 0.0 * w]))
        qd_new = jnp.where(real, qd_imp, qd_new)
        n_imp = c["n_impacts"] + real.astype(jnp.int32)
        slot = jnp.minimum(c["n_impacts"], cfg["max_impacts"] - 1)
        impact_times = jnp.where(real, c["impact_times"].at[slot].set(tend), c["impact_times"])
        # offsets: a condition that just fired restarts from its current value
        raw, _ = conditions((q_end, qd_new), (new_pivot, X_new, cl, cr, 0.0, 0.0,
                                              c["vsign"], 0.0), jnp.zeros(2, dtype))
        vsign = jnp.where(hit_turn, -c["vsign"], c["vsign"])
        o0 = jnp.where(hit_l, raw[0], 0.0)
        o1 = jnp.where(hit_r, raw[1], 0.0)
        o3 = jnp.where(hit_turn, vsign * (qd_new[0] - qd_new[1]), 0.0)

        failed = ~ok
        reached = ok & ~fired & (tend >= t1)
        too_many = real & (n_imp >= cfg["max_impacts"])
        status = jnp.select(
            [failed, hit_ot, too_many],
            [STATUS["solver_failure"], STATUS["overturned"], STATUS["max_impacts"]],
            c["status"],
        ).astype(jnp.int32)
        return dict(
            t=tend, q=q_end, qd=qd_new, pivot=new_pivot.astype(fdt), X=X_new.astype(fdt),
            cl=cl.astype(fdt), cr=cr.astype(fdt), o0=o0.astype(fdt), o1=o1.astype(fdt),
            vsign=vsign.astype(fdt), o3=o3.astype(fdt), n_impacts=n_imp,
            impact_times=impact_times, out_u=put(c["out_u"], u_w), out_v=put(c["out_v"], v_w),
            out_th=put(c["out_th"], th_w), out_up=put(c["out_up"], up_w),
            peak_u=jnp.where(hit_ot, u_ot, peak_u), peak_up=peak_up, status=status,
            t_overturn=jnp.where(hit_ot, tend, c["t_overturn"]),
            done=failed | hit_ot | too_many | reached,
        )

    max_segments = 8 * cfg["max_impacts"] + 2 * (n // (_WINDOW - 1) + 1) + 64
    final = eqxi.while_loop(lambda c: ~c["done"], body, init, max_steps=max_segments,
                            kind=loop_kind)
    # the segment budget ran out before the end (e.g. a very stiff foundation's spring
    # oscillation): a solver failure, not a count of impacts
    status = jnp.where(final["done"], final["status"], STATUS["solver_failure"]).astype(jnp.int32)
    after = ts > final["t"]
    q_f, qd_f = final["q"], final["qd"]
    u_hold = top_x(s, q_f, final["pivot"], final["X"])
    v_hold = top_xd(s, q_f, qd_f, final["pivot"])
    u_out = jnp.where(after, u_hold, final["out_u"])
    v_out = jnp.where(after, v_hold, final["out_v"])
    th_out = jnp.where(after, geometry(s, q_f)[1], final["out_th"])
    up_out = jnp.where(after, jnp.maximum(jnp.max(q_f), 0.0), final["out_up"])
    u_out = jnp.where(over0, xe0, u_out)
    peak_up = jnp.maximum(final["peak_up"], jnp.max(up_out))
    return Response(
        ts=ts, u=u_out, v=v_out, theta=th_out, uplift=up_out,
        impact_times=final["impact_times"], n_impacts=final["n_impacts"],
        peak_u=final["peak_u"], peak_uplift=peak_up, status=status,
        t_overturn=final["t_overturn"],
    )


class _Cfg(eqx.Module):
    """Settings of the jitted 2-DOF core (all static but the solver)."""

    solver: object
    rtol: float = eqx.field(static=True)
    atol: float = eqx.field(static=True)
    max_steps: int = eqx.field(static=True)
    max_impacts: int = eqx.field(static=True)
    adjoint: str = eqx.field(static=True)
    dt: float | None = eqx.field(static=True)

    def __getitem__(self, key):
        return getattr(self, key)


def simulate_2dof(structure, model, excitation, t1, ts, r, *, solver, rtol, atol, max_steps,
                  max_impacts, adjoint, dt):
    """`rockjax.simulate` for `TwoSpring2DOF` (arguments already validated)."""
    if not isinstance(excitation, (FreeVibration, GroundMotion)):
        raise ValueError("two_spring_2dof supports FreeVibration and GroundMotion excitations")
    cfg = _Cfg(solver=solver, rtol=float(rtol), atol=float(atol), max_steps=int(max_steps),
               max_impacts=int(max_impacts), adjoint=adjoint,
               dt=None if dt is None else float(dt))
    dtype = jnp.result_type(structure.B)
    return _simulate_2dof(structure, model, excitation, jnp.asarray(t1, dtype),
                          jnp.asarray(ts, dtype), jnp.asarray(r, dtype), cfg)
