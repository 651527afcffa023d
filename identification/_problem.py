r"""The fit's problem: the checked arguments of `fit_decay`, with the trace as arrays.

`Settings` holds the keyword arguments of `fit_decay` (the same names, the same defaults);
`setup(trace, structure, params, settings)` checks them with the trace and the structure
(ValueError, or `TraceError`, naming the first bad one) and returns the `Problem`: the
model resolved (`identification._models`), the parameters to fit, the release found in
the trace (`detect_release`), the starting (or held) values of every parameter and the
bounds of k_f. Nothing here is traced or compiled.

**Channels.** A trace may hold any of u [m], the rotation theta [rad] and the uplift [m];
each is fitted through the model's own observation of it (`rockjax.Response.u`, `.theta`,
`.uplift`). The first present (u, else theta, else the uplift) is the *primary* channel:
the release is found in it, its residuals are the ones the lack-of-fit check and `rms`
describe. u0 stays the release displacement [m]: without u, its start is the release level
of the primary channel mapped through the kinematics of the structure at its starting k_f
(`rockjax.u_from_theta`; for the uplift, $\sin\theta = (\mathrm{uplift}/2 +
\delta_0)/B$, the inverse of `rockjax.uplift_from_theta`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

import rockjax

from . import _anomalies, _models, _sensor
from ._models import FitModel
from ._release import detect_release, Release
from ._trace import DecayTrace, TraceError

PARAM_NAMES = ("k_f", "r", "u0", "t0", "c_f")
"""The parameters `fit_decay` can fit (`DEFAULT_PARAMS`, less those that do not act in the
model, are fitted by default; see `identification.default_params`)."""
UNITS = {"k_f": "N/m", "r": "-", "u0": "m", "t0": "s", "c_f": "N s/m", **_sensor.UNITS}
"""The (SI) unit of each parameter (and of the nuisance parameters `NUISANCE`)."""
NUISANCE = _sensor.NUISANCE
"""The nuisance parameters of the sensor: `offset` (the zero of the displacement channel
[m]), `offset_uplift` (of the uplift channel [m]) and `drift` [m/s]
(`identification._sensor`)."""
ALL_NAMES = PARAM_NAMES + NUISANCE


@dataclasses.dataclass(frozen=True)
class Settings:
    """The keyword arguments of `fit_decay` (its docstring says what each means)."""

    model: object = "simplified"
    impact: str = "paper"
    contact: str | None = None
    initial: dict | None = None
    starts: int | None = None
    max_iter: int = 40
    horizons: object = None
    tol: float = 1e-9
    uplift_weight: float = 1.0
    theta_weight: float = 1.0
    rtol: float = 1e-9
    atol: float = 1e-11
    progress: object = None
    offset: object = None
    drift: bool = False


def k_min_of(structure) -> float:
    """The stability limit of k_f (Eq. 15), W H_c / (2 B^2) [N/m]."""
    return structure.W * structure.H_c / (2.0 * structure.B**2)


@dataclasses.dataclass(frozen=True, eq=False)
class Problem:
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
    u_meas: np.ndarray | None  # None: no displacement channel
    up_meas: np.ndarray | None
    scale: float  # trace amplitude max |u| [m] (or its equivalent): the unit of the residuals
    values0: dict  # starting (or fixed) values of all of PARAM_NAMES
    k_min: float  # stability limit of k_f (Eq. 15) [N/m]
    release: Release  # found in the trace (detect_release)
    k_cap: float | None = None  # the (smooth) upper bound of k_f, None: none
    notes: tuple = ()  # default parameters left out (they do not act in the model)
    th_meas: np.ndarray | None = None  # measured rotation [rad], None: no such channel
    theta_weight: float = 1.0
    theta_scale: float = 1.0  # max |theta| [rad]: the unit of the rotation's residuals
    primary: str = "u"  # the channel the release is found in, and that rms describes
    # the base (table) motion of a shake-table run, None for a decay: the ground
    # acceleration [m/s^2] sampled every `accel_dt` [s] from model time 0, which lies at
    # t0 on the trace's clock (`identification._shake`)
    accel: np.ndarray | None = None
    accel_dt: float | None = None

    @property
    def fits_theta(self) -> bool:
        """Whether the rotation channel is in the residuals."""
        return self.th_meas is not None and self.theta_weight > 0

    @property
    def channels(self) -> tuple:
        """The channels in the residuals, in their order (u, theta, uplift)."""
        return tuple(c for c, on in (("u", self.u_meas is not None),
                                     ("theta", self.fits_theta),
                                     ("uplift", self.fits_uplift)) if on)

    def measured(self, ch: str) -> np.ndarray:
        """The measured channel `ch` (numpy)."""
        return {"u": self.u_meas, "theta": self.th_meas, "uplift": self.up_meas}[ch]

    def unit_of(self, ch: str) -> tuple[float, float]:
        """(the scale, the weight) of channel `ch`'s residuals: (measured - model) x
        weight / scale."""
        return {"u": (self.scale, 1.0), "theta": (self.theta_scale, self.theta_weight),
                "uplift": (self.scale, self.uplift_weight)}[ch]

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



def check_structure(structure):
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
        return _models.fitted_by_default(fm)
    if isinstance(params, str):
        raise ValueError(
            f"params must be a sequence of names from {PARAM_NAMES}, e.g. ('k_f', 'r'), "
            f"got the string {params!r}"
        )
    params = tuple(params)
    bad = [p for p in params if p not in ALL_NAMES]
    if bad or not params or len(set(params)) != len(params):
        raise ValueError(f"params must be distinct names from {ALL_NAMES}, got {params}")
    _models.refuse_inactive(fm, tuple(p for p in params if p not in NUISANCE))
    return params


def _check_options(starts, max_iter, impact, horizons, tol, uplift_weight,
                   theta_weight=1.0) -> tuple:
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
    for name, val in (("tol", tol), ("uplift_weight", uplift_weight),
                      ("theta_weight", theta_weight)):
        if not (isinstance(val, (int, float)) and math.isfinite(val) and val >= 0):
            raise ValueError(f"{name} must be a finite number >= 0, got {val!r}")
    return hs


def as_trace(trace) -> DecayTrace:
    if isinstance(trace, DecayTrace):
        return trace
    if not (hasattr(trace, "t") and any(hasattr(trace, c) for c in ("u", "theta", "uplift"))):
        raise ValueError(
            "trace must be an identification.DecayTrace (t [s], u [m], optional uplift "
            f"[m], optional theta [rad]), got {type(trace).__name__}"
        )
    # validated like a DecayTrace: finite, strictly increasing, no gaps, >= 10 samples
    return DecayTrace(t=trace.t, u=getattr(trace, "u", None),
                      uplift=getattr(trace, "uplift", None),
                      theta=getattr(trace, "theta", None),
                      source=str(getattr(trace, "source", "")))


def _trace_arrays(trace: DecayTrace, params: tuple, structure):
    """(t, u or None, uplift or None, amplitude max |u| [m]) of the trace, checked to be
    fittable; without u, the amplitude is the displacement of the structure at the peak
    of the primary channel (`u_equivalent`)."""
    t = np.asarray(trace.t, float)
    u_meas = None if trace.u is None else np.asarray(trace.u, float)
    up_meas = None if getattr(trace, "uplift", None) is None else np.asarray(trace.uplift, float)
    if t.size < max(10, len(params) + 2):
        raise ValueError(f"the trace has {t.size} samples: too few to fit {params}")
    ch = trace.channels[0]
    x = np.asarray(getattr(trace, ch), float)
    peak = float(np.max(np.abs(x)))
    if not peak > 0:
        what = {"u": "displacement", "theta": "rotation", "uplift": "uplift"}[ch]
        raise ValueError(f"the trace's {what} is zero everywhere: nothing to fit")
    if ch == "u":
        _check_amplitude(trace, peak, float(structure.u_overturn))
        return t, u_meas, up_meas, peak
    _check_equivalent(trace, ch, structure)
    return t, u_meas, up_meas, u_equivalent(structure, ch, peak)


def u_equivalent(structure, ch: str, x: float) -> float:
    """The top displacement [m] of the structure (at its k_f) whose rotation is `x` [rad]
    (`ch` "theta"), or whose uplift is `x` [m] (`ch` "uplift"; positive), or `x` itself."""
    if ch == "u":
        return float(x)
    if ch == "uplift":
        s = float((x / 2.0 + float(structure.delta_0)) / float(structure.B))
        x = math.asin(min(max(s, 0.0), 1.0))
    return float(rockjax.u_from_theta(structure, x))


def _check_equivalent(trace: DecayTrace, ch: str, structure):
    """TraceError when the primary channel (rotation, uplift) lies beyond the structure's
    overturning (a rotation in degrees read as rad, an uplift in mm read as m)."""
    x = np.pad(np.asarray(getattr(trace, ch), float), 2, mode="edge")
    smooth = float(np.max(np.abs(np.median(
        np.lib.stride_tricks.sliding_window_view(x, 5), axis=1))))
    u_ot = float(structure.u_overturn)
    if ch == "theta":
        beyond = smooth > float(rockjax.theta_from_u(structure, u_ot))
    else:
        beyond = 2.0 * float(structure.B) < smooth or u_equivalent(structure, ch, smooth) > u_ot
    if not beyond:
        return
    unit, frm = trace.units.get(ch, "SI"), trace.units_from.get(ch, "SI")
    what = "rotation" if ch == "theta" else "uplift"
    si = "rad" if ch == "theta" else "m"
    raise TraceError(f"max |{ch}| = {smooth:.4g} {si} is beyond the {what} at which the "
                     f"structure overturns (u_overturn = {u_ot:.4g} m): is the {what} in "
                     f"other units? (read in {unit}, {frm}; column "
                     f"{trace.columns.get(ch, ch)!r})", param="units",
                     value={ch: "deg" if ch == "theta" else "mm"},
                     advice="; give units in the header, or pass {}",
                     python="; give units in the header, or read it with read_trace(path, "
                     f"units={{{ch!r}: {'deg' if ch == 'theta' else 'mm'!r}}})")


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
        raise TraceError(msg, param="structure", advice=" ({})", python="")
    msg += f" (u read in {unit}, {frm or 'SI'}): is the trace in mm? "
    raise TraceError(msg, param="units", value={"u": "mm"},
                     advice="give units in the header, such as t,u_mm, or pass {}",
                     python="give units in the header, such as t,u_mm, or read it with "
                     "read_trace(path, units={'u': 'mm'})")


def _release_u0(structure, release: Release, initial) -> float:
    """The start of u0 [m]: the release level, mapped to u when found in the rotation or
    the uplift (TraceError when the uplift at the release is ~0: no lift-off to map,
    unless `initial` gives u0 and t0)."""
    ch = release.channel
    if ch == "u":
        return float(release.level)
    if ch == "uplift" and not release.level > release.threshold:
        if initial and "u0" in initial and "t0" in initial:
            return float(initial["u0"])
        raise TraceError(
            f"the release cannot be found in the uplift: it reads {release.level:.3g} m "
            f"at the release found (t = {release.time:.4g} s), within the noise "
            f"({release.threshold:.3g} m): an uplift-only trace must start lifted (a release "
            "beyond u_crit). Give the release as initial={'u0': U0_m, 't0': T0_s}",
            param="initial", python="")
    return math.copysign(u_equivalent(structure, ch, abs(release.level)), release.level)


def _starting_values(structure, release: Release, initial, fm: FitModel, params: tuple):
    """(starting values of all of PARAM_NAMES, the stability limit k_min of k_f)."""
    values0 = {
        "k_f": float(structure.k_f),
        "r": float(structure.restitution),
        "u0": _release_u0(structure, release, initial),
        "t0": float(release.time),
        **dict.fromkeys(NUISANCE, 0.0),
    }
    if initial is not None and not isinstance(initial, dict):
        raise ValueError(
            f"initial must be a dict of starting values such as {{'k_f': 5e5}}, got {initial!r}"
        )
    if initial:
        unknown = set(initial) - set(ALL_NAMES)
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
    k_min = float(k_min_of(structure))
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


def setup(trace, structure, params, settings: Settings = Settings()) -> Problem:
    """Check and normalise the arguments of `fit_decay` (ValueError on the first bad one)."""
    st = settings
    structure = check_structure(structure)
    # ValueError naming the model (or the impact rule, or the contact law) if unknown
    fm = _models.resolve_model(st.model, st.impact, st.contact)
    notes = tuple(_models.default_notes(fm)) if params is None else ()
    params = _check_params(params, fm)
    horizons = _models.default_horizons(fm) if st.horizons is None else st.horizons
    starts = _models.default_starts(fm) if st.starts is None else st.starts
    horizons = _check_options(starts, st.max_iter, st.impact, horizons, st.tol,
                              st.uplift_weight, st.theta_weight)
    trace = as_trace(trace)
    t, u_meas, up_meas, scale = _trace_arrays(trace, params, structure)
    release = detect_release(trace)
    _anomalies.check_trace(trace, release)  # TraceError: clipped, or a second release
    fits_uplift = up_meas is not None and st.uplift_weight > 0
    th_meas = None if trace.theta is None else np.asarray(trace.theta, float)
    fitted = tuple(c for c, on in (("u", u_meas is not None),
                                   ("theta", th_meas is not None and st.theta_weight > 0),
                                   ("uplift", fits_uplift)) if on)
    if not fitted:
        raise ValueError("no channel to fit: the trace's channels "
                         f"({', '.join(trace.channels)}) all have weight 0")
    primary = release.channel
    nuisance, sensor_notes = _sensor.choose(params, st.offset, st.drift, fitted, t,
                                            np.asarray(getattr(trace, primary), float),
                                            release)
    params = tuple(p for p in params if p not in NUISANCE) + nuisance
    notes = notes + tuple(sensor_notes)
    values0, k_min = _starting_values(structure, release, st.initial, fm, params)
    if primary != "u" and "u0" not in params and "u0" not in (st.initial or {}):
        notes = notes + (f"u0 held at {values0['u0']:.6g} m: the release level of the "
                         f"{primary} channel mapped to u through the structure's kinematics "
                         "at its starting k_f (fit u0, or give it in initial)",)
    return Problem(
        structure=structure, params=params, fit_model=fm, impact=st.impact,
        horizons=horizons, starts=starts, max_iter=st.max_iter, tol=st.tol,
        uplift_weight=st.uplift_weight, rtol=st.rtol, atol=st.atol, progress=st.progress,
        t=t, u_meas=u_meas, up_meas=up_meas, scale=scale, values0=values0, k_min=k_min,
        release=release, notes=notes, k_cap=_models.k_f_cap(fm, k_min),
        th_meas=th_meas, theta_weight=st.theta_weight, primary=primary,
        theta_scale=1.0 if th_meas is None else max(float(np.max(np.abs(th_meas))), 1e-300),
    )
