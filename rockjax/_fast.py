r"""The fast path: Eq. 1 integrated on a fixed grid, with every event located inside its step.

The event-restart loop of `rockjax.simulate` (one diffrax solve per segment between
events) is exact but, under `vmap`, every member waits for the slowest and each restart
costs a solver set-up. Here a whole batch advances together through the record, one
record interval at a time (optionally split into `substeps`), as arrays of shape
`(batch,)`: no padding to the slowest member, no per-segment overhead.

Within a step each member integrates one smooth branch of $k(u)$ (side of $u = 0$,
before or after lift-off; `AbstractRestoringForce.locked`). A trial step of classical
RK4 (or, with `method="adaptive"`, a Dormand–Prince 5(4) step with error control) is
checked for the events of `rockjax.simulate`:

- impact, $u$ crossing 0 (then $v \leftarrow \sqrt r\,v$, Eq. 2);
- lift-off and landing, $|u|$ crossing $u_{crit}$ (for models whose $k(u)$ jumps there);
- overturning, $|u|$ reaching $u_{overturn}$.

The earliest crossing is located on the cubic Hermite interpolant of the trial step
(safeguarded Newton, ending on a Newton step so that the event time has the implicit
derivative), the step is redone up to the event, the event is applied and the rest of the
step is integrated on the new branch: the result converges at the order of the method
although $k(u)$ has kinks and jumps. The peak $|u|$ between grid points comes from the
same interpolant. Everything is differentiable: reverse mode for the fixed-step method
(a fixed number of pieces per step, skipped by `lax.cond` when no member needs them) and
forward mode (`jax.jacfwd`) for the adaptive one.
"""

from __future__ import annotations

import types

import equinox as eqx
import jax
import jax.numpy as jnp

from ._response import STATUS
from ._structure import DERIVED

_FIELDS = ("m_e", "m_b", "H_e", "H_b", "B", "I_eg", "I_bg", "k_f", "g")

# Dormand–Prince 5(4): nodes, stage coefficients, 5th-order weights, error weights.
_DP_C = (0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0)
_DP_A = (
    (),
    (1 / 5,),
    (3 / 40, 9 / 40),
    (44 / 45, -56 / 15, 32 / 9),
    (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
    (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656),
    (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84),
)
_DP_B = (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0.0)
_DP_E = (
    35 / 384 - 5179 / 57600,
    0.0,
    500 / 1113 - 7571 / 16695,
    125 / 192 - 393 / 640,
    -2187 / 6784 + 92097 / 339200,
    11 / 84 - 187 / 2100,
    -1 / 40,
)


def constants(structure):
    """Every field and derived quantity of a structure, evaluated once (outside loops)."""
    ns = types.SimpleNamespace()
    for name in (*_FIELDS, *DERIVED, "mass"):
        setattr(ns, name, getattr(structure, name))
    return ns


def _hermite(a0, m0, a1, m1, s):
    """Cubic Hermite interpolant on [0, 1] (ends a0, a1; end slopes m0, m1) and d/ds."""
    s2 = s * s
    s3 = s2 * s
    val = (
        (2 * s3 - 3 * s2 + 1) * a0
        + (s3 - 2 * s2 + s) * m0
        + (3 * s2 - 2 * s3) * a1
        + (s3 - s2) * m1
    )
    der = (6 * s2 - 6 * s) * (a0 - a1) + (3 * s2 - 4 * s + 1) * m0 + (3 * s2 - 2 * s) * m1
    return val, der


def _hermite_root(a0, m0, a1, m1, level, iters=4):
    """The s in [0, 1] where the Hermite interpolant equals `level` (a0, a1 bracket it).

    Safeguarded Newton (bisection when a Newton step leaves the bracket), finishing with two
    plain Newton steps so that the root is converged and carries the implicit-function
    derivative.
    """
    g0 = a0 - level
    den = g0 - (a1 - level)
    safe = jnp.where(den != 0, den, 1.0)
    s = jnp.clip(jnp.where(den != 0, g0 / safe, 0.5), 0.0, 1.0)
    lo = jnp.zeros_like(s)
    hi = jnp.ones_like(s)
    for _ in range(iters):
        val, der = _hermite(a0, m0, a1, m1, s)
        g = val - level
        above = g * g0 > 0  # still on the starting side: the root lies beyond s
        lo = jnp.where(above, s, lo)
        hi = jnp.where(above, hi, s)
        ok = der != 0
        sn = s - g / jnp.where(ok, der, 1.0)
        s = jnp.where(ok & (sn > lo) & (sn < hi), sn, 0.5 * (lo + hi))
    for _ in range(2):  # plain Newton: converged, and the implicit-function derivative
        val, der = _hermite(a0, m0, a1, m1, s)
        ok = der != 0
        s = jnp.clip(s - jnp.where(ok, (val - level) / jnp.where(ok, der, 1.0), 0.0), 0.0, 1.0)
    return s


def _piece_peak(u0, v0, u1, v1, h):
    """max |u| over a step, from its cubic Hermite interpolant (exact ends, interior turn)."""
    m0 = v0 * h
    m1 = v1 * h
    turn = v0 * v1 < 0
    den = m0 - m1
    s = jnp.clip(jnp.where(turn, m0 / jnp.where(turn, den, 1.0), 0.5), 0.0, 1.0)
    A = 6 * (u0 - u1) + 3 * m0 + 3 * m1
    Bq = -6 * (u0 - u1) - 4 * m0 - 2 * m1
    for _ in range(2):  # Newton on H'(s) = A s^2 + B s + m0
        d1 = (A * s + Bq) * s + m0
        d2 = 2 * A * s + Bq
        s = jnp.clip(s - d1 / jnp.where(d2 != 0, d2, 1.0), 0.0, 1.0)
    mid, _ = _hermite(u0, m0, u1, m1, s)
    return jnp.maximum(jnp.maximum(jnp.abs(u0), jnp.abs(u1)), jnp.where(turn, jnp.abs(mid), 0.0))


class FastConfig(eqx.Module):
    """Static settings of the fast integrator (hashable; part of the compile key)."""

    model: object
    impact: str = eqx.field(static=True)
    method: str = eqx.field(static=True)  # "fixed" (RK4) or "adaptive" (Dormand–Prince 5(4))
    substeps: int = eqx.field(static=True)
    n_steps: int = eqx.field(static=True)
    free: bool = eqx.field(static=True)
    full: bool = eqx.field(static=True)
    max_impacts: int = eqx.field(static=True)
    max_pieces: int = eqx.field(static=True)
    rtol: float = eqx.field(static=True)
    atol: float = eqx.field(static=True)


def run(structure, table, rec, dt_rec, scale, u0, v0, r, t1, cfg: FastConfig):
    """Integrate a batch. Per-member arrays (`rec`, `scale`, `u0`, `v0`, `r`, structure
    fields) have shape `(N,)` or `()`; `table` is `(n_records, n_samples + pad)` [m/s²],
    zero beyond each record's end; `dt_rec` [s] the record step (the output grid step for
    a free vibration) and `t1` [s] the end time, both scalars.

    Returns a dict: peak_u, n_impacts, status, t_overturn (shape (N,)) and, with
    `cfg.full`, u and v on the grid (N, n_steps + 1) and impact_times (N, max_impacts).
    """
    c = constants(structure)
    model = cfg.model
    split = model.jumps_at_lift_off
    rigid = model.rigid
    dtype = jnp.result_type(c.B)
    shape = jnp.broadcast_shapes(
        (1,), *(jnp.shape(x) for x in (u0, v0, scale, r, rec, *vars(c).values()))
    )
    M = c.mass
    uc = jnp.zeros_like(c.u_crit) if rigid else c.u_crit
    uot = c.u_overturn
    sqrt_r = jnp.sqrt(r)
    zero = jnp.zeros(shape, dtype)
    u0 = u0 + zero
    v0 = v0 + zero

    def force(u, sgn, br):
        return model.locked(c, u, sgn, br)

    def nonzero_sign(x, fallback):
        return jnp.where(x > 0, 1.0, jnp.where(x < 0, -1.0, fallback)).astype(dtype)

    if cfg.free:
        first = jnp.ones(shape, dtype)
    else:
        nz = jnp.argmax(table != 0, axis=-1)  # first non-zero sample of each record
        a_first = table[jnp.arange(table.shape[0]), nz][rec]
        first = (-jnp.sign(scale * a_first) + zero).astype(dtype)
        first = jnp.where(first == 0, 1.0, first)
    sgn0 = nonzero_sign(u0, nonzero_sign(v0, first))
    over0 = jnp.abs(u0) >= uot
    E0 = 0.5 * M * v0**2 + jnp.abs(u0) * jnp.abs(model(c, u0))
    n_rec = table.shape[-1]

    if cfg.method == "fixed" and not rigid:
        # RK4 on the springs (pre-lift-off stiffness K1) is stable only for h sqrt(K1/M)
        # below about 2.8; beyond 2.5 the run would be wrong, so it is refused up front
        h_step = dt_rec / cfg.substeps
        unstable = h_step * jnp.sqrt(jnp.abs(c.K1) / M) > 2.5
        unstable = unstable & ~over0
    else:
        unstable = jnp.zeros(shape, bool)
    state = dict(
        u=u0,
        v=v0,
        sgn=sgn0,
        br=(jnp.abs(u0) >= uc) | rigid,
        lifted=(jnp.abs(u0) > uc) | rigid,
        peak=jnp.minimum(jnp.abs(u0), uot),
        n_imp=jnp.zeros(shape, jnp.int32),
        status=jnp.select([over0, unstable], [STATUS["overturned"], STATUS["solver_failure"]],
                          STATUS["completed"]).astype(jnp.int32)
        + jnp.zeros(shape, jnp.int32),
        done=over0 | unstable,
        t_ot=jnp.where(over0, 0.0, jnp.inf).astype(dtype) + zero,
        hprop=jnp.full(shape, jnp.inf, dtype),
    )
    if cfg.full:
        state["it"] = jnp.full((*shape, cfg.max_impacts), jnp.inf, dtype)
    # A rigid block (housner) on the ground stays at rest until the ground acceleration
    # exceeds the uplift threshold A = k(0+) / M; without this rule Eq. 1, whose force jumps
    # at u = 0, chatters through infinitely many impacts from rest.
    sticky = rigid and not cfg.free
    if sticky:
        A_up = model.locked(c, jnp.zeros(shape, dtype), jnp.ones(shape, dtype),
                            jnp.ones(shape, bool)) / M
        state["rest"] = (u0 == 0) & (v0 == 0) & ~over0

    def rk_step(u, v, tau, h, sgn, br, a0, da):
        def f(uu, tt):
            return -force(uu, sgn, br) / M - (a0 + da * tt)

        if cfg.method == "fixed":
            k1u, k1v = v, f(u, tau)
            k2u, k2v = v + 0.5 * h * k1v, f(u + 0.5 * h * k1u, tau + 0.5 * h)
            k3u, k3v = v + 0.5 * h * k2v, f(u + 0.5 * h * k2u, tau + 0.5 * h)
            k4u, k4v = v + h * k3v, f(u + h * k3u, tau + h)
            u1 = u + h / 6 * (k1u + 2 * k2u + 2 * k3u + k4u)
            v1 = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
            return u1, v1, None
        ku, kv = [], []
        for i in range(7):
            ui = u + h * sum(a * k for a, k in zip(_DP_A[i], ku))
            vi = v + h * sum(a * k for a, k in zip(_DP_A[i], kv))
            ku.append(vi)
            kv.append(f(ui, tau + _DP_C[i] * h))
        u1 = u + h * sum(b * k for b, k in zip(_DP_B, ku) if b)
        v1 = v + h * sum(b * k for b, k in zip(_DP_B, kv) if b)
        eu = h * sum(e * k for e, k in zip(_DP_E, ku) if e)
        ev = h * sum(e * k for e, k in zip(_DP_E, kv) if e)
        su = cfg.atol + cfg.rtol * jnp.maximum(jnp.abs(u), jnp.abs(u1))
        sv = cfg.atol + cfg.rtol * jnp.maximum(jnp.abs(v), jnp.abs(v1))
        err = jnp.maximum(jnp.abs(eu) / su, jnp.abs(ev) / sv)
        return u1, v1, err

    def release(st, L, a0, da, tau):
        """Resting rigid blocks: when, within [tau, L], |a_g| first exceeds A_up."""
        resting = st["rest"] & ~st["done"] & (tau < L)
        now = jnp.abs(a0 + da * tau) > A_up
        safe = jnp.where(da != 0, da, 1.0)
        cands = [(A_up - a0) / safe, (-A_up - a0) / safe]
        t_cross = jnp.full_like(tau, jnp.inf)
        for tc in cands:
            t_cross = jnp.minimum(t_cross, jnp.where((da != 0) & (tc > tau) & (tc <= L), tc,
                                                     jnp.inf))
        t_rel = jnp.where(now, tau, t_cross)
        released = resting & jnp.isfinite(t_rel)
        a_rel = a0 + da * jnp.where(released, t_rel, tau)
        tau = jnp.where(resting, jnp.where(released, t_rel, L), tau)
        sgn = jnp.where(released, jnp.where(a_rel > 0, -1.0, 1.0).astype(dtype), st["sgn"])
        return dict(st, sgn=sgn, rest=st["rest"] & ~released), tau

    def piece(st, L, t_start, a0, da, tau):
        """Advance every active member by one piece: a trial step, then the first event."""
        if sticky:
            st, tau = release(st, L, a0, da, tau)
        active = ~st["done"] & (tau < L)
        if sticky:
            active = active & ~st["rest"]
        u, v, sgn, br = st["u"], st["v"], st["sgn"], st["br"]
        rest_len = L - tau
        if cfg.method == "fixed":
            h = rest_len
        else:
            h = jnp.minimum(jnp.where(jnp.isfinite(st["hprop"]), st["hprop"], rest_len), rest_len)
        u1, v1, err = rk_step(u, v, tau, h, sgn, br, a0, da)
        if err is None:
            accept = jnp.ones_like(active)
            hprop = st["hprop"]
        else:
            err = jnp.where(jnp.isfinite(err), err, jnp.inf)
            accept = err <= 1.0
            fac = jnp.clip(0.9 * jnp.where(err > 0, err, 1e-10) ** -0.2, 0.2, 5.0)
            hprop = jnp.where(active, h * fac, st["hprop"])
        a_start = sgn * u
        a_end = sgn * u1
        if split:
            imp = ~br & (a_end <= 0)
            lift = ~br & (a_end >= uc)
            land = br & (a_end < uc)
            # overturning from either branch (a squat body on soft springs can reach
            # u_overturn before lift-off, u_crit > u_overturn); the lower level comes first
            ot = (a_end >= uot) & (br | ~lift | (uot <= uc))
            lift = lift & ~ot
        else:
            imp = a_end <= 0
            lift = land = jnp.zeros_like(imp)
            ot = a_end >= uot
        hit = (imp | lift | land | ot) & active & accept
        level = jnp.where(imp, 0.0, jnp.where(ot, uot, uc))
        s = _hermite_root(a_start, sgn * v * h, a_end, sgn * v1 * h, level)
        hp = jnp.where(hit, s * h, h)

        def redo(hp):
            ue, ve, _e = rk_step(u, v, tau, hp, sgn, br, a0, da)
            if cfg.method == "adaptive":
                # The cubic Hermite locates the event to O(h^4), below the 5th order of the
                # steps: two Newton corrections on the integrated solution itself.
                for _ in range(2):
                    rate = sgn * ve
                    corr = (sgn * ue - level) / jnp.where(rate != 0, rate, 1.0)
                    hp = jnp.where(hit, jnp.clip(hp - corr, 0.0, h), hp)
                    ue, ve, _e = rk_step(u, v, tau, hp, sgn, br, a0, da)
            return jnp.where(hit, ue, u1), jnp.where(hit, ve, v1), hp

        ue, ve, hp = jax.lax.cond(jnp.any(hit), redo, lambda hp: (u1, v1, hp), hp)
        ue = jnp.where(hit, sgn * level, ue)  # on the switching surface exactly
        ok = jnp.isfinite(ue) & jnp.isfinite(ve)
        step = active & accept & ok
        pp = _piece_peak(u, v, ue, ve, hp)
        peak = jnp.where(step, jnp.maximum(st["peak"], jnp.minimum(pp, uot)), st["peak"])
        t_ev = t_start + tau + hp
        if split:
            lifted = st["lifted"] | br | (hit & lift)
        else:
            lifted = st["lifted"] | (step & (pp > uc))
        imp_h = hit & imp & ok
        real = imp_h & (lifted if cfg.impact == "after_uplift" else True)
        v_new = jnp.where(real, sqrt_r * ve, ve)
        n_imp = st["n_imp"] + real.astype(jnp.int32)
        rest = imp_h & (0.5 * M * v_new**2 <= 1e-14 * E0) if cfg.free else jnp.zeros_like(hit)
        if sticky:  # the impacts of a settling block converge: it comes to rest
            settle = real & (0.5 * v_new**2 <= 1e-8 * A_up * c.B)
            v_new = jnp.where(settle, 0.0, v_new)
        too_many = real & (n_imp >= cfg.max_impacts)
        ot_h = hit & ot & ok
        failed = active & ~ok
        status = jnp.select(
            [failed, ot_h, too_many],
            [STATUS["solver_failure"], STATUS["overturned"], STATUS["max_impacts"]],
            st["status"],
        ).astype(jnp.int32)
        new = dict(
            u=jnp.where(step, jnp.where(rest, 0.0, ue), u),
            v=jnp.where(step, jnp.where(rest, 0.0, v_new), v),
            sgn=jnp.where(imp_h, -sgn, sgn),
            br=jnp.where(imp_h, rigid, jnp.where(hit & (lift | land), ~br, br)),
            lifted=jnp.where(real, rigid, lifted),
            peak=jnp.where(ot_h, uot, peak),
            n_imp=n_imp,
            status=status,
            done=st["done"] | failed | ot_h | too_many | rest,
            t_ot=jnp.where(ot_h, t_ev, st["t_ot"]),
            hprop=hprop,
        )
        if sticky:
            new["rest"] = st["rest"] | settle
        if cfg.full:
            it = st["it"]
            slot = jnp.minimum(st["n_imp"], cfg.max_impacts - 1)
            old = jnp.take_along_axis(it, slot[..., None], axis=-1)[..., 0]
            val = jnp.where(real, t_ev, old)
            new["it"] = jnp.put_along_axis(
                it, slot[..., None], val[..., None], axis=-1, inplace=False
            )
        tau_new = jnp.where(step, jnp.where(hit, tau + hp, tau + h), tau)
        tau_new = jnp.where(step & ~hit & (h >= rest_len), L, tau_new)
        return new, tau_new

    def substep(st, t_start, L, a0, a1):
        da = (a1 - a0) / L
        tau = jnp.zeros(shape, dtype)
        if cfg.method == "fixed":
            # a fixed number of pieces (reverse-mode differentiable), each skipped when no
            # member needs it; the last one integrates what is left without events
            def one_piece(x, _):
                return jax.lax.cond(
                    jnp.any(~x[0]["done"] & (x[1] < L)),
                    lambda x: piece(x[0], L, t_start, a0, da, x[1]),
                    lambda x: x,
                    x,
                ), None

            (st, tau), _ = jax.lax.scan(one_piece, (st, tau), None, length=cfg.max_pieces)

            def finish(x):
                st, tau = x
                todo = ~st["done"] & (tau < L)
                if sticky:
                    todo = todo & ~st["rest"]
                u1, v1, _ = rk_step(st["u"], st["v"], tau, L - tau, st["sgn"], st["br"], a0, da)
                ok = jnp.isfinite(u1) & jnp.isfinite(v1)
                st = dict(
                    st, u=jnp.where(todo & ok, u1, st["u"]), v=jnp.where(todo & ok, v1, st["v"])
                )
                return st, jnp.where(todo, L, tau)

            st, tau = jax.lax.cond(jnp.any(~st["done"] & (tau < L)), finish, lambda x: x, (st, tau))
            return st

        def cond(x):
            st, tau, k = x
            return jnp.any(~st["done"] & (tau < L)) & (k < cfg.max_pieces)

        def body(x):
            st, tau, k = x
            st, tau = piece(st, L, t_start, a0, da, tau)
            return st, tau, k + 1

        st, tau, k = jax.lax.while_loop(cond, body, (st, tau, jnp.zeros((), jnp.int32)))
        # a member that ran out of pieces has failed to advance: report it
        stuck = ~st["done"] & (tau < L)
        return dict(
            st,
            status=jnp.where(stuck, STATUS["solver_failure"], st["status"]),
            done=st["done"] | stuck,
        )

    sub = cfg.substeps

    def outer(st, k):
        t0 = k * dt_rec
        hk = jnp.minimum(dt_rec, t1 - t0)
        if cfg.free:
            a_lo = a_hi = jnp.zeros((), dtype)
        else:
            # right limit at the interval start (the record is zero after its end)
            a_lo = jnp.where(k < n_rec - 1, table[rec, k], 0.0) * scale
            a_hi = table[rec, jnp.minimum(k + 1, n_rec - 1)] * scale
            a_hi = jnp.where(k + 1 <= n_rec - 1, a_hi, 0.0)
        slope = (a_hi - a_lo) / dt_rec
        L = hk / sub

        def sub_body(st, j):
            j = j.astype(dtype)
            return substep(st, t0 + j * L, L, a_lo + slope * (j * L),
                           a_lo + slope * ((j + 1) * L)), None

        if sub == 1:
            st, _ = sub_body(st, jnp.zeros((), jnp.int32))
        else:
            st, _ = jax.lax.scan(sub_body, st, jnp.arange(sub))
        out = (st["u"], st["v"]) if cfg.full else None
        return st, out

    final, outs = jax.lax.scan(outer, state, jnp.arange(cfg.n_steps))
    res = dict(
        peak_u=final["peak"],
        n_impacts=final["n_imp"],
        status=final["status"],
        t_overturn=final["t_ot"],
    )
    if cfg.full:
        us, vs = outs
        res["u"] = jnp.concatenate([u0[None], us], axis=0)
        res["v"] = jnp.concatenate([v0[None], vs], axis=0)
        res["impact_times"] = final["it"]
    return res
