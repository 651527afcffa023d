r"""Time integration of Eq. 1 with diffrax, impacts at $u = 0$ and restarts with $\sqrt r$.

$$(m_e + m_b)\,\ddot u + k(u) = -(m_e + m_b)\,\ddot u_g(t) \qquad \text{(Eq. 1)}$$

The solve runs from one impact to the next. A diffrax `Event` with an optimistix root
finder locates each crossing of $u = 0$ (differentiably), the run stops there and restarts
with $v \leftarrow \sqrt r\, v$ (Eq. 2), same sign. The restarts happen inside one bounded
loop under `jit` (`equinox.internal.while_loop`, checkpointed so that reverse-mode
differentiation works), never in Python. A second event stops the run when $|u|$ reaches
$u_{overturn}$.
"""

from __future__ import annotations

import diffrax as dfx
import equinox as eqx
import equinox.internal as eqxi
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from ._excitation import AbstractExcitation, FreeVibration, GroundMotion
from ._kinematics import theta_from_u, uplift
from ._response import Response, STATUS
from ._restoring import get_model

IMPACT_RULES = ("paper", "after_uplift")


def _default_solver():
    return dfx.Tsit5()


class _Config(eqx.Module):
    model: object
    impact: str = eqx.field(static=True)
    solver: object
    rtol: float = eqx.field(static=True)
    atol: float = eqx.field(static=True)
    max_steps: int = eqx.field(static=True)
    max_impacts: int = eqx.field(static=True)
    adjoint: str = eqx.field(static=True)
    use_jump_ts: bool = eqx.field(static=True)
    dt: float | None = eqx.field(static=True, default=None)


class _PIDController(dfx.PIDController):
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


class _EventBisection(optx.Bisection):
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


def _strong(tree):
    """Strip weak types from the array leaves of a pytree (no copy for strong arrays)."""

    def fix(x):
        if isinstance(x, jax.Array) and getattr(x, "weak_type", False):
            return jnp.asarray(x, dtype=x.dtype)
        return x

    return jax.tree_util.tree_map(fix, tree)


_WINDOW = 64  # output times handled per segment: saving costs O(_WINDOW), not O(len(ts))


@eqx.filter_jit
def _simulate(structure, excitation, t1, ts, r, cfg: _Config):
    """The jitted core. The run is a sequence of segments; each segment is one diffrax
    solve that ends at the first of these events (each located by bisection on the
    dense solution, so its time is differentiable):

    0. impact: u crosses 0 -> restart with v <- sqrt(r) v (Eq. 2);
    1. overturning: |u| reaches u_overturn -> stop;
    2. lift-off: |u| crosses u_crit (only for models whose k(u) jumps there) -> switch the
       branch of k(u) integrated;
    3. turning point: v crosses 0 -> record |u| (so peak_u is the peak of the continuous
       solution: between turning points |u| is monotonic);
    4. the end of a window of `_WINDOW` output times (the solve's own t1).
    """
    s = structure
    model = cfg.model
    rigid = model.rigid
    split = model.jumps_at_lift_off
    M = s.mass
    dtype = jnp.result_type(s.B)
    t1 = jnp.asarray(t1, dtype)
    ts = jnp.asarray(ts, dtype)
    n = ts.shape[0]
    sqrt_r = jnp.sqrt(jnp.asarray(r, dtype))
    u_ot = s.u_overturn
    u_crit = jnp.zeros_like(s.u_crit) if rigid else s.u_crit

    # ---- the equation of motion, Eq. 1 (args: sign, side, lift offset, vsign, v offset)
    def vector_field(t, y, args):
        u, v = y
        if split:
            # one smooth branch per segment: side = +1 before lift-off, -1 after
            pre, post = model.branches(s, u)
            force = jnp.where(args[1] > 0, pre, post)
        else:
            force = model(s, u)
        return v, -force / M - excitation.ground_acceleration(t)

    # Each condition is positive during a segment and fires on a downcrossing. Conditions
    # that start at a switching surface subtract their (~1e-12) start value, so that they
    # start at exactly 0 and cannot fire again at once; the state is never snapped.
    # args = (sign of u, branch side, lift offset, sign of v, turning offset)
    def conditions(y, args):
        """Each condition with its rate of change: (values, d/dt values)."""
        u, v = y
        a = args[5]  # acceleration at the evaluation point (rates only)
        su = jnp.where(u >= 0, 1.0, -1.0)
        vals = [args[0] * u, u_ot - jnp.abs(u), args[3] * v - args[4]]
        rates = [args[0] * v, -su * v, args[3] * a]
        if split:
            vals.append(args[1] * (u_crit - jnp.abs(u)) - args[2])
            rates.append(-args[1] * su * v)
        return jnp.stack(vals), jnp.stack(rates)

    def event_cond(t, y, args, **kwargs):
        # One scalar, positive during a segment; it crosses 0 at the earliest event in a
        # step even when two events fall in the same step. The condition that restarted
        # the segment starts at exactly 0 and grows; the tiny +1e-30 makes the start
        # strictly positive, so that an event in the first step is not missed (diffrax
        # fires on old > 0 >= new).
        vals, _ = conditions(y, (*args, 0.0))
        return jnp.min(vals) + 1e-30

    event = dfx.Event(event_cond, root_finder=_EventBisection(), direction=False)
    term = dfx.ODETerm(vector_field)
    jump_ts = excitation.jump_times() if cfg.use_jump_ts else None
    if cfg.dt is not None:
        # Fixed steps of dt: a controller that accepts every step and never exceeds dt. Unlike
        # ConstantStepSize it can also be clipped to the record's samples.
        base = (
            dfx.ConstantStepSize()
            if jump_ts is None
            else _PIDController(rtol=1.0, atol=1e300, dtmax=cfg.dt, factormax=1e6)
        )
        dt0 = cfg.dt
    else:
        base = _PIDController(rtol=cfg.rtol, atol=cfg.atol)
        dt0 = None
    # Steps end on the record's samples, where the interpolated forcing has kinks.
    controller = base if jump_ts is None else dfx.ClipStepSizeController(base, jump_ts=jump_ts)
    if cfg.adjoint == "forward":
        adjoint, loop_kind = dfx.ForwardMode(), "lax"
    else:
        adjoint, loop_kind = dfx.RecursiveCheckpointAdjoint(), "checkpointed"

    # ---- initial state
    u0, v0 = excitation.initial_state()
    u0 = jnp.asarray(u0, dtype)
    v0 = jnp.asarray(v0, dtype)
    if isinstance(excitation, GroundMotion):
        first = excitation.first_direction().astype(dtype)
        acc0 = -model(s, u0) / M - excitation.ground_acceleration(jnp.zeros((), dtype))
    else:
        first = jnp.ones((), dtype)
        acc0 = -model(s, u0) / M

    def nonzero_sign(x, fallback):
        return jnp.where(x > 0, 1.0, jnp.where(x < 0, -1.0, fallback)).astype(dtype)

    # side of u = 0 the motion is on (or about to be on), and the sign of v (or of the
    # acceleration when starting from rest)
    sign0 = nonzero_sign(u0, nonzero_sign(v0, first))
    vsign0 = nonzero_sign(v0, nonzero_sign(acc0, -sign0))
    overturned0 = jnp.abs(u0) >= u_ot
    free = isinstance(excitation, FreeVibration)
    E0 = 0.5 * M * v0**2 + jnp.abs(u0) * jnp.abs(model(s, u0))  # an energy scale
    ts_pad = jnp.concatenate([ts, jnp.full((_WINDOW,), jnp.inf, dtype)])
    window = jnp.arange(_WINDOW)

    init = dict(
        t=jnp.zeros((), dtype),
        u=u0,
        v=v0,
        sign=sign0,
        side=jnp.where(jnp.abs(u0) < u_crit, 1.0, -1.0).astype(dtype),
        lift_offset=jnp.zeros((), dtype),
        vsign=vsign0,
        v_offset=jnp.zeros((), dtype),
        n_impacts=jnp.zeros((), jnp.int32),
        impact_times=jnp.full((cfg.max_impacts,), jnp.inf, dtype),
        out_u=jnp.zeros((n,), dtype),
        out_v=jnp.zeros((n,), dtype),
        peak_u=jnp.minimum(jnp.abs(u0), u_ot),
        lifted=jnp.abs(u0) > u_crit,
        status=jnp.where(overturned0, STATUS["overturned"], STATUS["completed"]).astype(jnp.int32),
        t_overturn=jnp.where(overturned0, 0.0, jnp.inf).astype(dtype),
        done=overturned0,
        rest=jnp.zeros((), bool),
        rest_g=jnp.asarray(rigid and isinstance(excitation, GroundMotion))
        & (u0 == 0) & (v0 == 0) & ~overturned0,
    )

    sticky = rigid and isinstance(excitation, GroundMotion)
    if sticky:
        # A rigid block (housner) on the ground stays at rest until |ground accel| exceeds
        # the uplift threshold A = k(0+) / M; Eq. 1 alone (its force jumps at u = 0) would
        # chatter through infinitely many impacts from rest.
        A_up = model.locked(s, jnp.zeros((), dtype), jnp.ones((), dtype), True) / M
        acc_s = excitation.scale * excitation.accel
        t_s = excitation.dt * jnp.arange(acc_s.shape[-1], dtype=dtype)

        def release_time(t):
            """First time >= t when |a_g| exceeds A_up (inf if never), and a_g's sign."""
            a_now = excitation.ground_acceleration(t)
            mask = (t_s > t) & (jnp.abs(acc_s) > A_up)
            j = jnp.argmax(mask)
            a_j = acc_s[j]
            a_p = jnp.where(j > 0, acc_s[jnp.maximum(j - 1, 0)], 0.0)
            f = (jnp.sign(a_j) * A_up - a_p) / jnp.where(a_j != a_p, a_j - a_p, 1.0)
            t_c = jnp.maximum(t_s[j] - (1.0 - f) * excitation.dt, t)
            now = jnp.abs(a_now) > A_up
            t_r = jnp.where(now, t, jnp.where(jnp.any(mask), t_c, jnp.inf))
            return t_r, jnp.where(now, a_now, a_j)

    def body(c):
        if sticky:
            t_r, a_r = release_time(c["t"])
            resting = c["rest_g"]
            go = jnp.where(a_r > 0, -1.0, 1.0).astype(dtype)
            c = dict(
                c,
                t=jnp.where(resting, jnp.minimum(t_r, t1), c["t"]),
                sign=jnp.where(resting, go, c["sign"]),
                vsign=jnp.where(resting, go, c["vsign"]),
                v_offset=jnp.where(resting, 0.0, c["v_offset"]).astype(dtype),
                lift_offset=jnp.where(resting, 0.0, c["lift_offset"]).astype(dtype),
                rest_g=resting & (t_r >= t1),
            )
        t_start = c["t"]
        # the window of output times handled by this segment
        i0 = jnp.searchsorted(ts, t_start, side="left")
        win = jax.lax.dynamic_slice(ts_pad, (i0,), (_WINDOW,))
        full = i0 + _WINDOW < n
        seg_t1 = jnp.where(full, win[-1], t1)
        sol = dfx.diffeqsolve(
            term,
            cfg.solver,
            t_start,
            seg_t1,
            dt0,
            (c["u"], c["v"]),
            args=(c["sign"], c["side"], c["lift_offset"], c["vsign"], c["v_offset"]),
            saveat=dfx.SaveAt(subs=[dfx.SubSaveAt(ts=jnp.clip(win, t_start, seg_t1)),
                                    dfx.SubSaveAt(t1=True)]),
            stepsize_controller=controller,
            event=event,
            max_steps=cfg.max_steps,
            throw=False,
            adjoint=adjoint,
        )
        (u_win, v_win), tend = sol.ys[0], sol.ts[1][-1]
        u_end, v_end = sol.ys[1][0][-1], sol.ys[1][1][-1]
        # diffrax 0.7.2 saves inf at an output time equal to t1 when t1 is also a jump time
        # (diffrax issue #663): outputs at the segment's end come from its final state
        at_end = jnp.clip(win, t_start, seg_t1) == tend
        u_win = jnp.where(at_end, u_end, u_win)
        v_win = jnp.where(at_end, v_end, v_win)
        ok = (sol.result == dfx.RESULTS.successful) | (sol.result == dfx.RESULTS.event_occurred)
        fired = sol.event_mask & ok
        # Which event: the condition with the shortest time to its zero, |c| / |dc/dt| [s]
        # (dimensionally consistent, unlike comparing metres with metres per second).
        args = (c["sign"], c["side"], c["lift_offset"], c["vsign"], c["v_offset"])
        acc_end = vector_field(tend, (u_end, v_end), args)[1]
        vals, rates = conditions((u_end, v_end), (*args, acc_end))
        which = jnp.argmin(jnp.abs(vals) / (jnp.abs(rates) + 1e-300))
        hit_impact = fired & (which == 0)
        hit_overturn = fired & (which == 1)
        hit_turn = fired & (which == 2)
        hit_lift = fired & (which == 3)

        # outputs on this window
        idx = i0 + window
        valid = (win >= t_start) & (win <= tend) & (idx < n)
        out_u = c["out_u"].at[idx].set(jnp.where(valid, u_win, c["out_u"][jnp.minimum(idx, n - 1)]),
                                        mode="drop")
        out_v = c["out_v"].at[idx].set(jnp.where(valid, v_win, c["out_v"][jnp.minimum(idx, n - 1)]),
                                        mode="drop")

        # |u| is monotonic within a segment, so its peak is at an end
        peak_u = jnp.maximum(c["peak_u"], jnp.minimum(jnp.abs(u_end), u_ot))
        lifted = c["lifted"] | (jnp.abs(u_end) > u_crit)

        # impact: restart at u = 0 with v <- sqrt(r) v, same sign (Eq. 2)
        real = hit_impact & (lifted if cfg.impact == "after_uplift" else True)
        u_new = jnp.where(hit_impact, 0.0, u_end)
        v_new = jnp.where(real, sqrt_r * v_end, v_end)
        n_imp = c["n_impacts"] + real.astype(jnp.int32)
        slot = jnp.minimum(c["n_impacts"], cfg.max_impacts - 1)
        impact_times = jnp.where(real, c["impact_times"].at[slot].set(tend), c["impact_times"])
        sign = jnp.where(hit_impact, nonzero_sign(v_new, c["sign"]), c["sign"])
        side = jnp.where(hit_lift, -c["side"], jnp.where(hit_impact, 1.0, c["side"]))
        lift_offset = jnp.where(hit_lift, side * (u_crit - jnp.abs(u_new)), 0.0)
        vsign = jnp.where(hit_turn, -c["vsign"], c["vsign"])
        v_offset = jnp.where(hit_turn, vsign * v_new, 0.0)

        # stopping
        failed = ~ok
        reached = ok & ~fired & (tend >= t1)
        too_many = real & (n_imp >= cfg.max_impacts)
        # a free vibration that has run out of energy rests at u = 0
        rest = free & hit_impact & (0.5 * M * v_new**2 <= 1e-14 * E0)
        if sticky:  # the impacts of a settling block converge: it comes to rest
            settle = real & (0.5 * v_new**2 <= 1e-8 * A_up * s.B)
            v_new = jnp.where(settle, 0.0, v_new)
        else:
            settle = jnp.zeros((), bool)
        status = jnp.select(
            [failed, hit_overturn, too_many],
            [STATUS["solver_failure"], STATUS["overturned"], STATUS["max_impacts"]],
            c["status"],
        ).astype(jnp.int32)
        return dict(
            t=tend,
            u=u_new,
            v=jnp.where(rest, 0.0, v_new),
            sign=sign,
            side=side.astype(dtype),
            lift_offset=lift_offset.astype(dtype),
            vsign=vsign,
            v_offset=v_offset.astype(dtype),
            n_impacts=n_imp,
            impact_times=impact_times,
            out_u=out_u,
            out_v=out_v,
            peak_u=peak_u,
            lifted=jnp.where(real, False, lifted),
            status=status,
            t_overturn=jnp.where(hit_overturn, tend, c["t_overturn"]),
            done=failed | hit_overturn | too_many | reached | rest | c["rest_g"],
            rest=rest,
            rest_g=c["rest_g"] | settle,
        )

    # Bound on the number of segments: impacts, lift-offs (2 per impact), turning points
    # (about 2 per impact) and windows.
    max_segments = 6 * cfg.max_impacts + 2 * (n // (_WINDOW - 1) + 1) + 16
    final = eqxi.while_loop(
        lambda c: ~c["done"], body, init, max_steps=max_segments, kind=loop_kind
    )
    # the segment budget ran out before the end (e.g. a very stiff foundation's spring
    # oscillation): a solver failure, not a count of impacts
    status = jnp.where(final["done"], final["status"], STATUS["solver_failure"]).astype(jnp.int32)
    # After the run stops (rest, overturning, failure) the outputs hold the last state.
    after = ts > final["t"]
    hold_u = jnp.where(final["rest"], 0.0, final["u"])
    hold_v = jnp.where(final["rest"], 0.0, final["v"])
    u_out = jnp.where(after, hold_u, final["out_u"])
    v_out = jnp.where(after, hold_v, final["out_v"])
    u_out = jnp.where(overturned0, u0, u_out)
    v_out = jnp.where(overturned0, v0, v_out)
    return Response(
        ts=ts,
        u=u_out,
        v=v_out,
        theta=theta_from_u(s, u_out, rigid=rigid),
        uplift=uplift(s, u_out, rigid=rigid),
        impact_times=final["impact_times"],
        n_impacts=final["n_impacts"],
        peak_u=final["peak_u"],
        peak_uplift=uplift(s, final["peak_u"], rigid=rigid),
        status=status,
        t_overturn=final["t_overturn"],
    )


def simulate(
    structure,
    excitation: AbstractExcitation,
    t1,
    *,
    ts=None,
    model="simplified",
    r=None,
    impact: str = "paper",
    solver=None,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_steps: int = 16384,
    max_impacts: int = 1024,
    adjoint: str = "reverse",
    jump_ts: bool = True,
    dt: float | None = None,
    method: str = "diffrax",
    substeps: int | None = None,
) -> Response:
    r"""Integrate Eq. 1 from $t = 0$ to `t1` with impacts at $u = 0$ (Eqs 1–3).

    $(m_e+m_b)\ddot u + k(u) = -(m_e+m_b)\ddot u_g(t)$; at each crossing of $u = 0$ the run
    stops and restarts with $\dot u \leftarrow \sqrt{r}\,\dot u$ (Eq. 2, same sign).

    **Arguments:**

    - `structure`: a `RockingStructure` (SI units).
    - `excitation`: `FreeVibration(u0 [m], v0 [m/s])` or `GroundMotion(dt [s], accel [m/s²],
      scale)`.
    - `t1`: end time [s], > 0.
    - `ts`: output times [s], increasing, within [0, t1]. Default: the record's samples for a
      ground motion, else 1001 points.
    - `model`: restoring force, `"simplified"` (default), `"exact"`, `"smooth"`, `"housner"`
      or an `AbstractRestoringForce`.
    - `r`: coefficient of restitution in [0, 1] (Eq. 2); default `structure.restitution`
      (Eq. 3).
    - `impact`: `"paper"` (default): an impact at every crossing of $u = 0$, as in the
      paper. `"after_uplift"`: a crossing is an impact only if the structure has lifted off
      ($|u| > u_{crit}$) since the last impact; small oscillations on the springs before
      lift-off then lose no energy, which is more physical.
    - `solver`: a diffrax solver (default `diffrax.Tsit5()`); `rtol`, `atol`: tolerances of
      the PID step-size controller; `max_steps`: steps per segment between impacts;
      `max_impacts`: bound on the number of impacts (status `max_impacts` when reached).
    - `adjoint`: `"reverse"` (default; `jax.grad` works) or `"forward"` (`jax.jacfwd` with
      `diffrax.ForwardMode`, often cheaper for a few parameters).
    - `jump_ts`: tell the step-size controller where a record's samples are (default True).
    - `dt`: a fixed step [s] instead of adaptive steps (`rtol`, `atol` then unused). The
      result is then a smooth function of every parameter, impact times included.
    - `method`: `"diffrax"` (default): the event-restart diffrax solve described above.
      `"rk4"`: the fast path of `rockjax.simulate_batch`, fixed RK4 steps on the record's
      samples (`substeps` per interval, default 4; for a free vibration, `substeps`, default
      1, steps per `dt`, default min(t1/4000, 10 ms)) with each event located inside its step;
      `jax.grad` and `jax.jacfwd` work.
      `"dopri5"`: the same loop with adaptive Dormand–Prince 5(4) steps to `rtol`, `atol`
      (forward-mode `jax.jacfwd` only). Both need a concrete `t1`; outputs are computed on
      the grid and interpolated (cubic Hermite) to `ts`. Much faster for a full record
      (see `benchmarks/results.md`); `solver`, `max_steps`, `adjoint` and `jump_ts` apply
      to `"diffrax"` only.

    **Returns:** a `Response` (see its docstring). Runtime failures come back as
    `Response.status`, never as NaN: completed, overturned, max_impacts, solver_failure.

    **Example:**

    ```python
    s = rockjax.mcmanus_column()
    res = rockjax.simulate(s, rockjax.FreeVibration(0.10), 4.0)
    res.n_impacts, res.peak_u
    ```
    """
    from ._structure import RockingStructure

    if not isinstance(structure, RockingStructure):
        raise ValueError(f"structure must be a RockingStructure, got {type(structure).__name__}")
    if not isinstance(excitation, AbstractExcitation):
        raise ValueError(
            f"excitation must be a FreeVibration or GroundMotion, got {type(excitation).__name__}"
        )
    if impact not in IMPACT_RULES:
        raise ValueError(f"impact must be one of {IMPACT_RULES}, got {impact!r}")
    if adjoint not in ("reverse", "forward"):
        raise ValueError(f"adjoint must be 'reverse' or 'forward', got {adjoint!r}")
    if not isinstance(t1, jax.core.Tracer):
        try:
            t1a = np.asarray(t1, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(
                f"t1 must be a positive, finite number of seconds, got {t1!r}"
            ) from None
        if t1a.size < 1:
            raise ValueError("t1 must be a positive, finite number of seconds, got an empty array")
        t1f = float(np.max(t1a))
        if not np.isfinite(t1f) or not float(np.min(t1a)) > 0:
            raise ValueError(f"t1 must be positive and finite, got {t1a}")
    else:
        t1f = None
    if ts is None:
        if t1f is None:
            raise ValueError("ts must be given when t1 is traced")
        if isinstance(excitation, GroundMotion) and not isinstance(excitation.dt, jax.core.Tracer):
            rec_dt = float(excitation.dt)
            ts = np.arange(0.0, t1f + 0.5 * rec_dt, rec_dt)
            ts = ts[ts <= t1f]
        else:
            ts = np.linspace(0.0, t1f, 1001)
    if not isinstance(ts, jax.core.Tracer):
        tsn = np.asarray(ts, dtype=float)
        if tsn.ndim != 1 or tsn.size < 1:
            raise ValueError("ts must be a 1-D array of output times")
        if not np.all(np.isfinite(tsn)):
            raise ValueError("ts must be finite")
        if tsn.size > 1 and not np.all(np.diff(tsn) > 0):
            raise ValueError("ts must be strictly increasing")
        if tsn[0] < 0 or (t1f is not None and tsn[-1] > t1f * (1 + 1e-12)):
            raise ValueError(f"ts must lie within [0, t1] = [0, {t1f}]")
    if r is None:
        r = structure.restitution
    elif not isinstance(r, jax.core.Tracer):
        rr = np.asarray(r)
        if not np.all(np.isfinite(rr)) or np.any(rr < 0) or np.any(rr > 1):
            raise ValueError(f"r must lie in [0, 1], got {rr}")
    for name, val in (("rtol", rtol), ("atol", atol)):
        if not (isinstance(val, (int, float)) and val > 0):
            raise ValueError(f"{name} must be a positive number, got {val!r}")
    if not (isinstance(max_impacts, int) and max_impacts >= 1):
        raise ValueError(f"max_impacts must be a positive integer, got {max_impacts!r}")
    if dt is not None and not (isinstance(dt, (int, float)) and np.isfinite(dt) and dt > 0):
        raise ValueError(f"dt must be a positive number of seconds (finite), got {dt!r}")
    if not (isinstance(max_steps, int) and max_steps >= 1):
        raise ValueError(f"max_steps must be a positive integer, got {max_steps!r}")
    if method not in ("diffrax", "rk4", "dopri5"):
        raise ValueError(f"method must be 'diffrax', 'rk4' or 'dopri5', got {method!r}")
    if substeps is not None and not (isinstance(substeps, int) and substeps >= 1):
        raise ValueError(f"substeps must be a positive integer, got {substeps!r}")
    model_obj = get_model(model)
    if method == "diffrax" and jnp.result_type(structure.B) != jnp.float64:
        raise ValueError(
            f"method 'diffrax' runs in float64; this structure is "
            f"{jnp.result_type(structure.B)}: use method='rk4' or 'dopri5' for float32 "
            "(see docs/batches.md), or structure.astype(jnp.float64)"
        )
    if model_obj.two_dof:
        if method != "diffrax":
            raise ValueError("model two_spring_2dof is integrated with method='diffrax' only")
        from ._twospring import simulate_2dof

        return simulate_2dof(
            _strong(structure), model_obj, _strong(excitation), t1, ts,
            structure.restitution if r is None else r,
            solver=_default_solver() if solver is None else solver, rtol=rtol, atol=atol,
            max_steps=max_steps, max_impacts=max_impacts, adjoint=adjoint, dt=dt,
        )
    if method != "diffrax":
        from ._batch import simulate_fast

        return simulate_fast(
            _strong(structure), _strong(excitation), t1, ts, r, model=model, impact=impact,
            method=method, substeps=substeps, dt=dt, rtol=rtol, atol=atol,
            max_impacts=max_impacts, max_pieces=None,
        )
    cfg = _Config(
        model=get_model(model),
        impact=impact,
        solver=_default_solver() if solver is None else solver,
        rtol=float(rtol),
        atol=float(atol),
        max_steps=int(max_steps),
        max_impacts=int(max_impacts),
        adjoint=adjoint,
        use_jump_ts=bool(jump_ts),
        dt=None if dt is None else float(dt),
    )
    dtype = jnp.result_type(structure.B)
    # every number becomes a strongly typed array, so that new values never trigger a
    # recompile (eqx.tree_at, for one, can insert weakly typed leaves)
    return _simulate(
        _strong(structure),
        _strong(excitation),
        jnp.asarray(t1, dtype),
        jnp.asarray(ts, dtype),
        jnp.asarray(r, dtype),
        cfg,
    )
