"""What every integrator records of a run, whatever the model: impacts, peaks, status.

The rules are written once here: an impact is counted and its time stored, the run stops
at overturning, at rest, at the impact bound or on a solver failure, with the status of
`rockjax.Status`.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from .._status import STATUS


class Tally(eqx.Module):
    """Per-member record of a run (scalars, and `impact_times` of shape (K,), K = 0 when
    the times are not stored). `peak_u` is the peak |u| [m]; in the batched stepper, the
    peak |q| of the model's `peak_coordinate` (its caller applies `u_of_peak`)."""

    n_impacts: jnp.ndarray
    impact_times: jnp.ndarray
    peak_u: jnp.ndarray
    peak_uplift: jnp.ndarray
    status: jnp.ndarray
    t_overturn: jnp.ndarray
    done: jnp.ndarray
    rest: jnp.ndarray


def tally_start(model, structure, y, mode, n_store, failed=False, coordinate=False):
    """The record at t = 0: overturned already if |u0| >= u_overturn; `failed` marks a
    member refused up front (e.g. a fixed step beyond its stability limit). With
    `coordinate`, the peak is of the model's `peak_coordinate` (the batched stepper's)."""
    obs = model.observe(structure, y, mode)
    u_ot = model.u_overturn(structure)
    over = jnp.abs(obs.u) >= u_ot
    if coordinate:
        q_ot = model.peak_limit(structure)
        peak = jnp.where(over, q_ot, jnp.minimum(
            jnp.abs(model.peak_coordinate(structure, y, mode)[0]), q_ot))
    else:
        peak = jnp.minimum(jnp.abs(obs.u), u_ot)
    failed = jnp.asarray(failed) & ~over
    dtype = jnp.result_type(obs.u)
    status = jnp.where(over, STATUS["overturned"],
                       jnp.where(failed, STATUS["solver_failure"], STATUS["completed"]))
    return Tally(
        n_impacts=jnp.zeros((), jnp.int32),
        impact_times=jnp.full((n_store,), jnp.inf, dtype),
        peak_u=peak,
        peak_uplift=jnp.maximum(model.tracked_uplift(structure, y, mode), 0.0),
        status=status.astype(jnp.int32),
        t_overturn=jnp.where(over, 0.0, jnp.inf).astype(dtype),
        done=over | failed,
        rest=jnp.zeros((), bool),
    )


def tally_peak(tally, peak_u, uplift, u_ot):
    """Fold a piece's peak |u| [m] (clipped at `u_ot`, its value at overturning; the peak
    coordinate's in the batched stepper) and uplift [m] into the record."""
    return eqx.tree_at(
        lambda t: (t.peak_u, t.peak_uplift),
        tally,
        (jnp.maximum(tally.peak_u, jnp.minimum(peak_u, u_ot)),
         jnp.maximum(tally.peak_uplift, uplift)),
    )


def tally_event(tally, flags, t, max_impacts, u_ot):
    """Fold a jump's `Flags` at time `t` [s] into the record (flags already masked to the
    members whose event happened)."""
    n = tally.n_impacts + flags.impact.astype(jnp.int32)
    times = tally.impact_times
    if times.shape[-1]:
        slot = jnp.minimum(tally.n_impacts, times.shape[-1] - 1)
        times = jnp.where(flags.impact, times.at[slot].set(t.astype(times.dtype)), times)
    too_many = flags.impact & (n >= max_impacts)
    status = jnp.select([flags.overturned, too_many],
                        [STATUS["overturned"], STATUS["max_impacts"]], tally.status)
    return Tally(
        n_impacts=n,
        impact_times=times,
        peak_u=jnp.where(flags.overturned, u_ot, tally.peak_u),
        peak_uplift=tally.peak_uplift,
        status=status.astype(jnp.int32),
        t_overturn=jnp.where(flags.overturned, t, tally.t_overturn).astype(times.dtype),
        done=tally.done | flags.overturned | too_many | flags.rest,
        rest=tally.rest | flags.rest,
    )


def tally_fail(tally, failed):
    """Mark members whose integration failed (non-finite state, budget exhausted)."""
    failed = failed & ~tally.done
    return eqx.tree_at(
        lambda t: (t.status, t.done),
        tally,
        (jnp.where(failed, STATUS["solver_failure"], tally.status).astype(jnp.int32),
         tally.done | failed),
    )
