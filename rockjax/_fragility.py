r"""Fragility curves: `rockjax.fragility`, a lognormal fit to a `rockjax.sweep` (`_sweep.py`).

docs/fragility.md has the method, the units, the bootstrap and the checks.

`sweep` runs every record at every scale factor through `rockjax.simulate_batch`
(summaries only) and keeps the results per record × scale. `fragility` fits a lognormal
fragility curve to them by maximum likelihood (Baker 2015): each run $i$ that completed or
overturned is a Bernoulli trial at its intensity measure $x_i$, exceeding the limit state
($y_i = 1$) with probability

$$P(y_i = 1 \mid x_i) = \Phi\!\left(\frac{\ln(x_i/\theta)}{\beta}\right),$$

and $(\theta, \beta)$, the median [IM units] and the logarithmic standard deviation, maximise

$$\ln L(\theta, \beta) = \sum_i w_i\left[y_i \ln\Phi(z_i) + (1 - y_i)\ln\Phi(-z_i)\right],
\qquad z_i = \frac{\ln x_i - \ln\theta}{\beta},$$

with $w_i = 1$ (the fit) or the number of times run $i$'s record was drawn (a bootstrap
resample of the records). In $(a, b) = (-\ln\theta/\beta,\ 1/\beta)$, $z_i = a + b\ln x_i$
and $\ln L$ is concave (probit regression), so Newton's method with a line search finds its
maximum from any start; it runs in JAX (`jax.scipy.stats.norm.logcdf`), vmapped over the
bootstrap resamples.

Runs that ended as `max_impacts` or `solver_failure` are left out of the fit and counted.
Degenerate data: no exceedance or no survivor is an error (the median lies outside the
data); data separated by the IM (every exceedance at an IM at or above every survivor's) has
no finite-β maximum: the result is the limit β = 0 with the median at the geometric middle
of the gap, flagged `separated` and warned about.
"""

from __future__ import annotations

import dataclasses
import re
import warnings

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.stats import norm

from ._config import ensure_x64
from ._errors import ParameterError
from ._intensity import pga, pgd, pgv, spectral_acceleration
from ._kinematics import theta_from_u
from ._records import G_STANDARD
from ._status import STATUS, STATUS_NAMES
from ._sweep import FAILED, SweepResult, USABLE
from .models import get_model

#: the units of each intensity measure (PGA and Sa in g)
IM_UNITS = {"PGA": "g", "PGV": "m/s", "PGD": "m", "Sa": "g", "scale": "-"}
_SA = re.compile(r"^\s*sa\s*\(\s*(?:t\s*=\s*)?([0-9.eE+-]+)\s*s?\s*\)\s*$", re.I)
#: bootstrap outcomes (docs of `FragilityResult.bootstrap_counts`)
_FIT, _SEPARATED, _NONE, _ALL, _NOT_CONVERGED = range(5)
_OUTCOMES = ("fit", "separated", "none exceeded", "all exceeded", "not converged")
_NEWTON_ITERATIONS = 60
#: converged: |grad ln L| <= this x the weight of the runs, in the centred (a, b)
_GRAD_TOL = 1e-9
#: the fit pads the runs to a multiple of this (one compilation for similar sizes)
_PAD = 256


# ------------------------------------------------------------------ IM and limit state
def parse_im(im):
    """(name, period [s] or None, unit) of an intensity measure: "PGA", "PGV", "PGD",
    "Sa(T)" with T in seconds (e.g. "Sa(1.0)", 5 % damping) or "scale"."""
    if isinstance(im, str):
        key = im.strip()
        for name in ("PGA", "PGV", "PGD", "scale"):
            if key.lower() == name.lower():
                return name, None, IM_UNITS[name]
        m = _SA.match(key)
        if m:
            try:
                T = float(m.group(1))
            except ValueError:
                T = float("nan")
            if np.isfinite(T) and T > 0:
                return "Sa", T, IM_UNITS["Sa"]
    raise ParameterError(f"im must be 'PGA', 'PGV', 'PGD', 'Sa(T)' with a period T > 0 in "
                         f"seconds such as 'Sa(1.0)', or 'scale', got {im!r}", param="im")


def im_label(name, period):
    return f"Sa({period:g} s)" if name == "Sa" else name


def record_im(record, name, period=None) -> float:
    """The intensity measure of one record at scale 1 (its GroundMotion scale applied):
    PGA and Sa(T, 5 %) in g, PGV [m/s], PGD [m], 1 for "scale"."""
    if name == "scale":
        return 1.0
    if name == "PGA":
        return pga(record) / G_STANDARD
    if name == "PGV":
        return pgv(record)
    if name == "PGD":
        return pgd(record)
    return float(spectral_acceleration(record, [period])[0]) / G_STANDARD


def parse_limit(limit):
    """(kind, threshold or None) of a limit state: "overturned", ("uplift", metres),
    ("rotation", radians), or the text "uplift=0.01" / "rotation=0.02"."""
    msg = ("limit must be 'overturned', ('uplift', threshold in m) or ('rotation', threshold "
           "in rad) (as text: 'uplift=0.01', 'rotation=0.02')")
    if isinstance(limit, str):
        text = limit.strip().lower()
        if text == "overturned":
            return "overturned", None
        if "=" not in text:
            raise ParameterError(f"{msg}, got {limit!r}", param="limit")
        limit = tuple(p.strip() for p in text.split("=", 1))
    if not isinstance(limit, (tuple, list)) or len(limit) != 2 or limit[0] not in (
            "uplift", "rotation"):
        raise ParameterError(f"{msg}, got {limit!r}", param="limit")
    try:
        thr = float(limit[1])
    except (TypeError, ValueError):
        raise ParameterError(f"limit: the {limit[0]} threshold must be a number, got "
                             f"{limit[1]!r}", param="limit") from None
    if not (np.isfinite(thr) and thr > 0):
        raise ParameterError(f"limit: the {limit[0]} threshold must be positive and finite, "
                             f"got {limit[1]!r}", param="limit")
    return limit[0], thr


def limit_label(kind, threshold):
    unit = {"uplift": "m", "rotation": "rad"}
    return "overturned" if kind == "overturned" else f"{kind} >= {threshold:g} {unit[kind]}"


def peak_theta(result: SweepResult) -> np.ndarray:
    """|θ(peak |u|)| [rad] of every run (n_records, n_scales), by the model's uplift
    mapping (`rockjax.theta_from_u`; rigid for `housner`), whatever the run's status."""
    m = get_model(result.model, result.impact)
    theta = (m.theta_uplift_of_u(result.structure, jnp.asarray(result.peak_u))[0]
             if m.kinematics_of_u else theta_from_u(result.structure, result.peak_u))
    return np.abs(np.asarray(theta, float))


def exceedances(result: SweepResult, kind, threshold=None) -> np.ndarray:
    """Whether each run (n_records, n_scales) reached the limit state: overturned, or peak
    uplift >= threshold [m], or peak rotation θ(peak |u|) >= threshold [rad] (the model's
    uplift mapping, `rockjax.theta_from_u`; rigid for `housner`). An overturned run
    exceeds every limit."""
    over = result.status == STATUS["overturned"]
    if kind == "overturned":
        return over
    if kind == "uplift":
        return over | (result.peak_uplift >= threshold)
    return over | (peak_theta(result) >= threshold)


# ------------------------------------------------------------------------------ the fit
def _loglik(p, lx, y, w):
    """ln L of (a, b) = p: z = a + b lx, exceedance y with probability Φ(z), weights w."""
    z = p[0] + p[1] * lx
    return jnp.sum(w * norm.logcdf(jnp.where(y, z, -z)))


def _derivatives(p, lx, y, w):
    r"""ln L, its gradient and Hessian in (a, b): with $s_i = \pm 1$ (exceeded or not),
    $t_i = s_i z_i$ and $\lambda_i = \varphi(z_i)/\Phi(t_i)$, $\partial \ln L/\partial z_i =
    w_i s_i \lambda_i$ and $\partial^2 \ln L/\partial z_i^2 = -w_i\lambda_i(t_i + \lambda_i)$."""
    z = p[0] + p[1] * lx
    t = jnp.where(y, z, -z)
    lc = norm.logcdf(t)
    lam = jnp.exp(norm.logpdf(z) - lc)
    d1 = w * jnp.where(y, lam, -lam)
    d2 = -w * lam * (t + lam)
    g = jnp.stack([jnp.sum(d1), jnp.sum(d1 * lx)])
    h01 = jnp.sum(d2 * lx)
    H = jnp.stack([jnp.stack([jnp.sum(d2), h01]), jnp.stack([h01, jnp.sum(d2 * lx**2)])])
    return jnp.sum(w * lc), g, H


def _newton(lx, y, w):
    """The maximum of `_loglik` over (a, b), b > 0, from (0, 1) (lx centred and scaled):
    Newton steps (a gradient step where H is not negative definite), each halved until
    ln L does not fall; until |∂ ln L| <= `_GRAD_TOL` Σw or `_NEWTON_ITERATIONS`.
    Returns ((a, b), ln L, max |∂ ln L|)."""
    tol = _GRAD_TOL * jnp.maximum(jnp.sum(w), 1.0)

    def search(p, ll, d):
        def cond(c):
            t, q, v = c
            return (t > 1e-6) & ~((q[1] > 0) & (v >= ll))

        def body(c):
            t = c[0] / 2
            q = p + t * d
            return t, q, _loglik(q, lx, y, w)

        q = p + d
        _, q, v = jax.lax.while_loop(cond, body, (jnp.ones((), lx.dtype), q, _loglik(q, lx, y, w)))
        ok = (q[1] > 0) & (v >= ll)
        return jnp.where(ok, q, p)

    def cond(c):
        k, p, ll, g, H = c
        return (k < _NEWTON_ITERATIONS) & (jnp.max(jnp.abs(g)) > tol)

    def body(c):
        k, p, ll, g, H = c
        d = jnp.linalg.solve(H, -g)
        d = jnp.where(jnp.all(jnp.isfinite(d)) & (d @ g > 0), d, g)
        p = search(p, ll, d)
        return (k + 1, p, *_derivatives(p, lx, y, w))

    p0 = jnp.array([0.0, 1.0], lx.dtype)
    _, p, ll, g, _ = jax.lax.while_loop(cond, body, (0, p0, *_derivatives(p0, lx, y, w)))
    return p, ll, jnp.max(jnp.abs(g))


#: `_newton` for each row of a weight matrix (the fit and the bootstrap resamples) and of
#: exceedances (the fits of `rockjax.fragility_band`, one per posterior draw)
_newton_rows = jax.jit(jax.vmap(_newton, in_axes=(None, 0, 0)))


def _fit_rows(lx, y, W):
    """(ln θ, β, outcome, ln L) for each row of weights W (n_rows, n_runs) on the runs'
    ln IM `lx` and exceedances `y` (n_runs,), or one row of exceedances per row of W
    (n_rows, n_runs). Outcomes: a fit; separated (β = 0, θ at the middle of the gap in
    ln IM); none / all exceeded (θ = +inf / 0, β NaN); not converged (NaN)."""
    W = np.asarray(W, float)
    y = np.broadcast_to(np.asarray(y, bool), W.shape)
    has = W > 0
    n_exc, n_surv = (W * y).sum(1), (W * ~y).sum(1)
    hi_surv = np.where(has & ~y, lx, -np.inf).max(1)
    lo_exc = np.where(has & y, lx, np.inf).min(1)
    outcome = np.full(len(W), _FIT)
    outcome[hi_surv <= lo_exc] = _SEPARATED
    outcome[n_exc == 0] = _NONE
    outcome[n_surv == 0] = _ALL
    m, sd = float(np.mean(lx)), float(np.std(lx))
    sd = sd if sd > 0 else 1.0
    rows = outcome == _FIT
    p, ll, g = np.full((len(W), 2), np.nan), np.full(len(W), np.nan), np.zeros(len(W))
    if rows.any():  # Newton on every row, those without a finite maximum given a fit's weights
        Wn = np.where(rows[:, None], W, W[np.argmax(rows)])
        Yn = np.where(rows[:, None], y, y[np.argmax(rows)])
        n = -(-lx.size // _PAD) * _PAD  # runs padded with zero weight: fewer compilations
        pad = (0, n - lx.size)
        out = _newton_rows(jnp.asarray(np.pad((lx - m) / sd, pad)),
                           jnp.asarray(np.pad(Yn, ((0, 0), pad))),
                           jnp.asarray(np.pad(Wn, ((0, 0), pad))))
        p[rows], ll[rows], g[rows] = (np.asarray(v)[rows] for v in out)
    converged = g <= _GRAD_TOL * np.maximum(W.sum(1), 1.0)
    outcome[rows & ~converged] = _NOT_CONVERGED
    with np.errstate(divide="ignore", invalid="ignore"):
        beta = sd / p[:, 1]
        ln_theta = m - p[:, 0] * beta
    fit = outcome == _FIT
    sep = outcome == _SEPARATED
    ln_theta = np.where(fit, ln_theta, np.where(sep, (hi_surv + lo_exc) / 2, np.nan))
    ln_theta[outcome == _NONE], ln_theta[outcome == _ALL] = np.inf, -np.inf
    beta = np.where(fit, beta, np.where(sep, 0.0, np.nan))
    ll = np.where(fit, ll, np.nan)
    ll[sep] = [_separated_loglik(lx, yr, w, t) for yr, w, t in zip(y[sep], W[sep], ln_theta[sep])]
    return ln_theta, beta, outcome, ll


def _separated_loglik(lx, y, w, ln_theta):
    """The supremum of ln L of separated data (β -> 0): only the runs tied at θ count, at
    the fraction of them that exceeded."""
    tie = (w > 0) & (lx == ln_theta)
    ne, ns = float(np.sum(w[tie] * y[tie])), float(np.sum(w[tie] * ~y[tie]))
    if ne == 0 or ns == 0:
        return 0.0
    p = ne / (ne + ns)
    return ne * np.log(p) + ns * np.log1p(-p)


def _probability(ln_theta, beta, ln_x):
    """Φ(ln(x/θ)/β) for rows (ln θ, β) against ln x: a step (½ at θ) where β = 0; 0 where
    θ = +inf, 1 where θ = 0; NaN where ln θ is NaN."""
    ln_theta = np.asarray(ln_theta, float)[..., None]
    beta = np.asarray(beta, float)[..., None]
    with np.errstate(invalid="ignore", divide="ignore"):
        z = (ln_x - ln_theta) / np.where(beta > 0, beta, 1.0)
    p = np.asarray(norm.cdf(jnp.asarray(np.nan_to_num(z, nan=0.0, posinf=np.inf))))
    p = np.where(np.isinf(ln_theta), (ln_theta < 0).astype(float), p)
    step = np.where(ln_x > ln_theta, 1.0, np.where(ln_x == ln_theta, 0.5, 0.0))
    p = np.where((beta == 0) & np.isfinite(ln_theta), step, p)
    return np.where(np.isnan(ln_theta), np.nan, p)


def _bootstrap_weights(rec_of_run, n_records, n_boot, rng):
    """(weights (n_boot, n_runs), what was resampled): the records drawn with replacement
    (each run weighted by its record's count), or the runs when there is one record."""
    unit = "records" if n_records >= 2 else "runs"
    n = n_records if unit == "records" else rec_of_run.size
    draws = rng.integers(0, n, size=(n_boot, n))
    counts = np.zeros((n_boot, n))
    np.add.at(counts, (np.arange(n_boot)[:, None], draws), 1.0)
    return (counts[:, rec_of_run] if unit == "records" else counts), unit


#: standard normal quantiles of P = 10, 50 and 90 % (`FragilityResult.report`)
_Z_10_50_90 = (-1.2815515655446004, 0.0, 1.2815515655446004)


# ----------------------------------------------------------------------------- result
@dataclasses.dataclass(frozen=True, eq=False)
class FragilityResult:
    r"""A lognormal fragility curve $P(\text{limit} \mid x) = \Phi(\ln(x/\theta)/\beta)$
    fitted by maximum likelihood (`rockjax.fragility`, docs/fragility.md).

    - `im` (e.g. "PGA", "Sa(1 s)"), `im_unit` ("g" for PGA and Sa, "m/s" for PGV, "m" for
      PGD, "-" for the scale factor), `limit` (e.g. "overturned", "uplift >= 0.01 m").
    - `median` θ [im_unit] and `beta` β (dimensionless), `log_likelihood` at them;
      `separated`: the data are separated by the IM (β = 0, a step at θ; module docs).
    - Per run, arrays (n_records, n_scales): `im_values` [im_unit], `exceeded`, `used`
      (completed or overturned: the runs fitted), `status`; `records` (labels), `scales`.
    - The bootstrap: `n_bootstrap` resamples of `resampled` ("records", with replacement;
      "runs" when there is one record; "none" for n_bootstrap = 0) at `seed`, each refitted.
      `grid` [im_unit] and `band` (2, n_grid): the pointwise (1 ± `confidence`)/2
      quantiles of the resampled curves (None without resamples). `median_ci`, `beta_ci`:
      the same quantiles of θ and β over the resamples with a curve of finite θ.
      `bootstrap_counts`: resamples per outcome: "fit", "separated" (β = 0: a step, in the
      band and the intervals), "none exceeded" / "all exceeded" (curves ≡ 0 / ≡ 1: in the
      band only), "not converged" (left out). `bootstrap_median`, `bootstrap_beta`: θ and
      β of the resamples in the intervals.
    """

    im: str
    im_unit: str
    limit: str
    median: float
    beta: float
    log_likelihood: float
    separated: bool
    im_values: np.ndarray
    exceeded: np.ndarray
    used: np.ndarray
    status: np.ndarray
    records: tuple
    scales: np.ndarray
    model: str
    confidence: float
    n_bootstrap: int
    seed: int | None
    resampled: str
    grid: np.ndarray
    band: np.ndarray | None
    median_ci: tuple | None
    beta_ci: tuple | None
    bootstrap_counts: dict
    bootstrap_median: np.ndarray
    bootstrap_beta: np.ndarray

    def __repr__(self):
        beta = "0 (separated)" if self.separated else f"{self.beta:.4g}"
        return (f"FragilityResult(P({self.limit} | {self.im}): median {self.median:.4g} "
                f"{self.im_unit}, beta {beta}; {self.n_used} runs used, {self.n_exceeded} "
                f"reached the limit, failed {self.n_failed})")

    @property
    def n_runs(self) -> int:
        return int(self.status.size)

    @property
    def n_used(self) -> int:
        return int(self.used.sum())

    @property
    def n_exceeded(self) -> int:
        return int((self.exceeded & self.used).sum())

    @property
    def n_failed(self) -> dict[str, int]:
        """Failed runs left out of the fit, by status name (max_impacts, solver_failure)."""
        return {name: int(np.sum(self.status == STATUS[name])) for name in FAILED}

    def probability(self, im):
        """P(limit | im) = Φ(ln(im/θ)/β) at `im` [im_unit] (a step where β = 0); an array
        of the shape of `im`, a float for a scalar."""
        x = np.asarray(im, float)
        if np.any(~np.isfinite(x) | (x < 0)):
            raise ParameterError(f"im must be finite numbers >= 0 [{self.im_unit}], got {im!r}",
                                 param="im")
        with np.errstate(divide="ignore"):
            p = _probability(np.log(self.median), self.beta, np.log(x).reshape(-1))
        p = p.reshape(x.shape)
        return float(p) if p.ndim == 0 else p

    def to_dict(self) -> dict:
        """Plain Python values for JSON (per-run arrays as nested lists, record-major)."""
        def opt(v):
            return None if v is None else [float(t) for t in v]

        band = None if self.band is None else {
            "im": self.grid.tolist(), "lower": self.band[0].tolist(),
            "upper": self.band[1].tolist(), "probability": self.probability(self.grid).tolist()}
        return {
            "im": self.im, "im_unit": self.im_unit, "limit": self.limit, "model": self.model,
            "median": self.median, "beta": self.beta, "log_likelihood": self.log_likelihood,
            "separated": self.separated, "n_runs": self.n_runs, "n_used": self.n_used,
            "n_exceeded": self.n_exceeded, "n_failed": self.n_failed,
            "confidence": self.confidence, "n_bootstrap": self.n_bootstrap, "seed": self.seed,
            "resampled": self.resampled, "median_ci": opt(self.median_ci),
            "beta_ci": opt(self.beta_ci), "bootstrap_counts": dict(self.bootstrap_counts),
            "band": band, "records": list(self.records), "scales": self.scales.tolist(),
            "im_values": self.im_values.tolist(), "exceeded": self.exceeded.tolist(),
            "used": self.used.tolist(),
            "status": [[STATUS_NAMES[int(c)] for c in row] for row in self.status],
        }

    def report(self) -> str:
        """The fit as text: the model fitted and the runs it used, `median` and `beta` with
        their bootstrap intervals, the IM at P = 10, 50 and 90 % and the resamples.

        ```python
        status = np.array([[0, 0, 1, 1], [0, 1, 0, 1], [0, 0, 0, 1]])  # 0 completed, 1 overturned
        z = np.zeros(status.shape)  # 3 records x 4 scales; the peaks do not enter this fit
        res = rockjax.SweepResult(rockjax.mcmanus_column(), records=[None] * 3,
                                  labels=["a", "b", "c"], scales=[0.5, 1, 2, 4], peak_u=z,
                                  peak_uplift=z, n_impacts=z, status=status, t_overturn=z,
                                  t_end=z)
        print(rockjax.fragility(res, im="scale", n_bootstrap=20).report())
        ```
        """
        def interval(ci, unit=""):
            return "" if ci is None else (f"  ({self.confidence:.0%} interval {ci[0]:.4g} to "
                                          f"{ci[1]:.4g}{unit})")

        failed = {k: v for k, v in self.n_failed.items() if v}
        left = ", ".join(f"{k} {v}" for k, v in failed.items())
        unit = f" {self.im_unit}" if self.im_unit != "-" else ""
        beta = "0 (separated: a step at the median)" if self.separated else f"{self.beta:.4g}"
        at = ", ".join(f"{self.median * np.exp(self.beta * z):.4g}" for z in _Z_10_50_90)
        lines = [f"fit           P({self.limit} | {self.im}) = Phi(ln({self.im}/median)/beta), "
                 f"maximum likelihood over the {self.n_used} runs that completed or overturned "
                 f"({self.n_exceeded} reached the limit); "
                 + (f"{sum(failed.values())} failed runs left out ({left})" if failed else
                    "no failed runs"),
                 f"median        {self.median:.4g}{unit}{interval(self.median_ci, unit)}",
                 f"beta          {beta}{interval(self.beta_ci)}",
                 f"quantiles     {self.im} at P = 10, 50, 90 %: {at}{unit}"]
        if self.n_bootstrap:
            kinds = ", ".join(f"{k} {v}" for k, v in self.bootstrap_counts.items() if v)
            lines.append(f"bootstrap     {self.n_bootstrap} resamples of the {self.resampled} "
                         f"(seed {self.seed}): {kinds}")
        return "\n".join(lines)

    def plot(self, ax=None):
        """The fitted curve, the bootstrap band, the observed fractions (at each scale for
        im="scale", else in bins of ln IM, marker area ∝ runs) and every run used (at 0 or
        1) against the IM (matplotlib; returns the axes)."""
        return _plot(self, ax)


# -------------------------------------------------------------------------- fragility
def _check_fit_args(sweep_result, n_bootstrap, confidence, seed, grid):
    if not isinstance(sweep_result, SweepResult):
        raise TypeError(f"sweep_result must be a rockjax.SweepResult (from rockjax.sweep), "
                        f"got {type(sweep_result).__name__}")
    if isinstance(n_bootstrap, bool) or not isinstance(n_bootstrap, (int, np.integer)) or (
            n_bootstrap < 0):
        raise ParameterError(f"n_bootstrap must be an integer >= 0, got {n_bootstrap!r}",
                             param="n_bootstrap")
    if not (isinstance(confidence, (int, float, np.floating)) and 0 < confidence < 1):
        raise ParameterError(f"confidence must lie in (0, 1), e.g. 0.9, got {confidence!r}",
                             param="confidence")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))):
        raise ParameterError(f"seed must be an integer or None, got {seed!r}", param="seed")
    if grid is not None:
        g = np.asarray(grid, float)
        if g.ndim != 1 or g.size < 2 or not np.all(np.isfinite(g)) or np.any(g <= 0):
            raise ParameterError(
                f"grid must be a 1-D array of >= 2 positive IM values, got {grid!r}", param="grid")


def _degenerate(x, y, name, unit, limit):
    """The error for data with no exceedance or no survivor (else None)."""
    n = x.size
    if not y.any():
        return (f"no run reached the limit ({limit}) among the {n} runs used, up to {name} = "
                f"{x.max():.4g} {unit}: the median lies above the data; raise the scales")
    if y.all():
        return (f"every one of the {n} runs used reached the limit ({limit}), down to {name} "
                f"= {x.min():.4g} {unit}: the median lies below the data; lower the scales")
    return None


def _check_data(x, y, name, unit, limit, status):
    """A ValueError for data without a fit: no run used, no exceedance or no survivor."""
    if x.size == 0:
        failed = {n: int(np.sum(status == STATUS[n])) for n in FAILED}
        raise ParameterError(f"sweep_result: no run completed or overturned ({failed}); nothing "
                             "to fit", param="sweep_result")
    msg = _degenerate(x, y, name, unit, limit)
    if msg:
        raise ParameterError(msg, param="scales")


def _main_fit(ln_theta, outcome, name, unit, limit):
    """Whether the fit (row 0) is separated (warned); a ValueError if it has no maximum."""
    if outcome == _NOT_CONVERGED:
        raise ValueError(f"the likelihood has no maximum at a finite β: the fraction "
                         f"reaching the limit ({limit}) does not grow with {name}")
    if outcome == _SEPARATED:
        warnings.warn(f"the runs are separated by {name}: every run that reached the limit "
                      f"({limit}) has {name} >= every run that did not; the likelihood's "
                      f"supremum is β -> 0 (a step at the median, {np.exp(ln_theta):.4g} "
                      f"{unit}): add scales between", RuntimeWarning, stacklevel=3)
    return bool(outcome == _SEPARATED)


def _bootstrap(ln_theta, beta, outcome, lgrid, confidence):
    """The band, the intervals of θ and β, the outcome counts and the θ and β in the
    intervals, of the resamples' fits (`FragilityResult`)."""
    counts = {name: int(np.sum(outcome == k)) for k, name in enumerate(_OUTCOMES)}
    q = [(1 - confidence) / 2, (1 + confidence) / 2]
    curves = _probability(ln_theta, beta, lgrid)[outcome != _NOT_CONVERGED]
    band = np.quantile(curves, q, axis=0) if len(curves) else None
    finite = (outcome == _FIT) | (outcome == _SEPARATED)
    th, be = np.exp(ln_theta[finite]), beta[finite]
    med_ci = tuple(float(v) for v in np.quantile(th, q)) if th.size else None
    beta_ci = tuple(float(v) for v in np.quantile(be, q)) if th.size else None
    return band, med_ci, beta_ci, counts, th, be


def fragility(sweep_result, im="PGA", limit="overturned", *, n_bootstrap=1000,
              confidence=0.9, seed=0, grid=None) -> FragilityResult:
    r"""A lognormal fragility curve fitted by maximum likelihood to a `rockjax.sweep`.

    Every run that completed or overturned is a Bernoulli trial at its intensity measure
    $x_i$ = the scale times its record's IM; $(\theta, \beta)$ maximise
    $\ln L = \sum_i y_i\ln\Phi(z_i) + (1-y_i)\ln\Phi(-z_i)$, $z_i = \ln(x_i/\theta)/\beta$
    (module docs). Runs that ended as max_impacts or solver_failure are left out and
    counted (`FragilityResult.n_failed`).

    **Arguments:**

    - `sweep_result`: a `rockjax.SweepResult`.
    - `im`: "PGA" [g], "PGV" [m/s], "PGD" [m] (`rockjax.pga`, `pgv`, `pgd` of each record),
      "Sa(T)" [g], 5 %-damped pseudo-spectral acceleration at the period T [s] (e.g.
      "Sa(1.0)"), or "scale" (the scale factor itself).
    - `limit`: "overturned" (default), ("uplift", m) the peak corner uplift reaching a
      threshold, or ("rotation", rad) the peak rotation θ(peak |u|) reaching one (also as
      text "uplift=0.01", "rotation=0.02"). An overturned run exceeds every limit.
    - `n_bootstrap` resamples (default 1000; 0: no band) of the records, with replacement
      (the runs of one record are correlated), each refitted; `confidence` (default 0.9)
      of the pointwise band and intervals; `seed` of the resampling.
    - `grid` [IM units]: where the band is evaluated (default 200 points from half the
      smallest IM used to 1.5 times the largest).

    **Returns:** a `FragilityResult`. Errors: no run completed or overturned; no run (or
    every run) reached the limit. Separated data give β = 0 with a RuntimeWarning.
    """
    ensure_x64()
    _check_fit_args(sweep_result, n_bootstrap, confidence, seed, grid)
    name, period, unit = parse_im(im)
    kind, threshold = parse_limit(limit)
    res, label, lim = sweep_result, im_label(name, period), limit_label(kind, threshold)
    base = np.array([record_im(r, name, period) for r in res.records])
    bad = [lab for lab, v in zip(res.labels, base) if not (np.isfinite(v) and v > 0)]
    if bad:
        raise ParameterError(f"im: {label} is zero for record(s) {', '.join(bad)}", param="im")
    x = base[:, None] * res.scales[None, :]
    y = exceedances(res, kind, threshold)
    used = np.isin(res.status, USABLE)
    xu, yu = x[used], y[used]
    _check_data(xu, yu, label, unit, lim, res.status)
    rec = np.broadcast_to(np.arange(res.n_records)[:, None], x.shape)[used]
    W, resampled = _bootstrap_weights(rec, res.n_records, int(n_bootstrap),
                                      np.random.default_rng(seed))
    ln_th, beta, outcome, ll = _fit_rows(np.log(xu), yu, np.vstack([np.ones(xu.size), W]))
    separated = _main_fit(ln_th[0], outcome[0], label, unit, lim)
    g = (np.geomspace(xu.min() / 2, xu.max() * 1.5, 200) if grid is None
         else np.asarray(grid, float))
    band, med_ci, beta_ci, counts, th, be = _bootstrap(ln_th[1:], beta[1:], outcome[1:],
                                                       np.log(g), float(confidence))
    return FragilityResult(
        im=label, im_unit=unit, limit=lim, median=float(np.exp(ln_th[0])),
        beta=float(beta[0]), log_likelihood=float(ll[0]), separated=separated, im_values=x,
        exceeded=y, used=used, status=res.status, records=res.labels, scales=res.scales,
        model=res.model_name, confidence=float(confidence), n_bootstrap=int(n_bootstrap),
        seed=seed, resampled=resampled if n_bootstrap else "none", grid=g, band=band,
        median_ci=med_ci, beta_ci=beta_ci, bootstrap_counts=counts, bootstrap_median=th,
        bootstrap_beta=be)


# ------------------------------------------------------------------------------- plot
def _binned(x, y, n_bins):
    """(geometric-mean IM, fraction exceeded, runs) per non-empty bin of equal ln width."""
    edges = np.geomspace(x.min(), x.max() * (1 + 1e-12), n_bins + 1)
    k = np.clip(np.digitize(x, edges) - 1, 0, n_bins - 1)
    out = [(np.exp(np.mean(np.log(x[k == i]))), y[k == i].mean(), int(np.sum(k == i)))
           for i in range(n_bins) if np.any(k == i)]
    return tuple(np.array(v) for v in zip(*out))


def _plot(r, ax=None):
    """`FragilityResult.plot`."""
    if ax is None:
        from ._plotting import new_figure

        ax = new_figure(figsize=(6.5, 4.5), layout="constrained").subplots()
    x, y = r.im_values[r.used], r.exceeded[r.used]
    g = np.geomspace(min(x.min(), r.grid.min()), max(x.max(), r.grid.max()), 400)
    if r.band is not None:
        ax.fill_between(r.grid, r.band[0], r.band[1], color="C0", alpha=0.25, lw=0,
                        label=f"{r.confidence:.0%} bootstrap band ({r.n_bootstrap} "
                        f"resamples of the {r.resampled})")
    beta = "0 (separated)" if r.separated else f"{r.beta:.3g}"
    ax.plot(g, r.probability(g), color="C0", lw=2,
            label=f"lognormal MLE: median {r.median:.4g} {r.im_unit}, β {beta}")
    ax.axvline(r.median, color="C0", ls=":", lw=1)
    if r.im == "scale":
        xs = np.unique(x)
        fr = np.array([y[x == v].mean() for v in xs])
        n = np.array([np.sum(x == v) for v in xs])
        what = "fraction at each scale"
    else:
        xs, fr, n = _binned(x, y, int(np.clip(x.size // 8, 4, 12)))
        what = "fraction in bins of ln IM"
    ax.scatter(xs, fr, s=12 + 60 * n / n.max(), color="k", zorder=3, label=what)
    ax.plot(x, np.where(y, 1.02, -0.02), "|", color="0.4", alpha=0.5, ms=8,
            label=f"runs used ({r.n_used}; {sum(r.n_failed.values())} failed left out)")
    ax.set_ylim(-0.05, 1.05)
    ax.set_xlabel(f"{r.im} [{r.im_unit}]" if r.im_unit != "-" else "scale factor")
    ax.set_ylabel(f"P({r.limit} | {r.im})")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="lower right")
    return ax
