r"""The batched stepper: any rocking model on a fixed grid, events located inside the step.

A whole batch advances together through the record, one record interval at a time
(optionally split into `substeps`), as arrays with a leading batch axis: no padding to the
slowest member, no per-segment solver set-up. The model's methods are written for one
member and `jax.vmap`ped here.

Within a step each member integrates its current mode. A trial step of classical RK4
(`method="rk4"`) or of Dormand–Prince 5(4) with error control (`method="dopri5"`; both
from diffrax `ButcherTableau`s) is checked for the model's event conditions: a condition
that falls to 0 fires. The earliest root is located on the cubic Hermite interpolant of
each fired condition (safeguarded Newton, ending on Newton steps so that the event time
has its implicit derivative), the step is redone up to it, the model's jump is applied,
and the rest of the step continues in the new mode: the result converges at the order
of the method although the forces have kinks and jumps. The peak $|u|$ between grid points
comes from the Hermite interpolant of the observed $u$.

With `rk4` a large batch (`COMPACT_MIN` members or more) pays for the events only where
they happen: one trial step for the whole batch, and the few members with an event in it
(about 2 % on an earthquake record) take the pieces in a gathered sub-batch
(`_compacted`), instead of every piece running for the whole batch whenever one member
needs it (measured in `benchmarks/run.py --only yardstick`, beside the floor of
`benchmarks/floor.py`: the same RK4 without events). The whole-batch trial computes the
conditions at its end without their rates (only the sub-batch locates roots; those at the
start only in a step where a member ends one exactly at 0), the peak's interior turn only
in a step where it could raise a member's peak (`piece_peak`'s Bernstein-hull test), and
the sub-batch is indexed by `first_members`, not `jnp.nonzero`. Events come in bursts: below
lift-off the response is linear in the scale, so the members of a scale sweep cross
u = 0 in the same step, and the sub-batch then takes several rounds. Its rounds are a
`lax.while_loop`, so the compacted path is not reverse-differentiable; only
`simulate_batch`, whose results are concrete arrays, runs batches that large (a
differentiated `simulate`, also under `jax.vmap`, is a batch of one).

Reverse-mode differentiable with `rk4` (a fixed number of pieces per step, each skipped by
`lax.cond` when no member needs it), forward mode (`jax.jacfwd`) with `dopri5`.
"""

from __future__ import annotations

import diffrax as dfx
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ._hermite import hermite_root, piece_peak, root_estimate
from ._tally import Tally, tally_event, tally_fail, tally_peak, tally_start

#: classical Runge–Kutta 4 as a diffrax tableau (diffrax ships no RK4 solver)
RK4_TABLEAU = dfx.ButcherTableau(
    c=np.array([0.5, 0.5, 1.0]),
    b_sol=np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6]),
    b_error=np.zeros(4),
    a_lower=(np.array([0.5]), np.array([0.0, 0.5]), np.array([0.0, 0.0, 1.0])),
)
METHODS = {"rk4": RK4_TABLEAU, "dopri5": dfx.Dopri5.tableau}


class StepperConfig(eqx.Module):
    """Static settings of the stepper (hashable; part of the compile key)."""

    method: str = eqx.field(static=True)  # "rk4" (fixed steps) or "dopri5" (adaptive)
    substeps: int = eqx.field(static=True)
    n_steps: int = eqx.field(static=True)
    forced: bool = eqx.field(static=True)
    full: bool = eqx.field(static=True)
    max_impacts: int = eqx.field(static=True)
    max_pieces: int = eqx.field(static=True)
    rtol: float = eqx.field(static=True)
    atol: float = eqx.field(static=True)
    #: None: the model's `recrossing_conditions`
    grazing_roots: bool | None = eqx.field(static=True, default=None)


class Member(eqx.Module):
    """The carry of one member: state, mode, record, and the proposed step (dopri5)."""

    y: jnp.ndarray
    mode: object
    tally: Tally
    hprop: jnp.ndarray


def per_member(f, s):
    """`f(s, *args)` mapped over the members (`jax.vmap`), the members on the **last** axis
    of every argument and result (a member's state of d values is a (d, N) array: each
    component contiguous over the members, which XLA vectorises; (N, d) interleaved ran
    the same RK4 about 2.9x slower). The structure's leaves that vary per member (shape
    (N,)) are mapped and the shared ones (shape ()) are not, so that a shared structure is
    not copied into every member; every other argument is mapped."""
    axes = jax.tree_util.tree_map(lambda x: 0 if jnp.ndim(x) == 1 else None, s)
    return lambda *args: jax.vmap(f, in_axes=(axes,) + (-1,) * len(args),
                                  out_axes=-1)(s, *args)


def tree_where(pred, a, b):
    """`jnp.where` leaf by leaf, `pred` (shape (N,)) broadcast against each leaf's last
    axis, the members' (`per_member`)."""
    return jax.tree_util.tree_map(lambda x, z: jnp.where(pred, x, z), a, b)


def rk_step(model, s, y, mode, tau, h, a0, da, cfg):
    """One explicit Runge–Kutta step of `h` [s] from `tau` in a fixed mode, the ground
    acceleration linear in time, `a0 + da * t` [m/s²]. Returns (y1, scaled error)."""
    tab = METHODS[cfg.method]

    def f(yy, tt):
        return model.vector_field(s, yy, mode, a0 + da * tt)

    ks = [f(y, tau)]
    for c, a in zip(tab.c, tab.a_lower):
        yi = y + h * sum(float(ai) * k for ai, k in zip(a, ks) if ai != 0)
        ks.append(f(yi, tau + float(c) * h))
    y1 = y + h * sum(float(b) * k for b, k in zip(tab.b_sol, ks) if b != 0)
    if cfg.method == "rk4":
        return y1, jnp.zeros((), y.dtype)
    e = h * sum(float(b) * k for b, k in zip(tab.b_error, ks) if b != 0)
    scale = cfg.atol + cfg.rtol * jnp.maximum(jnp.abs(y), jnp.abs(y1))
    return y1, jnp.max(jnp.abs(e) / scale)


def _conditions_and_rates(model, s, y, mode, a, da, flow):
    """The model's event conditions and their time derivatives along the flow."""
    a = jnp.asarray(a, y.dtype)
    return jax.jvp(lambda yy, aa: model.conditions(s, yy, mode, aa), (y, a),
                   (flow.astype(y.dtype), jnp.asarray(da, y.dtype)))


class Trial(eqx.Module):
    """A member's trial step: its end, error, and the conditions at both ends."""

    y1: jnp.ndarray
    err: jnp.ndarray
    g0: jnp.ndarray
    dg0: jnp.ndarray
    g1: jnp.ndarray
    dg1: jnp.ndarray


def trial(model, cfg, s, y, mode, tau, h, a0, da, y1=None):
    """A trial step of one member and its conditions (values and rates) at both ends
    (`y1`: its end, when known already: rk4 only)."""
    if y1 is None:
        y1, err = rk_step(model, s, y, mode, tau, h, a0, da, cfg)
    else:
        err = jnp.zeros((), y.dtype)
    a_s, a_e = a0 + da * tau, a0 + da * (tau + h)
    g0, dg0 = _conditions_and_rates(model, s, y, mode, a_s, da,
                                    model.vector_field(s, y, mode, a_s))
    g1, dg1 = _conditions_and_rates(model, s, y1, mode, a_e, da,
                                    model.vector_field(s, y1, mode, a_e))
    return Trial(y1, err, g0, dg0, g1, dg1)


def fired(tr):
    """Which conditions fell to 0 over the step: below 0 at its end, or reaching exactly 0
    from above (a condition resting at 0, e.g. a body at rest at u = 0, does not fire)."""
    return (tr.g1 < 0) | ((tr.g1 <= 0) & (tr.g0 > 0))


def locate(model, cfg, s, y, mode, tau, h, a0, da, tr, fire):
    """The earliest event of a member: (state at it, step to it [s], which condition).

    The fired conditions are ordered by the linear estimate of their roots; the earliest
    is then located on its cubic Hermite interpolant (one root find, not one per
    condition: the batch pays for every piece any member needs).
    """
    # a condition that leaves its surface at a jump and crosses it again later in the
    # step (rigid_body: a landing, then the lift-off on the other corner) is located at
    # the crossing, where the model asks for it (`recrossing_conditions`)
    gr = model.recrossing_conditions if cfg.grazing_roots is None else cfg.grazing_roots
    lin = jnp.where(fire, root_estimate(tr.g0, tr.dg0 * h, tr.g1, tr.dg1 * h, gr), 2.0)
    which = jnp.argmin(lin).astype(jnp.int32)
    root = hermite_root(tr.g0[which], tr.dg0[which] * h, tr.g1[which], tr.dg1[which] * h,
                        grazing=gr)
    hp = root * h
    ye, _ = rk_step(model, s, y, mode, tau, hp, a0, da, cfg)
    if cfg.method == "dopri5":
        # The cubic Hermite locates the event to O(h^4), below the 5th order of the
        # steps: two Newton corrections on the integrated solution itself.
        for _ in range(2):
            a = a0 + da * (tau + hp)
            g, dg = _conditions_and_rates(model, s, ye, mode, a, da,
                                          model.vector_field(s, ye, mode, a))
            corr = g[which] / jnp.where(dg[which] != 0, dg[which], 1.0)
            hp = jnp.clip(hp - corr, 0.0, h)
            ye, _ = rk_step(model, s, y, mode, tau, hp, a0, da, cfg)
    return ye, hp, which


def _step_size(cfg, st, active, rest_len):
    if cfg.method == "rk4":
        return rest_len
    h = jnp.where(jnp.isfinite(st.hprop), st.hprop, rest_len)
    return jnp.minimum(h, rest_len)


def _accept(cfg, st, tr, h, active):
    """(accepted, next proposed step) from the trial's error (always accepted for rk4)."""
    if cfg.method == "rk4":
        return jnp.ones_like(active), st.hprop
    err = jnp.where(jnp.isfinite(tr.err), tr.err, jnp.inf)
    fac = jnp.clip(0.9 * jnp.where(err > 0, err, 1e-10) ** -0.2, 0.2, 5.0)
    return err <= 1.0, jnp.where(active, h * fac, st.hprop)


def piece(model, cfg, s, r, st, tau, L, t_start, a0, da, y1=None):
    """Advance every active member by one piece: a trial step, then its first event.
    `y1`: the trial step's end when it is known already (rk4, the first piece of a step)."""
    active = ~st.tally.done & (tau < L)
    rest_len = L - tau
    h = _step_size(cfg, st, active, rest_len)
    if y1 is None:
        tr = per_member(lambda *a: trial(model, cfg, *a), s)(st.y, st.mode, tau, h, a0, da)
    else:
        tr = per_member(lambda *a: trial(model, cfg, *a), s)(st.y, st.mode, tau, h, a0, da,
                                                             y1)
    accept, hprop = _accept(cfg, st, tr, h, active)
    fire = fired(tr) & (active & accept)
    hit = jnp.any(fire, axis=0)

    def with_events(_):
        return per_member(lambda *a: locate(model, cfg, *a), s)(st.y, st.mode, tau, h, a0, da,
                                                               tr, fire)

    def without(_):
        return tr.y1, h, jnp.zeros(h.shape, jnp.int32)

    ye, hp, which = jax.lax.cond(jnp.any(hit), with_events, without, None)
    ye = jnp.where(hit, ye, tr.y1)
    hp = jnp.where(hit, hp, h)
    ok = jnp.all(jnp.isfinite(ye), axis=0)
    step = active & accept & ok
    st = _advance(model, cfg, s, r, st, ye, hp, which, hit & step, step, active & ~ok,
                  t_start + tau + hp, a0 + da * (tau + hp))
    st = eqx.tree_at(lambda m: m.hprop, st, hprop)
    tau_new = jnp.where(step, jnp.where(hit, tau + hp, tau + h), tau)
    tau_new = jnp.where(step & ~hit & (h >= rest_len), L, tau_new)
    return st, tau_new


def _advance(model, cfg, s, r, st, ye, hp, which, event, step, failed, t_ev, a_ev):
    """The bookkeeping of a piece: peaks, the jump at an event, the record."""
    q0, dq0 = per_member(model.peak_coordinate, s)(st.y, st.mode)
    q1, dq1 = per_member(model.peak_coordinate, s)(ye, st.mode)
    q_ot = per_member(lambda s_, _: model.peak_limit(s_), s)(hp)
    peak = piece_peak(q0, dq0, q1, dq1, hp)
    up = per_member(model.tracked_uplift, s)(ye, st.mode)
    tally = tree_where(step, tally_peak(st.tally, peak, up, q_ot), st.tally)
    yj, mj, flags = per_member(model.jump, s)(ye, st.mode, which, r, a_ev)
    flags = jax.tree_util.tree_map(lambda f: f & event, flags)
    tally = jax.vmap(lambda tl, fl, t, uo: tally_event(tl, fl, t, cfg.max_impacts, uo),
                     in_axes=-1, out_axes=-1)(tally, flags, t_ev, q_ot)
    tally = tally_fail(tally, failed)
    return Member(
        y=jnp.where(step, jnp.where(event, yj, ye), st.y),
        mode=tree_where(event, mj, st.mode),
        tally=tally,
        hprop=st.hprop,
    )


def _finish(model, cfg, s, st, tau, L, a0, da):
    """rk4: integrate what is left of the step without events (pieces ran out)."""
    todo = ~st.tally.done & (tau < L)
    y1, _ = per_member(lambda *a: rk_step(model, *a, cfg), s)(st.y, st.mode, tau, L - tau, a0, da)
    ok = jnp.all(jnp.isfinite(y1), axis=0)
    st = eqx.tree_at(lambda m: (m.y, m.tally), st,
                     (jnp.where(todo & ok, y1, st.y), tally_fail(st.tally, todo & ~ok)))
    return st


def _compact_width(n):
    """Width of the sub-batch that takes the members with an event in a step of a batch of
    n (more take several rounds); 0 for a small batch, where the whole batch takes the
    pieces."""
    return 0 if n < COMPACT_MIN else max(8, n // 32)


#: the smallest batch whose members with events are compacted into a sub-batch
COMPACT_MIN = 256


def _take(x, idx, n):
    """The members `idx` of a leaf with the members on its last axis, of length n (others
    as is)."""
    return jnp.take(x, idx, axis=-1, mode="clip") if jnp.ndim(x) and x.shape[-1] == n else x


#: bits per word of `first_members`' bit mask
_WORD = 32


def first_members(mask, width):
    """The indices of the first `width` True entries of the 1-D `mask`, in order (the
    rest filled with len(mask)): `jnp.nonzero(mask, size=width, fill_value=len(mask))[0]`
    at a fifth of its cost on a CPU, where `nonzero`'s cumulative sum over the whole
    batch is a long chain of small operations.

    The mask is packed into 32-bit words; a word's rank is the count of set bits before
    it (a triangular product of the words' bit counts); each output slot finds its word
    by comparison and its bit within the word by a binary search on bit counts."""
    n = mask.shape[0]
    nw = -(-n // _WORD)
    bits = jnp.pad(mask, (0, nw * _WORD - n)).reshape(nw, _WORD).astype(jnp.uint32)
    words = jnp.sum(bits << jnp.arange(_WORD, dtype=jnp.uint32), axis=1, dtype=jnp.uint32)
    cnt = jax.lax.population_count(words).astype(jnp.float32)
    if nw <= 512:  # set bits before each word (exact in float32 below 2**24 members)
        before = (cnt @ jnp.triu(jnp.ones((nw, nw), jnp.float32), 1)).astype(jnp.int32)
    else:  # a large chunk: the product would grow as nw**2
        before = (jnp.cumsum(cnt) - cnt).astype(jnp.int32)
    slot = jnp.arange(width, dtype=jnp.int32)
    upto = before + cnt.astype(jnp.int32)  # set bits up to and including each word
    w = jnp.sum((upto[None, :] <= slot[:, None]).astype(jnp.int32), axis=1)
    found = w < nw
    w = jnp.minimum(w, nw - 1)
    word, k = words[w], slot - before[w]  # the slot is the k-th set bit of its word
    pos = jnp.zeros_like(slot)
    step = _WORD // 2
    while step:
        low = (jnp.uint32(1) << (pos + step).astype(jnp.uint32)) - jnp.uint32(1)
        pos = jnp.where(jax.lax.population_count(word & low).astype(jnp.int32) <= k,
                        pos + step, pos)
        step //= 2
    return jnp.where(found, w * _WORD + pos, n)


def _compacted(model, cfg, s, r, st, t_start, L, a0, a1):
    """rk4 over one step: one trial step for the whole batch; the members it takes to the
    end of the step without an event are done (the common case), the others (an event, a
    non-finite state) take `substep`'s pieces in a sub-batch of just them, gathered and
    scattered back. Same results as `substep` for the whole batch, at the cost of one
    trial step plus the pieces of the few members that need them."""
    da = (a1 - a0) / L
    tau = jnp.zeros_like(a0)
    active = ~st.tally.done & (tau < L)
    # the trial step of the whole batch: its end and the conditions there (their rates,
    # for locating a root, only in the sub-batch of the members with an event)
    y1, _ = per_member(lambda *a: rk_step(model, *a, cfg), s)(st.y, st.mode, tau, L - tau, a0, da)
    g1 = per_member(model.conditions, s)(y1, st.mode, a0 + da * (tau + (L - tau)))
    live = active & jnp.all(jnp.isfinite(y1), axis=0)
    # `fired`: a condition below 0 at the step's end fires and one above 0 does not,
    # whatever it was at the start; the start's conditions decide only for one exactly at
    # 0 (a body resting on its surface, e.g. at u = 0 through a record's leading zeros),
    # so they are evaluated only in the steps where a member has one (the same members
    # are easy, bit for bit)
    low = jnp.min(g1, axis=0)  # the lowest condition of each member at the step's end

    def exact(_):  # both ends again (g1 is not kept: it fuses into the reduction)
        g0 = per_member(model.conditions, s)(st.y, st.mode, a0 + da * tau)
        g1 = per_member(model.conditions, s)(y1, st.mode, a0 + da * (tau + (L - tau)))
        return ~jnp.any(fired(Trial(y1, None, g0, None, g1, None)), axis=0)

    easy = live & jax.lax.cond(jnp.any(live & (low == 0)), exact, lambda _: low > 0, None)
    hard = active & ~easy
    # the easy members: exactly a piece without an event (its peak, then the step's end)
    q0, dq0 = per_member(model.peak_coordinate, s)(st.y, st.mode)
    q1, dq1 = per_member(model.peak_coordinate, s)(y1, st.mode)
    q_ot = per_member(lambda s_, _: model.peak_limit(s_), s)(a0)
    # the interior turn only where it could raise a member's peak (bit for bit the same),
    # where the coordinate is read from the state (else evaluating it for the test and
    # again for the peak costs more than the turn: the 2-DOF body, 15 %)
    peak = piece_peak(q0, dq0, q1, dq1, L - tau,
                      st.tally.peak_u if model.peak_from_state else None)
    up = per_member(model.tracked_uplift, s)(y1, st.mode)
    st = eqx.tree_at(lambda m: (m.y, m.tally), st,
                     (jnp.where(easy, y1, st.y),
                      tree_where(easy, tally_peak(st.tally, peak, up, q_ot), st.tally)))

    return _event_rounds(model, cfg, s, r, st, t_start, L, a0, a1, y1, hard)


def _event_rounds(model, cfg, s, r, st, t_start, L, a0, a1, y1, hard):
    """The members `hard` of a compacted step (an event, a non-finite trial step) take
    `substep`'s pieces from the step's start, `_compact_width` of them at a time, gathered
    into a sub-batch and scattered back. Most steps with events take one round, but events
    cluster: in a batch of scales of one record the members still in the linear range
    cross u = 0 in the same step, and such steps take many (on 10,000 El Centro runs, 2 %
    of the member-steps carry an event, at about 190 ns each, 59 % of the batch's time:
    `benchmarks/event_cost.md`, whose script replaces this function to time the step
    without it)."""
    n = a0.shape[0]
    width = _compact_width(n)

    def rounds(carry):  # up to `width` members with events at a time
        st, todo = carry
        idx = first_members(todo, width)
        # t_start is per member when the members have their own grid steps
        s_, r_, st_, a0_, a1_, L_, t_, y1_ = jax.tree_util.tree_map(
            lambda x: _take(x, idx, n), (s, r, st, a0, a1, L, t_start, y1))
        # every member of a round starts the step here: its first piece continues from
        # the whole-batch trial step (not integrated again)
        out = substep(model, cfg, s_, r_, st_, t_, L_, a0_, a1_, compact=False, y1=y1_)
        st = jax.tree_util.tree_map(lambda x, y: x.at[..., idx].set(y, mode="drop"), st, out)
        return st, todo.at[idx].set(False, mode="drop")

    return jax.lax.while_loop(lambda c: jnp.any(c[1]), rounds, (st, hard))[0]


def substep(model, cfg, s, r, st, t_start, L, a0, a1, compact=True, y1=None):
    """Advance every member over [t_start, t_start + L] [s], the ground acceleration
    linear from a0 to a1 [m/s²]. With rk4 a large batch (`COMPACT_MIN` members) takes its
    events in a compacted sub-batch (`_compacted`; `compact=False` turns this off)."""
    if cfg.method == "rk4" and compact and _compact_width(a0.shape[0]):
        return _compacted(model, cfg, s, r, st, t_start, L, a0, a1)
    da = (a1 - a0) / L
    tau = jnp.zeros_like(a0)

    def go(x):
        return piece(model, cfg, s, r, x[0], x[1], L, t_start, a0, da)

    def needed(x):
        return jnp.any(~x[0].tally.done & (x[1] < L))

    if cfg.method == "rk4":
        # a fixed number of pieces (reverse-mode differentiable), each skipped when no
        # member needs it; the last one integrates what is left without events
        def one(x, _):
            return jax.lax.cond(needed(x), go, lambda x: x, x), None

        pieces = cfg.max_pieces
        if y1 is not None:  # the first piece's trial step is known (the sub-batch's)
            st, tau = piece(model, cfg, s, r, st, tau, L, t_start, a0, da, y1)
            pieces -= 1
        (st, tau), _ = jax.lax.scan(one, (st, tau), None, length=pieces)
        return jax.lax.cond(needed((st, tau)),
                            lambda st: _finish(model, cfg, s, st, tau, L, a0, da),
                            lambda st: st, st)

    def cond(x):
        return needed(x[:2]) & (x[2] < cfg.max_pieces)

    def body(x):
        return (*go(x[:2]), x[2] + 1)

    st, tau, _ = jax.lax.while_loop(cond, body, (st, tau, jnp.zeros((), jnp.int32)))
    # a member that ran out of pieces has failed to advance: report it
    return eqx.tree_at(lambda m: m.tally, st, tally_fail(st.tally, tau < L))


def _step_length(st, t0, dt_rec, t1):
    """(carry, length [s] of the step from `t0`): `min(dt_rec, t1 - t0)`. With one end per
    member (`t1` of shape (N,)) a member whose end is reached is marked done first (its
    record is over: nothing more counts), and keeps a dummy full step."""
    if jnp.ndim(t1) == 0:
        return st, jnp.minimum(dt_rec, t1 - t0)
    left = t1 - t0
    # float64: as the grid's ceil(t1 / dt - 1e-9); float32: steps under 1e-3 dt are dropped
    tol = (1e-9 if left.dtype == jnp.float64 else 1e-3) * dt_rec
    alive = left > tol
    st = eqx.tree_at(lambda m: m.tally.done, st, st.tally.done | ~alive)
    return st, jnp.where(alive, jnp.minimum(dt_rec, left), dt_rec)


def run(model, structure, excitation, r, t1, cfg: StepperConfig):
    """Integrate a batch with `model`. `excitation` is a `rockjax.RecordTable` (its table
    zero-padded to at least `cfg.n_steps + 2` samples); its per-member fields, `r` and the
    fields of `structure` have shape `(N,)` (one value per member) or `()` (shared). The
    record step `excitation.dt` [s] is the grid step (for a free vibration, the output
    grid's); shape `(N,)` gives each member its own grid, e.g. pulses of different
    lengths. `t1` [s] is the end time.

    `t1` of shape `(N,)` gives each member its own end: a member stops there (its last
    step shortened to end exactly at its `t1`) and nothing after it counts: no impacts,
    peaks or status; its state is held on the rest of the grid. The ground acceleration
    is zero after a record's last sample (`excitation.lengths`), as `GroundMotion`
    defines it, rather than falling linearly to the zero padding over one step.

    Returns a dict: peak_u, peak_uplift (the largest uplift seen at piece ends: the caller
    applies `model.peak_uplift`, outside the compiled loop, so that summaries and full
    results agree bit for bit), n_impacts, status, t_overturn (shape (N,)) and,
    with `cfg.full`, u, v, theta, uplift on the grid (N, n_steps + 1) and impact_times
    (N, max_impacts).
    """
    exc = excitation
    N = max([1, *(jnp.shape(x)[0] for x in jax.tree_util.tree_leaves(
        (structure, r, t1, *(getattr(exc, k) for k in exc.MEMBER_FIELDS)))
        if jnp.ndim(x) == 1)])
    s = structure.evaluated()
    scale, r, rec, u0, v0 = (jnp.broadcast_to(x, (N,)) for x in (
        exc.scale, r, exc.record, exc.u0, exc.v0))
    table, dt_rec = exc.table, exc.dt
    first = jnp.broadcast_to(exc.first_direction(), (N,))
    y, mode = per_member(lambda *a: model.init(*a, cfg.forced), s)(u0, v0, first)
    if cfg.forced:  # the ground acceleration at t = 0 (right limit, zero past the end)
        a_start = jnp.where(exc.lengths[rec] > 1, exc.table[rec, 0], 0.0) * scale
        y, mode = per_member(model.start, s)(y, mode, a_start)
    unstable = jnp.zeros((N,), bool)
    if cfg.method == "rk4":
        # RK4 is stable only for h * omega below about 2.8; beyond 2.5 the run would be
        # wrong, so it is refused up front (status solver_failure)
        omega = per_member(lambda s_, _: model.frequency(s_), s)(u0)
        unstable = omega * (dt_rec / cfg.substeps) > 2.5
    n_store = cfg.max_impacts if cfg.full else 0
    tally = per_member(lambda s_, y_, m_, f_: tally_start(model, s_, y_, m_, n_store, f_,
                                                      coordinate=True), s)(
        y, mode, unstable)
    st = Member(y=y, mode=mode, tally=tally, hprop=jnp.full((N,), jnp.inf, y.dtype))
    n_tab = table.shape[-1]
    n_rec = exc.lengths[rec]
    sub = cfg.substeps

    def outer(st, k):
        t0 = k * dt_rec
        st, hk = _step_length(st, t0, dt_rec, t1)
        if cfg.forced:
            # right limit at the interval start (the record is zero after its end)
            a_lo = jnp.where(k < n_rec - 1, table[rec, k], 0.0) * scale
            a_hi = jnp.where(k + 1 <= n_rec - 1, table[rec, jnp.minimum(k + 1, n_tab - 1)], 0.0)
            a_hi = a_hi * scale
        else:
            a_lo = a_hi = jnp.zeros((N,), y.dtype)
        slope = (a_hi - a_lo) / dt_rec
        L = hk / sub

        def sub_body(st, j):
            j = j.astype(y.dtype)
            return substep(model, cfg, s, r, st, t0 + j * L, L, a_lo + slope * (j * L),
                           a_lo + slope * ((j + 1) * L)), None

        st, _ = jax.lax.scan(sub_body, st, jnp.arange(sub))
        return st, (per_member(model.observe, s)(st.y, st.mode) if cfg.full else None)

    # checkpointed: reverse mode keeps one carry per record interval and recomputes the
    # interval, instead of stacking every residual of every piece (fewer, larger steps)
    final, outs = jax.lax.scan(jax.checkpoint(outer, prevent_cse=False), st,
                               jnp.arange(cfg.n_steps))
    return _results(model, cfg, s, st, final, outs)


def _results(model, cfg, s, start, final, outs):
    t = final.tally
    res = dict(
        peak_u=t.peak_u,  # of the model's peak_coordinate: the caller applies u_of_peak
        peak_uplift=t.peak_uplift,  # tracked; the caller applies model.peak_uplift
        n_impacts=t.n_impacts,
        status=t.status,
        t_overturn=t.t_overturn,
    )
    if cfg.full:
        obs0 = per_member(model.observe, s)(start.y, start.mode)
        for name in ("u", "v", "theta", "uplift"):
            res[name] = jnp.concatenate([getattr(obs0, name)[:, None],
                                         getattr(outs, name).T], axis=1)
        res["impact_times"] = t.impact_times.T  # (N, max_impacts)
    return res
