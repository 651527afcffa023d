r"""The floor of the batched stepper (issue 26): the same RK4 of the same SDOF, without
event location or impacts, as plain JAX arrays of shape (N,) in one `lax.fori_loop`.

What `simulate_batch(..., summary_only=True)` computes for a member in a step without an
event is a classical RK4 step of Eq. 1 under a ground acceleration linear within the step
(the record interval split into `substeps`), and the running peak |u|. This module writes
just that, by hand: the paper's `simplified` piecewise-linear restoring force evaluated on
|u| (no modes, no conditions, no jumps, no Hermite peaks between grid points), the members
as separate (N,) arrays for u, v and peak |u|, the record interpolated the way the stepper
does it (zero after its last sample), one `lax.fori_loop` over every RK4 step. It is not a
simulator (the structure never lands or impacts); it is the arithmetic every member pays
for in every step, the cost the stepper should approach.

On one device it is one jitted loop over all N members; on several (`devices=`) the members
are split the way `simulate_batch` splits them (`jax.shard_map` over a 1-D mesh, each device
running its own loop).

    from floor import floor_inputs, simulate_floor
    inp = floor_inputs(rockjax.mcmanus_column(), gm, 40.0)
    peak = simulate_floor(**inp, scales=np.linspace(0.25, 1.5, 10_000), devices=2)

`benchmarks/run.py --only yardstick` times it beside `simulate_batch` and the numba peer.
Units: SI (m, s, N, kg; accelerations m/s²).
"""

from __future__ import annotations

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np

#: parameters of the simplified law, in the order the kernel takes them (as numba_peer)
PARAMS = ("K1", "P_crit2", "u_crit", "u_overturn", "mass")


def floor_inputs(structure, gm, t1):
    """The floor's inputs from a rockjax structure and `GroundMotion` (one record): the
    law's constants, the record [m/s²] padded with zeros, its step [s], samples, end [s]."""
    p = np.array([float(getattr(structure, k)) for k in PARAMS])
    accel = np.asarray(gm.accel, float) * float(gm.scale)
    dt = float(gm.dt)
    n_steps = int(math.ceil(t1 / dt - 1e-9))
    n_tab = max(accel.size, n_steps + 2)
    table = np.concatenate([accel, np.zeros(n_tab - accel.size)])
    return dict(params=p, table=table, n_rec=accel.size, dt=dt, t1=float(t1))


def _force(p, u):
    """k(u) [N] of the simplified law, branch-free (`rockjax.models.Simplified`)."""
    K1, P2, uc, uo = p[0], p[1], p[2], p[3]
    a = jnp.abs(u)
    post = jnp.sign(u) * ((a - uo) * (P2 / (uc - uo)))  # as `rockjax.models.Simplified`
    return jnp.where(a > uc, post, K1 * u)


def _kernel(p, table, scale, *, n_rec, dt, t1, n_steps, substeps, stacked=False):
    """Peak |u| [m] of each member (shape (N,)) over `n_steps` record intervals of
    `substeps` RK4 steps each. |u| is held at u_overturn (the stepper stops a member
    there), so that the arithmetic stays finite for the scales that overturn.

    `stacked`: the state as one (2, N) array (u and v each contiguous over the members,
    as the stepper lays it out) instead of two (N,) arrays: XLA then evaluates the RK4
    chain once, where with separate arrays it fuses one loop per output (u, v, peak),
    each evaluating the chain again."""
    inv_m = 1.0 / p[4]
    uo = p[3]
    n_tab = table.shape[0]
    zero = jnp.zeros_like(scale)

    def acc(u, a_g):
        return -_force(p, u) * inv_m - a_g

    def step(i):
        """RK4 step i (substep j of record interval k): its length [s] and the ground
        acceleration at its start, middle and end [m/s²] (the record zero after its end)."""
        k, j = i // substeps, i % substeps
        hk = jnp.minimum(dt, t1 - k * dt)
        a_lo = jnp.where(k < n_rec - 1, table[k], 0.0) * scale
        a_hi = jnp.where(k + 1 <= n_rec - 1, table[jnp.minimum(k + 1, n_tab - 1)], 0.0) * scale
        slope = (a_hi - a_lo) / dt
        h = hk / substeps
        a0 = a_lo + slope * (j * h)
        am = a_lo + slope * ((j + 0.5) * h)
        a1 = a_lo + slope * ((j + 1) * h)
        return h, a0, am, a1

    def body(i, c):  # one RK4 step
        if stacked:
            return body_stacked(i, *c)
        u, v, peak = c
        h, a0, am, a1 = step(i)
        k1u, k1v = v, acc(u, a0)
        k2u, k2v = v + 0.5 * h * k1v, acc(u + 0.5 * h * k1u, am)
        k3u, k3v = v + 0.5 * h * k2v, acc(u + 0.5 * h * k2u, am)
        k4u, k4v = v + h * k3v, acc(u + h * k3u, a1)
        u = jnp.clip(u + h / 6.0 * (k1u + 2.0 * k2u + 2.0 * k3u + k4u), -uo, uo)
        v = v + h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
        return u, v, jnp.maximum(peak, jnp.abs(u))

    def flow(y, a_g):  # (u, v)' as one (2, N) array, as the stepper's vector field
        return jnp.stack([y[1], acc(y[0], a_g)])

    def body_stacked(i, y, peak):  # the same step on the state as one (2, N) array
        h, a0, am, a1 = step(i)
        k1 = flow(y, a0)
        k2 = flow(y + 0.5 * h * k1, am)
        k3 = flow(y + 0.5 * h * k2, am)
        k4 = flow(y + h * k3, a1)
        y = y + h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
        y = jnp.stack([jnp.clip(y[0], -uo, uo), y[1]])
        return y, jnp.maximum(peak, jnp.abs(y[0]))

    # one loop over every step (a loop over the record intervals with the substeps
    # unrolled inside measured 2.4x slower: XLA recomputes the unrolled chain per output)
    init = (jnp.stack([zero, zero]), zero) if stacked else (zero, zero, zero)
    return jax.lax.fori_loop(0, n_steps * substeps, body, init)[-1]


@functools.cache
def _compiled(n_devices, n_rec, dt, t1, n_steps, substeps, stacked=False):
    kernel = functools.partial(_kernel, n_rec=n_rec, dt=dt, t1=t1, n_steps=n_steps,
                               substeps=substeps, stacked=stacked)
    if n_devices == 1:
        return jax.jit(kernel)
    P = jax.sharding.PartitionSpec
    mesh = jax.sharding.Mesh(np.array(jax.local_devices()[:n_devices]), ("batch",))
    return jax.jit(jax.shard_map(kernel, mesh=mesh, in_specs=(P(), P(), P("batch")),
                                 out_specs=P("batch"), check_vma=False))


def simulate_floor(params, table, n_rec, dt, t1, scales, substeps=4, devices=1,
                   stacked=False):
    """Peak |u| [m] of one floor run per scale (shape (N,)), on `devices` local devices
    (N is padded to a multiple of them); `stacked`: the state as one (2, N) array."""
    scales = np.asarray(scales, float)
    n = scales.size
    pad = -n % devices
    sc = np.concatenate([scales, np.full(pad, scales[-1] if n else 1.0)])
    n_steps = int(math.ceil(t1 / dt - 1e-9))
    f = _compiled(int(devices), int(n_rec), float(dt), float(t1), n_steps, int(substeps),
                  bool(stacked))
    out = f(jnp.asarray(params), jnp.asarray(table), jnp.asarray(sc))
    return jax.block_until_ready(out)[:n]


def member_steps(t1, dt, substeps, n):
    """Member-steps of n runs to `t1` [s] on record step `dt` [s] with `substeps`."""
    return n * int(math.ceil(t1 / dt - 1e-9)) * substeps
