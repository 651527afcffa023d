r"""The event-restart integrator: any rocking model, one diffrax solve per mode.

The run is a sequence of segments; each segment is one `diffrax.diffeqsolve` in a fixed
mode of the model, ended by the first of its events (`model.conditions` falling to 0) or
by a turning point of $u$ (so that the peak $|u|$ is that of the continuous solution:
between turning points $|u|$ is monotonic), or by the end of a window of output times.
Each event is located by bisection on the dense solution (its time is differentiable);
the model's jump map is applied and the next segment starts. The restarts run inside one
bounded loop under `jit` (`equinox.internal.while_loop`, checkpointed so that reverse-mode
differentiation works), never in Python.
"""

from __future__ import annotations

import diffrax as dfx
import equinox as eqx
import equinox.internal as eqxi
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ._tally import Tally, tally_event, tally_fail, tally_peak, tally_start

WINDOW = 64  # output times handled per segment: saving costs O(WINDOW), not O(len(ts))


class PIDController(dfx.PIDController):
    """diffrax's PID controller, with no gradient through the proposed step *size*.

    diffrax stops the gradient of the error factor but not of the previous step size, so a
    step clipped to a record sample (whose end is fixed while its start moves with the
    parameters) passes a derivative to every later step, multiplied by each step's growth
    factor: over a 40 s record this explodes (1e100). Here step ends keep their gradient
    (event times, record samples, output windows) and step sizes carry none, so the
    gradient is that of the discrete solution with its steps frozen.
    """

    def adapt_step_size(self, t0, t1, y0, y1_candidate, args, y_error, error_order,
                        controller_state):
        keep, next_t0, next_t1, made_jump, state, result = super().adapt_step_size(
            t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state
        )
        next_t1 = next_t0 + jax.lax.stop_gradient(next_t1 - next_t0)
        state = jax.lax.stop_gradient(state)
        return keep, next_t0, next_t1, made_jump, state, result


class EventBisection(optx.Bisection):
    """Bisection down to adjacent floating-point numbers, for event times.

    Bracketed by the step that saw the sign change (diffrax passes lower/upper), it cannot
    fail near a tangency as Newton can, and it locates the time to machine precision
    (about 50 halvings of a step). The event time is still differentiated implicitly.
    """

    rtol: float = 4 * float(np.finfo(np.float64).eps)
    atol: float = 1e-300
    # The event condition falls through its root (positive before, <= 0 after), and so does
    # diffrax's stand-in when no event fired (distance to the step end); fixing the
    # direction skips the sign check, which would raise under vmap, where diffrax evaluates
    # the root find for batch members without an event too.
    flip: bool = True

    def terminate(self, fn, y, args, options, state, tags):
        width = jnp.abs(state.upper - state.lower)
        tiny = 4 * jnp.finfo(jnp.result_type(y)).eps * jnp.abs(y) + self.atol
        return (width <= tiny) | (state.error == 0), optx.RESULTS.successful


class RestartConfig(eqx.Module):
    """Settings of the event-restart integrator (all static but the solver)."""

    solver: object
    rtol: float = eqx.field(static=True)
    atol: float = eqx.field(static=True)
    max_steps: int = eqx.field(static=True)
    max_impacts: int = eqx.field(static=True)
    adjoint: str = eqx.field(static=True)  # "reverse" or "forward"
    use_jump_ts: bool = eqx.field(static=True)
    dt: float | None = eqx.field(static=True, default=None)


class Segment(eqx.Module):
    """The carry between segments: time, state, mode, the offsets that start a just-fired
    condition at exactly 0, the sign of du/dt (turning points), the record, outputs."""

    t: jnp.ndarray
    y: jnp.ndarray
    mode: object
    offsets: jnp.ndarray
    vsign: jnp.ndarray
    tally: Tally
    out: jnp.ndarray  # (4, n): u, v, theta, uplift on ts


class Scene(eqx.Module):
    """One run's model, structure (evaluated), excitation and restitution, with the
    segment's vector field and event conditions built from the model's methods. The
    conditions are the model's, then the turning point of u (sign of du/dt)."""

    model: object
    s: object
    excitation: object
    r: jnp.ndarray

    def a_g(self, t):
        return self.excitation.ground_acceleration(t)

    def field(self, t, y, args):
        return self.model.vector_field(self.s, y, args[0], self.a_g(t))

    def values(self, t, y, args):
        mode, offsets, vsign = args
        g = self.model.conditions(self.s, y, mode, self.a_g(t))
        v = self.model.observe(self.s, y, mode).v
        return jnp.concatenate([g, (vsign * v)[None]]) - offsets

    def rates(self, t, y, args):
        """The conditions' time derivatives along the solution (to tell which fired)."""
        one = jnp.ones_like(t)
        return jax.jvp(lambda tt, yy: self.values(tt, yy, args), (t, y),
                       (one, self.field(t, y, args)))


def _controller(cfg, excitation):
    """Adaptive PID steps (or fixed steps of cfg.dt), ending on the record's samples,
    where the interpolated forcing has kinks."""
    jump_ts = excitation.jump_times() if cfg.use_jump_ts else None
    if cfg.dt is not None:
        # a controller that accepts every step and never exceeds dt; unlike
        # ConstantStepSize it can also be clipped to the record's samples
        base = (dfx.ConstantStepSize() if jump_ts is None else
                PIDController(rtol=1.0, atol=1e300, dtmax=cfg.dt, factormax=1e6))
    else:
        base = PIDController(rtol=cfg.rtol, atol=cfg.atol)
    return base if jump_ts is None else dfx.ClipStepSizeController(base, jump_ts=jump_ts)


def _solve_segment(scene, cfg, c, ts, ts_pad, t1):
    """One diffrax solve from c.t to the first event or the end of the output window."""
    n = ts.shape[0]
    i0 = jnp.searchsorted(ts, c.t, side="left")
    win = jax.lax.dynamic_slice(ts_pad, (i0,), (WINDOW,))
    # output times past t1 (a batch member that ends before the others) are not solved
    seg_t1 = jnp.minimum(jnp.where(i0 + WINDOW < n, win[-1], t1), t1)
    event = dfx.Event(lambda t, y, args, **kw: jnp.min(scene.values(t, y, args)) + 1e-30,
                      root_finder=EventBisection(), direction=False)
    # A condition that restarted the segment starts at exactly 0 and grows; the tiny
    # +1e-30 makes the start strictly positive, so that an event in the first step is not
    # missed (diffrax fires on old > 0 >= new).
    sol = dfx.diffeqsolve(
        dfx.ODETerm(scene.field), cfg.solver, c.t, seg_t1, cfg.dt, c.y,
        args=(c.mode, c.offsets, c.vsign),
        saveat=dfx.SaveAt(subs=[dfx.SubSaveAt(ts=jnp.clip(win, c.t, seg_t1)),
                                dfx.SubSaveAt(t1=True)]),
        stepsize_controller=_controller(cfg, scene.excitation), event=event,
        max_steps=cfg.max_steps, throw=False,
        adjoint=dfx.ForwardMode() if cfg.adjoint == "forward" else
        dfx.RecursiveCheckpointAdjoint(),
    )
    return sol, i0, win, seg_t1


def _save_window(scene, c, sol, i0, win, seg_t1, tend, y_end):
    """Write the segment's outputs on its window of output times (observed in its mode)."""
    n = c.out.shape[1]
    # diffrax 0.7.2 saves inf at an output time equal to t1 when t1 is also a jump time
    # (diffrax issue #663): outputs at the segment's end come from its final state
    at_end = jnp.clip(win, c.t, seg_t1) == tend
    idx = i0 + jnp.arange(WINDOW)
    valid = (win >= c.t) & (win <= tend) & (idx < n)
    # times past the event hold inf: replace them before observing, so that no NaN
    # reaches a reverse-mode gradient through the masked entries
    ys = jnp.where((at_end | ~valid)[:, None], y_end, sol.ys[0])
    obs = jax.vmap(lambda y: scene.model.observe(scene.s, y, c.mode))(ys)
    new = jnp.stack([obs.u, obs.v, obs.theta, obs.uplift])
    keep = c.out[:, jnp.minimum(idx, n - 1)]
    out = c.out.at[:, idx].set(jnp.where(valid, new, keep), mode="drop")
    return out, jnp.max(jnp.where(valid, obs.uplift, 0.0))


def _next_segment(scene, cfg, c, ts, ts_pad, t1):
    """Solve one segment, then apply its event: the model's jump or a turning point."""
    model, s = scene.model, scene.s
    sol, i0, win, seg_t1 = _solve_segment(scene, cfg, c, ts, ts_pad, t1)
    tend, y_end = sol.ts[1][-1], sol.ys[1][-1]
    out, up_win = _save_window(scene, c, sol, i0, win, seg_t1, tend, y_end)
    ok = (sol.result == dfx.RESULTS.successful) | (sol.result == dfx.RESULTS.event_occurred)
    fired = sol.event_mask & ok
    # which condition: the shortest time to its zero, |c| / |dc/dt| [s]; one that sits
    # at 0 without moving (a turning point of a body at rest) did not fire
    args = (c.mode, c.offsets, c.vsign)
    vals, rates = scene.rates(tend, y_end, args)
    still = (vals == 0) & (rates == 0)
    which = jnp.argmin(jnp.where(still, jnp.inf, jnp.abs(vals) / (jnp.abs(rates) + 1e-300)))
    n_model = vals.shape[0] - 1
    event = fired & (which < n_model)
    turn = fired & (which == n_model)
    u_ot = model.u_overturn(s)
    obs = model.observe(s, y_end, c.mode)
    tally = tally_peak(c.tally, jnp.abs(obs.u),
                       jnp.maximum(up_win, model.tracked_uplift(s, y_end, c.mode)), u_ot)
    idx = jnp.minimum(which, n_model - 1)
    yj, mj, flags = model.jump(s, y_end, c.mode, idx, scene.r, scene.a_g(tend))
    flags = jax.tree_util.tree_map(lambda f: f & event, flags)
    y_new = jnp.where(event, yj, y_end)
    mode = jax.tree_util.tree_map(lambda a, b: jnp.where(event, a, b), mj, c.mode)
    tally = tally_event(tally, flags, tend, cfg.max_impacts, u_ot)
    tally = tally_fail(tally, ~ok)
    tally = eqx.tree_at(lambda t: t.done, tally, tally.done | (ok & ~fired & (tend >= t1)))
    # offsets: a condition that just fired restarts from its current value (exactly 0)
    g_new = model.conditions(s, y_new, mode, scene.a_g(tend))
    v_new = model.observe(s, y_new, mode).v
    vsign = jnp.where(turn, -c.vsign, c.vsign)
    hit = jnp.arange(n_model) == which
    offsets = jnp.concatenate([jnp.where(event & hit, g_new, 0.0),
                               jnp.where(turn, vsign * v_new, 0.0)[None]])
    return Segment(t=tend, y=y_new, mode=mode, offsets=offsets, vsign=vsign, tally=tally,
                   out=out)


def _nonzero_sign(x, fallback):
    return jnp.where(x > 0, 1.0, jnp.where(x < 0, -1.0, fallback))


def _start(scene, excitation, n, cfg):
    """The first segment's carry: the model's initial state and mode, the direction of
    the first motion of u (for turning points), an empty record."""
    model, s = scene.model, scene.s
    u0, v0 = excitation.initial_state()
    dtype = jnp.result_type(s.B)
    first = jnp.asarray(excitation.first_direction(), dtype)
    y0, mode0 = model.init(s, jnp.asarray(u0, dtype), jnp.asarray(v0, dtype), first,
                           excitation.forced)
    t0 = jnp.zeros((), dtype)
    y0, mode0 = model.start(s, y0, mode0, scene.a_g(t0))
    obs = model.observe(s, y0, mode0)
    flow = scene.field(t0, y0, (mode0, None, None))
    _, acc = jax.jvp(lambda y: model.observe(s, y, mode0).v, (y0,), (flow,))
    vsign = _nonzero_sign(obs.v, _nonzero_sign(acc, -_nonzero_sign(obs.u, first)))
    n_cond = model.conditions(s, y0, mode0, scene.a_g(t0)).shape[0] + 1
    return Segment(
        t=t0, y=y0, mode=mode0, offsets=jnp.zeros((n_cond,), dtype),
        vsign=vsign.astype(dtype), tally=tally_start(model, s, y0, mode0, cfg.max_impacts),
        out=jnp.zeros((4, n), dtype),
    )


@eqx.filter_jit
def solve(model, structure, excitation, t1, ts, r, cfg: RestartConfig):
    """Integrate one run of `model` from t = 0 to `t1` [s], output on `ts` [s].

    Returns a dict: u, v, theta, uplift on `ts`; impact_times (max_impacts,); n_impacts,
    peak_u, peak_uplift, status, t_overturn.
    """
    dtype = jnp.result_type(structure.B)
    scene = Scene(model, structure.evaluated(), excitation, jnp.asarray(r, dtype))
    n = ts.shape[0]
    c0 = _start(scene, excitation, n, cfg)
    ts_pad = jnp.concatenate([ts, jnp.full((WINDOW,), jnp.inf, dtype)])
    # bound on the number of segments: events (about 8 per impact: lift-offs, landings,
    # turning points, pivot changes) and output windows
    max_segments = 8 * cfg.max_impacts + 2 * (n // (WINDOW - 1) + 1) + 64
    final = eqxi.while_loop(
        lambda c: ~c.tally.done,
        lambda c: _next_segment(scene, cfg, c, ts, ts_pad, t1),
        c0, max_steps=max_segments, kind="lax" if cfg.adjoint == "forward" else "checkpointed",
    )
    # the segment budget ran out before the end (e.g. a very stiff foundation's spring
    # oscillation): a solver failure, not a count of impacts
    tally = tally_fail(final.tally, ~final.tally.done)
    return _outputs(scene, c0, final, tally, ts)


def _outputs(scene, c0, final, tally, ts):
    """Outputs on ts: after the run stops (overturning, rest, failure) they hold the
    state at that moment; a release beyond u_overturn holds the initial state."""
    model, s = scene.model, scene.s

    def stacked(y, mode):
        o = model.observe(s, y, mode)
        return jnp.stack([o.u, o.v, o.theta, o.uplift])[:, None]

    out = jnp.where(ts > final.t, stacked(final.y, final.mode), final.out)
    out = jnp.where(c0.tally.done, stacked(c0.y, c0.mode), out)
    tracked = jnp.maximum(tally.peak_uplift, jnp.max(out[3]))
    return dict(
        u=out[0], v=out[1], theta=out[2], uplift=out[3],
        impact_times=tally.impact_times, n_impacts=tally.n_impacts, peak_u=tally.peak_u,
        peak_uplift=model.peak_uplift(s, tally.peak_u, tracked), status=tally.status,
        t_overturn=tally.t_overturn,
    )
