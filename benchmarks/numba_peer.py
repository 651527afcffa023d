r"""A hand-written numba peer of rockjax's fast path (`simulate_batch(method="rk4")`), the
yardstick for its speed (issue 15).

The same algorithm, written as a scalar loop per run and `numba.prange` over the runs: the
paper's SDOF Eq. 1 with the piecewise-linear `simplified` restoring force and the `paper`
impact rule (every crossing of u = 0 is an impact, v <- sqrt(r) v), under a ground motion
that is linear within each record interval (zero after the record's last sample, as
rockjax's `GroundMotion`). Each record interval is split into `substeps` classical RK4 steps.
Within a step the events (impact at u = 0, overturning at |u| = u_overturn, lift-off and
landing at |u| = u_crit, as `rockjax.models.SDOF.conditions`) are found from the
conditions at both ends of a trial step, the earliest is located on the cubic Hermite
interpolant of its condition (safeguarded Newton, then two plain Newton steps), the step is
redone up to it, the jump applied and the rest of the step integrated in the new mode, at
most `max_pieces` pieces per step (the last remainder without events). The peak |u| of a
piece comes from the Hermite interpolant of u. It follows rockjax's arithmetic operation by
operation, so the two agree to rounding (see `benchmarks/run.py --only yardstick`).

numba is an optional extra (`pip install -e ".[bench]"`); rockjax itself never imports it.

    from numba_peer import peer_inputs, simulate_peer
    out = simulate_peer(**peer_inputs(rockjax.mcmanus_column(), gm, 40.0), scales=scales)
    out["peak_u"], out["n_impacts"], out["status"], out["t_overturn"]

Units: SI (m, s, N, kg; accelerations m/s²). Status codes as `rockjax.Status`: 0
completed, 1 overturned, 2 max_impacts, 3 solver_failure.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import njit, prange

#: parameters of the simplified law, in the order the kernels take them
PARAMS = ("K1", "P_crit2", "u_crit", "u_overturn", "mass")


@njit(inline="always")
def _acc(u, sign, branch, K1, P2, u_crit, u_ot, mass, a_g):
    """du/dt of Eq. 1 on one smooth branch [m/s²] (`Simplified.branch`)."""
    if branch:
        k = sign * ((sign * u - u_ot) * (P2 / (u_crit - u_ot)))
    else:
        k = K1 * u
    return -k * (1.0 / mass) - a_g


@njit(inline="always")
def _rk4(u, v, sign, branch, p, tau, h, a0, da):
    """One classical RK4 step of `h` [s] from `tau` [s] on a fixed branch, the ground
    acceleration `a0 + da * t` [m/s²]; the operations in rockjax's order."""
    K1, P2, uc, uo, m = p[0], p[1], p[2], p[3], p[4]
    k1u = v
    k1v = _acc(u, sign, branch, K1, P2, uc, uo, m, a0 + da * tau)
    u2 = u + h * (0.5 * k1u)
    v2 = v + h * (0.5 * k1v)
    t2 = tau + 0.5 * h
    k2u = v2
    k2v = _acc(u2, sign, branch, K1, P2, uc, uo, m, a0 + da * t2)
    u3 = u + h * (0.5 * k2u)
    v3 = v + h * (0.5 * k2v)
    k3u = v3
    k3v = _acc(u3, sign, branch, K1, P2, uc, uo, m, a0 + da * t2)
    u4 = u + h * k3u
    v4 = v + h * k3v
    k4u = v4
    k4v = _acc(u4, sign, branch, K1, P2, uc, uo, m, a0 + da * (tau + h))
    c6 = 1.0 / 6.0
    c3 = 1.0 / 3.0
    u1 = u + h * (c6 * k1u + c3 * k2u + c3 * k3u + c6 * k4u)
    v1 = v + h * (c6 * k1v + c3 * k2v + c3 * k3v + c6 * k4v)
    return u1, v1


@njit(inline="always")
def _hermite(a0, m0, a1, m1, s):
    """Cubic Hermite interpolant on [0, 1] and its derivative (`_hermite.hermite`)."""
    s2 = s * s
    s3 = s2 * s
    val = ((2 * s3 - 3 * s2 + 1) * a0 + (s3 - 2 * s2 + s) * m0 + (3 * s2 - 2 * s3) * a1
           + (s3 - s2) * m1)
    der = (6 * s2 - 6 * s) * (a0 - a1) + (3 * s2 - 4 * s + 1) * m0 + (3 * s2 - 2 * s) * m1
    return val, der


@njit(inline="always")
def _hermite_root(a0, m0, a1, m1):
    """The s in [0, 1] where the Hermite interpolant vanishes (`_hermite.hermite_root`)."""
    den = a0 - a1
    s = 0.5 if den == 0 else a0 / den
    s = min(max(s, 0.0), 1.0)
    lo = 0.0
    hi = 1.0
    for _ in range(4):
        g, der = _hermite(a0, m0, a1, m1, s)
        if g * a0 > 0:
            lo = s
        else:
            hi = s
        if der != 0:
            sn = s - g / der
            s = sn if (sn > lo and sn < hi) else 0.5 * (lo + hi)
        else:
            s = 0.5 * (lo + hi)
    for _ in range(2):
        g, der = _hermite(a0, m0, a1, m1, s)
        if der != 0:
            s = min(max(s - g / der, 0.0), 1.0)
    return s


@njit(inline="always")
def _piece_peak(u0, v0, u1, v1, h):
    """max |u| [m] over a piece from its Hermite interpolant (`_hermite.piece_peak`)."""
    m0 = v0 * h
    m1 = v1 * h
    peak = max(abs(u0), abs(u1))
    if v0 * v1 < 0:
        s = min(max(m0 / (m0 - m1), 0.0), 1.0)
        A = 6 * (u0 - u1) + 3 * m0 + 3 * m1
        Bq = -6 * (u0 - u1) - 4 * m0 - 2 * m1
        for _ in range(2):
            d1 = (A * s + Bq) * s + m0
            d2 = 2 * A * s + Bq
            s = min(max(s - d1 / (d2 if d2 != 0 else 1.0), 0.0), 1.0)
        mid, _ = _hermite(u0, m0, u1, m1, s)
        peak = max(peak, abs(mid))
    return peak


@njit(inline="always")
def _conditions(u, v, sign, branch, p):
    """The three event conditions and their rates (`SDOF.conditions` and its jvp)."""
    a = sign * u
    da = sign * v
    c2 = a - p[2] if branch else p[2] - a
    d2 = da if branch else -da
    return a, p[3] - a, c2, da, -da, d2


@njit(inline="always")
def _fired(g0, g1):
    return (g1 < 0) or (g1 <= 0 and g0 > 0)


@njit(inline="always")
def _locate(g0, dg0, g1, dg1, f, h):
    """(which, s) of the earliest fired condition: linear estimate, then Hermite root."""
    best = 3.0
    which = 0
    for i in range(3):
        den = g0[i] - g1[i]
        lin = (g0[i] / (den if den != 0 else 1.0)) if f[i] else 2.0
        if lin < best:
            best = lin
            which = i
    return which, _hermite_root(g0[which], dg0[which] * h, g1[which], dg1[which] * h)


@njit
def _run_one(p, sqrt_r, table, n_rec, dt, t1, n_steps, scale, substeps, max_pieces,
             max_impacts, a_first):
    """One run: (peak |u| [m], impacts, status, overturning time [s])."""
    u_crit, u_ot = p[2], p[3]
    first = -np.sign(scale * a_first)
    sign = first if first != 0 else 1.0
    u = 0.0
    v = 0.0
    branch = False
    peak_u = 0.0
    n_imp = 0
    status = 0
    t_ot = math.inf
    omega = math.sqrt(abs(p[0]) / p[4])
    if omega * (dt / substeps) > 2.5:
        return peak_u, n_imp, 3, t_ot
    g0 = np.empty(3)
    dg0 = np.empty(3)
    g1 = np.empty(3)
    dg1 = np.empty(3)
    f = np.empty(3, np.bool_)
    for k in range(n_steps):
        t0 = k * dt
        hk = min(dt, t1 - t0)
        a_lo = (table[k] if k < n_rec - 1 else 0.0) * scale
        a_hi = (table[min(k + 1, table.size - 1)] if k + 1 <= n_rec - 1 else 0.0) * scale
        slope = (a_hi - a_lo) / dt
        L = hk / substeps
        for j in range(substeps):
            jf = float(j)
            t_start = t0 + jf * L
            a0 = a_lo + slope * (jf * L)
            da = (a_lo + slope * ((jf + 1.0) * L) - a0) / L
            tau = 0.0
            for _ in range(max_pieces):
                if not tau < L:
                    break
                h = L - tau
                u1, v1 = _rk4(u, v, sign, branch, p, tau, h, a0, da)
                g0[0], g0[1], g0[2], dg0[0], dg0[1], dg0[2] = _conditions(u, v, sign, branch, p)
                g1[0], g1[1], g1[2], dg1[0], dg1[1], dg1[2] = _conditions(u1, v1, sign, branch, p)
                hit = False
                for i in range(3):
                    f[i] = _fired(g0[i], g1[i])
                    hit = hit or f[i]
                hp = h
                which = 0
                if hit:
                    which, root = _locate(g0, dg0, g1, dg1, f, h)
                    hp = root * h
                    u1, v1 = _rk4(u, v, sign, branch, p, tau, hp, a0, da)
                if not (math.isfinite(u1) and math.isfinite(v1)):
                    return peak_u, n_imp, 3, t_ot
                peak_u = max(peak_u, min(_piece_peak(u, v, u1, v1, hp), u_ot))
                u, v = u1, v1
                if not hit:
                    tau = L
                    continue
                t_ev = t_start + tau + hp
                tau = tau + hp
                if which == 0:  # impact: v <- sqrt(r) v on the other side
                    v = sqrt_r * v
                    u = 0.0 * v
                    sign = -sign
                    branch = False
                    n_imp += 1
                    if n_imp >= max_impacts:
                        return peak_u, n_imp, 2, t_ot
                elif which == 1:  # overturning
                    return u_ot, n_imp, 1, t_ev
                else:  # lift-off or landing
                    u = sign * u_crit
                    branch = not branch
            if tau < L:  # the pieces ran out: the rest of the step without events
                u1, v1 = _rk4(u, v, sign, branch, p, tau, L - tau, a0, da)
                if not (math.isfinite(u1) and math.isfinite(v1)):
                    return peak_u, n_imp, 3, t_ot
                u, v = u1, v1
    return peak_u, n_imp, status, t_ot


@njit(parallel=True)
def _run_all(p, sqrt_r, table, n_rec, dt, t1, n_steps, scales, substeps, max_pieces,
             max_impacts, a_first, peak_u, n_imp, status, t_ot):
    for i in prange(scales.size):
        peak_u[i], n_imp[i], status[i], t_ot[i] = _run_one(
            p, sqrt_r, table, n_rec, dt, t1, n_steps, scales[i], substeps, max_pieces,
            max_impacts, a_first)


def peer_inputs(structure, gm, t1):
    """The peer's inputs from a rockjax structure and `GroundMotion` (one record): the
    law's constants, sqrt(r), the record [m/s²] padded with zeros, its step [s], end [s]."""
    p = np.array([float(getattr(structure, k)) for k in PARAMS])
    accel = np.asarray(gm.accel, float) * float(gm.scale)
    dt = float(gm.dt)
    n_steps = int(math.ceil(t1 / dt - 1e-9))
    n_tab = max(accel.size, n_steps + 2)
    table = np.concatenate([accel, np.zeros(n_tab - accel.size)])
    return dict(params=p, r=float(structure.restitution), table=table, n_rec=accel.size,
                dt=dt, t1=float(t1))


def simulate_peer(params, r, table, n_rec, dt, t1, scales, substeps=4, max_pieces=4,
                  max_impacts=1024, threads=None):
    """Summaries of one run per scale (arrays of shape (N,)): peak_u [m], n_impacts,
    status, t_overturn [s]. `threads`: numba threads (default all)."""
    scales = np.ascontiguousarray(scales, float)
    n = scales.size
    out = dict(peak_u=np.zeros(n), n_impacts=np.zeros(n, np.int64),
               status=np.zeros(n, np.int64), t_overturn=np.full(n, np.inf))
    nz = np.flatnonzero(table != 0)
    a_first = float(table[nz[0]]) if nz.size else 0.0
    n_steps = int(math.ceil(t1 / dt - 1e-9))
    old = numba.get_num_threads()
    numba.set_num_threads(threads or numba.config.NUMBA_NUM_THREADS)
    try:
        _run_all(np.asarray(params, float), math.sqrt(r), table, int(n_rec), float(dt),
                 float(t1), n_steps, scales, int(substeps), int(max_pieces), int(max_impacts),
                 a_first, out["peak_u"], out["n_impacts"], out["status"], out["t_overturn"])
    finally:
        numba.set_num_threads(old)
    return out
