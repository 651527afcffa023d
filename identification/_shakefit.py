r"""`fit_shake_table`: fit $k_f$, $r$ (and the 2-DOF body's $c_f$) to shake-table runs.

The same fit machinery as `fit_decay` (`_problem.Problem`, `_residuals.TraceModel`,
`_stages`, `_uncertainty`), with another kind of evidence: the `Problem` carries the
table record (`Problem.accel`, `accel_dt`), and `TraceModel.respond` simulates the
structure under the `rockjax.GroundMotion` of it instead of a free vibration. The
parameters:

- `k_f`, `r` (where they act), `c_f` (the 2-DOF body's dashpots);
- `t0` [s]: the time on the response's clock of the table record's first sample (the
  role the release time plays for a decay); its start is `ShakeTableRun.table_start` (as
  read), and `clock_offset` = t0 - table_start is the clock offset between the table and
  the response channels that the fit finds (reported with its standard error);
- `u0` [m]: the initial displacement (held at 0 by default: at rest when the table
  starts);
- the sensor zero of each channel (`offset`, `offset_theta`, `offset_uplift`; fitted by
  default) and a drift of u (`drift=True`).

**Noise weighting.** Each channel's residuals are divided by its noise level, so that
every sample counts as its noise says: before the fit, a robust estimate from the data's
second differences ($1.4826\,\mathrm{MAD}(\Delta^2 x)/\sqrt6$); after it, the residuals'
RMS of each channel; if a channel's weight would change by more than
`REWEIGHT_TOLERANCE`, the fit is run again from its optimum (the whole run, one stage)
with the weights of the residuals. In the machinery's terms: u's residuals stay in units
of its amplitude, and the other channels get the weights (`theta_weight`,
`uplift_weight`) that give them the same noise level in the residuals. The noise level of
each channel is reported (`ShakeTableFitResult.noise`).
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np

from . import _models, _sensor
from ._bayes import PosteriorProblem
from ._problem import (
    _check_options,
    _check_params,
    _starting_values,
    _trace_arrays,
    check_structure,
    NUISANCE,
    Problem,
    Settings,
)
from ._release import Release
from ._residuals import observed, TraceModel
from ._result import (
    ConvergenceWarning,
    FitResult,
    IdentifiabilityWarning,
    LackOfFitWarning,
    result,
)
from ._shake import _noise, check_saturation, ShakeTableRun
from ._stages import best_start, optimizer_of, run_stages
from ._transforms import Transform
from ._uncertainty import identifiability, lack_of_fit, uncertainty

REWEIGHT_TOLERANCE = 0.2
"""A channel's noise weight changing by more than this fraction after the fit refits."""
SHAKE_HORIZONS = (0.1, 0.2, 0.35, 0.5, 0.75, 1.0)
"""The growing horizons of a shake-table fit (fractions of the run after the table
starts), finer than a decay's: a strong part of the record that rocks the structure far
puts local minima in the misfit over a long horizon (a rigid body under 1.5 x Corralitos,
20 u_crit: from the decay's (0.25, 0.5, 1.0), k_f +15 % and r -30 % with the lack-of-fit
check firing; from these, within 0.1 %)."""
DEFAULT_SHAKE_PARAMS = ("k_f", "r", "t0")
"""Fitted by default (less those that do not act; c_f in place of r with continuous
contact), with the sensor zero of each channel."""


@dataclasses.dataclass(frozen=True, eq=False)
class ShakeTableFitResult(FitResult):
    """A `FitResult` of a shake-table run (`fit_shake_table`), with:

    - `clock_offset` [s]: t0 less the table start as read (`clock_offset_stderr`);
    - `noise`: the noise std of each channel fitted, from its residuals (SI);
    - `run`: `ShakeTableRun.info()` (what was read, the notes on the clocks).

    `release` holds the table start (as read) and the t0 the fit started from.
    """

    clock_offset: float = 0.0
    clock_offset_stderr: float = float("nan")
    noise: dict = dataclasses.field(default_factory=dict)
    run: dict = dataclasses.field(default_factory=dict)
    _posterior: tuple = ()  # (TraceModel, mask, residual sigma per channel, Transform)

    def report(self, truth=None, read_warnings=()) -> str:
        """The fit as text: the values table, the clock offset, the noise of each channel,
        then what `FitResult.report` gives after its table."""
        from ._report import stats_lines, value_table

        noise = ", ".join(f"{c} {v:.3g} {'rad' if c == 'theta' else 'm'}"
                          for c, v in self.noise.items())
        se = self.clock_offset_stderr
        clock = (f"clock offset  {1e3 * self.clock_offset:+.4g} ms (std. error "
                 f"{1e3 * se:.2g} ms): t0 less the table start as read"
                 if math.isfinite(se) else
                 f"clock offset  {1e3 * self.clock_offset:+.4g} ms (held)")
        return "\n".join([value_table(self, truth), "", clock, f"noise         {noise}",
                          *(f"warning: {w}" for w in read_warnings), *stats_lines(self)])

    def summary(self) -> dict:
        """`FitResult.summary`, with `clock_offset`, `clock_offset_stderr` [s], `noise`
        (per channel) and `run` (what was read)."""
        out = super().summary()
        out["units"] = {**out["units"], "clock_offset": "s", "noise": "m (theta: rad)"}
        return {**out, "kind": "shake table", "clock_offset": self.clock_offset,
                "clock_offset_stderr": self.clock_offset_stderr, "noise": dict(self.noise),
                "run": self.run}

    def posterior_problem(self, priors=None) -> PosteriorProblem:
        """The posterior of the fitted parameters (`identification.PosteriorProblem`), as
        for a decay fit (`identification._posterior_decay`): Gaussian residuals of each
        channel with its noise level integrated out (Jeffreys prior),
        $\\log L(z) = -\\sum_c \\tfrac{n}{2} \\log \\mathrm{RSS}_c(z)$, the gradient
        $J^T g$ from the forward-mode Jacobian (`TraceModel.res_jac`), and the same default
        priors (k_f, c_f lognormal around their start with sd 2 in the log, r uniform on
        [0, 1], the rest flat; `priors`: name -> `Prior` or text over them)."""
        from ._posterior_decay import residual_problem

        model, mask, _, _ = self._posterior
        z0 = np.array([self._z0[p] for p in self.names])
        return residual_problem(model, mask, z0, priors, source="shake table")

    @property
    def _z0(self) -> dict:
        tf = self._posterior[3]
        return tf.encode({**{k: float(v) for k, v in tf.values0.items()}, **self.values})


@dataclasses.dataclass(frozen=True, eq=False)
class ShakeProblem(Problem):
    """The `Problem` of a shake-table run: t0 (the clock) is held on the first horizon
    (`hold_first`, read by `_stages.run_horizon`), as k_f and the sensor zeros are: a
    record that starts quietly (the rigid body hardly moves before it lifts off) does not
    inform the clock there, and t0 free on it wandered off (to 0.1-0.3 s, a wrong minimum)
    on 3 of 20 runs under Corralitos."""

    hold_first: tuple = ("t0",)


def default_shake_params(fm) -> tuple:
    """The parameters fitted by default with this model: `DEFAULT_SHAKE_PARAMS` less
    those that do not act (c_f in place of r with continuous contact)."""
    out = [p for p in DEFAULT_SHAKE_PARAMS if p in fm.acting]
    if "r" not in fm.acting and fm.has_dashpots:
        out.insert(1 if "k_f" in out else 0, "c_f")
    return tuple(out)


def _as_run(run) -> ShakeTableRun:
    if isinstance(run, ShakeTableRun):
        return run
    raise ValueError("fit_shake_table: expected an identification.ShakeTableRun (read one "
                     "with identification.read_shake_table), or a list of them, got "
                     f"{type(run).__name__}")


def setup_run(run: ShakeTableRun, structure, params, settings: Settings,
              noise_weights: dict | None = None, by_noise: bool = True) -> Problem:
    """The `Problem` of a shake-table run (`fit_shake_table`'s arguments checked):
    the table record as the excitation, t0 starting at the table start as read,
    channel weights from each channel's noise (`noise_weights`: sigma per channel;
    default estimated from the data; `by_noise` False: the settings' weights)."""
    st = settings
    run = _as_run(run)
    structure = check_structure(structure)
    fm = _models.resolve_model(st.model, st.impact, st.contact)
    params = default_shake_params(fm) if params is None else _check_params(params, fm)
    horizons = SHAKE_HORIZONS if st.horizons is None else st.horizons
    starts = _models.default_starts(fm) if st.starts is None else st.starts
    horizons = _check_options(starts, st.max_iter, st.impact, horizons, st.tol, 1.0, 1.0)
    trace = run.response
    check_saturation(trace)
    t, u_meas, up_meas, scale = _trace_arrays(trace, params, structure)
    th_meas = None if trace.theta is None else np.asarray(trace.theta, float)
    fitted = trace.channels
    sig = dict(noise_weights or {c: _noise(getattr(trace, c)) for c in fitted})
    primary = fitted[0]
    amp = {"u": scale, "uplift": scale,
           "theta": max(float(np.max(np.abs(th_meas))), 1e-300) if th_meas is not None
           else 1.0}
    floor = {c: max(sig[c], 1e-6 * amp[c]) for c in fitted}
    level = floor[primary] / amp[primary]  # the primary channel's noise in residual units
    w = {c: level * amp[c] / floor[c] for c in fitted}
    theta_w = w.get("theta", 1.0) if by_noise else st.theta_weight
    uplift_w = w.get("uplift", 1.0) if by_noise else st.uplift_weight
    if primary == "theta":
        theta_w = 1.0
    release = Release(time=run.table_start, estimate=run.table_start, index=0, level=0.0,
                      sigma=floor[primary], threshold=5.0 * floor[primary], held=False,
                      channel="u")
    named = tuple(p for p in params if p in NUISANCE)
    nuisance = list(named)
    if st.offset is not False:
        nuisance += [_sensor.OFFSET_OF[c] for c in fitted]
    if st.drift and "u" in fitted:
        nuisance.append("drift")
    params = tuple(p for p in params if p not in NUISANCE) + tuple(
        p for p in NUISANCE if p in nuisance)
    values0, k_min = _starting_values(structure, release, st.initial, fm, params)
    notes = tuple(run.notes)
    if "u0" not in params:
        notes += (f"u0 held at {values0['u0']:.6g} m: the structure at rest when the table "
                  "starts (fit it with params=(..., 'u0'))",)
    return ShakeProblem(
        structure=structure, params=params, fit_model=fm, impact=st.impact,
        horizons=horizons, starts=starts, max_iter=st.max_iter, tol=st.tol,
        uplift_weight=float(uplift_w), rtol=st.rtol, atol=st.atol, progress=st.progress,
        t=t, u_meas=u_meas, up_meas=up_meas, scale=scale, values0=values0, k_min=k_min,
        release=release, notes=notes, k_cap=_models.k_f_cap(fm, k_min),
        th_meas=th_meas, theta_weight=float(theta_w), primary=primary,
        theta_scale=amp["theta"], accel=np.asarray(run.table.accel, float),
        accel_dt=float(run.table.dt))


def channel_noise(problem: Problem, best, keep) -> dict:
    """The noise std of each fitted channel (SI) from the residuals at the optimum: RMS
    over the kept samples, less a share of the parameters."""
    n = problem.t.size
    chans = problem.channels
    k = max(int(np.count_nonzero(keep)), 1)
    dof = max(k - len(problem.params) / len(chans), 1.0)
    out = {}
    for i, ch in enumerate(chans):
        s, w = problem.unit_of(ch)
        r = np.asarray(best.r[i * n:(i + 1) * n])[keep]
        out[ch] = math.sqrt(float(np.sum(r**2)) / dof) * s / max(w, 1e-300)
    return out


def _fit_problem(problem, optimizer, z_start=None):
    transform = Transform.of(problem)
    model = TraceModel.build(problem)
    opt = optimizer_of(optimizer)
    z0 = (transform.starting_points(problem.starts) if z_start is None
          else np.tile(np.asarray(z_start), (problem.starts, 1)))
    run = run_stages(problem, model, opt, z0, lm=optimizer is None, outliers=False)
    return transform, model, opt, run, best_start(problem, model, opt, run)


def fit_run(run: ShakeTableRun, structure, params, settings: Settings, optimizer=None,
            weights_given: bool = False) -> ShakeTableFitResult:
    """The fit of one run (`fit_shake_table`'s arguments; `settings` the keyword ones)."""
    problem = setup_run(run, structure, params, settings, by_noise=not weights_given)
    transform, model, opt, srun, best = _fit_problem(problem, optimizer)
    noise = channel_noise(problem, best, srun.keep)
    if not weights_given and len(problem.channels) > 1:
        again = setup_run(run, structure, params, settings, noise_weights=noise)
        change = max(abs(a / b - 1.0) for a, b in (
            (again.theta_weight, problem.theta_weight),
            (again.uplift_weight, problem.uplift_weight)))
        if change > REWEIGHT_TOLERANCE:
            again = dataclasses.replace(again, horizons=(1.0,), values0=problem.values0)
            problem = again
            transform, model, opt, srun, best = _fit_problem(problem, optimizer, best.z)
            noise = channel_noise(problem, best, srun.keep)
    unc = uncertainty(problem, transform, best, srun.keep)
    ident, messages = identifiability(problem, best, unc)
    for m in messages:
        warnings.warn(m, IdentifiabilityWarning, stacklevel=4)
    response = observed(model, best.z)
    primary = np.asarray(getattr(response, problem.channels[0]))
    lack = lack_of_fit(problem, primary, srun.keep)
    if lack["fires"]:
        messages.append(lack["message"])
        warnings.warn(lack["message"], LackOfFitWarning, stacklevel=4)
    if not (bool(srun.converged[best.index]) and np.isfinite(best.loss) and best.loss < 1e5):
        msg = (f"the fit did not converge: stopped after {srun.n_iter} iterations at loss "
               f"{best.loss:.4g}: the values are not a minimum and their standard errors "
               "mean nothing; raise max_iter (Schedule)")
        messages.append(msg)
        warnings.warn(msg, ConvergenceWarning, stacklevel=4)
    base = result(problem, srun, best, unc, ident, messages, response, lack)
    fields = {f.name: getattr(base, f.name) for f in dataclasses.fields(FitResult)}
    t0 = unc.values["t0"]
    fields["release"] = {"table_start_s": run.table_start, "t0_start_s": problem.values0["t0"],
                         "u0_start_m": problem.values0["u0"]}
    j = problem.params.index("t0") if "t0" in problem.params else None
    n = problem.t.size
    s_res = []
    for i, ch in enumerate(problem.channels):
        r = np.asarray(best.r[i * n:(i + 1) * n])[srun.keep]
        s_res.append(max(math.sqrt(float(np.mean(r**2))), 1e-300))
    return ShakeTableFitResult(
        **fields, clock_offset=float(t0 - run.table_start),
        clock_offset_stderr=float(unc.se[j]) if j is not None else float("nan"),
        noise=noise, run=run.info(),
        _posterior=(model, np.asarray(srun.keep, float), np.asarray(s_res), transform))


def fit_shake_table(runs, structure=None, params=None, *, model="simplified",
                    initial: dict | None = None, offset=True, drift: bool = False,
                    weights: dict | None = None, optimizer=None, schedule=None,
                    integrator=None, progress=None, impact: str = "paper",
                    contact: str | None = None):
    r"""Fit `params` of a rocking structure to a shake-table run (or several jointly).

    **Arguments:**

    - `runs`: an `identification.ShakeTableRun` (`read_shake_table`,
      `synthetic_shake_table`), or a list of runs of one specimen (a joint fit: k_f, r,
      c_f shared; each run its own t0, u0 and sensor zeros; a `JointFitResult`).
    - `structure`: the `rockjax.RockingStructure` (default Table 1); its `k_f` and
      `restitution` are the starting values.
    - `params`: any of `"k_f"`, `"r"`, `"c_f"`, `"u0"` (the initial displacement),
      `"t0"` (the response-clock time of the table's first sample: the clock offset),
      and the sensor's `"offset"`, `"offset_theta"`, `"offset_uplift"`, `"drift"`.
      Default: k_f, r and t0 (less what does not act in the model; c_f in place of r
      with continuous contact).
    - `model`: any model of the ladder, by name or instance, as `fit_decay`'s
      (`"simplified"`, `"rigid_body"`, `"two_spring_2dof"`, ...).
    - `initial`: starting (or held) values, as `fit_decay`'s.
    - `offset`: fit the sensor zero of every channel (default True); `drift`: also a
      linear drift of u.
    - `weights`: `{"theta": w, "uplift": w}` to weight the channels by hand; default
      (None): by each channel's noise (module docstring).
    - `optimizer`, `schedule`, `integrator`, `progress`: as `fit_decay`'s; `impact`,
      `contact`: the SDOF impact rule, the 2-DOF body's contact law.

    **Returns:** a `ShakeTableFitResult` (a `FitResult`: values, standard errors,
    correlations, the lack-of-fit check, identifiability warnings; and `clock_offset`,
    `noise`, `run`), or a `JointFitResult` for several runs. Raises `TraceError` for a
    saturated response channel, or a response in other units than it says.
    """
    from ._fit import _tolerances, Schedule

    schedule = Schedule.from_keywords(schedule, {})
    rtol, atol = _tolerances(integrator, {})
    uplift_w, theta_w = 1.0, 1.0
    if weights is not None:
        from ._fit import _weights

        uplift_w, theta_w = _weights(weights, {})
    if isinstance(model, str) and model == "auto":
        raise ValueError("model='auto' is for decay traces: fit a shake-table run with a "
                         "model of the ladder")
    settings = Settings(model=model, impact=impact, contact=contact, initial=initial,
                        starts=schedule.starts, max_iter=schedule.max_iter,
                        horizons=schedule.horizons, tol=schedule.tol,
                        uplift_weight=uplift_w, theta_weight=theta_w, rtol=rtol, atol=atol,
                        progress=progress, offset=offset, drift=drift)
    if isinstance(runs, (list, tuple)):
        runs = [_as_run(r) for r in runs]
        if len(runs) == 1:
            return fit_run(runs[0], structure, params, settings, optimizer,
                           weights is not None)
        from ._joint import fit_joint_problems

        problems = [setup_run(r, structure, params, settings, by_noise=weights is None)
                    for r in runs]
        n_acc = max(pb.accel.size for pb in problems)
        problems = [dataclasses.replace(pb, accel=np.pad(pb.accel, (0, n_acc - pb.accel.size)))
                    for pb in problems]
        return fit_joint_problems(problems, optimizer,
                                  [r.source or f"run[{i}]" for i, r in enumerate(runs)])
    return fit_run(_as_run(runs), structure, params, settings, optimizer, weights is not None)
