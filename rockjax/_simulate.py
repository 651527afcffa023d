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


def _hermite_peak(t0, u0, v0, t1, u1, v1):
    """Max |u| of the cubic Hermite interpolant of (u, v) on [t0, t1] (endpoints included)."""
    h = t1 - t0
    h = jnp.where(h > 0, h, 1.0)
    # u(s) = a s^3 + b s^2 + c s + d on s in [0, 1]
    d = u0
    c = v0 * h
    a = 2 * (u0 - u1) + h * (v0 + v1)
    b = 3 * (u1 - u0) - h * (2 * v0 + v1)
    # u'(s) = 3a s^2 + 2b s + c = 0
    A, B, C = 3 * a, 2 * b, c
    disc = B**2 - 4 * A * C
    pos = disc > 0
    sq = jnp.where(pos, jnp.sqrt(jnp.where(pos, disc, 1.0)), 0.0)  # NaN-free gradient at 0
    safeA = jnp.where(jnp.abs(A) > 1e-300, A, 1.0)
    r1 = jnp.where(jnp.abs(A) > 1e-300, (-B + sq) / (2 * safeA), -C / jnp.where(B != 0, B, 1.0))
    r2 = jnp.where(jnp.abs(A) > 1e-300, (-B - sq) / (2 * safeA), r1)

    def val(s):
        ok = (s > 0) & (s < 1) & (disc >= 0)
        s = jnp.where(ok, s, 0.0)
        return jnp.where(ok, jnp.abs(((a * s + b) * s + c) * s + d), 0.0)

    return jnp.maximum(jnp.maximum(jnp.abs(u0), jnp.abs(u1)), jnp.maximum(val(r1), val(r2)))


def _segment_peak(step_ts, step_ys, t_start, y_start):
    """Peak |u| of the continuous solution over one segment, from its accepted steps."""
    u, v = step_ys
    finite = jnp.isfinite(step_ts)
    ts = jnp.concatenate([t_start[None], jnp.where(finite, step_ts, t_start)])
    us = jnp.concatenate([y_start[0][None], jnp.where(finite, u, y_start[0])])
    vs = jnp.concatenate([y_start[1][None], jnp.where(finite, v, y_start[1])])
    peaks = _hermite_peak(ts[:-1], us[:-1], vs[:-1], ts[1:], us[1:], vs[1:])
    # Unused step slots (diffrax pads them with inf) give no interval.
    return jnp.maximum(jnp.abs(y_start[0]), jnp.max(jnp.where(finite, peaks, 0.0)))


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


@eqx.filter_jit
def _simulate(structure, excitation, t1, ts, r, cfg: _Config):
    s = structure
    model = cfg.model
    rigid = model.rigid
    M = s.mass
    dtype = jnp.result_type(s.B)
    t1 = jnp.asarray(t1, dtype)
    ts = jnp.asarray(ts, dtype)
    r = jnp.asarray(r, dtype)
    sqrt_r = jnp.sqrt(r)
    u_ot = s.u_overturn
    u_crit = jnp.zeros_like(s.u_crit) if rigid else s.u_crit

    split = model.jumps_at_lift_off

    def vector_field(t, y, args):
        u, v = y
        if split:
            # one smooth branch per segment: args[1] = +1 before lift-off, -1 after
            pre, post = model.branches(s, u)
            force = jnp.where(args[1] > 0, pre, post)
        else:
            force = model(s, u)
        acc = -force / M - excitation.ground_acceleration(t)
        return v, acc

    def impact_cond(t, y, args, **kwargs):
        return args[0] * y[0]

    def overturn_cond(t, y, args, **kwargs):
        return u_ot - jnp.abs(y[0])

    def lift_cond(t, y, args, **kwargs):
        # args[1] = +1 below u_crit (fires on the way up), -1 above (fires on the way down).
        # args[2] is the value at a lift-off restart (~1e-12), subtracted so that the
        # condition starts at exactly 0 and cannot fire again at once; the state itself
        # is left continuous (no snapping, which would inject energy).
        return args[1] * (u_crit - jnp.abs(y[0])) - args[2]

    conds = (impact_cond, overturn_cond, lift_cond) if split else (impact_cond, overturn_cond)
    event = dfx.Event(
        conds,
        root_finder=optx.Newton(rtol=1e-14, atol=1e-14),
        direction=(False,) * len(conds),
    )
    term = dfx.ODETerm(vector_field)
    jump_ts = excitation.jump_times() if cfg.use_jump_ts else None
    if cfg.dt is not None:
        # Fixed steps of dt: a controller that accepts every step and never exceeds dt. Unlike
        # ConstantStepSize it can also be clipped to the record's samples.
        base = (
            dfx.ConstantStepSize()
            if jump_ts is None
            else dfx.PIDController(rtol=1.0, atol=1e300, dtmax=cfg.dt, factormax=1e6)
        )
        dt0 = cfg.dt
    else:
        base = dfx.PIDController(rtol=cfg.rtol, atol=cfg.atol)
        dt0 = None
    # Steps end on the record's samples, where the interpolated forcing has kinks.
    controller = base if jump_ts is None else dfx.ClipStepSizeController(base, jump_ts=jump_ts)
    if cfg.adjoint == "forward":
        adjoint = dfx.ForwardMode()
        loop_kind = "lax"
    else:
        adjoint = dfx.RecursiveCheckpointAdjoint()
        loop_kind = "checkpointed"

    u0, v0 = excitation.initial_state()
    u0 = jnp.asarray(u0, dtype)
    v0 = jnp.asarray(v0, dtype)
    if isinstance(excitation, GroundMotion):
        first = excitation.first_direction()
    else:
        first = jnp.ones((), dtype)
    sign0 = jnp.where(u0 != 0, jnp.sign(u0), jnp.where(v0 != 0, jnp.sign(v0), first))
    sign0 = jnp.where(sign0 == 0, 1.0, sign0).astype(dtype)

    n = ts.shape[0]
    overturned0 = jnp.abs(u0) >= u_ot
    E0 = 0.5 * M * v0**2 + jnp.abs(u0) * jnp.abs(model(s, u0))  # a scale, not the energy
    free = isinstance(excitation, FreeVibration)

    init = dict(
        t=jnp.zeros((), dtype),
        u=u0,
        v=v0,
        sign=sign0,
        side=jnp.where(jnp.abs(u0) < u_crit, 1.0, -1.0).astype(dtype),
        lift_offset=jnp.zeros((), dtype),
        n_impacts=jnp.zeros((), jnp.int32),
        impact_times=jnp.full((cfg.max_impacts,), jnp.inf, dtype),
        out_u=jnp.zeros((n,), dtype),
        out_v=jnp.zeros((n,), dtype),
        peak_u=jnp.abs(u0),
        lifted=jnp.abs(u0) > u_crit,
        status=jnp.where(overturned0, STATUS["overturned"], STATUS["completed"]).astype(jnp.int32),
        t_overturn=jnp.where(overturned0, 0.0, jnp.inf).astype(dtype),
        done=overturned0 | (t1 <= 0),
        rest=jnp.zeros((), bool),
    )

    def body(c):
        t_start = c["t"]
        y0 = (c["u"], c["v"])
        saveat = dfx.SaveAt(
            subs=[
                dfx.SubSaveAt(ts=jnp.clip(ts, t_start, t1)),
                dfx.SubSaveAt(steps=True),
                dfx.SubSaveAt(t1=True),
            ]
        )
        sol = dfx.diffeqsolve(
            term,
            cfg.solver,
            t_start,
            t1,
            dt0,
            y0,
            args=(c["sign"], c["side"], c["lift_offset"]),
            saveat=saveat,
            stepsize_controller=controller,
            event=event,
            max_steps=cfg.max_steps,
            throw=False,
            adjoint=adjoint,
        )
        (ys_ts, (steps_t, ys_steps), (tend, yend)) = (
            sol.ys[0],
            (sol.ts[1], sol.ys[1]),
            (sol.ts[2][-1], (sol.ys[2][0][-1], sol.ys[2][1][-1])),
        )
        ok = (sol.result == dfx.RESULTS.successful) | (sol.result == dfx.RESULTS.event_occurred)
        hit_impact = sol.event_mask[0] & ok
        hit_overturn = sol.event_mask[1] & ok & ~hit_impact
        if split:
            hit_lift = sol.event_mask[2] & ok & ~hit_impact & ~hit_overturn
        else:
            hit_lift = jnp.zeros((), bool)
        in_seg = (ts >= t_start) & (ts <= tend)
        out_u = jnp.where(in_seg, jnp.where(jnp.isfinite(ys_ts[0]), ys_ts[0], 0.0), c["out_u"])
        out_v = jnp.where(in_seg, jnp.where(jnp.isfinite(ys_ts[1]), ys_ts[1], 0.0), c["out_v"])
        seg_peak = _segment_peak(steps_t, ys_steps, t_start, y0)
        seg_peak = jnp.minimum(seg_peak, u_ot)
        peak_u = jnp.maximum(c["peak_u"], seg_peak)
        lifted = c["lifted"] | (seg_peak > u_crit)
        # impact: restart at u = 0 with v <- sqrt(r) v (same sign), Eq. 2
        real = lifted if cfg.impact == "after_uplift" else jnp.ones((), bool)
        real = real & hit_impact
        v_new = jnp.where(real, sqrt_r * yend[1], yend[1])
        u_new = jnp.where(hit_impact, jnp.zeros_like(yend[0]), yend[0])
        new_side = jnp.where(hit_lift, -c["side"], jnp.where(hit_impact, 1.0, c["side"]))
        lift_offset = jnp.where(hit_lift, new_side * (u_crit - jnp.abs(u_new)), 0.0)
        n_imp = c["n_impacts"] + real.astype(jnp.int32)
        idx = jnp.minimum(c["n_impacts"], cfg.max_impacts - 1)
        impact_times = jnp.where(
            real, c["impact_times"].at[idx].set(tend), c["impact_times"]
        )
        sign = jnp.where(hit_impact, jnp.where(v_new != 0, jnp.sign(v_new), c["sign"]), c["sign"])
        # stopping
        failed = ~ok
        reached = ~hit_impact & ~hit_overturn & ~hit_lift & ok
        too_many = real & (n_imp >= cfg.max_impacts)
        # a free vibration that has run out of energy rests at u = 0
        rest = free & hit_impact & (0.5 * M * v_new**2 <= 1e-14 * E0)
        status = jnp.select(
            [failed, hit_overturn, too_many],
            [STATUS["solver_failure"], STATUS["overturned"], STATUS["max_impacts"]],
            c["status"],
        ).astype(jnp.int32)
        t_ot = jnp.where(hit_overturn, tend, c["t_overturn"])
        done = failed | hit_overturn | too_many | reached | rest
        return dict(
            t=tend,
            u=u_new,
            v=jnp.where(rest, 0.0, v_new),
            sign=sign,
            side=new_side.astype(dtype),
            lift_offset=lift_offset.astype(dtype),
            n_impacts=n_imp,
            impact_times=impact_times,
            out_u=out_u,
            out_v=out_v,
            peak_u=peak_u,
            lifted=jnp.where(real, False, lifted),
            status=status,
            t_overturn=t_ot,
            done=done,
            rest=rest,
        )

    final = eqxi.while_loop(
        lambda c: ~c["done"],
        body,
        init,
        max_steps=(4 if split else 1) * cfg.max_impacts + 8,
        kind=loop_kind,
    )
    # After the run stops (rest, overturning, failure) the outputs hold the last state.
    after = ts > final["t"]
    hold_u = jnp.where(final["rest"], 0.0, final["u"])
    hold_v = jnp.where(final["rest"], 0.0, final["v"])
    u_out = jnp.where(after, hold_u, final["out_u"])
    v_out = jnp.where(after, hold_v, final["out_v"])
    u_out = jnp.where(overturned0, u0, u_out)
    v_out = jnp.where(overturned0, v0, v_out)
    theta = theta_from_u(s, u_out, rigid=rigid)
    return Response(
        ts=ts,
        u=u_out,
        v=v_out,
        theta=theta,
        uplift=uplift(s, u_out, rigid=rigid),
        impact_times=final["impact_times"],
        n_impacts=final["n_impacts"],
        peak_u=final["peak_u"],
        peak_uplift=uplift(s, final["peak_u"], rigid=rigid),
        status=final["status"],
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

    **Returns:** a `Response` (see its docstring). Runtime failures come back as
    `Response.status`, never as NaN: completed, overturned, max_impacts, solver_failure.

    **Example:**

    ```python
    s = rockjax.mcmanus_column()
    res = rockjax.simulate(s, rockjax.FreeVibration(0.10), 4.0)
    res.n_impacts, res.peak_u
    ```
    """
    if not isinstance(excitation, AbstractExcitation):
        raise ValueError(
            f"excitation must be a FreeVibration or GroundMotion, got {type(excitation).__name__}"
        )
    if impact not in IMPACT_RULES:
        raise ValueError(f"impact must be one of {IMPACT_RULES}, got {impact!r}")
    if adjoint not in ("reverse", "forward"):
        raise ValueError(f"adjoint must be 'reverse' or 'forward', got {adjoint!r}")
    if not isinstance(t1, jax.core.Tracer):
        t1f = float(np.max(np.asarray(t1)))
        if not np.isfinite(t1f) or not float(np.min(np.asarray(t1))) > 0:
            raise ValueError(f"t1 must be positive and finite, got {np.asarray(t1)}")
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
    if dt is not None and not (isinstance(dt, (int, float)) and dt > 0):
        raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
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
    # every number becomes an array, so that new values never trigger a recompile
    return _simulate(
        structure,
        excitation,
        jnp.asarray(t1, dtype),
        jnp.asarray(ts, dtype),
        jnp.asarray(r, dtype),
        cfg,
    )
