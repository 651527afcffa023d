r"""Fit $k_f$, $r$ (or the dashpots' $c_f$) and the release state $u_0$, $t_0$ to a
free-vibration decay trace.

The model is `rockjax.simulate` of a release from rest at $u_0$ at time $t_0$ with any model
of the fidelity ladder (`identification._models`: the SDOF Eq. 1 with impacts, Eqs 2–3, by
default; the 2-DOF body with either contact law and its dashpots $c_f$); before $t_0$ the
structure is held at $u_0$. Since it is released at rest, the model is continuously
differentiable in $t_0$ (the velocity is 0 on both sides of the release), and every sample
is defined wherever $t_0$ lies: samples before it (a hold) inform $u_0$, the others all the
parameters. The residuals are the differences between the model and the measured top
displacement (and uplift, when the trace has that channel), scaled by the trace amplitude.
The fit minimises $\tfrac12\|r\|^2$ in unconstrained coordinates

$$z = \big(\log(k_f - k_{f,min}),\ \operatorname{logit} r,\ u_0/u_{s},\
(t_0 - t_{ref})/10\,\mathrm{ms},\ \log c_f\big),$$

where $k_{f,min} = W H_c / (2B^2)$ is the stability limit (Eq. 15) and $t_{ref}$ the
starting value of $t_0$ (the release found by `identification.detect_release`), with an
optax optimiser (default: Levenberg–Marquardt, `identification.levenberg_marquardt`), from
several starts vectorised with `jax.vmap` (oscillatory traces have local minima in phase).
Standard errors and correlations come from the Gauss–Newton approximation of the Fisher
information at the optimum (a sandwich over the channels, see `_uncertainty`); they hold
only if the residuals are noise, which the lack-of-fit check (`identification._lack`)
tests.

The compiled optimiser step takes the trace and the fixed values as arguments: a second fit
of a trace of the same length, with the same parameters and settings, reuses it (it traces
and compiles nothing). With JAX's persistent compilation cache on (as `rockjax fit` has
it), the traced programs are kept on disk too (`identification._aot`), so that a new
process neither traces nor compiles them. Each stage of the growing horizon simulates only
as far as the last sample it fits.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import math
import sys
import time
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

import rockjax

from . import _aot, _lack, _models
from ._models import FitModel
from ._optim import levenberg_marquardt
from ._trace import DecayTrace, detect_release, Release, TraceError

PARAM_NAMES = ("k_f", "r", "u0", "t0", "c_f")
"""The parameters `fit_decay` can fit (`DEFAULT_PARAMS`, less those that do not act in the
model, are fitted by default; see `identification.default_params`)."""
UNITS = {"k_f": "N/m", "r": "-", "u0": "m", "t0": "s", "c_f": "N s/m"}
"""The (SI) unit of each parameter."""
_T_SCALE = 0.01  # s, unit of t0 in the unconstrained coordinates
_WARN_LEVEL = 3  # warnings point at the caller of identification.fit_decay (a wrapper)
_LM = levenberg_marquardt()  # the default optimiser: one instance, so compiled code is reused
_aot.name_static(_LM.init, "identification.levenberg_marquardt().init")
_aot.name_static(_LM.update, "identification.levenberg_marquardt().update")


class IdentifiabilityWarning(UserWarning):
    """The trace does not pin a parameter down (large standard error or correlation)."""


class LackOfFitWarning(IdentifiabilityWarning):
    """The residuals are not noise: the model cannot represent the trace (or the fit is in
    a local minimum), and the standard errors do not hold (`FitResult.lack_of_fit`)."""


class OutlierWarning(UserWarning):
    """Samples of the trace lie far from the fit (spikes): they were left out of it."""


OUTLIER_SIGMAS = 6.0
"""A residual more than this many robust standard deviations from its channel's median
(and above `_OUTLIER_FLOOR` of the trace amplitude) marks an outlier."""
_OUTLIER_FLOOR = 1e-6
_MAX_REFITS = 3
_MAX_OUTLIER_FRACTION = 0.05


def _find_outliers(channels, excluded, within, sigmas=OUTLIER_SIGMAS):
    """Samples whose residual is an outlier, as a boolean array (n samples).

    `channels`: residual arrays (n,) scaled by the trace amplitude (displacement, and
    uplift when measured); `excluded`: samples already left out of the fit; `within`: the
    samples the fit covers (its last horizon), the only ones considered. The scale of
    each channel is the median absolute deviation (x 1.4826, the standard deviation for
    Gaussian noise) over its kept samples (for uplift, those with a non-zero residual: the
    model and a noise-free trace both have exactly zero uplift before lift-off). A sample
    is an outlier when its residual lies more than `sigmas` of these, and more than
    `_OUTLIER_FLOOR`, from the median, and - since a few large spikes pull the fit and
    spread the residuals of the other samples - within a factor 10 of the largest such
    deviation among the kept samples. Excluded samples stay out while they remain
    outliers: the search converges in a few refits, largest spikes first.
    """
    flag = np.zeros(channels[0].shape, bool)
    for k, res in enumerate(channels):
        kept = within & ~excluded & ((res != 0) if k > 0 else True)
        if np.count_nonzero(kept) < 10:
            continue
        med = float(np.median(res[kept]))
        mad = 1.4826 * float(np.median(np.abs(res[kept] - med)))
        dev = np.abs(res - med)
        z = dev / max(mad, 1e-300)
        big = (dev > sigmas * mad) & (dev > _OUTLIER_FLOOR) & within
        if not np.any(big & ~excluded):
            flag |= big & excluded
            continue
        z_top = float(np.max(np.where(within & ~excluded, z, 0.0)))
        flag |= big & (excluded | (z >= 0.1 * z_top))
    return flag


@dataclasses.dataclass(frozen=True, eq=False)
class FitResult:
    """Result of `fit_decay` (SI units: k_f [N/m], r [-], u0 [m], t0 [s], c_f [N s/m]).

    - `values`, `stderr`: fitted value and standard error of each fitted parameter;
      `fixed`: the values held fixed (of the parameters that act in the model); `start`:
      the starting value of each fitted parameter (the first start).
    - `correlation`: correlation matrix of the fitted parameters (order `names`).
    - `loss`: final $\\tfrac12\\|r\\|^2$ (residuals scaled by `scale` [m]); `rms` [m]: RMS
      residual of the displacement; `sigma` [m]: estimated noise std of the displacement.
    - `loss_history`: the loss of the best start at each iteration; `start_losses`: final
      loss of every start.
    - `response`: the fitted `rockjax.Response` on the trace times (model time t - t0).
    - `converged`: the optimiser stopped on its tolerance (not on `max_iter`), at a finite
      loss.
    - `identifiability`: sensitivities and the k_f-r correlation (see `identifiability`);
      `warnings`: the messages of any `IdentifiabilityWarning` or `OutlierWarning` raised.
    - `outliers`: indices of the trace samples left out of the fit as outliers (empty if
      none); `loss`, `rms`, `sigma` and the standard errors are over the other samples.
    - `release`: the release found in the trace (`identification.detect_release`, as
      `Release.as_dict()`) and the t0 the fit started from or held (`t0_start_s`).
    - `lack_of_fit`: whether the displacement residuals are noise (`identification._lack`):
      their lag-1 autocorrelation and runs test, `fires`, the thresholds, `next_model` (up
      the ladder) and `message` (also a `LackOfFitWarning` and in `warnings` when it fires).
    - `model`: the model fitted, in words; `notes`: default parameters left out because
      they do not act in it (r with continuous contact, say).
    """

    names: tuple
    values: dict
    stderr: dict
    fixed: dict
    correlation: np.ndarray
    loss: float
    rms: float
    sigma: float
    loss_history: np.ndarray
    start_losses: np.ndarray
    response: object
    converged: bool
    n_iterations: int
    identifiability: dict
    warnings: tuple
    scale: float
    outliers: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0, int))
    release: dict = dataclasses.field(default_factory=dict)
    lack_of_fit: dict = dataclasses.field(default_factory=dict)
    model: str = ""
    notes: tuple = ()
    start: dict = dataclasses.field(default_factory=dict)

    def summary(self) -> dict:
        """A JSON-ready dict: values, standard errors, held and starting values,
        correlation, loss, converged, the release, the lack-of-fit check, the model fitted
        (`fitted_model`), notes, and `units` (of the parameters, `rms_residual` and
        `sigma`)."""
        units = {**UNITS, "rms_residual": "m", "sigma": "m", "loss": "-"}
        return {
            "units": units,
            "values": dict(self.values),
            "stderr": dict(self.stderr),
            "fixed": dict(self.fixed),
            "start": dict(self.start),
            "correlation": {
                a: {b: float(self.correlation[i, j]) for j, b in enumerate(self.names)}
                for i, a in enumerate(self.names)
            },
            "loss": self.loss,
            "rms_residual": self.rms,
            "sigma": self.sigma,
            "converged": self.converged,
            "n_iterations": self.n_iterations,
            "identifiability": self.identifiability,
            "warnings": list(self.warnings),
            "outliers": [int(i) for i in self.outliers],
            "release": dict(self.release),
            "lack_of_fit": dict(self.lack_of_fit),
            "fitted_model": self.model,
            "notes": list(self.notes),
        }


def _k_min(structure):
    return structure.W * structure.H_c / (2.0 * structure.B**2)


def fit_decay(
    trace,
    structure=None,
    params=None,
    *,
    model="simplified",
    impact="paper",
    contact=None,
    initial=None,
    starts: int | None = None,
    optimizer=None,
    max_iter: int = 40,
    horizons=None,
    tol: float = 1e-9,
    uplift_weight: float = 1.0,
    rtol: float = 1e-9,
    atol: float = 1e-11,
    progress=None,
) -> FitResult:
    r"""Fit `params` of a rocking structure to a measured free-vibration decay trace.

    **Arguments:**

    - `trace`: an `identification.DecayTrace` (t [s], u [m], optional uplift [m]).
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
      start or held value of c_f); `impact`: the SDOF impact rule (`rockjax.simulate`).
    - `contact`: the contact law of the 2-DOF body, `"impact"` (Housner's impact at a
      landing, r) or `"continuous"` (the springs and dashpots carry it; r does not act);
      None: the model's own (`"impact"` for `"two_spring_2dof"`). Refused for models
      without one.
    - `initial`: dict of starting values overriding the defaults above (for a parameter
      not in `params`: the value it is held at). c_f starts, unless given here or by the
      model instance, at 5 % of critical damping of the vertical mode,
      $0.05\sqrt{2k_f(m_e+m_b)}$; held, at the model's damping (0 for "two_spring_2dof").
    - `starts`: number of starting points (vectorised with vmap): the first is `initial`,
      the others shift logit(r) (and log c_f) by ±1 and multiply k_f by 2, 1/2, 4, ...
      Default (None): 2; for the 2-DOF body 3, the others at k_f / 2 and 2 k_f first (its
      misfit's basin around the true k_f is narrow: see `_models.start_offsets`).
    - `optimizer`: an optax optimiser; default `levenberg_marquardt()`. A plain optax
      optimiser (e.g. `optax.adam(1e-2)`) gets the gradient $J^Tr$.
    - `max_iter`, `tol`: iteration limit (per horizon) and relative loss-change tolerance.
    - `horizons`: fractions of the motion after the release fitted in turn (growing
      horizon; the samples before the release are in all of them), each stage starting
      from the last: short horizons fix r and the phase before later cycles refine k_f,
      which avoids the local minima of oscillatory fits. Default (None): (0.25, 0.5, 1.0);
      for the 2-DOF body (0.125, 0.25, 0.5, 1.0), whose misfit over a whole trace has
      many minima in k_f (see `identification._models.default_horizons`).
    - `uplift_weight`: weight of the uplift residuals (when the trace has them).
    - `rtol`, `atol`: simulation tolerances; `progress`: show a progress bar (default: only
      if the fit takes more than about 3 s and stderr is a terminal).

    **Returns:** a `FitResult`. Warns `IdentifiabilityWarning` when the trace cannot pin a
    parameter down, and `LackOfFitWarning` (a subclass) when the residuals are not noise
    (`FitResult.lack_of_fit`: the model cannot represent the trace, the standard errors do
    not hold; the message names the next model up the ladder); never raises for a poor fit
    (see `converged`). Raises `TraceError` (a `ValueError`) when the trace's amplitude lies
    beyond the structure's `u_overturn` (a trace in mm read as m, say).

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
    """
    setup = dict(model=model, impact=impact, contact=contact, initial=initial, starts=starts,
                 max_iter=max_iter, horizons=horizons, tol=tol, uplift_weight=uplift_weight,
                 rtol=rtol, atol=atol, progress=progress)
    problem = _setup(trace, structure, params, **setup)
    transform = _Transform(problem.params, problem.values0, problem.k_min, problem.scale,
                           problem.t_ref, _models.start_offsets(problem.fit_model),
                           problem.k_cap)
    model = _Model.build(problem)
    opt = _optimizer(optimizer)
    run = _run_stages(problem, model, opt, transform.starting_points(problem.starts),
                      lm=optimizer is None)
    best = _best_start(problem, model, opt, run)
    unc = _uncertainty(problem, model, transform, best, run.keep)
    ident, messages = _identifiability(problem, best, unc)
    for m in messages:
        warnings.warn(m, IdentifiabilityWarning, stacklevel=_WARN_LEVEL)
    response = _respond(model, jnp.asarray(best.z))
    msg = _outlier_message(problem, np.asarray(response.u), run.keep, unc.sigma)
    if msg is not None:
        messages.append(msg)
        warnings.warn(msg, OutlierWarning, stacklevel=_WARN_LEVEL)
    lack = _lack_of_fit(problem, np.asarray(response.u), run.keep)
    if lack["fires"]:
        messages.append(lack["message"])
        warnings.warn(lack["message"], LackOfFitWarning, stacklevel=_WARN_LEVEL)
    return _result(problem, run, best, unc, ident, messages, response, lack)


def _optimizer(optimizer):
    """The optax optimiser of a fit: the one default instance (its compiled code is
    reused by every fit), or `optimizer` with extra-args support."""
    return _LM if optimizer is None else optax.with_extra_args_support(optimizer)


def _lack_of_fit(problem: _Problem, u_fit: np.ndarray, keep: np.ndarray) -> dict:
    """The lack-of-fit check of the displacement residuals (kept samples, time order)."""
    e = (u_fit - problem.u_meas)[keep]
    rms = float(np.sqrt(np.mean(e**2)))
    fm = problem.fit_model
    return _lack.lack_of_fit(e, rms, problem.scale, fm.describe(),
                             _models.models_above(fm, problem.params))


_CHUNK = 4
"""Optimiser steps per compiled call (one `jax.lax.scan`) between convergence checks."""


# ------------------------------------------------------------------ arguments


@dataclasses.dataclass(frozen=True, eq=False)
class _Problem:
    """The checked arguments of `fit_decay`, with the trace as float arrays."""

    structure: object
    params: tuple
    fit_model: FitModel  # the model simulated, and the parameters that act in it
    impact: str
    horizons: tuple  # fractions of the trace, floats
    starts: int
    max_iter: int
    tol: float
    uplift_weight: float
    rtol: float
    atol: float
    progress: object
    t: np.ndarray
    u_meas: np.ndarray
    up_meas: np.ndarray | None
    scale: float  # trace amplitude max |u| [m]: the unit of the residuals
    values0: dict  # starting (or fixed) values of all of PARAM_NAMES
    k_min: float  # stability limit of k_f (Eq. 15) [N/m]
    release: Release  # found in the trace (detect_release)
    k_cap: float | None = None  # the (smooth) upper bound of k_f, None: none
    notes: tuple = ()  # default parameters left out (they do not act in the model)

    @property
    def t_ref(self) -> float:
        """The starting value of t0 [s]: the origin of its unconstrained coordinate."""
        return self.values0["t0"]

    @property
    def fits_uplift(self) -> bool:
        """Whether the uplift channel is in the residuals."""
        return self.up_meas is not None and self.uplift_weight > 0

    def samples(self) -> np.ndarray:
        """The samples that may be fitted (all of them; boolean)."""
        return np.ones(self.t.size, bool)

    def within(self, frac: float) -> np.ndarray:
        """The samples up to the first `frac` of the motion after the release (boolean):
        the samples before the release (a hold) are in every horizon."""
        t, t_rel = self.t, min(max(self.t_ref, self.t[0]), self.t[-1])
        return t <= t_rel + frac * (t[-1] - t_rel)


def _check_structure(structure):
    structure = rockjax.mcmanus_column() if structure is None else structure
    if not isinstance(structure, rockjax.RockingStructure):
        raise ValueError(
            f"structure must be a rockjax.RockingStructure, got {type(structure).__name__}"
        )
    if any(np.ndim(getattr(structure, k)) != 0 for k in ("m_e", "m_b", "H_e", "H_b", "B",
                                                         "I_eg", "I_bg", "k_f", "g")):
        raise ValueError("structure must be a single structure (scalar fields), not a batch")
    return structure


def _check_params(params, fm: FitModel) -> tuple:
    """The parameters to fit, checked (the default ones of the model for None)."""
    if params is None:
        return _models._defaults(fm)
    if isinstance(params, str):
        raise ValueError(
            f"params must be a sequence of names from {PARAM_NAMES}, e.g. ('k_f', 'r'), "
            f"got the string {params!r}"
        )
    params = tuple(params)
    bad = [p for p in params if p not in PARAM_NAMES]
    if bad or not params or len(set(params)) != len(params):
        raise ValueError(f"params must be distinct names from {PARAM_NAMES}, got {params}")
    _models.refuse_inactive(fm, params)
    return params


def _check_options(starts, max_iter, impact, horizons, tol, uplift_weight) -> tuple:
    """Check the optimiser and simulation options; returns `horizons` as a tuple of floats."""
    if not (isinstance(starts, int) and starts >= 1):
        raise ValueError(f"starts must be a positive integer, got {starts!r}")
    if not (isinstance(max_iter, int) and max_iter >= 1):
        raise ValueError(f"max_iter must be a positive integer, got {max_iter!r}")
    if impact not in rockjax.IMPACT_RULES:
        raise ValueError(f"impact must be one of {rockjax.IMPACT_RULES}, got {impact!r}")
    try:
        hs = tuple(float(h) for h in horizons)
    except (TypeError, ValueError):
        hs = ()
    if not hs or not all(0.0 < h <= 1.0 for h in hs):
        raise ValueError(
            f"horizons must be a non-empty sequence of fractions in (0, 1], got {horizons!r}"
        )
    for name, val in (("tol", tol), ("uplift_weight", uplift_weight)):
        if not (isinstance(val, (int, float)) and math.isfinite(val) and val >= 0):
            raise ValueError(f"{name} must be a finite number >= 0, got {val!r}")
    return hs


def _as_trace(trace) -> DecayTrace:
    if isinstance(trace, DecayTrace):
        return trace
    if not (hasattr(trace, "t") and hasattr(trace, "u")):
        raise ValueError(
            "trace must be an identification.DecayTrace (t [s], u [m], optional uplift "
            f"[m]), got {type(trace).__name__}"
        )
    # validated like a DecayTrace: finite, strictly increasing, no gaps, >= 10 samples
    return DecayTrace(t=trace.t, u=trace.u, uplift=getattr(trace, "uplift", None),
                      source=str(getattr(trace, "source", "")))


def _trace_arrays(trace: DecayTrace, params: tuple, structure):
    """(t, u, uplift or None, amplitude max |u|) of the trace, checked to be fittable."""
    t = np.asarray(trace.t, float)
    u_meas = np.asarray(trace.u, float)
    up_meas = None if getattr(trace, "uplift", None) is None else np.asarray(trace.uplift, float)
    if t.size < max(10, len(params) + 2):
        raise ValueError(f"the trace has {t.size} samples: too few to fit {params}")
    scale = float(np.max(np.abs(u_meas)))
    if not scale > 0:
        raise ValueError("the trace's displacement is zero everywhere: nothing to fit")
    _check_amplitude(trace, scale, float(structure.u_overturn))
    return t, u_meas, up_meas, scale


def _check_amplitude(trace: DecayTrace, amplitude: float, u_overturn: float):
    """TraceError when the trace's displacement lies beyond u_overturn: a structure
    released there overturns, so the trace is most likely in other units (mm, cm).

    Judged on a 5-point running median of u, so that spikes (outliers, left out by the
    fit) do not count; the message gives the plain max |u|."""
    u = np.pad(np.asarray(trace.u, float), 2, mode="edge")
    smooth = np.median(np.lib.stride_tricks.sliding_window_view(u, 5), axis=1)
    if float(np.max(np.abs(smooth))) <= u_overturn:
        return
    unit, frm = trace.units.get("u", "m"), trace.units_from.get("u", "")
    msg = (f"max |u| = {amplitude:.4g} m is beyond u_overturn = {u_overturn:.4g} m of the "
           "structure, where it would overturn")
    if frm == "header":
        msg += (f": the header gives u in {unit} (column {trace.columns.get('u', 'u')!r}); "
                "check that unit and the structure")
        raise TraceError(msg, msg + " (--structure)")
    msg += f" (u read in {unit}, {frm or 'SI'}): is the trace in mm? "
    raise TraceError(
        msg + "give units in the header, such as t,u_mm, or read it with "
        "read_trace(path, units={'u': 'mm'})",
        msg + "give units in the header, such as t,u_mm, or pass --units u=mm",
    )


def _starting_values(structure, release: Release, initial, fm: FitModel, params: tuple):
    """(starting values of all of PARAM_NAMES, the stability limit k_min of k_f)."""
    values0 = {
        "k_f": float(structure.k_f),
        "r": float(structure.restitution),
        "u0": float(release.level),
        "t0": float(release.time),
    }
    if initial is not None and not isinstance(initial, dict):
        raise ValueError(
            f"initial must be a dict of starting values such as {{'k_f': 5e5}}, got {initial!r}"
        )
    if initial:
        unknown = set(initial) - set(PARAM_NAMES)
        if unknown:
            raise ValueError(f"initial has unknown parameter(s) {sorted(unknown)}")
        for k, v in initial.items():
            try:
                v = float(v)
            except (TypeError, ValueError):
                raise ValueError(f"initial {k} must be a number, got {v!r}") from None
            if not math.isfinite(v):
                raise ValueError(f"initial {k} must be finite, got {v}")
            values0[k] = v
    k_min = float(_k_min(structure))
    if not values0["k_f"] > k_min:
        raise ValueError(
            f"initial k_f must exceed the stability limit {k_min:.6g} N/m "
            f"(2 k_f B^2 > W H_c), got {values0['k_f']:.6g} N/m"
        )
    if not 0.0 < values0["r"] < 1.0:
        raise ValueError(f"initial r must lie strictly inside (0, 1), got {values0['r']}")
    values0["c_f"] = _start_c_f(structure, values0, initial, fm, params)
    k_cap = _models.k_f_cap(fm, k_min)
    if k_cap is not None and not values0["k_f"] < 0.1 * k_cap:
        raise ValueError(
            f"initial k_f must lie below {0.1 * k_cap:.6g} N/m ({0.1 * _models.K_F_CAP:g} x "
            f"the stability limit) with the {fm.describe()} model, got {values0['k_f']:.6g} "
            "N/m: its fits bound k_f (the foundation is rigid for any purpose beyond)"
        )
    return values0, k_min


def _start_c_f(structure, values0: dict, initial, fm: FitModel, params: tuple) -> float:
    """The start (or held value) of c_f [N s/m]: `initial`, else the model instance's
    damping, else (fitted) 5 % of critical of the vertical mode at the starting k_f."""
    given = (initial or {}).get("c_f")
    if given is not None and not fm.has_dashpots:
        raise ValueError(
            f"initial c_f: c_f (the dashpot coefficient of the 2-DOF body) is not a "
            f"parameter of the {fm.describe()} model; leave it out of initial"
        )
    if given is not None:
        c_f = values0["c_f"]  # checked to be a finite number above
    else:
        c_f = _models.model_damping(fm)
        if "c_f" in params and not c_f > 0:
            c_f = _models.c_f_start(structure, values0["k_f"])
    if "c_f" in params and not c_f > 0:
        raise ValueError(
            f"initial c_f must be positive to be fitted (its logarithm is), got {c_f:g} N s/m"
        )
    if not c_f >= 0:
        raise ValueError(f"initial c_f must be >= 0 (a dashpot coefficient), got {c_f:g} N s/m")
    return c_f


def _setup(trace, structure, params, *, model, impact, initial, starts, max_iter, horizons,
           tol, uplift_weight, rtol, atol, progress, contact=None) -> _Problem:
    """Check and normalise the arguments of `fit_decay` (ValueError on the first bad one)."""
    structure = _check_structure(structure)
    # ValueError naming the model (or the impact rule, or the contact law) if unknown
    fm = _models.resolve_model(model, impact, contact)
    notes = tuple(_models.default_notes(fm)) if params is None else ()
    params = _check_params(params, fm)
    if horizons is None:
        horizons = _models.default_horizons(fm)
    if starts is None:
        starts = _models.default_starts(fm)
    horizons = _check_options(starts, max_iter, impact, horizons, tol, uplift_weight)
    trace = _as_trace(trace)
    t, u_meas, up_meas, scale = _trace_arrays(trace, params, structure)
    release = detect_release(trace)
    values0, k_min = _starting_values(structure, release, initial, fm, params)
    return _Problem(
        structure=structure, params=params, fit_model=fm, impact=impact, horizons=horizons,
        starts=starts, max_iter=max_iter, tol=tol, uplift_weight=uplift_weight, rtol=rtol,
        atol=atol, progress=progress, t=t, u_meas=u_meas, up_meas=up_meas, scale=scale,
        values0=values0, k_min=k_min, release=release, notes=notes,
        k_cap=_models.k_f_cap(fm, k_min),
    )


# --------------------------------------------------------- parameters <-> z


@dataclasses.dataclass(frozen=True, eq=False)
class _Transform:
    """Natural parameters <-> the optimiser's unconstrained coordinates z (module docstring),
    on the Python side (floats); `_Model.decode` is the traced inverse.

    z holds the fitted parameters only (order `params`); the others keep `values0`.
    """

    params: tuple
    values0: dict
    k_min: float
    scale: float
    t_ref: float
    offsets: tuple = _models.SDOF_START_OFFSETS  # (log k_f, dissipation) shift of each start
    k_cap: float | None = None  # smooth upper bound of k_f (see _k_f_of_z)

    def encode(self, v: dict) -> dict:
        """Natural values of all the parameters -> their z coordinates."""
        y = math.log(v["k_f"] - self.k_min)
        if self.k_cap is not None:  # the inverse of _k_f_of_z
            span = math.log(self.k_cap - self.k_min)
            y = span - math.log(math.expm1(span - y))
        return {
            "k_f": y,
            "r": math.log(v["r"] / (1.0 - v["r"])),
            "u0": v["u0"] / self.scale,
            "t0": (v["t0"] - self.t_ref) / _T_SCALE,
            "c_f": math.log(v["c_f"]) if v["c_f"] > 0 else -math.inf,  # fitted: > 0
        }

    def decode(self, z) -> dict:
        """The optimiser's coordinates of the fitted parameters -> natural values of all
        the parameters (floats; the inverse of `encode`, as `_Model.decode`)."""
        out = {k: float(v) for k, v in self.values0.items()}
        for p, zi in zip(self.params, (float(x) for x in z)):
            if p == "k_f":
                y = zi
                if self.k_cap is not None:
                    span = math.log(self.k_cap - self.k_min)
                    x = span - zi
                    y = span - (max(x, 0.0) + math.log1p(math.exp(-abs(x))))
                out["k_f"] = self.k_min + math.exp(y)
            elif p == "r":
                out["r"] = 1.0 / (1.0 + math.exp(-zi))
            elif p == "u0":
                out["u0"] = zi * self.scale
            elif p == "c_f":
                out["c_f"] = math.exp(zi)
            else:
                out["t0"] = self.t_ref + zi * _T_SCALE
        return out

    def derivatives(self, z) -> list:
        """d(natural value)/dz of each fitted parameter at the point `z` (floats)."""
        out = []
        for p, zi in zip(self.params, z):
            if p == "k_f" and self.k_cap is not None:
                span = math.log(self.k_cap - self.k_min)
                x = span - zi
                soft = max(x, 0.0) + math.log1p(math.exp(-abs(x)))
                out.append(math.exp(span - soft) / (1.0 + math.exp(-x)))
            elif p in ("k_f", "c_f"):
                out.append(math.exp(zi))
            elif p == "r":
                s_ = 1.0 / (1.0 + math.exp(-zi))
                out.append(s_ * (1 - s_))
            elif p == "u0":
                out.append(self.scale)
            else:
                out.append(_T_SCALE)
        return out

    def starting_points(self, n: int) -> np.ndarray:
        """`n` starting points (n, P): `values0`, then k_f and the dissipation (logit r,
        log c_f) shifted (`offsets`)."""
        z0 = self.encode(self.values0)
        base = np.array([z0[p] for p in self.params])
        starts_z = []
        for i in range(n):
            dk, dr = self.offsets[i % len(self.offsets)]
            dk *= 1 + i // len(self.offsets)
            zi = base.copy()
            for j, p in enumerate(self.params):
                zi[j] += dk if p == "k_f" else dr if p in ("r", "c_f") else 0.0
            starts_z.append(zi)
        return np.stack(starts_z)


# -------------------------------------------------------- residuals, Jacobian


class _Model(eqx.Module):
    """The model of the trace at a point z, and its residuals: the compiled part of the fit.

    The trace and the values are arrays, so that `_run_chunk` and `_respond` (compiled with
    `eqx.filter_jit`) are reused by any trace of the same length with the same `params` and
    settings (strings and Python numbers are static: part of the compilation key).
    """

    structure: rockjax.RockingStructure
    t: jax.Array  # sample times [s]
    u: jax.Array  # measured displacement [m]
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
    params: tuple = eqx.field(static=True)
    dashpots: bool = eqx.field(static=True)  # the model has a dashpot coefficient (c_f)
    impact: str = eqx.field(static=True)
    rtol: float = eqx.field(static=True)
    atol: float = eqx.field(static=True)

    @classmethod
    def build(cls, pb: _Problem) -> _Model:
        arr = jnp.asarray
        n = pb.t.size
        return cls(
            structure=pb.structure, t=arr(pb.t), u=arr(pb.u_meas),
            up=arr(pb.up_meas) if pb.fits_uplift else None,
            values0={k: arr(float(v)) for k, v in pb.values0.items()},
            k_min=arr(pb.k_min), scale=arr(pb.scale), t_ref=arr(pb.t_ref),
            k_span=None if pb.k_cap is None else arr(math.log(pb.k_cap - pb.k_min)),
            eps=arr(1e-9 * float(np.median(np.diff(pb.t))) / n),
            eps_end=arr(1e-9 * float(np.median(np.diff(pb.t)))),
            uplift_weight=arr(float(pb.uplift_weight)), model=_model_instance(pb),
            params=pb.params, dashpots=pb.fit_model.has_dashpots, impact=pb.impact,
            rtol=float(pb.rtol), atol=float(pb.atol),
        )

    def decode(self, z) -> dict:
        """Unconstrained z (fitted params only) -> dict of all the natural values."""
        out = dict(self.values0)
        for i, name in enumerate(self.params):
            zi = z[i]
            if name == "k_f":
                out["k_f"] = self.k_min + jnp.exp(_k_f_of_z(zi, self.k_span))
            elif name == "r":
                out["r"] = jax.nn.sigmoid(zi)
            elif name == "u0":
                out["u0"] = zi * self.scale
            elif name == "c_f":
                out["c_f"] = jnp.exp(zi)
            else:
                out["t0"] = self.t_ref + zi * _T_SCALE
        return out

    def respond(self, z, t_end=None):
        """The model on the trace times: held at u0 before the release at t0, then
        `rockjax.simulate` of the release at rest (model time t - t0).

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
        return rockjax.simulate(
            s, rockjax.FreeVibration(v["u0"]), ts[-1], ts=ts, r=v["r"], model=model,
            impact=self.impact, rtol=self.rtol, atol=self.atol, adjoint="forward",
        )

    def residuals(self, z, mask):
        """Masked residuals (displacement, then weighted uplift) in units of `scale`."""
        # the simulation ends at the last sample in the fit (a horizon, padding)
        res = self.respond(z, jnp.max(jnp.where(mask > 0, self.t, self.t[0])))
        parts = [mask * (res.u - self.u) / self.scale]
        if self.up is not None:
            parts.append(mask * self.uplift_weight * (res.uplift - self.up) / self.scale)
        r = jnp.concatenate(parts)
        # a failed or overturned run is a bad point, not a crash: large finite residuals
        bad = (res.status != rockjax.STATUS["completed"]) | ~jnp.all(jnp.isfinite(r))
        return jnp.where(bad, 1e3, r)

    def res_jac(self, z, mask):
        """The residuals and their Jacobian d r / d z (forward mode; one trace of the
        model: the residuals are the primal of the Jacobian's pushforward)."""
        J, r = jax.jacfwd(lambda x: (self.residuals(x, mask),) * 2, has_aux=True)(z)
        return r, J


def _k_f_of_z(z, span):
    """log(k_f - k_min) from its coordinate z: z itself, or with a smooth upper bound
    `span` = log(k_cap - k_min): span - softplus(span - z), = z - e^(z - span) well below."""
    return z if span is None else span - jax.nn.softplus(span - z)


def _model_instance(pb: _Problem):
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


def _compiled(out_structure):
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


@_compiled(lambda model, z: response_structure())
def _respond(model: _Model, z):
    """`model.respond(z)`, compiled."""
    return model.respond(z)


def _channels(pb: _Problem, response) -> list:
    """Unmasked residual arrays of a response (numpy), one per fitted channel."""
    out = [(np.asarray(response.u) - pb.u_meas) / pb.scale]
    if pb.fits_uplift:
        out.append(pb.uplift_weight * (np.asarray(response.uplift) - pb.up_meas) / pb.scale)
    return out


@_compiled(lambda model, opt, z, opt_state, mask, free:
           jax.tree.structure((z, opt_state, 0, 0, 0)))
def _run_chunk(model: _Model, opt, z, opt_state, mask, free):
    """`_CHUNK` optimiser steps of every start (vmap over the first axis), compiled.

    Returns the new points and states, the loss at each step (starts, _CHUNK), and the
    residuals and Jacobian at each step (starts, _CHUNK, ...).
    """

    def one(z, opt_state):
        def step(carry, _):
            z, st = carry
            r, J = model.res_jac(z, mask)
            J = J * free  # frozen parameters get a zero column: a zero step
            value = 0.5 * jnp.sum(r**2)
            g = J.T @ r
            upd, st = opt.update(g, st, z, value=value, jtj=J.T @ J)
            return (z + upd, st), (value, r, J)

        (z_new, st), (vals, rs, Js) = jax.lax.scan(step, (z, opt_state), None,
                                                    length=_CHUNK)
        return z_new, st, vals, rs, Js

    return jax.vmap(one)(z, opt_state)


@eqx.filter_jit
def _init_states(opt, z):
    """The optimiser's state of every start (vmap over the first axis of z), compiled:
    one small program instead of a compile per operation."""
    return jax.vmap(opt.init)(z)


# ----------------------------------------- multi-start run with growing horizon


class _Progress:
    """A tqdm bar: shown if `progress` is True, or (None) once the fit has taken 3 s and
    stderr is a terminal (no carriage returns in logs)."""

    def __init__(self, progress, total: int):
        self.progress = progress
        self.total = total
        self.bar = None
        self.t_start = time.perf_counter()

    def update(self, n_iter: int, frac: float, best_now: np.ndarray):
        if self.progress is not False and self.bar is None and (
            self.progress
            or (sys.stderr.isatty() and time.perf_counter() - self.t_start > 3.0)
        ):
            from tqdm.auto import tqdm

            self.bar = tqdm(total=self.total, desc="fit_decay", unit="it", leave=False)
            self.bar.update(n_iter)
        elif self.bar is not None:
            self.bar.update(_CHUNK)
        if self.bar is not None:
            self.bar.set_postfix(horizon=f"{frac:.2f}", loss=f"{np.nanmin(best_now):.3e}")

    def close(self):
        if self.bar is not None:
            self.bar.close()


@dataclasses.dataclass(eq=False)
class _Run:
    """State of the multi-start run, carried from one horizon (stage) to the next."""

    z: object  # (starts, P) current points
    opt_state: object
    lm: bool  # the default optimiser: its state keeps the best point of each start
    keep: np.ndarray  # samples in the fit (False: outliers)
    converged: np.ndarray  # (starts,) converged on the last stage
    history: list = dataclasses.field(default_factory=list)  # losses on the last horizon
    vals: np.ndarray | None = None  # losses of the last chunk (starts, _CHUNK)
    n_iter: int = 0
    n_refits: int = 0
    tracked: dict | None = None  # the LM's best point of the last stage: loss, r, J, mask

    def best_params(self):
        return self.opt_state.best_params if self.lm else self.z


def _run_horizon(problem: _Problem, model: _Model, opt, run: _Run, stage: int, frac: float,
                 progress: _Progress):
    """Iterate every start on the first `frac` of the trace until all of them stall (no
    relative improvement of the best loss over two chunks) or `max_iter` iterations."""
    params, horizons = problem.params, problem.horizons
    mask = jnp.asarray(problem.within(frac) & run.keep, dtype=float)
    # On the first (short) horizon k_f and r are nearly collinear (the early cycles
    # depend on r, the phase and u0); k_f is held there and freed afterwards. Without r
    # (continuous contact) the first bounces on the springs pin k_f: it is free throughout.
    freeze_kf = (stage == 0 and len(horizons) > 1 and "k_f" in params and len(params) > 1
                 and "r" in problem.fit_model.acting)
    free = jnp.asarray([0.0 if (p == "k_f" and freeze_kf) else 1.0 for p in params])
    best_prev = np.full(problem.starts, np.inf)
    stall = np.zeros(problem.starts, int)
    stage_iter = 0
    while stage_iter < problem.max_iter:
        run.z, run.opt_state, vals, rs, Js = _run_chunk(model, opt, run.z, run.opt_state,
                                                        mask, free)
        vals = np.asarray(vals)  # (starts, chunk)
        if run.lm and frac == horizons[-1]:
            _track_best(run, vals, rs, Js, np.asarray(mask) > 0, first=stage_iter == 0)
        run.vals = vals
        run.n_iter += _CHUNK
        stage_iter += _CHUNK
        if frac == horizons[-1]:
            run.history.append(vals)
        # converged: no relative improvement of the best loss over two chunks
        finite = np.where(np.isfinite(vals), vals, np.inf)
        best_now = np.minimum(best_prev, np.min(finite, 1))
        improved = best_now < best_prev * (1 - problem.tol) - 1e-300
        stall = np.where(improved, 0, stall + 1)
        best_prev = best_now
        run.converged = stall >= 2
        progress.update(run.n_iter, frac, best_now)
        if np.all(run.converged):
            break


def _track_best(run: _Run, vals, rs, Js, mask: np.ndarray, first: bool):
    """Follow the Levenberg-Marquardt state's accepted point through a chunk (the same
    test: a loss at or below the last accepted one, or the stage's first point), keeping
    its residuals and Jacobian: `_best_start` needs them, and would otherwise evaluate
    them again (a chunk)."""
    t = run.tracked
    if first or t is None:
        t = run.tracked = {"value": np.full(vals.shape[0], np.inf), "r": None, "J": None,
                           "started": np.zeros(vals.shape[0], bool), "mask": mask}
    rs, Js = np.asarray(rs), np.asarray(Js)
    if t["r"] is None:
        t["r"], t["J"] = rs[:, 0].copy(), Js[:, 0].copy()
    for c in range(vals.shape[1]):
        acc = (vals[:, c] <= t["value"]) | ~t["started"]
        t["value"] = np.where(acc, vals[:, c], t["value"])
        t["r"][acc], t["J"][acc] = rs[acc, c], Js[acc, c]
        t["started"][:] = True


def _check_outliers(problem: _Problem, model: _Model, run: _Run) -> bool:
    """Look for outliers in the fit just finished; update `run.keep`. True: fit again.

    Outliers (spikes) are residuals of the converged fit far outside the spread of the
    others. They pull a least-squares fit off (a few 0.3 m spikes bias k_f by 5 %): leave
    them out and fit the whole trace again (see _find_outliers). An unconverged fit is not
    checked: its residuals are a misfit, not noise.
    """
    z_now = np.asarray(run.best_params())
    last = np.asarray(run.opt_state.best_value) if run.lm else run.vals[:, -1]
    i_now = int(np.argmin(np.where(np.isfinite(last), last, np.inf)))
    res_now = _respond(model, jnp.asarray(z_now[i_now]))
    if not (run.converged[i_now] and int(res_now.status) == rockjax.STATUS["completed"]):
        return False
    found = _find_outliers(_channels(problem, res_now), ~run.keep,
                           problem.within(problem.horizons[-1]))
    # more than a few is a misfit (a wrong minimum, a wrong model), not spikes
    if (np.count_nonzero(found) > _MAX_OUTLIER_FRACTION * problem.t.size
            or np.array_equal(found, ~run.keep)):
        return False
    run.keep = ~found  # after the last refit: the final statistics only
    if run.n_refits >= _MAX_REFITS:
        return False
    run.n_refits += 1
    return True


def _run_stages(problem: _Problem, model: _Model, opt, z_start, lm: bool,
                outliers: bool = True) -> _Run:
    """The multi-start fit: each horizon in turn, then (`outliers`) refits of the whole
    trace without its outliers (if any)."""
    z = jnp.asarray(z_start)
    run = _Run(z=z, opt_state=_init_states(opt, z), lm=lm, keep=problem.samples(),
               converged=np.zeros(problem.starts, bool))
    progress = _Progress(problem.progress, problem.max_iter * len(problem.horizons))
    # Growing horizon: fit the first quarter of the trace, then half, then all of it. Early
    # cycles fix r and the phase; later ones refine k_f. Masks keep every shape, so nothing
    # recompiles between stages.
    plan = list(problem.horizons)  # the outlier check appends refits of the whole trace
    for stage, frac in enumerate(plan):
        if stage > 0:
            run.z = run.best_params()
            run.opt_state = _init_states(opt, run.z)
        _run_horizon(problem, model, opt, run, stage, frac, progress)
        if stage == len(plan) - 1 and outliers and _check_outliers(problem, model, run):
            plan.append(problem.horizons[-1])
    progress.close()
    return run


@dataclasses.dataclass(frozen=True, eq=False)
class _Best:
    """The best start, evaluated on the whole trace (outliers left out)."""

    index: int  # of the start
    z: np.ndarray
    r: np.ndarray  # residuals
    J: np.ndarray  # their Jacobian d r / d z
    loss: float
    start_losses: np.ndarray  # final loss of every start
    history: np.ndarray  # its loss at each iteration on the last horizon


def _best_start(problem: _Problem, model: _Model, opt, run: _Run) -> _Best:
    # best point of every start, and r, J there: those the LM's last stage evaluated there
    # (on the same samples), else one more chunk evaluates them
    z_best = run.best_params()
    t = run.tracked
    if (run.lm and t is not None and np.array_equal(t["mask"], run.keep)
            and np.array_equal(t["value"], np.asarray(run.opt_state.best_value))):
        final_losses, r_b, J_b = t["value"], t["r"], t["J"]
    else:
        full = jnp.asarray(run.keep, dtype=float)  # outliers (if any) stay out
        _, _, vals_b, r_b, J_b = _run_chunk(model, opt, z_best, _init_states(opt, z_best),
                                            full, jnp.ones(len(problem.params)))
        final_losses = np.asarray(vals_b)[:, 0]
        r_b, J_b = np.asarray(r_b)[:, 0], np.asarray(J_b)[:, 0]
    i_best = int(np.nanargmin(np.where(np.isfinite(final_losses), final_losses, np.inf)))
    return _Best(
        index=i_best,
        z=np.asarray(z_best)[i_best],
        r=np.asarray(r_b)[i_best],
        J=np.asarray(J_b)[i_best],
        loss=float(final_losses[i_best]),
        start_losses=final_losses,
        history=np.concatenate(run.history, axis=1)[i_best],
    )


# ------------------------------------------------------------------ uncertainty


@dataclasses.dataclass(frozen=True, eq=False)
class _Uncertainty:
    values: dict  # natural values of all of PARAM_NAMES at the optimum
    derivatives: list  # d(natural value)/dz of each fitted parameter
    se: np.ndarray  # standard errors (natural units)
    corr: np.ndarray  # correlation matrix
    sigma: float  # estimated noise std of the displacement [m]


def _uncertainty(problem: _Problem, model: _Model, transform: _Transform, best: _Best,
                 keep: np.ndarray) -> _Uncertainty:
    """Standard errors and correlations at the optimum (Gauss-Newton / Fisher information).

    In natural coordinates. The fit minimises unweighted least squares over the channels
    (displacement, uplift), whose noise levels differ, so the covariance is the sandwich
    A^-1 B A^-1 with A = J^T J, B = J^T diag(sigma_c^2) J and sigma_c^2 = RSS_c / (N_c - P
    share) for each channel.
    """
    J, r = best.J, best.r
    n_res, n_par = J.shape
    n_u = problem.t.size
    channels = [slice(0, n_u)] + ([slice(n_u, n_res)] if n_res > n_u else [])
    var = np.empty(n_res)
    sig2 = []
    for ch in channels:
        n_c = int(np.count_nonzero(keep))  # samples in the fit, per channel
        dof_c = max(n_c - n_par / len(channels), 1.0)
        s2 = max(float(np.sum(r[ch] ** 2)) / dof_c, 1e-300)
        sig2.append(s2)
        var[ch] = s2
    sigma2 = sig2[0]
    vals_nat = transform.decode(best.z)
    dtheta_dz = transform.derivatives(best.z)
    D = np.diag(dtheta_dz)
    try:
        a_inv = np.linalg.inv(J.T @ J)
        cov = D @ (a_inv @ (J.T @ (var[:, None] * J)) @ a_inv) @ D
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
        corr = cov / np.outer(np.where(se > 0, se, 1.0), np.where(se > 0, se, 1.0))
    except np.linalg.LinAlgError:
        se = np.full(n_par, np.inf)
        corr = np.full((n_par, n_par), np.nan)
    return _Uncertainty(values=vals_nat, derivatives=dtheta_dz, se=se, corr=corr,
                        sigma=math.sqrt(sigma2) * problem.scale)


def _identifiability(problem: _Problem, best: _Best, unc: _Uncertainty):
    """(the `FitResult.identifiability` dict, the messages of the IdentifiabilityWarning's).

    The sensitivity of a parameter is the RMS change of the displacement trace [m] for a
    1 % change of it (t0: for 1 ms), to compare with the noise level.
    """
    params, vals_nat, se, sigma = problem.params, unc.values, unc.se, unc.sigma
    Ju = best.J[:problem.t.size] * problem.scale  # d u / d z [m]
    sens = {}
    for j, p in enumerate(params):
        per = 0.01 * abs(vals_nat[p]) if p != "t0" else 1e-3
        sens[p] = float(np.sqrt(np.mean((Ju[:, j] / unc.derivatives[j] * per) ** 2)))
    ident = {
        "sensitivity_per_percent": sens,
        "noise_sigma": sigma,
        "relative_stderr": {p: float(se[j] / abs(vals_nat[p])) if vals_nat[p] else None
                            for j, p in enumerate(params)},
    }
    for other in ("r", "c_f"):
        if "k_f" in params and other in params:
            ident[f"corr_k_f_{other}"] = float(unc.corr[params.index("k_f"),
                                                        params.index(other)])
    messages = []
    for j, p in enumerate(params):
        rel = se[j] / abs(vals_nat[p]) if vals_nat[p] else np.inf
        if sens[p] == 0.0:  # an exactly zero Jacobian column
            messages.append(
                f"the trace does not pin {p} down: it does not depend on {p} at all "
                f"(nothing in this trace, or in the {problem.fit_model.describe()} model, "
                f"brings {p} into play: an impact for r, say); leave it out of params"
            )
        elif p != "t0" and not rel < 0.1:
            messages.append(
                f"the trace does not pin {p} down: standard error {100 * rel:.3g} % of its "
                f"value (a 1 % change moves the trace by {sens[p]:.3g} m RMS, noise "
                f"{sigma:.3g} m)"
            )
    for other in ("r", "c_f"):
        rho = ident.get(f"corr_k_f_{other}", 0.0)
        if abs(rho) > 0.95:
            messages.append(
                f"k_f and {other} are strongly correlated (rho = {rho:.3f}): the trace "
                "constrains a combination of them, not each"
            )
    return ident, messages


def _outlier_message(problem: _Problem, u_fit: np.ndarray, keep: np.ndarray,
                     sigma: float) -> str | None:
    """The OutlierWarning's message, or None when no sample was left out."""
    outliers = np.flatnonzero(~keep)
    if not outliers.size:
        return None
    t, u_meas = problem.t, problem.u_meas
    worst = outliers[np.argmax(np.abs(u_fit - u_meas)[outliers])]
    return (
        f"{outliers.size} sample(s) of the trace lie more than {OUTLIER_SIGMAS:g} robust "
        f"standard deviations from the fit (largest displacement residual "
        f"{abs(u_fit[worst] - u_meas[worst]):.3g} m at t = {t[worst]:.6g} s; noise "
        f"sigma {sigma:.3g} m): they were left out and the fit repeated without them "
        "(indices in FitResult.outliers)"
    )


# ---------------------------------------------------------------------- result


def _result(problem: _Problem, run: _Run, best: _Best, unc: _Uncertainty, ident: dict,
            messages: list, response, lack: dict) -> FitResult:
    params, vals_nat, loss, keep = problem.params, unc.values, best.loss, run.keep
    u_fit = np.asarray(response.u)
    converged = bool(run.converged[best.index]) and np.isfinite(loss) and loss < 1e5
    return FitResult(
        names=params,
        values={p: vals_nat[p] for p in params},
        stderr={p: float(unc.se[j]) for j, p in enumerate(params)},
        fixed={p: vals_nat[p] for p in PARAM_NAMES
               if p not in params and p in problem.fit_model.acting},
        correlation=np.asarray(unc.corr),
        loss=loss,
        rms=float(np.sqrt(np.mean((u_fit - problem.u_meas)[keep] ** 2))),
        sigma=unc.sigma,
        loss_history=best.history,
        start_losses=best.start_losses,
        response=response,
        converged=converged,
        n_iterations=run.n_iter,
        identifiability=ident,
        warnings=tuple(messages),
        scale=problem.scale,
        outliers=np.flatnonzero(~keep),
        release={**problem.release.as_dict(), "t0_start_s": problem.values0["t0"],
                 "u0_start_m": problem.values0["u0"]},
        lack_of_fit=lack,
        model=problem.fit_model.describe(),
        notes=problem.notes,
        start={p: float(problem.values0[p]) for p in params},
    )
