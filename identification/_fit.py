r"""`fit_decay`: fit $k_f$, $r$ (or the dashpots' $c_f$) and the release state $u_0$, $t_0$
to one free-vibration decay trace, or jointly to several traces of one structure.

The fit, concept by concept (one file each):

- `_problem`: the checked arguments (`Settings`, `setup` -> `Problem`);
- `_transforms`: natural parameters <-> the unconstrained coordinates z;
- `_residuals`: the model of the trace and its residuals and Jacobian (compiled);
- `_stages`: the multi-start fit with a growing horizon, and the optimiser;
- `_outliers`: spikes left out and the trace fitted again;
- `_uncertainty`: standard errors, identifiability, the lack-of-fit check;
- `_result`: `FitResult` and the warnings; `_joint`: the joint fit of several traces.

The fit minimises $\tfrac12\|r\|^2$ in the unconstrained coordinates with an optax
optimiser (default: Levenberg–Marquardt, `identification.levenberg_marquardt`), from
several starts vectorised with `jax.vmap` (oscillatory traces have local minima in phase).
The compiled optimiser step takes the trace and the fixed values as arguments: a second fit
of a trace of the same length, with the same parameters and settings, reuses it (it traces
and compiles nothing). With JAX's persistent compilation cache on (as `rockjax fit` has
it), the traced programs are kept on disk too (`identification._aot`).
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

import rockjax

from . import _auto, _joint
from ._outliers import outlier_message
from ._problem import Settings, setup
from ._residuals import observed, TraceModel
from ._result import (
    ConvergenceWarning,
    FitResult,
    IdentifiabilityWarning,
    LackOfFitWarning,
    OutlierWarning,
    result,
)
from ._stages import best_start, optimizer_of, run_stages
from ._transforms import Transform
from ._uncertainty import identifiability, lack_of_fit, uncertainty

_WARN_LEVEL = 3  # warnings point at the caller of fit_decay (fit_decay -> fit_single)


@dataclasses.dataclass(frozen=True)
class Schedule:
    r"""How `fit_decay` searches: starting points and growing horizons, stage by stage.

    **Arguments:**

    - `starts`: number of starting points (vectorised with vmap): the first is `initial`,
      the others shift logit(r) (and log c_f) by ±1 and multiply k_f by 2, 1/2, 4, ...
      Default (None): 2; for the 2-DOF body 3, the others at k_f / 2 and 2 k_f first (its
      misfit's basin around the true k_f is narrow: see `_models.start_offsets`).
    - `horizons`: fractions of the motion after the release fitted in turn (growing
      horizon; the samples before the release are in all of them), each stage starting
      from the last: short horizons fix r and the phase before later cycles refine k_f,
      which avoids the local minima of oscillatory fits. Default (None): (0.25, 0.5, 1.0);
      for the 2-DOF body (0.125, 0.25, 0.5, 1.0), whose misfit over a whole trace has
      many minima in k_f (see `identification._models.default_horizons`).
    - `max_iter`: the iteration limit of each stage (default 40).
    - `tol`: the relative change of the loss that ends a stage (default 1e-9).

    The values are checked by `fit_decay` (errors name them).

    **Example:**

        >>> identification.Schedule(starts=4)
        Schedule(starts=4, horizons=None, max_iter=40, tol=1e-09)
    """

    starts: int | None = None
    horizons: tuple | None = None
    max_iter: int = 40
    tol: float = 1e-9

    #: the keyword form of earlier versions: `fit_decay(starts=...)` and so on
    KEYWORDS = ("starts", "horizons", "max_iter", "tol")

    @classmethod
    def from_keywords(cls, schedule, keywords: dict) -> Schedule:
        """`schedule`, or one built from the keyword form popped from `keywords`; both at
        once is a `rockjax.ParameterError` naming the keyword."""
        given = {k: keywords.pop(k) for k in cls.KEYWORDS if k in keywords}
        if schedule is None:
            return cls(**given)
        if not isinstance(schedule, cls):
            raise rockjax.ParameterError(f"schedule must be an identification.Schedule, got "
                                         f"{type(schedule).__name__}", param="schedule")
        if given:
            name = next(iter(given))
            raise rockjax.ParameterError(f"{name}= and schedule= both given; set {name} on "
                                         "the Schedule", param=name)
        return schedule


def _weights(weights, keywords):
    """(uplift, theta) weights: `weights` by channel, or the keyword form's."""
    given = {k[: -len("_weight")]: keywords.pop(k) for k in ("uplift_weight", "theta_weight")
             if k in keywords}
    if weights is not None and given:
        name = next(iter(given))
        raise rockjax.ParameterError(f"{name}_weight= and weights= both given; put "
                                     f"{name!r} in weights", param=f"{name}_weight")
    weights = dict(given if weights is None else weights)
    unknown = sorted(set(weights) - {"uplift", "theta"})
    if unknown:
        raise rockjax.ParameterError(f"weights: unknown channel(s) {unknown}; the weighted "
                                     "channels are 'uplift' and 'theta' (u's weight is 1)",
                                     param="weights")
    return float(weights.get("uplift", 1.0)), float(weights.get("theta", 1.0))


def _tolerances(integrator, keywords):
    """(rtol, atol) of the fit's simulations: the integrator's, or the keyword form's."""
    rtol, atol = keywords.pop("rtol", None), keywords.pop("atol", None)
    if integrator is None:
        return (1e-9 if rtol is None else rtol), (1e-11 if atol is None else atol)
    if not isinstance(integrator, rockjax.integrators.EventRestart):
        raise rockjax.ParameterError(
            "integrator: a fit runs the event-restart integrator (its release time t0 is "
            "differentiated); pass rockjax.integrators.EventRestart(rtol=..., atol=...), got "
            f"{type(integrator).__name__}", param="integrator")
    if rtol is not None or atol is not None:
        raise rockjax.ParameterError("rtol=/atol= and integrator= both given; set them on "
                                     "the integrator", param="rtol" if rtol is not None
                                     else "atol")
    return integrator.rtol, integrator.atol


def fit_decay(
    trace,
    structure=None,
    params=None,
    *,
    model="simplified",
    initial: dict | None = None,
    offset=None,
    drift: bool = False,
    weights: dict | None = None,
    optimizer=None,
    schedule: Schedule | None = None,
    integrator=None,
    progress=None,
    **keywords,
):
    r"""Fit `params` of a rocking structure to a measured free-vibration decay trace.

    **Arguments:**

    - `trace`: an `identification.DecayTrace` (t [s] and any of u [m], theta [rad],
      uplift [m]).
    - `structure`: the `rockjax.RockingStructure` (geometry, masses; default Table 1). Its
      `k_f` and `restitution` (Eq. 3) are the starting values of `k_f` and `r`.
    - `params`: the parameters to fit, any of `"k_f"`, `"r"`, `"u0"` (release displacement
      [m]), `"t0"` (release time [s]) and `"c_f"` (the dashpot coefficient of the 2-DOF
      body [N s/m]). Default (None): `identification.default_params(model, contact=...)`,
      k_f, r, u0 and t0 less what does not act in the model (with continuous contact, c_f
      in place of r; with the rigid `housner` law, no k_f: a note in `FitResult.notes`). A
      parameter that does not act in the model is refused (ValueError naming it): its
      standard error would be meaningless. The release is found in the
      trace (`identification.detect_release`): u0 and t0 start from it, or are held there
      when not fitted: the first sample's displacement and time for a trace that starts at
      the release, the plateau level and the release time for one that starts with a hold
      or a clock offset. Holding u0 at a noisy first sample biases k_f and r.
    - `model`: any model of the fidelity ladder, by name (`rockjax.MODELS`: "housner",
      "simplified", "exact", "smooth", "two_spring_2dof", ...) or as an instance (e.g.
      `rockjax.TwoSpring2DOF(damping=c_f, contact="continuous")`, whose damping is then the
      start or held value of c_f); or `"auto"`: every rung that applies (simplified,
      rigid_body, two_spring_2dof with impact and with continuous contact) fitted with its
      default parameters, the one whose residuals are noise with the lowest AIC returned
      (else the lowest AIC), its `ranking` holding the table (`FitResult.ranking_text`;
      a 2-DOF rung whose residuals are not noise is fitted again over finer horizons, the
      better fit kept; minutes: each rung is a full fit). An SDOF impact rule other than
      the paper's and the 2-DOF body's contact law go on the model object:
      `rockjax.get_model("simplified", "after_uplift")`,
      `rockjax.TwoSpring2DOF(contact="continuous")` (the springs and dashpots carry the
      landing; r does not act, c_f is fitted in its place).
    - `initial`: dict of starting values overriding the defaults above (for a parameter
      not in `params`: the value it is held at). c_f starts, unless given here or by the
      model instance, at 5 % of critical damping of the vertical mode,
      $0.05\sqrt{2k_f(m_e+m_b)}$; held, at the model's damping (0 for "two_spring_2dof").
    - `weights`: the weight of each channel's residuals, by channel: `{"uplift": 1.0,
      "theta": 1.0}` (the defaults; u's is 1). The rotation's residuals are in units of
      the rotation's amplitude, u's and the uplift's of u's amplitude.
      A trace may hold any of u, theta and uplift: each is fitted through the model's
      own observation of it (`rockjax.Response.u`, `.theta`, `.uplift`); without u the
      release is found in the rotation (else the uplift) and u0 starts from its level
      mapped through the structure's kinematics (`identification._problem`).
    - `offset`: fit the sensor's zero of each channel (`offset` [m] of the displacement,
      `offset_uplift` [m] of the uplift when fitted) as nuisance parameters: the model as
      the sensor reads it is $u(t) + o$ (`identification._sensor`). None (default): where
      the trace can pin it, i.e. when it holds two cycles of motion after the release or
      ends at rest (else not, with a note in `FitResult.notes`); True: always; False:
      never. An unfitted offset shows in the lack-of-fit check (its sign and mean tests).
    - `drift`: also fit a linear drift of the displacement channel, $+ d\,(t - t_{ref})$
      [m/s] from the release time the fit starts from (default False).
      The nuisance parameters are in `FitResult.values` and `stderr` like the others; the
      fitted `response` is the model as the sensor reads it (offset and drift added).
    - `optimizer`: default (None) `levenberg_marquardt()`, stepped in chunks of 4 steps.
      A plain optax optimiser (e.g. `optax.adam(1e-2)`) gets the gradient $J^Tr$. An
      optimistix least-squares solver (e.g. `optimistix.LevenbergMarquardt(rtol=1e-6,
      atol=1e-9)`) runs each stage with `optimistix.least_squares` to its own
      termination (at most `schedule.max_iter` steps; `schedule.tol` does not apply).
    - `schedule`: an `identification.Schedule`: the starting points, the growing
      horizons, and each stage's iteration limit and tolerance (default `Schedule()`).
    - `integrator`: a `rockjax.integrators.EventRestart` whose `rtol`, `atol` are the
      simulations' tolerances (default rtol 1e-9, atol 1e-11; the fit differentiates in
      forward mode, whatever its `adjoint`).
    - `progress`: show a progress bar (default: only if the fit takes more than about
      3 s and stderr is a terminal).
    - `**keywords`: the keyword form of earlier versions, still accepted: `impact=`,
      `contact=` (the model's), `starts=`, `horizons=`, `max_iter=`, `tol=` (the
      `Schedule`'s), `rtol=`, `atol=` (the integrator's), `uplift_weight=`,
      `theta_weight=` (the `weights`').

    **Returns:** a `FitResult`. Warns `ConvergenceWarning` when the fit ends unconverged
    (`FitResult.converged` False), whatever the optimiser; warns `IdentifiabilityWarning`
    when the trace cannot pin a parameter down, and `LackOfFitWarning` (a subclass) when
    the residuals are not noise (`FitResult.lack_of_fit`, `FitResult.diagnosis`: what they
    look like: an offset, a drift, a periodic component, or a model that cannot represent
    the trace; the standard errors do not hold; for the model, the message names the next
    model up the ladder); never raises for a poor fit (see `converged`). Raises
    `TraceError` (a `ValueError`) when the trace's amplitude lies beyond the structure's
    `u_overturn` (a trace in mm read as m, say), when it is clipped (a saturated sensor),
    or when it holds a second release (`identification.split_releases`; see
    `identification._anomalies`).

    **Outliers:** after a converged fit, the residuals of each channel (displacement, uplift) are
    compared with their robust spread, 1.4826 x the median absolute deviation (the noise
    standard deviation for Gaussian noise). Samples more than `OUTLIER_SIGMAS` = 6 of these
    (and more than 1e-6 of the trace amplitude) from the median residual are outliers,
    e.g. spikes of a faulty sensor: they are left out (`FitResult.outliers`) and the whole
    trace is fitted again without them, largest first, until the set stops changing (at
    most 3 refits). An `OutlierWarning` (also in `FitResult.warnings`) says so. When more
    than 5 % of the samples would be outliers, the residuals are a misfit (a wrong minimum,
    a wrong model), not spikes: nothing is left out.

    **Example:**

    ```python
    path = identification.synthetic_trace_path("synthetic_decay_noisy")
    fit = identification.fit_decay(identification.read_trace(path), rockjax.mcmanus_column())
    fit.values["k_f"], fit.stderr["k_f"], fit.lack_of_fit["fires"]
    ```

    **Joint fit:** `trace` may be a list of traces of one structure (a list of equal
    structures is accepted too). k_f and r (or c_f) are shared, each trace has its own u0
    and t0 (fitted or held at its release); the traces are fitted at once (vmapped, padded
    to the longest with masked samples) and the result is a `JointFitResult`. Traces must
    all have, or all lack, the uplift channel; outliers are not searched for. The other
    arguments apply to every trace.
    """
    schedule = Schedule.from_keywords(schedule, keywords)
    rtol, atol = _tolerances(integrator, keywords)
    impact, contact = keywords.pop("impact", "paper"), keywords.pop("contact", None)
    uplift_weight, theta_weight = _weights(weights, keywords)
    if keywords:
        raise TypeError(f"fit_decay() got unexpected keyword arguments {sorted(keywords)}")
    settings = Settings(model=model, impact=impact, contact=contact, initial=initial,
                        starts=schedule.starts, max_iter=schedule.max_iter,
                        horizons=schedule.horizons, tol=schedule.tol,
                        uplift_weight=uplift_weight, theta_weight=theta_weight, rtol=rtol,
                        atol=atol, progress=progress,
                        offset=offset, drift=drift)
    if isinstance(model, str) and model == "auto":
        if isinstance(trace, (list, tuple)):
            raise ValueError("model='auto' fits one trace: fit a list of traces with a model")
        return _auto.fit_auto(trace, structure, params, settings, optimizer, fit_single)
    if isinstance(trace, (list, tuple)):
        return _joint.fit_joint(trace, structure, params, settings, optimizer)
    return fit_single(trace, structure, params, settings, optimizer)


def fit_single(trace, structure, params, settings: Settings, optimizer=None) -> FitResult:
    """The fit of one trace (`fit_decay`'s arguments: `settings` the keyword ones)."""
    problem = setup(trace, structure, params, settings)
    transform = Transform.of(problem)
    model = TraceModel.build(problem)
    opt = optimizer_of(optimizer)
    run = run_stages(problem, model, opt, transform.starting_points(problem.starts),
                     lm=optimizer is None)
    best = best_start(problem, model, opt, run)
    unc = uncertainty(problem, transform, best, run.keep)
    ident, messages = identifiability(problem, best, unc)
    for m in messages:
        warnings.warn(m, IdentifiabilityWarning, stacklevel=_WARN_LEVEL)
    response = observed(model, best.z)
    primary = np.asarray(getattr(response, problem.channels[0]))
    msg = outlier_message(problem, primary, run.keep, unc.sigma)
    if msg is not None:
        messages.append(msg)
        warnings.warn(msg, OutlierWarning, stacklevel=_WARN_LEVEL)
    lack = lack_of_fit(problem, primary, run.keep)
    if lack["fires"]:
        messages.append(lack["message"])
        warnings.warn(lack["message"], LackOfFitWarning, stacklevel=_WARN_LEVEL)
    if not (bool(run.converged[best.index]) and np.isfinite(best.loss) and best.loss < 1e5):
        how = ("the default Levenberg-Marquardt" if optimizer is None
               else f"the optimiser {type(optimizer).__name__}")
        msg = (f"the fit did not converge: {how} stopped after {run.n_iter} iterations "
               f"(max_iter = {problem.max_iter} per horizon) at loss {best.loss:.4g} without "
               "meeting its tolerance: the values are not a minimum and their standard "
               "errors mean nothing; raise max_iter, or fit with the default optimiser")
        messages.append(msg)
        warnings.warn(msg, ConvergenceWarning, stacklevel=_WARN_LEVEL)
    return result(problem, run, best, unc, ident, messages, response, lack)
