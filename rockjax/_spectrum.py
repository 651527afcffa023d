r"""`rockjax.overturning_spectrum`: the smallest pulse amplitude that overturns a structure.

For each pulse period (a rectangular pulse: its duration) the lowest amplitude [m/s²] of a
`rockjax.pulses` pulse that overturns the structure, found by batches of runs on the rk4
stepper (`rockjax.simulate_batch` with `record_steps="own"`: each period's pulse on its
own sample step): a scan of `n_scan` amplitudes per period, geometric from 0.25 to
$4\max(1, x)$ times $g\tan\alpha$ ($x = \omega_p/p$, or $1/(p\,t_1)$ for a rectangular
pulse; widened upwards where nothing overturns), then multisection of the bracket below
the lowest overturning amplitude, every period in one batch per round, until the bracket
is within `rtol`. The pulses overturn a block in two modes, after one or more impacts and
without impact (Zhang & Makris 2001); the overturning amplitudes need not form one
interval, so the scan finds the lowest, and the smallest amplitude that overturns without
an impact is bracketed alongside. Here $p = \sqrt{W R_c / I_O}$ [rad/s] (Housner's
frequency parameter, $I_O$ about a base corner) and $\tan\alpha = B/H_c$ (the rigid
block's uplift acceleration is $g\tan\alpha$).
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time

import jax
import numpy as np

from . import pulses as _pulses
from ._batch import simulate_batch
from ._checks import check_one_structure, check_periods
from ._config import ensure_x64
from ._errors import ParameterError
from ._execution import Execution
from ._report import model_info, model_line
from ._response import STATUS
from ._structure import FIELDS, RockingStructure
from ._sweep import failed_runs
from .integrators import RK4
from .models import get_model

#: substep length cap for the springs: omega h <= 0.5 (RK4 refuses omega h > 2.5)
_OMEGA_H = 0.5
#: no impact limit: a block that falls back chatters to rest (a rigid block's impacts
#: accumulate geometrically), and a run that stopped at a limit would not tell survival
_MAX_IMPACTS = 2**30
_OVERTURNED = STATUS["overturned"]


@dataclasses.dataclass(frozen=True)
class OverturningSpectrum:
    r"""Minimum overturning amplitudes of a pulse, one per period (SI units).

    - `kind`: "rectangular", "one_sine" or "one_cosine"; `periods` [s] (a rectangular
      pulse's durations $t_1$).
    - `amplitude` [m/s²]: the lowest amplitude that overturns (the middle of `bracket`, the
      highest amplitude seen to survive and the lowest seen to overturn, within `rtol`);
      NaN where nothing up to `max_ratio` $g\tan\alpha$ overturned.
    - `mode`: "no impact" or "after impact" — how the lowest-amplitude run overturned.
    - `amplitude_no_impact`, `bracket_no_impact`: the same for overturning without impact.
    - `p` [rad/s], `g_tan_alpha` [m/s²]: the normalisation (module docstring); `x` the
      abscissa of the literature's plot, $\omega_p/p = 2\pi/(pT)$, or $p\,t_1$ for a
      rectangular pulse; `normalised`: amplitude / ($g\tan\alpha$).
    - `dt` [s]: each period's pulse sample step (`rockjax.pulses.pulse(kind, a, T,
      max_dt=dt)` reproduces a run), `t_end` [s] each run's end.
    - `n_runs`, `n_failed` (runs with status max_impacts or solver_failure, counted as
      survivors), `wall_time` [s]; `impact` and `r` (None: Eq. 3) as given.
    """

    kind: str
    model: str
    periods: np.ndarray
    amplitude: np.ndarray
    bracket: np.ndarray
    mode: tuple
    amplitude_no_impact: np.ndarray
    bracket_no_impact: np.ndarray
    p: float
    g_tan_alpha: float
    rtol: float
    dt: np.ndarray
    t_end: np.ndarray
    n_runs: int
    n_failed: int
    wall_time: float
    impact: str = "paper"
    r: float | None = None

    @property
    def x(self) -> np.ndarray:
        """$\\omega_p/p$ (sine, cosine) or $p\\,t_1$ (rectangular): the plot's abscissa."""
        if self.kind == "rectangular":
            return self.p * self.periods
        return 2 * np.pi / (self.p * self.periods)

    @property
    def x_label(self) -> str:
        return "p t1" if self.kind == "rectangular" else "omega_p / p"

    @property
    def normalised(self) -> np.ndarray:
        """amplitude / ($g\\tan\\alpha$)."""
        return self.amplitude / self.g_tan_alpha

    def to_dict(self) -> dict:
        """Plain Python values (lists, floats, None for NaN), e.g. for JSON."""
        def floats(a):
            return [None if not np.isfinite(v) else float(v) for v in np.ravel(a)]

        return {
            "kind": self.kind, "model": self.model, "periods_s": floats(self.periods),
            "amplitude_m_s2": floats(self.amplitude),
            "bracket_m_s2": [floats(b) for b in self.bracket],
            "normalised": floats(self.normalised), "x": floats(self.x),
            "x_label": self.x_label, "mode": list(self.mode),
            "amplitude_no_impact_m_s2": floats(self.amplitude_no_impact),
            "p_rad_s": self.p, "g_tan_alpha_m_s2": self.g_tan_alpha, "rtol": self.rtol,
            "dt_s": floats(self.dt), "t_end_s": floats(self.t_end), "n_runs": self.n_runs,
            "n_failed": self.n_failed, "wall_time_s": self.wall_time,
        }

    def to_csv(self, path):
        """One row per period, header `period_s,x_-,amplitude_m/s2,normalised_-,
        amplitude_no_impact_m/s2,bracket_lo_m/s2,bracket_hi_m/s2` (SI units; nan where
        nothing overturned)."""
        cols = {"period": (self.periods, "s"), "x": (self.x, "-"),
                "amplitude": (self.amplitude, "m/s2"), "normalised": (self.normalised, "-"),
                "amplitude_no_impact": (self.amplitude_no_impact, "m/s2"),
                "bracket_lo": (self.bracket[:, 0], "m/s2"),
                "bracket_hi": (self.bracket[:, 1], "m/s2")}
        np.savetxt(path, np.column_stack([v for v, _ in cols.values()]), delimiter=",",
                   header=",".join(f"{k}_{u}" for k, (_, u) in cols.items()), comments="",
                   fmt="%.10g")

    def report(self) -> str:
        """A text report: the pulse, the model, $p$ and $g\\tan\\alpha$, then one row per
        period (in increasing order: period [s], abscissa, amplitude [m/s²], normalised,
        mode, the amplitude that overturns without impact [m/s²]) and the runs.

        ```python
        s = rockjax.mcmanus_column()
        sp = rockjax.overturning_spectrum(s, "sine", [0.5], n_scan=8, amplitude_rtol=0.05)
        print(sp.report())
        ```
        """
        x = "p t1" if self.kind == "rectangular" else "wp/p"
        lines = [f"overturning spectrum, {self.kind} pulse "
                 f"({model_line(model_info(self.model, self.impact, self.r))})",
                 f"p = {self.p:.4g} rad/s, g tan(alpha) = {self.g_tan_alpha:.4g} m/s2, rtol "
                 f"{self.rtol:g}", f"{'period [s]':>11} {x:>7} {'a [m/s2]':>10} "
                 f"{'a/(g tan a)':>12}  {'mode':<13}{'no impact [m/s2]':>17}"]
        lines += [f"{self.periods[i]:11.4g} {self.x[i]:7.3f} {self.amplitude[i]:10.4g} "
                  f"{self.normalised[i]:12.4f}  {self.mode[i]:<13}"
                  f"{self.amplitude_no_impact[i]:17.4g}" for i in np.argsort(self.periods)]
        lines.append(f"{self.n_runs} runs in {self.wall_time:.2f} s; {self.n_failed} failed "
                     "runs (max_impacts, solver_failure) counted as survivors")
        if np.any(np.isnan(self.amplitude)):
            lines.append("nan: nothing overturned up to 1000 g tan(alpha)")
        return "\n".join(lines)

    def plot(self, ax=None, label=None):
        """amplitude / ($g\\tan\\alpha$) against `x` (matplotlib; returns the axes): the
        lowest overturning amplitude, and the no-impact mode where it is higher."""
        import matplotlib.pyplot as plt

        if ax is None:
            _, ax = plt.subplots(figsize=(6, 4))
        order = np.argsort(self.x)
        x = self.x[order]
        line, = ax.plot(x, self.normalised[order], "-", lw=1.8,
                        label=label or f"{self.kind}, lowest amplitude")
        no = self.amplitude_no_impact[order] / self.g_tan_alpha
        if np.any(no > self.normalised[order] * (1 + 2 * self.rtol)):
            ax.plot(x, no, "--", lw=1, color=line.get_color(),
                    label=f"{label or self.kind}: overturning without impact")
        ax.set_xlabel("$p\\,t_1$" if self.kind == "rectangular" else "$\\omega_p / p$")
        ax.set_ylabel("$a / (g \\tan\\alpha)$")
        ax.set_title(f"overturning spectrum ({self.kind} pulse, model {self.model})",
                     fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        return ax


def frequency_parameter(structure) -> float:
    """Housner's frequency parameter $p = \\sqrt{W R_c / I_O}$ [rad/s] (an array for a
    structure of array fields)."""
    p = np.sqrt(np.asarray(structure.W * structure.R_c / structure.I_O, float))
    return float(p) if p.ndim == 0 else p


def periods_at(structure, kind, x) -> np.ndarray:
    """The pulse periods [s] (a rectangular pulse's durations) at the abscissae `x` of the
    spectrum's plot, $\\omega_p/p = 2\\pi/(pT)$ or $p\\,t_1$ for a rectangular pulse
    (the inverse of `OverturningSpectrum.x`)."""
    p, x = frequency_parameter(structure), np.asarray(x, float)
    return x / p if _pulses.KINDS.get(kind, kind) == "rectangular" else 2 * math.pi / (p * x)


def _check_options(rtol, n_scan, max_ratio, t_free):
    if not (isinstance(rtol, (int, float)) and 1e-8 <= rtol <= 0.1):
        raise ParameterError(f"rtol must lie in [1e-8, 0.1], got {rtol!r}", param="rtol")
    if not (isinstance(n_scan, int) and 8 <= n_scan <= 4096):
        raise ParameterError(f"n_scan must be an integer in [8, 4096], got {n_scan!r}",
                             param="n_scan")
    if not (isinstance(max_ratio, (int, float)) and max_ratio > 4):
        raise ParameterError(f"max_ratio must be a number > 4, got {max_ratio!r}",
                             param="max_ratio")
    if t_free is not None and not (np.isfinite(t_free) and t_free > 0):
        raise ParameterError(f"t_free must be a positive number of seconds, got {t_free!r}",
                             param="t_free")


@dataclasses.dataclass(frozen=True)
class _Runner:
    """Runs of the spectrum's pulses through `rockjax.simulate_batch`: entry i is period
    i % P (P = len(pulses)) of structure i // P; period j's pulse is record j of `pulses`,
    on its own sample step `dt[j]` [s] (record_steps="own"), and its run ends at
    `t_end[j]` [s]; every call is padded to a multiple of `chunk` members, so that every
    round reuses one compiled program. `structure`'s fields and `r` are scalars (one
    structure) or arrays (one value per structure: `rockjax.spectrum_band`'s draws)."""

    structure: RockingStructure
    pulses: tuple
    options: dict
    chunk: int
    dt: np.ndarray
    t_end: np.ndarray
    r: object = None

    def __call__(self, idx, amp):
        """(status, n_impacts) of the runs of entry `idx` at amplitude `amp` [m/s²]."""
        n = len(idx)
        pad = (-n) % self.chunk  # the last run again: no new shapes, no new compilation
        idx = np.concatenate([idx, np.repeat(idx[-1:], pad)])
        d, P = idx // len(self.pulses), len(self.pulses)
        s = self.structure
        if any(np.ndim(getattr(s, f)) for f in FIELDS):
            s = RockingStructure(**{f: np.asarray(getattr(s, f))[d] if np.ndim(getattr(s, f))
                                    else getattr(s, f) for f in FIELDS})
        out = simulate_batch(s, list(self.pulses), record=idx % P,
                             scale=np.concatenate([amp, np.repeat(amp[-1:], pad)]),
                             r=self.r[d] if np.ndim(self.r) else self.r, **self.options)
        return np.asarray(out.status)[:n], np.asarray(out.n_impacts)[:n]


def _runner(structure, model, impact, kind, T, t_free, substeps, devices, n_members, r):
    """The `_Runner` of one spectrum: each period's pulse on a grid of at most
    `rockjax.pulses.MAX_DT` and of omega h <= 0.5 per substep (the springs)."""
    omega = float(np.max(get_model(model, impact).frequency(structure.evaluated())))
    # a model without springs (housner: omega = 0) has no spring step to resolve
    max_dt = _pulses.MAX_DT if not omega > 0 else min(_pulses.MAX_DT,
                                                      substeps * _OMEGA_H / omega)
    pulses = tuple(_pulses.pulse(kind, 1.0, t, max_dt=max_dt) for t in T)
    dt = np.array([float(g.dt) for g in pulses])
    n_dev = len(jax.local_devices()) if devices is None else max(1, int(devices))
    chunk = n_dev * math.ceil(min(n_members, 4096 * n_dev) / n_dev)
    options = dict(tail=t_free, model=get_model(model, impact),
                   integrator=RK4(substeps=substeps, max_impacts=_MAX_IMPACTS),
                   summary_only=True, fidelity_warning=False,
                   execution=Execution(chunk_size=chunk, devices=devices, progress=False,
                                       record_steps="own"))
    return _Runner(structure=structure, pulses=pulses, options=options, chunk=chunk, dt=dt,
                   t_end=T + t_free, r=r)


_BRACKET, _UP, _DOWN, _DONE, _NONE = range(5)


@dataclasses.dataclass
class _Search:
    """Two searches per period (target 0: any overturning, 1: without impact): `lo` [m/s²]
    the highest amplitude seen to survive below `hi`, the lowest seen to overturn (NaN
    until seen), `state` (_BRACKET, _UP: nothing overturned yet, _DOWN: nothing survived
    yet, _DONE, _NONE: nothing overturns below the cap), `hi_imp` the impacts of the run
    at `hi`."""

    lo: np.ndarray
    hi: np.ndarray
    state: np.ndarray
    hi_imp: np.ndarray
    rtol: float
    cap: tuple  # (lowest, highest) amplitude [m/s²] searched, each (n,)

    @classmethod
    def start(cls, n, rtol, cap):
        nan = np.full((2, n), np.nan)
        return cls(nan, nan.copy(), np.full((2, n), _UP), np.zeros((2, n), int), rtol, cap)

    def active(self):
        return list(zip(*np.nonzero(np.isin(self.state, (_BRACKET, _UP, _DOWN)))))

    def points(self, k, i, m):
        """m increasing amplitudes [m/s²] to try next in search (k, i)."""
        lo, hi, st = self.lo[k, i], self.hi[k, i], self.state[k, i]
        j = np.arange(1, m + 1)
        if st == _BRACKET:
            return lo * (hi / lo) ** (j / (m + 1))
        if st == _UP:
            return lo * 16.0 ** (j / m)
        return hi / 16.0 ** (j[::-1] / m)  # _DOWN: below the lowest overturning

    def update(self, k, i, pts, hit, imp):
        """Take the runs at `pts` (increasing): `hit` where the target's overturning
        happened, `imp` their impacts."""
        first = np.flatnonzero(hit)
        if first.size == 0:
            self.lo[k, i] = pts[-1]
            if np.isnan(self.hi[k, i]):
                self.state[k, i] = _NONE if pts[-1] >= self.cap[1][i] else _UP
                return
        else:
            j = int(first[0])
            self.hi[k, i], self.hi_imp[k, i] = pts[j], imp[j]
            if j > 0:
                self.lo[k, i] = pts[j - 1]
            elif np.isnan(self.lo[k, i]):
                self.state[k, i] = _NONE if pts[0] <= self.cap[0][i] else _DOWN
                return
        self.state[k, i] = _BRACKET
        if self.hi[k, i] / self.lo[k, i] - 1 <= self.rtol:
            self.state[k, i] = _DONE


def _targets(status, impacts):
    """(any overturning, overturning without impact) of each run."""
    over = status == _OVERTURNED
    return over, over & (impacts == 0)


def _search(runner, search, scan, m, bar, max_rounds=60):
    """The scan (`scan` (P, n) amplitudes [m/s²]), then rounds of `m` amplitudes per open
    search until every search is done. Returns (runs, failed runs)."""
    P, n = scan.shape
    status, imp = runner(np.repeat(np.arange(P), n), scan.ravel())
    n_runs, n_failed = status.size, _failed(status)
    hits = _targets(status.reshape(P, n), imp.reshape(P, n))
    for k in (0, 1):
        for i in range(P):
            search.update(k, i, scan[i], hits[k][i], imp.reshape(P, n)[i])
    bar and bar.update(status.size)
    for _ in range(max_rounds):
        todo = search.active()
        if not todo:
            break
        pts = np.stack([search.points(k, i, m) for k, i in todo])
        idx = np.repeat([i for _, i in todo], m)
        status, imp = runner(idx, pts.ravel())
        n_runs, n_failed = n_runs + status.size, n_failed + _failed(status)
        hits = _targets(status.reshape(-1, m), imp.reshape(-1, m))
        for row, (k, i) in enumerate(todo):
            search.update(k, i, pts[row], hits[k][row], imp.reshape(-1, m)[row])
        bar and bar.update(status.size)
    return n_runs, n_failed


def _progress_bar(total, enabled):
    if not enabled:
        return None
    from tqdm.auto import tqdm

    return tqdm(total=total, desc="overturning spectrum", unit="run", file=sys.stderr,
                leave=False)


def _failed(status):
    return int(failed_runs(status))


def _amplitude_rtol(amplitude_rtol, rtol):
    """`amplitude_rtol`, or `rtol`, its earlier name (not both, unless they agree)."""
    if rtol is None or rtol == amplitude_rtol:
        return amplitude_rtol
    if amplitude_rtol != 1e-3:
        raise ParameterError(
            f"rtol={rtol!r} contradicts amplitude_rtol={amplitude_rtol!r}: rtol is the "
            "earlier name of amplitude_rtol, give one", param="amplitude_rtol")
    return rtol


def overturning_spectrum(structure, kind, periods, *, model="rigid_body",
                         amplitude_rtol=1e-3, r=None, n_scan=48, max_ratio=1000.0,
                         t_free=None, substeps=4, execution=None,
                         **keywords) -> OverturningSpectrum:
    r"""The lowest amplitude [m/s²] of a pulse that overturns `structure`, per period.

    **Arguments:**

    - `structure`: one `RockingStructure` (SI units).
    - `kind`: "rectangular" (Housner's pulse, `periods` are its durations $t_1$),
      "one_sine" / "sine" or "one_cosine" / "cosine" (`rockjax.pulses`).
    - `periods` [s]: positive, any order.
    - `model`: a model of the fidelity ladder (default `"rigid_body"`, the body's own
      equation: `docs/models.md`), or a model object (an SDOF model's impact rule goes on
      it: `rockjax.get_model("simplified", "after_uplift")`); `r`: the restitution
      (default the structure's, Eq. 3).
    - `amplitude_rtol`: the relative width of the final amplitude bracket (default 1e-3).
    - `n_scan`: amplitudes per period in the first scan (default 48; an overturning range
      narrower than the scan's step, about 11 %, below the lowest one found can be
      missed); `max_ratio`: give up above `max_ratio` $g\tan\alpha$ (NaN).
    - `t_free` [s]: how long each run goes on after its pulse (default $20/p$: a run near
      the threshold lingers near the unstable equilibrium for about
      $\ln(1/\epsilon)/p$); `substeps`: RK4 steps per sample step.
    - `execution`: a `rockjax.Execution` with `devices` and `progress` (the spectrum
      sets the chunks and the records' grid itself).
    - `**keywords`: the keyword form of earlier versions, still accepted: `impact=`,
      `rtol=` (now `amplitude_rtol`), `devices=`, `progress=`.

    **Returns:** an `OverturningSpectrum` (`.plot()` draws it as the literature does,
    amplitude / ($g\tan\alpha$) against $\omega_p/p$, or $p\,t_1$ for a rectangular pulse).
    """
    ensure_x64()
    start = time.perf_counter()
    impact, rtol = keywords.pop("impact", "paper"), keywords.pop("rtol", None)
    execution = Execution.from_keywords(execution, keywords)
    if keywords:
        raise TypeError(f"overturning_spectrum() got unexpected keyword arguments "
                        f"{sorted(keywords)}")
    if execution.chunk_size is not None or execution.record_steps != "common":
        raise ParameterError("execution: a spectrum sets its chunks and the records' grid "
                             "itself; give devices and progress only", param="execution")
    devices, progress = execution.devices, execution.progress
    rtol = _amplitude_rtol(amplitude_rtol, rtol)
    check_one_structure(structure, "a spectrum is computed for one structure at a time")
    if kind not in _pulses.KINDS:
        raise ParameterError(f"kind must be one of {sorted(_pulses.KINDS)}, got {kind!r}",
                             param="kind")
    kind = _pulses.KINDS[kind]
    T = check_periods(periods)
    _check_options(rtol, n_scan, max_ratio, t_free)
    if not (isinstance(substeps, int) and substeps >= 1):
        raise ParameterError(f"substeps must be a positive integer, got {substeps!r}",
                             param="substeps")
    get_model(model, impact)  # the model and impact rule checked before any run
    search, runner, n_runs, n_failed, p, gta = _spectra(
        structure, kind, T, model, impact, r, float(rtol), n_scan, max_ratio, t_free,
        substeps, devices, progress)
    return dataclasses.replace(
        _result(kind, model, T, search, float(p[0]), float(gta[0]), float(rtol), runner,
                n_runs, n_failed, time.perf_counter() - start),
        impact=impact, r=None if r is None else float(r))


def _spectra(structure, kind, T, model, impact, r, rtol, n_scan, max_ratio, t_free,
             substeps, devices, progress):
    """The searches of one structure, or of D structures at once (fields and `r` scalars
    or (D,) arrays): entry i is period i % P of structure i // P. Returns (the `_Search`,
    the `_Runner`, runs, failed runs, p (D,) [rad/s], g tan α (D,) [m/s²]); `t_free`
    None: 20 / the smallest p."""
    p = np.atleast_1d(frequency_parameter(structure))
    gta = np.atleast_1d(np.asarray(structure.g * structure.B / structure.H_c, float))
    D = max(np.size(r) if np.ndim(r) else 1, *(np.size(getattr(structure, f)) for f in FIELDS))
    p, gta = np.broadcast_to(p, (D,)), np.broadcast_to(gta, (D,))
    t_free = 20.0 / float(p.min()) if t_free is None else float(t_free)
    pT = p[:, None] * T[None, :]
    x = (1.0 / pT if kind == "rectangular" else 2 * np.pi / pT).ravel()
    g_e = np.repeat(gta, T.size)
    scan = g_e[:, None] * np.geomspace(0.25, 4.0 * np.maximum(1.0, x), n_scan, axis=-1)
    runner = _runner(structure, model, impact, kind, T, t_free, substeps, devices,
                     x.size * n_scan, r)
    search = _Search.start(x.size, rtol, (1e-3 * g_e, max_ratio * g_e))
    bar = _progress_bar(3 * x.size * n_scan, progress)
    try:
        n_runs, n_failed = _search(runner, search, scan, max(4, n_scan // 2), bar)
    finally:
        if bar is not None:
            bar.close()
    return search, runner, n_runs, n_failed, p, gta


def _result(kind, model, T, search, p, gta, rtol, runner, n_runs, n_failed, wall):
    found = search.state == _DONE
    amp = np.where(found, np.sqrt(search.lo * search.hi), np.nan)
    bracket = np.where(found[..., None], np.stack([search.lo, search.hi], -1), np.nan)
    mode = tuple("after impact" if n > 0 else "no impact" if f else "none"
                 for n, f in zip(search.hi_imp[0], found[0]))
    return OverturningSpectrum(
        kind=kind, model=model if isinstance(model, str) else type(model).__name__,
        periods=T, amplitude=amp[0], bracket=bracket[0], mode=mode,
        amplitude_no_impact=amp[1], bracket_no_impact=bracket[1], p=p, g_tan_alpha=gta,
        rtol=rtol, dt=runner.dt, t_end=runner.t_end, n_runs=int(n_runs),
        n_failed=int(n_failed), wall_time=float(wall))
