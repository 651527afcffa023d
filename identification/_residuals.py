r"""The residuals of a fit and their Jacobian: the compiled part of `fit_decay`.

The model is `rockjax.simulate` of a release from rest at $u_0$ at time $t_0$ with any model
of the fidelity ladder (`identification._models`); before $t_0$ the structure is held at
$u_0$. Since it is released at rest, the model is continuously differentiable in $t_0$ (the
velocity is 0 on both sides of the release), and every sample is defined wherever $t_0$
lies: samples before it (a hold) inform $u_0$, the others all the parameters. The residuals
are the differences between the model and each channel the trace has, in the order top
displacement u, rotation theta, uplift (`Response.u`, `.theta`, `.uplift`: the model's own
observation of each), scaled by the trace amplitude (the rotation's by its own amplitude)
and weighted (`uplift_weight`, `theta_weight`); their Jacobian is taken in forward mode.

`TraceModel` holds the trace and the values as arrays, so that the compiled programs
(`compiled`: `eqx.filter_jit`, kept on disk by `identification._aot` when JAX's persistent
compilation cache is on) are reused by any trace of the same length with the same
parameters and settings. Each stage of the growing horizon simulates only as far as the
last sample it fits.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import math
import sys

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import rockjax

from . import _aot, _sensor, _transforms
from ._problem import Problem


class TraceModel(eqx.Module):
    """The model of the trace at a point z, and its residuals: the compiled part of the fit.

    The trace and the values are arrays, so that `_stages.run_chunk` and `respond` (compiled with
    `eqx.filter_jit`) are reused by any trace of the same length with the same `params` and
    settings (strings and Python numbers are static: part of the compilation key).
    """

    structure: rockjax.RockingStructure
    t: jax.Array  # sample times [s]
    u: jax.Array | None  # measured displacement [m], None: no such channel
    up: jax.Array | None  # measured uplift [m], None when not fitted
    values0: dict  # starting / fixed values of all of PARAM_NAMES
    k_min: jax.Array
    scale: jax.Array
    t_ref: jax.Array
    eps: jax.Array  # spacing of the model times of the samples before the release [s]
    eps_end: jax.Array  # spacing of the model times of the samples after t_end [s]
    k_span: jax.Array | None  # log(k_cap - k_min): the bound of k_f, None: unbounded
    uplift_weight: jax.Array
    model: object  # the model instance (its dashpot coefficient an array, set from c_f)
    th: jax.Array | None = None  # measured rotation [rad], None when not fitted
    theta_scale: jax.Array | float = 1.0  # its amplitude [rad]
    theta_weight: jax.Array | float = 1.0
    accel: jax.Array | None = None  # the table's ground acceleration [m/s^2], None: a decay
    accel_dt: jax.Array | None = None  # its sample step [s]
    params: tuple = eqx.field(static=True, default=())
    dashpots: bool = eqx.field(static=True, default=False)  # a dashpot coefficient (c_f)
    impact: str = eqx.field(static=True, default="paper")
    rtol: float = eqx.field(static=True, default=1e-9)
    atol: float = eqx.field(static=True, default=1e-11)
    # the fixed-step path (`on_grid`; a decay's posterior): RK4 steps of grid_dt [s] to
    # grid_t1 [s] of model time, interpolated to the sample times; None: diffrax
    grid_dt: float | None = eqx.field(static=True, default=None)
    grid_t1: float | None = eqx.field(static=True, default=None)

    @classmethod
    def build(cls, pb: Problem) -> TraceModel:
        arr = jnp.asarray
        n = pb.t.size
        return cls(
            structure=pb.structure, t=arr(pb.t),
            u=None if pb.u_meas is None else arr(pb.u_meas),
            th=arr(pb.th_meas) if pb.fits_theta else None,
            theta_scale=arr(float(pb.theta_scale)), theta_weight=arr(float(pb.theta_weight)),
            up=arr(pb.up_meas) if pb.fits_uplift else None,
            values0={k: arr(float(v)) for k, v in pb.values0.items()},
            k_min=arr(pb.k_min), scale=arr(pb.scale), t_ref=arr(pb.t_ref),
            k_span=None if pb.k_cap is None else arr(math.log(pb.k_cap - pb.k_min)),
            eps=arr(1e-9 * float(np.median(np.diff(pb.t))) / n),
            eps_end=arr(1e-9 * float(np.median(np.diff(pb.t)))),
            uplift_weight=arr(float(pb.uplift_weight)), model=_model_instance(pb),
            params=pb.params, dashpots=pb.fit_model.has_dashpots, impact=pb.impact,
            rtol=float(pb.rtol), atol=float(pb.atol),
            accel=None if pb.accel is None else arr(np.asarray(pb.accel, float)),
            accel_dt=None if pb.accel is None else arr(float(pb.accel_dt)),
        )

    def decode(self, z) -> dict:
        """Unconstrained z (fitted params only) -> dict of all the natural values."""
        return _transforms.decode(z, self.params, self.values0, self.k_min, self.scale,
                                  self.t_ref, self.k_span, self.theta_scale)

    def respond(self, z, t_end=None):
        """The model on the trace times: held at u0 before the release at t0, then
        `rockjax.simulate` of the release at rest (model time t - t0). With a base motion
        (`accel`: a shake-table run), the excitation is the `rockjax.GroundMotion` of the
        table record from the state (u0, 0) at model time 0, the record's first sample,
        which lies at t0 on the trace's clock (zero ground motion after the record ends).

        The samples before the release get model times 0, eps, 2 eps, ... (eps ~ 1e-9 of
        a step / n: strictly increasing, as `simulate` needs, and as good as 0: the state
        there is the release state to ~1e-20 m), which do not depend on t0. `t_end`
        (trace time [s], traced): the simulation stops there, the samples after it get
        the state at t_end (+ n eps_end, eps_end ~ 1e-9 of a step): the residuals of a
        short horizon cost a short simulation.
        """
        v = self.decode(z)
        s = self.structure.replace(k_f=v["k_f"])
        model = self.model
        if self.dashpots:
            model = eqx.tree_at(lambda m: m.damping, model, v["c_f"])
        k = jnp.arange(self.t.shape[0])
        ts = jnp.maximum(self.t - v["t0"], self.eps * k)
        if t_end is not None:
            ts = jnp.minimum(ts, jnp.maximum(t_end - v["t0"], 0.0) + self.eps_end * k)
        if self.accel is None:
            excitation = rockjax.FreeVibration(v["u0"])
        else:
            excitation = rockjax.GroundMotion(dt=self.accel_dt, accel=self.accel, u0=v["u0"])
        if self.grid_dt is not None:
            return self._respond_on_grid(s, model, excitation, v["r"], ts)
        return rockjax.simulate(
            s, excitation, ts[-1], ts=ts, r=v["r"], model=model,
            impact=self.impact, rtol=self.rtol, atol=self.atol, adjoint="forward",
        )

    def on_grid(self, dt: float, t1: float) -> TraceModel:
        """This model on the fixed-step path: `rockjax.integrators.RK4` steps of `dt` [s]
        from the release to model time `t1` [s] (concrete), the response interpolated to
        the sample times (cubic Hermite in u and v; theta and uplift from u, or linearly
        for a model that carries them). Its cost does not grow with the chains' spread in
        the parameters and it differentiates in forward mode at a few microseconds a step;
        `identification._posterior_decay` checks it against the adaptive solver before
        a posterior uses it. A decay only (`accel` None)."""
        if self.accel is not None:
            raise ValueError("on_grid: a decay only (this model has a table record)")
        return dataclasses.replace(self, grid_dt=float(dt), grid_t1=float(t1))

    def _respond_on_grid(self, s, model, excitation, r, ts):
        dt, n = self.grid_dt, int(math.ceil(self.grid_t1 / self.grid_dt))
        grid = np.arange(n + 1) * dt
        res = rockjax.simulate(s, excitation, float(grid[-1]), ts=grid, r=r, model=model,
                               impact=self.impact, fidelity_warning=False,
                               integrator=rockjax.integrators.RK4(dt=dt, substeps=1))
        x = jnp.clip(ts / dt, 0.0, float(n))
        i = jnp.clip(jnp.floor(x).astype(jnp.int32), 0, n - 1)
        q = x - i
        h00, h10 = (1 + 2 * q) * (1 - q) ** 2, q * (1 - q) ** 2
        h01, h11 = q**2 * (3 - 2 * q), q**2 * (q - 1)
        u = h00 * res.u[i] + h10 * dt * res.v[i] + h01 * res.u[i + 1] + h11 * dt * res.v[i + 1]
        v = ((6 * q**2 - 6 * q) * (res.u[i] - res.u[i + 1]) / dt
             + (3 * q**2 - 4 * q + 1) * res.v[i] + (3 * q**2 - 2 * q) * res.v[i + 1])
        if getattr(model, "kinematics_of_u", False):
            theta, uplift = model.theta_uplift_of_u(s, u)
        else:
            theta = res.theta[i] * (1 - q) + res.theta[i + 1] * q
            uplift = res.uplift[i] * (1 - q) + res.uplift[i + 1] * q
        return dataclasses.replace(res, ts=ts, u=u, v=v, theta=theta, uplift=uplift)

    def _sensor(self, v):
        """The sensor's terms (`identification._sensor`) of the displacement channel (per
        sample) and of the uplift channel [m]."""
        return v["offset"] + v["drift"] * (self.t - self.t_ref), v["offset_uplift"]

    def _residuals_bad(self, z, mask):
        # the simulation ends at the last sample in the fit (a horizon, padding)
        v = self.decode(z)
        res = self.respond(z, jnp.max(jnp.where(mask > 0, self.t, self.t[0])))
        s_u, s_up = self._sensor(v)
        parts = [] if self.u is None else [mask * (res.u + s_u - self.u) / self.scale]
        if self.th is not None:
            parts.append(mask * self.theta_weight * (res.theta + v["offset_theta"] - self.th)
                         / self.theta_scale)
        if self.up is not None:
            parts.append(mask * self.uplift_weight * (res.uplift + s_up - self.up)
                         / self.scale)
        r = jnp.concatenate(parts)
        # a failed or overturned run is a bad point, not a crash: large finite residuals
        bad = (res.status != rockjax.STATUS["completed"]) | ~jnp.all(jnp.isfinite(r))
        return jnp.where(bad, 1e3, r), bad

    def residuals(self, z, mask):
        """Masked residuals (displacement, then weighted rotation in units of its
        amplitude, then weighted uplift) in units of `scale`: the model as the sensor reads
        it (its offsets and drift added) less the trace; the channels the trace has."""
        return self._residuals_bad(z, mask)[0]

    def res_jac(self, z, mask):
        """The residuals and their Jacobian d r / d z (forward mode through the simulation
        for the model's parameters; written out for the sensor's, which are linear)."""
        phys = [i for i, p in enumerate(self.params) if p not in _transforms.LINEAR]
        if len(phys) == len(self.params):  # one trace of the model: r is J's primal
            J, r = jax.jacfwd(lambda x: (self.residuals(x, mask),) * 2, has_aux=True)(z)
            return r, J

        def part(zp):
            r, bad = self._residuals_bad(z.at[jnp.asarray(phys)].set(zp), mask)
            return r, (r, bad)

        J_p, (r, bad) = jax.jacfwd(part, has_aux=True)(z[jnp.asarray(phys)])
        n = self.t.shape[0]
        zero = jnp.zeros(n)
        here = {"u": self.u is not None, "theta": self.th is not None,
                "uplift": self.up is not None}
        acts = {"offset": ("u", mask), "drift": ("u", mask * (self.t - self.t_ref)),
                "offset_theta": ("theta", mask * self.theta_weight),
                "offset_uplift": ("uplift", mask * self.uplift_weight)}
        cols = {p: [col if c == ch else zero for c in ("u", "theta", "uplift") if here[c]]
                for p, (ch, col) in acts.items()}
        out, k = [], 0
        for p in self.params:
            if p in _transforms.LINEAR:
                out.append(jnp.where(bad, 0.0, jnp.concatenate(cols[p])))
            else:
                out.append(J_p[:, k])
                k += 1
        return r, jnp.stack(out, axis=1)


def _model_instance(pb: Problem):
    """The model instance of the fit, with its dashpot coefficient as an array (a Python
    float would be static under `eqx.filter_jit`: a compile per value)."""
    model = pb.fit_model.model
    if pb.fit_model.has_dashpots:
        c_f = jnp.asarray(float(pb.values0["c_f"]))
        model = eqx.tree_at(lambda m: m.damping, model, c_f)
    return model


@contextlib.contextmanager
def _checks_as_nan():
    """Trace equinox's runtime checks (`eqx.error_if`, used by diffrax) in their "nan"
    mode: a failed check makes the simulation NaN (a bad point of the fit: large
    residuals) instead of raising through a host callback. A program with host callbacks
    is never written to JAX's persistent compilation cache, so without this every new
    process (`rockjax fit`) compiles the fit again. Affects only what is traced inside."""
    errors = sys.modules.get("equinox._errors")
    old = getattr(errors, "EQX_ON_ERROR", None)
    if old is None:  # another equinox: leave it as it is
        yield
        return
    errors.EQX_ON_ERROR = "nan"
    try:
        yield
    finally:
        errors.EQX_ON_ERROR = old


def compiled(out_structure):
    """Decorator: `eqx.filter_jit(fn)`, traced with `_checks_as_nan` (see there); its
    programs are kept on disk when JAX's persistent compilation cache is on
    (`_aot.persisted`; `out_structure(*args)`: the pytree structure of its output)."""

    def wrap(fn):
        jitted = _aot.persisted(fn, out_structure)

        @functools.wraps(fn)
        def call(*args):
            with _checks_as_nan():
                return jitted(*args)

        return call

    return wrap


@functools.cache
def response_structure():
    """The pytree structure of a `rockjax.Response` (of one run, or of several)."""
    names = [f.name for f in dataclasses.fields(rockjax.Response)]
    return jax.tree.structure(rockjax.Response(**dict.fromkeys(names, 0.0)))


@compiled(lambda model, z: response_structure())
def respond(model: TraceModel, z):
    """`model.respond(z)`, compiled."""
    return model.respond(z)


def observed(model: TraceModel, z):
    """The fitted response at z as the sensor reads it (`_sensor.observe`: u with its
    offset and drift, uplift with its offset), numpy u and uplift."""
    z = jnp.asarray(z)
    v = model.decode(z)
    return _sensor.observe(respond(model, z), {p: float(v[p]) for p in _sensor.NUISANCE},
                           model.t, float(model.t_ref))


def channels(pb: Problem, response) -> list:
    """Unmasked residual arrays of a response (numpy), one per fitted channel (order
    `Problem.channels`)."""
    out = []
    for ch in pb.channels:
        scale, w = pb.unit_of(ch)
        x = np.asarray(getattr(response, ch)) - pb.measured(ch)
        out.append(x / scale if ch == "u" else w * x / scale)
    return out

