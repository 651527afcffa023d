r"""Posterior-predictive fragility curves: `rockjax.fragility_band`, a fragility curve per
posterior draw of the identified parameters, and their median, band and mean.

docs/fragility.md ("Uncertainty of the parameters") has the method. For draws $d = 1..D$
of the parameters (`_draws.py`: any structure field, r, c_f), every record runs at every
scale with the structure of draw $d$; each draw's runs give a lognormal fit
$(\theta_d, \beta_d)$ (`rockjax.fragility`'s maximum likelihood, no bootstrap), and
$P_d(x) = \Phi(\ln(x/\theta_d)/\beta_d)$. The result holds, at every IM $x$, the median
and the (1 ± confidence)/2 quantiles of $P_d(x)$ over the draws (the band), and their
mean $\bar P(x) = \frac1D\sum_d P_d(x)$, the posterior-predictive probability (the pooled
curve). The structure as given (with `r` and the model's `c_f`) runs alongside as the
point estimate.

The runs: one batch per record (and per chunk), the members being draw × scale with the
draw's structure fields and r per member (`rockjax.simulate_batch` takes them per
member); each record on its own time step. c_f is the model's (the 2-DOF body's
`damping`), not the structure's, so draws of c_f run one draw at a time (one compiled
program: the damping goes in as an array).
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
import warnings

import jax
import jax.numpy as jnp
import numpy as np

from ._batch import _progress, DEFAULT_TAIL, simulate_batch
from ._checks import check_one_structure, check_scales
from ._config import ensure_x64
from ._draws import check_draws, describe, draw_structures, member_structure, n_draws, SI_UNITS
from ._errors import ParameterError
from ._execution import Execution
from ._fragility import (
    _fit_rows,
    _OUTCOMES,
    _probability,
    exceedances,
    fragility,
    FragilityResult,
    im_label,
    limit_label,
    parse_im,
    parse_limit,
    record_im,
)
from ._structure import FIELDS, RockingStructure
from ._sweep import _as_records, _SET_BY_SWEEP, _VECTOR, SweepResult, USABLE
from .models import get_model, TwoSpring2DOF

#: per-draw outcomes: those of the fit (`rockjax.fragility`) and a draw with no usable run
OUTCOMES = (*_OUTCOMES, "no usable run")
_NO_RUNS = len(_OUTCOMES)
#: the probabilities at which `FragilityBand.report` gives the IM
_P_REPORT = (0.1, 0.5, 0.9)


# --------------------------------------------------------------------------------- runs
@dataclasses.dataclass(frozen=True)
class _Members:
    """What varies per draw: `structure` (fields (n,) or scalar), `r` ((n,), scalar or
    None: Eq. 3 of each member's structure), `models` (one per draw when c_f is drawn,
    else None: `model` for all). Row n-1 is the point estimate (the structure as given)."""

    structure: RockingStructure
    r: object
    model: object
    models: list | None
    n: int


def _members(structure, draws, model, impact, r):
    """The draws and, last, the structure as given (`_Members`)."""
    D = n_draws(draws)
    sd = draw_structures(structure, draws)
    fields = {f: (np.append(np.asarray(getattr(sd, f)), float(getattr(structure, f)))
                  if np.ndim(getattr(sd, f)) == 1 else getattr(sd, f)) for f in FIELDS}
    s_all = RockingStructure(**fields)
    if "r" in draws:
        r = np.append(draws["r"], float(structure.restitution) if r is None else float(r))
    m = get_model(model, impact)
    models = None
    if "c_f" in draws:
        if not isinstance(m, TwoSpring2DOF):
            raise ParameterError(f"draws: c_f (the 2-DOF body's dashpots) needs "
                                 f"model='two_spring_2dof', got {model!r}", param="draws")
        point = jnp.asarray(m.damping, float)
        models = [TwoSpring2DOF(damping=jnp.asarray(c, float), contact=m.contact)
                  for c in draws["c_f"]] + [TwoSpring2DOF(damping=point, contact=m.contact)]
    return _Members(structure=s_all, r=r, model=m, models=models, n=D + 1)


def _chunk(K, execution):
    """Runs per call: at most `chunk_size` (default 4096 per device), equal chunks, a
    multiple of the vector width and of the devices."""
    n_dev = len(jax.local_devices()) if execution.devices is None else int(execution.devices)
    step = _VECTOR * n_dev // math.gcd(_VECTOR, n_dev)
    most = execution.chunk_size or 4096 * n_dev
    equal = math.ceil(K / math.ceil(K / most))
    return step * math.ceil(equal / step)


def _run_record(mem, model, rows, record, scales, run, bar, out, i):
    """Every (draw in `rows`) × scale of one record, in chunks: fills out[f][rows, i, :]."""
    S = scales.size
    K = rows.size * S
    chunk = _chunk(K, run["execution"])
    for lo in range(0, K, chunk):
        k = np.arange(lo, lo + chunk)
        k = np.minimum(k, K - 1)  # the last chunk padded with its last run
        d, j = rows[k // S], k % S
        r = mem.r[d] if np.ndim(mem.r) == 1 else mem.r
        res = simulate_batch(member_structure(mem.structure, d), [record], scale=scales[j],
                             record=np.zeros(chunk, int), r=r, model=model,
                             tail=run["tail"], t1=run["t1"], summary_only=True,
                             execution=dataclasses.replace(run["execution"], chunk_size=chunk),
                             fidelity_warning=False, **run["options"])
        n = min(chunk, K - lo)
        for f in out:
            out[f][d[:n], i, j[:n]] = np.asarray(getattr(res, f))[:n]
        if bar is not None:
            bar.update(n)


def _run(mem, records, scales, run, progress):
    """The summaries (mem.n, n_records, n_scales) of every draw, record and scale."""
    shape = (mem.n, len(records), scales.size)
    out = {f: np.zeros(shape) for f in ("peak_u", "peak_uplift", "n_impacts", "status",
                                       "t_overturn", "t_end")}
    total = int(np.prod(shape))
    auto = sys.stderr.isatty() and total > 4096
    bar = _progress(total, progress if progress is not None else auto, "fragility band")
    groups = ([(mem.model, np.arange(mem.n))] if mem.models is None else
              [(m, np.array([d])) for d, m in enumerate(mem.models)])
    try:
        for model, rows in groups:
            for i, rec in enumerate(records):
                _run_record(mem, model, rows, rec, scales, run, bar, out, i)
    finally:
        if bar is not None:
            bar.close()
    return out


# ------------------------------------------------------------------------------- result
@dataclasses.dataclass(frozen=True, eq=False)
class FragilityBand:
    r"""Fragility curves over posterior draws of the parameters (`rockjax.fragility_band`,
    docs/fragility.md).

    - `im`, `im_unit`, `limit`, `model`, `confidence`: as `FragilityResult`.
    - `draws` (name -> (n_draws,) SI values) and `units` (name -> SI unit) of the draws.
    - Per draw: `medians` θ_d [im_unit] and `betas` β_d of its maximum-likelihood fit,
      `outcomes` ("fit", "separated": β = 0, a step; "none exceeded" / "all exceeded":
      the curve ≡ 0 / ≡ 1, θ = inf / 0; "not converged", "no usable run": left out of
      the band, NaN), `counts` (draws per outcome).
    - `grid` [im_unit], `curves` (n_draws, n_grid) P_d on it; `median_curve` and `band`
      (2, n_grid): the pointwise median and (1 ± confidence)/2 quantiles over the draws;
      `pooled`: their mean, the posterior-predictive probability.
    - `median_ci`, `beta_ci`: the same quantiles of θ_d and β_d (draws with a finite θ).
    - `point`: the `FragilityResult` of the structure as given (None if it has no fit:
      `point_note` says why).
    - Per run: `im_values` (n_records, n_scales) [im_unit], `status`, `exceeded`, `used`
      (n_draws, n_records, n_scales); `records` (labels), `scales`; `wall_time` [s].
    """

    im: str
    im_unit: str
    limit: str
    model: str
    confidence: float
    draws: dict
    units: dict
    medians: np.ndarray
    betas: np.ndarray
    outcomes: tuple
    counts: dict
    grid: np.ndarray
    curves: np.ndarray
    median_curve: np.ndarray
    band: np.ndarray
    pooled: np.ndarray
    median_ci: tuple | None
    beta_ci: tuple | None
    point: FragilityResult | None
    point_note: str
    im_values: np.ndarray
    status: np.ndarray
    exceeded: np.ndarray
    used: np.ndarray
    records: tuple
    scales: np.ndarray
    wall_time: float

    def __repr__(self):
        th = self._finite_theta()
        return (f"FragilityBand({self.n_draws} draws, P({self.limit} | {self.im}): median "
                f"{_fmt(np.median(th) if th.size else None)} {self.im_unit})")

    @property
    def n_draws(self) -> int:
        return int(self.medians.size)

    @property
    def n_runs(self) -> int:
        """Runs simulated: every draw and the point estimate, records × scales."""
        return int((self.n_draws + 1) * self.im_values.size)

    def _finite(self):
        """The draws with a finite θ (a fit, or separated)."""
        return np.isin(np.asarray(self.outcomes), ("fit", "separated"))

    def _finite_theta(self):
        return self.medians[self._finite()]

    def at(self, im) -> dict:
        """At `im` [im_unit] (any shape): "median", "lower", "upper" (the band) and
        "pooled" (the mean) of P_d(im) over the draws, each an array of the shape of `im`
        (exact, not interpolated from `grid`)."""
        x = np.asarray(im, float)
        if np.any(~np.isfinite(x) | (x < 0)):
            raise ParameterError(f"im must be finite numbers >= 0 [{self.im_unit}], got {im!r}",
                                 param="im")
        with np.errstate(divide="ignore"):
            P = _probability(np.log(self.medians), self.betas, np.log(x).reshape(-1))
        med, lo, hi, pooled = _stats(P, self.confidence)
        return {k: v.reshape(x.shape) for k, v in
                (("median", med), ("lower", lo), ("upper", hi), ("pooled", pooled))}

    def probability(self, im):
        """The posterior-predictive P(limit | im): the mean of P_d(im) over the draws (a
        float for a scalar `im`)."""
        p = self.at(im)["pooled"]
        return float(p) if p.ndim == 0 else p

    def im_at(self, p) -> dict:
        """The IM [im_unit] at which the median curve, the band's lower and upper curves
        and the pooled curve reach the probability `p` (NaN where a curve does not reach it
        between grid[0]/10 and 10 grid[-1])."""
        if not 0 < p < 1:
            raise ParameterError(f"p must lie in (0, 1), got {p!r}", param="p")
        x = np.geomspace(self.grid[0] / 10, self.grid[-1] * 10, 4001)
        out = {}
        for k, P in self.at(x).items():
            ok = np.isfinite(P)
            if not ok.any() or not (P[ok].min() <= p <= P[ok].max()):
                out[k] = math.nan
                continue
            i = int(np.argmax(P[ok] >= p))
            xs, Ps = x[ok], P[ok]
            if i == 0 or Ps[i] == Ps[i - 1]:
                out[k] = float(xs[i])
            else:
                w = (p - Ps[i - 1]) / (Ps[i] - Ps[i - 1])
                out[k] = float(np.exp(np.log(xs[i - 1]) + w * np.log(xs[i] / xs[i - 1])))
        return out

    def summary(self) -> dict:
        """Plain Python values for JSON, with `units`: the draws (per parameter: unit,
        median, 5 and 95 % quantiles), the per-draw θ, β and outcome, the intervals, the
        IM at P = 10, 50, 90 % of each curve, the curves on `grid`, the point estimate."""
        def floats(a):
            return [None if not np.isfinite(v) else float(v) for v in np.ravel(a)]

        pt = self.point
        return {
            "im": self.im, "im_unit": self.im_unit, "limit": self.limit, "model": self.model,
            "confidence": self.confidence, "n_draws": self.n_draws, "n_runs": self.n_runs,
            "units": {"im": self.im_unit, "median": self.im_unit, "beta": "-",
                      "grid": self.im_unit, "probability": "-", **self.units},
            "draws": describe(self.draws), "outcome_counts": dict(self.counts),
            "median_ci": None if self.median_ci is None else list(self.median_ci),
            "beta_ci": None if self.beta_ci is None else list(self.beta_ci),
            "per_draw": {"median": floats(self.medians), "beta": floats(self.betas),
                         "outcome": list(self.outcomes)},
            "im_at": {f"{p:g}": self.im_at(p) for p in _P_REPORT},
            "curves": {"im": floats(self.grid), "median": floats(self.median_curve),
                       "lower": floats(self.band[0]), "upper": floats(self.band[1]),
                       "pooled": floats(self.pooled)},
            "point": None if pt is None else {
                "median": pt.median, "beta": pt.beta, "separated": pt.separated,
                "n_used": pt.n_used, "n_exceeded": pt.n_exceeded,
                "probability": floats(pt.probability(self.grid))},
            "point_note": self.point_note, "records": list(self.records),
            "scales": floats(self.scales), "wall_time_s": self.wall_time,
        }

    def report(self) -> str:
        """The band as text: the draws, the runs, θ and β over the draws (median and
        interval) beside the point estimate's, the IM at P = 10, 50 and 90 % of each curve
        (`print(rockjax.fragility_band(s, records, scales, draws).report())`)."""
        u = f" {self.im_unit}" if self.im_unit != "-" else ""
        c = f"{self.confidence:.0%}"
        lines = [f"draws         {self.n_draws}: " + ", ".join(
            f"{d['name']} {d['median']:.4g} {d['unit']} ({d['q05']:.4g} to {d['q95']:.4g})"
            for d in describe(self.draws)) + " (median, 5 to 95 %)",
            f"runs          {self.n_runs}: {self.n_draws} draws + the point estimate x "
            f"{len(self.records)} record(s) x {self.scales.size} scale(s), model "
            f"{self.model}, {self.wall_time:.3g} s",
            "fits          " + ", ".join(f"{k} {v}" for k, v in self.counts.items() if v)]
        th = self._finite_theta()
        if th.size:
            lines.append(f"median        {np.median(th):.4g}{u} over the draws ({c} "
                         f"{self.median_ci[0]:.4g} to {self.median_ci[1]:.4g})")
            lines.append(f"beta          {np.median(self.betas[self._finite()]):.4g} over the "
                         f"draws ({c} {self.beta_ci[0]:.4g} to {self.beta_ci[1]:.4g})")
        pt = self.point
        lines.append(f"point         median {pt.median:.4g}{u}, beta {pt.beta:.4g} (the "
                     "structure as given)" if pt is not None else
                     f"point         {self.point_note}")
        for p in _P_REPORT:
            a = self.im_at(p)
            lines.append(f"{self.im} at P={p:.0%}".ljust(14)
                         + f"median curve {_fmt(a['median'])}{u} (band {_fmt(a['upper'])} to "
                         f"{_fmt(a['lower'])}), pooled {_fmt(a['pooled'])}{u}")
        return "\n".join(lines)

    def plot(self, ax=None):
        """The band (shaded), the median curve, the pooled curve (dashed), the point
        estimate's curve (dotted) and, faintly, up to 40 of the draws' curves, against
        the IM (matplotlib; returns the axes)."""
        from ._plotting import plot_fragility_band

        return plot_fragility_band(self, ax)


def _fmt(x):
    return "-" if x is None or not np.isfinite(x) else f"{x:.4g}"


def _stats(P, confidence):
    """(median, lower, upper, mean) over the rows of P that are not all NaN."""
    ok = ~np.all(np.isnan(P), axis=1)
    P = P[ok]
    if not len(P):
        nan = np.full(P.shape[1], np.nan)
        return nan, nan, nan, nan
    q = np.quantile(P, [0.5, (1 - confidence) / 2, (1 + confidence) / 2], axis=0)
    return q[0], q[1], q[2], P.mean(axis=0)


# --------------------------------------------------------------------------- the band
def _check_args(structure, confidence, grid):
    check_one_structure(structure, "the draws vary it (draws=)")
    if not (isinstance(confidence, (int, float, np.floating)) and 0 < confidence < 1):
        raise ParameterError(f"confidence must lie in (0, 1), e.g. 0.9, got {confidence!r}",
                             param="confidence")
    if grid is not None:
        g = np.asarray(grid, float)
        if g.ndim != 1 or g.size < 2 or not np.all(np.isfinite(g)) or np.any(g <= 0):
            raise ParameterError(
                f"grid must be a 1-D array of >= 2 positive IM values, got {grid!r}", param="grid")


def _sweeps(structure, mem, fields, recs, labs, sc, model, impact, run):
    """A `SweepResult` per draw (and the point estimate, last)."""
    out = []
    for d in range(mem.n):
        s = member_structure(mem.structure, d) if d < mem.n - 1 else structure
        out.append(SweepResult(structure=s, records=recs, labels=labs, scales=sc, model=model,
                               impact=impact, tail=run["tail"], t1=run["t1"],
                               options=dict(run["options"]),
                               **{f: v[d] for f, v in fields.items()}))
    return out


def _fit_draws(sweeps, x, kind, threshold):
    """(ln θ, β, outcome code) of each draw's sweep (the point estimate excluded)."""
    Y = np.stack([exceedances(s, kind, threshold).ravel() for s in sweeps])
    W = np.stack([np.isin(s.status, USABLE).ravel() for s in sweeps]).astype(float)
    ln_th, beta, outcome, _ = _fit_rows(np.log(x.ravel()), Y, W)
    none = W.sum(1) == 0
    outcome[none], ln_th[none], beta[none] = _NO_RUNS, np.nan, np.nan
    return ln_th, beta, outcome, Y, W


def _point(sweep, im, limit):
    """(the point estimate's FragilityResult or None, a note)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            fit = fragility(sweep, im, limit, n_bootstrap=0)
        except ValueError as e:
            return None, f"the structure as given has no fit: {e}"
    note = "; ".join(str(w.message) for w in caught)
    return fit, note


def fragility_band(structure, records, scales, draws, *, im="PGA", limit="overturned",
                   model="simplified", confidence=0.9, grid=None, labels=None,
                   execution=None, **options) -> FragilityBand:
    r"""Fragility curves over posterior draws of the parameters: their median and band.

    For each draw, `structure` takes the draw's values (any of its fields, `r`, and
    `c_f` for the 2-DOF body's dashpots), every record runs at every scale (as
    `rockjax.sweep`), and a lognormal curve $P_d$ is fitted to the runs (as
    `rockjax.fragility`, without bootstrap). The band is the pointwise (1 ±
    `confidence`)/2 quantiles of $P_d(x)$ over the draws, the median curve their median,
    the pooled curve their mean (the posterior-predictive probability). The structure as
    given runs too, as the point estimate (`FragilityBand.point`).

    **Arguments:**

    - `structure`: one `RockingStructure`, the values of what is not drawn.
    - `records`, `scales`, `labels`, `model`: as `rockjax.sweep` (default model
      `"simplified"`, as `sweep`; `"rigid_body"` is the one recommended for fragility).
    - `draws`: name -> 1-D array of SI values, one per draw (`rockjax.read_draws` reads
      them from CSV; `identification.Posterior.draws_dict()` gives them), at least 2; a
      fit's nuisances (`rockjax._draws.NUISANCE`: t0, u0, sensor zeros, the clock offset)
      are left out.
    - `im`, `limit`: as `rockjax.fragility`; `confidence` (default 0.9) of the band and
      of the intervals of θ and β; `grid` [IM units]: where the curves are tabulated
      (default 200 points from half the smallest IM used to 1.5 times the largest).
    - `execution`: a `rockjax.Execution` (chunk size, devices, progress: a bar by default
      on a terminal for more than 4096 runs).
    - `**options`: `tail` (default 5 s), `t1`, `r` (the point estimate's, when r is drawn;
      else every draw's), `impact`, and `simulate_batch`'s other run settings
      (`method`, `substeps`, `max_impacts`, ...).

    **Returns:** a `FragilityBand`. Each record runs on its own time step (a sweep of
    several records runs them on their common step: the same forcing, finer steps).
    Errors: unknown or unphysical draws (naming the draw), no run that reached the
    limit (or none that did not) in any draw.
    """
    ensure_x64()
    t0 = time.perf_counter()
    _check_args(structure, confidence, grid)
    draws = check_draws(draws)
    recs, labs = _as_records(records, labels)
    sc = check_scales(scales)
    name, period, unit = parse_im(im)
    kind, threshold = parse_limit(limit)
    execution = Execution.from_keywords(execution, options)
    clash = [k for k in options if k in _SET_BY_SWEEP]
    if clash:
        raise TypeError(f"fragility_band sets {', '.join(clash)} itself")
    label, lim = im_label(name, period), limit_label(kind, threshold)
    base = np.array([record_im(r, name, period) for r in recs])
    bad = [lab for lab, v in zip(labs, base) if not (np.isfinite(v) and v > 0)]
    if bad:
        raise ParameterError(f"im: {label} is zero for record(s) {', '.join(bad)}", param="im")
    impact, r = options.pop("impact", "paper"), options.pop("r", None)
    mem = _members(structure, draws, model, impact, r)
    run = {"tail": options.pop("tail", DEFAULT_TAIL), "t1": options.pop("t1", None),
           "options": options, "execution": dataclasses.replace(execution, progress=False)}
    fields = _run(mem, recs, sc, run, execution.progress)
    run["options"] = {**options, **({} if r is None else {"r": r})}
    sweeps = _sweeps(structure, mem, fields, recs, labs, sc, model, impact, run)
    x = base[:, None] * sc[None, :]
    ln_th, beta, outcome, Y, W = _fit_draws(sweeps[:-1], x, kind, threshold)
    return _result(sweeps, x, ln_th, beta, outcome, Y, W, draws, grid, float(confidence),
                   (label, unit, lim, im, limit), time.perf_counter() - t0)


def _result(sweeps, x, ln_th, beta, outcome, Y, W, draws, grid, confidence, what, wall):
    label, unit, lim, im, limit = what
    used = W > 0
    if not used.any():
        raise ParameterError("no run completed or overturned in any draw; nothing to fit",
                             param="scales")
    if not (Y & used).any():
        raise ParameterError(f"no run reached the limit ({lim}) in any draw, up to {label} = "
                             f"{x.max():.4g} {unit}: raise the scales", param="scales")
    if (Y | ~used).all():
        raise ParameterError(f"every run reached the limit ({lim}) in every draw, down to "
                             f"{label} = {x.min():.4g} {unit}: lower the scales", param="scales")
    xu = np.broadcast_to(x.ravel(), used.shape)[used]
    g = (np.geomspace(xu.min() / 2, xu.max() * 1.5, 200) if grid is None
         else np.asarray(grid, float))
    with np.errstate(divide="ignore"):  # ln θ of the medians as stored (`at` uses them)
        curves = _probability(np.log(np.exp(ln_th)), beta, np.log(g))
    med, lo, hi, pooled = _stats(curves, confidence)
    q = [(1 - confidence) / 2, (1 + confidence) / 2]
    finite = np.isin(outcome, (0, 1))  # a fit or separated: a finite θ
    th, be = np.exp(ln_th[finite]), beta[finite]
    point, note = _point(sweeps[-1], im, limit)
    shape = (len(sweeps) - 1, *x.shape)
    first = sweeps[0]
    return FragilityBand(
        im=label, im_unit=unit, limit=lim, model=first.model_name, confidence=confidence,
        draws=draws, units={k: SI_UNITS[k] for k in draws}, medians=np.exp(ln_th),
        betas=beta, outcomes=tuple(OUTCOMES[k] for k in outcome),
        counts={name: int(np.sum(outcome == k)) for k, name in enumerate(OUTCOMES)},
        grid=g, curves=curves, median_curve=med, band=np.stack([lo, hi]), pooled=pooled,
        median_ci=tuple(float(v) for v in np.quantile(th, q)) if th.size else None,
        beta_ci=tuple(float(v) for v in np.quantile(be, q)) if th.size else None,
        point=point, point_note=note, im_values=x,
        status=np.stack([s.status for s in sweeps[:-1]]), exceeded=Y.reshape(shape),
        used=used.reshape(shape), records=first.labels, scales=first.scales, wall_time=wall)
