r"""Posterior-predictive overturning spectra: `rockjax.spectrum_band`, the threshold
amplitude per pulse period for every posterior draw of the parameters, with its median
and band (docs/spectra.md, "Uncertainty of the parameters").

The draws (`_draws.py`) and the structure as given (the point estimate) run in one search
(`rockjax.overturning_spectrum`'s scan and multisection): entry i is period i % P of draw
i // P, with the draw's structure fields and r per member, so that every round of every
draw is one batch. Draws of c_f (the 2-DOF body's dashpots, a field of the model) run one
draw at a time, each with its damping as an array (one compiled program).
"""

from __future__ import annotations

import dataclasses
import time

import jax.numpy as jnp
import numpy as np

from . import pulses as _pulses
from ._checks import check_one_structure, check_periods
from ._config import ensure_x64
from ._draws import check_draws, describe, draw_structures, n_draws, SI_UNITS
from ._errors import ParameterError
from ._execution import Execution
from ._spectrum import _check_options, _DONE, _result, _spectra, OverturningSpectrum
from ._structure import FIELDS, RockingStructure
from .models import get_model, TwoSpring2DOF


@dataclasses.dataclass(frozen=True, eq=False)
class SpectrumBand:
    r"""Overturning spectra over posterior draws of the parameters (`rockjax.spectrum_band`).

    - `kind`, `model`, `periods` [s], `confidence`; `draws` (name -> (n_draws,) SI
      values), `units` (name -> SI unit).
    - `amplitudes` (n_draws, n_periods) [m/s²]: each draw's lowest overturning amplitude
      (NaN where nothing overturned up to `max_ratio` $g\tan\alpha$).
    - `median`, `band` (2, n_periods) [m/s²]: the median and the (1 ± confidence)/2
      quantiles over the draws (a draw that never overturned counts as +inf: a quantile
      that falls on it is NaN); `n_none` (n_periods,): such draws per period.
    - `point`: the `OverturningSpectrum` of the structure as given; its `p` and
      `g_tan_alpha` normalise the plot (`x`, `normalised`).
    - `n_runs`, `wall_time` [s].
    """

    kind: str
    model: str
    periods: np.ndarray
    confidence: float
    draws: dict
    units: dict
    amplitudes: np.ndarray
    median: np.ndarray
    band: np.ndarray
    n_none: np.ndarray
    point: OverturningSpectrum
    n_runs: int
    wall_time: float

    @property
    def n_draws(self) -> int:
        return int(self.amplitudes.shape[0])

    @property
    def x(self) -> np.ndarray:
        """The abscissa of the structure as given (`OverturningSpectrum.x`)."""
        return self.point.x

    def summary(self) -> dict:
        """Plain Python values for JSON (None for NaN), with `units`."""
        def floats(a):
            return [None if not np.isfinite(v) else float(v) for v in np.ravel(a)]

        return {
            "kind": self.kind, "model": self.model, "confidence": self.confidence,
            "n_draws": self.n_draws, "units": {"periods": "s", "amplitude": "m/s2",
                                               "x": "-", **self.units},
            "draws": describe(self.draws), "periods": floats(self.periods),
            "x": floats(self.x), "x_label": self.point.x_label,
            "median": floats(self.median), "lower": floats(self.band[0]),
            "upper": floats(self.band[1]), "n_none": self.n_none.tolist(),
            "point": floats(self.point.amplitude),
            "g_tan_alpha_m_s2": self.point.g_tan_alpha, "p_rad_s": self.point.p,
            "per_draw": [floats(a) for a in self.amplitudes],
            "n_runs": self.n_runs, "wall_time_s": self.wall_time,
        }

    def report(self) -> str:
        """The draws, then per period (increasing): the point estimate's amplitude, the
        median and band over the draws [m/s²], and the draws that never overturned
        (`print(rockjax.spectrum_band(s, "sine", periods, draws).report())`)."""
        c = f"{self.confidence:.0%}"
        lines = [f"overturning spectrum over {self.n_draws} draws, {self.kind} pulse, model "
                 f"{self.model}",
                 "draws         " + ", ".join(
                     f"{d['name']} {d['median']:.4g} {d['unit']} ({d['q05']:.4g} to "
                     f"{d['q95']:.4g})" for d in describe(self.draws)) + " (median, 5 to 95 %)",
                 f"{'period [s]':>11} {self.point.x_label:>12} {'point [m/s2]':>13} "
                 f"{'median [m/s2]':>14} {c + ' band [m/s2]':>22} {'none':>5}"]
        for i in np.argsort(self.periods):
            lines.append(f"{self.periods[i]:11.4g} {self.x[i]:12.4g} "
                         f"{self.point.amplitude[i]:13.4g} {self.median[i]:14.4g} "
                         f"{self.band[0, i]:10.4g} to {self.band[1, i]:<8.4g} "
                         f"{int(self.n_none[i]):5d}")
        lines.append(f"{self.n_runs} runs in {self.wall_time:.2f} s")
        return "\n".join(lines)

    def plot(self, ax=None):
        """amplitude / ($g\\tan\\alpha$ of the structure as given) against its `x`: the
        band, the median and the point estimate (matplotlib; returns the axes)."""
        if ax is None:
            from ._plotting import new_figure

            ax = new_figure(figsize=(6, 4), layout="constrained").subplots()
        o = np.argsort(self.x)
        gta, x = self.point.g_tan_alpha, self.x[o]
        ax.fill_between(x, self.band[0, o] / gta, self.band[1, o] / gta, color="C0", alpha=0.25,
                        lw=0, label=f"{self.confidence:.0%} band over {self.n_draws} draws")
        ax.plot(x, self.median[o] / gta, color="C0", lw=2, label="median over the draws")
        ax.plot(x, self.point.normalised[o], color="k", lw=1.2, ls=":",
                label="point estimate (the structure as given)")
        ax.set_xlabel("$p\\,t_1$" if self.kind == "rectangular" else "$\\omega_p / p$")
        ax.set_ylabel("$a / (g \\tan\\alpha)$")
        ax.set_title(f"overturning spectrum over draws ({self.kind} pulse, model "
                     f"{self.model})", fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        return ax


def _with_point(structure, draws, r):
    """(the structure with fields (D + 1,) or scalar, r (D + 1,) or as given): the draws,
    then the structure as given."""
    sd = draw_structures(structure, draws)
    s = RockingStructure(**{f: (np.append(np.asarray(getattr(sd, f)),
                                          float(getattr(structure, f)))
                                if np.ndim(getattr(sd, f)) == 1 else getattr(sd, f))
                            for f in FIELDS})
    if "r" in draws:
        r = np.append(draws["r"], float(structure.restitution) if r is None else float(r))
    return s, r


def _take(s, r, d):
    """Structure and r of member `d` (scalar fields)."""
    return (RockingStructure(**{f: np.asarray(getattr(s, f))[d] if np.ndim(getattr(s, f))
                                else getattr(s, f) for f in FIELDS}),
            r[d] if np.ndim(r) else r)


def _quantiles(A, confidence):
    """(median, lower, upper, draws with NaN) over the rows of A, NaN as +inf."""
    B = np.where(np.isnan(A), np.inf, A)
    q = np.quantile(B, [0.5, (1 - confidence) / 2, (1 + confidence) / 2], axis=0)
    q = np.where(np.isinf(q), np.nan, q)
    return q[0], q[1], q[2], np.isnan(A).sum(0)


def spectrum_band(structure, kind, periods, draws, *, model="rigid_body", confidence=0.9,
                  amplitude_rtol=1e-3, r=None, n_scan=48, max_ratio=1000.0, substeps=4,
                  execution=None) -> SpectrumBand:
    r"""The overturning spectrum over posterior draws of the parameters: per period, each
    draw's lowest overturning amplitude [m/s²], their median and band.

    For each draw, `structure` takes the draw's values (any field, `r`, and `c_f` for the
    2-DOF body's dashpots) and `rockjax.overturning_spectrum`'s search finds its
    threshold at every period; the draws and the structure as given (the point estimate)
    run in one search, each round one batch (c_f: one draw at a time). The pulses' sample
    step is the one of the stiffest draw, and each run goes on for $20/p$ of the draw with
    the smallest $p$ after its pulse (for identical draws, those of the point estimate).

    **Arguments:** `structure`, `kind`, `periods`, `model` (default `"rigid_body"`),
    `amplitude_rtol`, `r` (the point estimate's when r is drawn, else every draw's),
    `n_scan`, `max_ratio`, `substeps`, `execution` (devices, progress): as
    `rockjax.overturning_spectrum`; `draws`: name -> 1-D array of SI values, one per
    draw (`rockjax.read_draws`), at least 2; `confidence` (default 0.9) of the band.

    **Returns:** a `SpectrumBand`.
    """
    ensure_x64()
    start = time.perf_counter()
    check_one_structure(structure, "the draws vary it (draws=)")
    draws = check_draws(draws)
    if not (isinstance(confidence, (int, float, np.floating)) and 0 < confidence < 1):
        raise ParameterError(f"confidence must lie in (0, 1), e.g. 0.9, got {confidence!r}",
                             param="confidence")
    execution = Execution() if execution is None else execution
    if not isinstance(execution, Execution) or execution.chunk_size is not None or (
            execution.record_steps != "common"):
        raise ParameterError("execution: a spectrum sets its chunks and the records' grid "
                             "itself; give devices and progress only", param="execution")
    if kind not in _pulses.KINDS:
        raise ParameterError(f"kind must be one of {sorted(_pulses.KINDS)}, got {kind!r}",
                             param="kind")
    kind, T = _pulses.KINDS[kind], check_periods(periods)
    _check_options(amplitude_rtol, n_scan, max_ratio, None)
    m = get_model(model)
    s_all, r_all = _with_point(structure, draws, r)
    D = n_draws(draws)
    args = (kind, T, float(amplitude_rtol), n_scan, float(max_ratio), substeps,
            execution.devices, execution.progress)
    if "c_f" in draws:
        if not isinstance(m, TwoSpring2DOF):
            raise ParameterError(f"draws: c_f (the 2-DOF body's dashpots) needs "
                                 f"model='two_spring_2dof', got {model!r}", param="draws")
        c = np.append(draws["c_f"], float(m.damping))
        parts = [_search(*_take(s_all, r_all, d), TwoSpring2DOF(
            damping=jnp.asarray(c[d], float), contact=m.contact), *args) for d in range(D + 1)]
    else:
        parts = [_search(s_all, r_all, m, *args)]
    amp = np.concatenate([a for a, _, _ in parts]).reshape(D + 1, T.size)
    n_runs = sum(n for _, n, _ in parts)
    med, lo, hi, none = _quantiles(amp[:D], float(confidence))
    point = dataclasses.replace(parts[-1][2], model=model if isinstance(model, str) else
                                type(model).__name__, r=None if r is None else float(r))
    return SpectrumBand(kind=kind, model=point.model, periods=T, confidence=float(confidence),
                        draws=draws, units={k: SI_UNITS[k] for k in draws},
                        amplitudes=amp[:D], median=med, band=np.stack([lo, hi]), n_none=none,
                        point=point, n_runs=int(n_runs),
                        wall_time=time.perf_counter() - start)


def _search(s, r, model, kind, T, rtol, n_scan, max_ratio, substeps, devices, progress):
    """(amplitudes (D * P,) [m/s²], runs, the last structure's `OverturningSpectrum`)."""
    t0 = time.perf_counter()
    search, runner, n_runs, n_failed, p, gta = _spectra(
        s, kind, T, model, "paper", r, rtol, n_scan, max_ratio, None, substeps, devices,
        progress)
    found = search.state[0] == _DONE
    amp = np.where(found, np.sqrt(search.lo[0] * search.hi[0]), np.nan)
    P = T.size
    last = dataclasses.replace(search, **{k: getattr(search, k)[:, -P:] for k in
                                          ("lo", "hi", "state", "hi_imp")})
    point = _result(kind, model, T, last, float(p[-1]), float(gta[-1]), rtol, runner,
                    n_runs, n_failed, time.perf_counter() - t0)
    return amp, n_runs, point
