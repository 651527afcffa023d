r"""Fidelity as a distribution: models of the ladder compared over an ensemble of ground
motions, the way the field compares rocking models (issue 27).

Near the onset of rocking a single history is very sensitive: two equally valid contact
models of the same 2-DOF body differ by a median 16 % in peak response, history by history
(`benchmarks/fidelity.md`), and shake-table studies found the same for real blocks
(Bachmann et al. 2018, "Is rocking motion predictable?"). A rocking model is judged by the
*distribution* of its response over an ensemble of motions and by the fragility it
predicts. `compare_models` runs every model on the same records and scales
(`rockjax.sweep`) and returns, against a reference model:

- the quantiles of the peak rotation $\theta_{peak}$ [rad] at each scale (an overturned run
  counts as $+\infty$: it lies above every finite peak; a failed run is left out);
- the two-sample Kolmogorov–Smirnov distance between the model's and the reference's peak
  rotations at each scale, $D = \sup_x |F_m(x) - F_{ref}(x)|$ (`ks_distance`), with its
  asymptotic p-value;
- a lognormal fragility curve of each model for each limit state (`rockjax.fragility`: the
  median $\theta$ and dispersion $\beta$ by maximum likelihood, with intervals from
  resampling the records), and each model's median ratio and $\beta$ difference to the
  reference's.
"""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np

from ._errors import ParameterError
from ._fragility import fragility, FragilityResult, limit_label, parse_limit, peak_theta
from ._status import STATUS
from ._sweep import sweep, SweepResult

__all__ = ["compare_models", "ModelComparison", "ks_distance"]


def ks_distance(a, b) -> tuple[float, float]:
    r"""The two-sample Kolmogorov–Smirnov distance $D = \sup_x |F_a(x) - F_b(x)|$ of the
    samples `a` and `b` (NaNs left out; $\pm\infty$ allowed: an overturned run's peak), and
    its asymptotic p-value $Q_{KS}(\sqrt{n_e}\,D)$, $n_e = n_a n_b / (n_a + n_b)$,
    $Q_{KS}(\lambda) = 2\sum_{k\ge1} (-1)^{k-1} e^{-2k^2\lambda^2}$ (Kolmogorov's limit
    distribution; conservative for a few tens of runs). Returns (nan, nan) when either
    sample is empty."""
    a = np.asarray(a, float).ravel()
    b = np.asarray(b, float).ravel()
    a, b = np.sort(a[~np.isnan(a)]), np.sort(b[~np.isnan(b)])
    if a.size == 0 or b.size == 0:
        return float("nan"), float("nan")
    x = np.concatenate([a, b])
    fa = np.searchsorted(a, x, side="right") / a.size
    fb = np.searchsorted(b, x, side="right") / b.size
    d = float(np.max(np.abs(fa - fb)))
    lam = math.sqrt(a.size * b.size / (a.size + b.size)) * d
    if lam < 1e-3:
        return d, 1.0
    k = np.arange(1, 101)
    p = float(2 * np.sum((-1.0) ** (k - 1) * np.exp(-2 * k**2 * lam**2)))
    return d, min(max(p, 0.0), 1.0)


def peak_rotation(result: SweepResult) -> np.ndarray:
    """The peak rotation [rad] of every run of a sweep (n_records, n_scales): θ(peak |u|)
    by the model's uplift mapping (`rockjax.theta_from_u`; rigid for `housner`), +inf for
    an overturned run, NaN for a run that failed (max_impacts, solver_failure)."""
    theta = np.where(result.status == STATUS["overturned"], np.inf, peak_theta(result))
    ok = np.isin(result.status, (STATUS["completed"], STATUS["overturned"]))
    return np.where(ok, theta, np.nan)


@dataclasses.dataclass(frozen=True)
class ModelComparison:
    r"""Models compared over an ensemble (`rockjax.compare_models`).

    - `labels`: the models' labels, the reference first; `models`: label -> model;
      `records` (labels), `scales` (n_scales,), `limits` (labels such as "overturned",
      "uplift >= 0.01 m"), `im` of the fragility curves, `quantile_levels`.
    - `sweeps`: label -> `rockjax.SweepResult`; `peak_theta`: label -> (n_records,
      n_scales) peak rotation [rad] (`peak_rotation`: +inf overturned, NaN failed).
    - `quantiles`: label -> (n_levels, n_scales) quantiles of the peak rotation at each
      scale [rad] (+inf where more than that share overturned).
    - `ks`: label -> (n_scales,) KS distance to the reference at each scale; `ks_p`: their
      asymptotic p-values (`ks_distance`); NaN for the reference itself.
    - `fragility`: label -> limit -> `rockjax.FragilityResult`, or the reason (text) why
      no curve could be fitted (no run reached the limit, say).
    """

    labels: tuple
    models: dict
    records: tuple
    scales: np.ndarray
    limits: tuple
    im: str
    quantile_levels: tuple
    sweeps: dict
    peak_theta: dict
    quantiles: dict
    ks: dict
    ks_p: dict
    fragility: dict

    @property
    def reference(self) -> str:
        """The reference model's label (the first)."""
        return self.labels[0]

    def rows(self) -> list[dict]:
        """One row per model and limit: `median` [im units] and `median_ci`, `beta` and
        `beta_ci`, `median_ratio` (to the reference's median) and `beta_diff` (model less
        reference), `ks_max` (the largest KS distance over the scales) and `ks_scale` (where),
        `failed` runs; `fit` None, or the reason no curve was fitted."""
        out = []
        for lab in self.labels:
            ks = self.ks[lab]
            j = int(np.nanargmax(ks)) if np.any(np.isfinite(ks)) else None
            failed = int(np.sum(np.isnan(self.peak_theta[lab])))
            for lim in self.limits:
                f, ref = self.fragility[lab][lim], self.fragility[self.reference][lim]
                row = {"model": lab, "limit": lim, "failed": failed,
                       "ks_max": None if j is None else float(ks[j]),
                       "ks_scale": None if j is None else float(self.scales[j])}
                if isinstance(f, FragilityResult):
                    row.update(median=f.median, median_ci=_ci(f.median_ci), beta=f.beta,
                               beta_ci=_ci(f.beta_ci), fit=None)
                    if isinstance(ref, FragilityResult):
                        row.update(median_ratio=f.median / ref.median,
                                   beta_diff=f.beta - ref.beta)
                else:
                    row["fit"] = f
                out.append(row)
        return out

    def to_dict(self) -> dict:
        """Plain data (JSON-ready): the rows, the quantiles and KS distances per scale."""
        def fin(a):
            return [None if not np.isfinite(v) else float(v) for v in np.ravel(a)]

        return {"reference": self.reference, "labels": list(self.labels),
                "records": list(self.records), "scales": fin(self.scales),
                "im": self.im, "limits": list(self.limits),
                "quantile_levels": list(self.quantile_levels),
                "quantiles_rad": {k: [fin(q) for q in v] for k, v in self.quantiles.items()},
                "overturned_share": {k: fin(np.mean(np.isposinf(v), axis=0))
                                     for k, v in self.peak_theta.items()},
                "ks": {k: fin(v) for k, v in self.ks.items()},
                "ks_p": {k: fin(v) for k, v in self.ks_p.items()},
                "rows": self.rows()}

    def report(self) -> str:
        """The comparison as text: per model and limit, the fragility median and β with
        their intervals, the ratio and difference to the reference, the largest KS
        distance."""
        lines = [f"{len(self.records)} records x {len(self.scales)} scales "
                 f"({self.scales.min():g}-{self.scales.max():g}); reference: {self.reference};"
                 f" fragility IM {self.im}",
                 f"{'model':<34} {'limit':<22} {'median':>9} {'90 % interval':>21} "
                 f"{'ratio':>6} {'beta':>6} {'interval':>13} {'d beta':>7} {'KS max':>7}"]
        for r in self.rows():
            if r["fit"] is not None:
                lines.append(f"{r['model']:<34} {r['limit']:<22} no curve: {r['fit']}")
                continue
            ci = r["median_ci"] or (float("nan"),) * 2
            bci = r["beta_ci"] or (float("nan"),) * 2
            ratio = r.get("median_ratio", float("nan"))
            db = r.get("beta_diff", float("nan"))
            ks = float("nan") if r["ks_max"] is None else r["ks_max"]
            lines.append(f"{r['model']:<34} {r['limit']:<22} {r['median']:9.4g} "
                         f"[{ci[0]:9.4g}, {ci[1]:9.4g}] {ratio:6.3f} {r['beta']:6.3f} "
                         f"[{bci[0]:5.3f}, {bci[1]:5.3f}] {db:+7.3f} {ks:7.3f}")
        return "\n".join(lines)

    def plot(self, fig=None):
        """Two panels: the median and the band between the outer quantiles of the peak
        rotation against the scale, per model; the fragility curves of the first limit."""
        import matplotlib.pyplot as plt

        fig = fig or plt.figure(figsize=(11, 4.2))
        ax1, ax2 = fig.subplots(1, 2)
        lv = np.asarray(self.quantile_levels)
        mid, lo, hi = (int(np.argmin(np.abs(lv - 0.5))), int(np.argmin(lv)),
                       int(np.argmax(lv)))
        qs = np.stack([np.asarray(self.quantiles[lab]) for lab in self.labels])
        top = np.nanmax(np.where(np.isfinite(qs), qs, np.nan)) if np.any(
            np.isfinite(qs)) else 1.0
        cap = 1.15 * top  # an overturned run is drawn here, one line for every model
        for lab, q in zip(self.labels, qs):
            (ln,) = ax1.plot(self.scales, np.minimum(q[mid], cap), label=lab)
            ax1.fill_between(self.scales, np.minimum(q[lo], cap), np.minimum(q[hi], cap),
                             color=ln.get_color(), alpha=0.12)
        ax1.axhline(cap, color="k", lw=0.8, ls=":")
        ax1.text(self.scales[0], cap, " overturned", va="bottom", fontsize=8)
        if self.scales.min() > 0 and self.scales.max() / self.scales.min() > 4:
            _log_axis(ax1)
        ax1.set_xlabel("scale")
        ax1.set_ylabel("peak rotation [rad]")
        ax1.set_title(f"quantiles {lv[lo]:g}, {lv[mid]:g}, {lv[hi]:g} over the records",
                      fontsize=9)
        ax1.legend(fontsize=7)
        lim = self.limits[0]
        for lab in self.labels:
            f = self.fragility[lab][lim]
            if isinstance(f, FragilityResult):
                ax2.plot(f.grid, f.probability(f.grid), label=f"{lab} (median {f.median:.3g},"
                         f" beta {f.beta:.2f})")
        if self.im == "scale" and self.scales.min() > 0 and \
                self.scales.max() / self.scales.min() > 4:
            _log_axis(ax2)
        ax2.set_xlabel(self.im)
        ax2.set_ylabel(f"P({lim})")
        ax2.legend(fontsize=7)
        fig.tight_layout()
        return fig


def _log_axis(ax):
    """A logarithmic x axis labelled at 1, 2, 5 x 10^k in plain numbers."""
    from matplotlib import ticker

    ax.set_xscale("log")
    ax.xaxis.set_major_locator(ticker.LogLocator(subs=(1.0, 2.0, 5.0)))
    ax.xaxis.set_major_formatter(ticker.FormatStrFormatter("%g"))
    ax.xaxis.set_minor_formatter(ticker.NullFormatter())


def _ci(ci):
    return None if ci is None else (float(ci[0]), float(ci[1]))


def _models(models):
    if isinstance(models, dict):
        items = list(models.items())
    else:
        items = [(m if isinstance(m, str) else type(m).__name__, m) for m in models]
    if len(items) < 2:
        raise ParameterError("models: give at least two models to compare (the reference "
                             f"first), got {len(items)}", param="models")
    labels = [str(k) for k, _ in items]
    if len(set(labels)) != len(labels):
        raise ParameterError(f"models: labels must be unique, got {labels}", param="models")
    return labels, dict(items)


def compare_models(structure, records, scales, models, *, limits=("overturned",),
                   im="scale", quantiles=(0.1, 0.5, 0.9), n_bootstrap=200, seed=0,
                   labels=None, **options) -> ModelComparison:
    r"""Compare models of the ladder over an ensemble of ground motions: the distribution
    of their peak rotation at each scale and the fragility each predicts (module docs).

    **Arguments:**

    - `structure`: one `RockingStructure`; `records`, `scales`: as `rockjax.sweep` (every
      record at every scale; a standard suite's `Suite.records`, say).
    - `models`: a dict label -> model (a name of the ladder such as "rigid_body", or a
      model object such as `rockjax.TwoSpring2DOF(contact="continuous", damping=c_f)`), or
      a sequence of names; the **first is the reference**.
    - `limits`: the limit states of the fragility curves ("overturned", "uplift=0.01"
      [m], "rotation=0.05" [rad]; `rockjax.fragility`'s `limit`).
    - `im`: the fragility curves' intensity measure (default "scale"; "PGA", "PGV",
      "Sa(1.0)", ...).
    - `quantiles`: levels of the peak-rotation quantiles; `n_bootstrap`, `seed`: the
      fragility intervals' resampling of the records (the same resamples for every model).
    - `labels`: the records' labels; `**options`: `rockjax.sweep`'s (`tail`, `t1`,
      `impact`, `substeps`, `max_impacts`, `progress`, ...), the same for every model.

    **Returns:** a `ModelComparison` (`report()`, `rows()`, `to_dict()`, `plot()`).
    """
    names, mods = _models(models)
    lims = tuple(limit_label(*parse_limit(lim)) for lim in limits)
    raw = {limit_label(*parse_limit(lim)): lim for lim in limits}
    lv = tuple(float(q) for q in quantiles)
    if not lv or not all(0.0 <= q <= 1.0 for q in lv):
        raise ParameterError(f"quantiles: levels in [0, 1], got {quantiles!r}",
                             param="quantiles")
    sweeps, peaks = {}, {}
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", module="rockjax._fidelity")
        for lab in names:
            sweeps[lab] = sweep(structure, records, scales, model=mods[lab], labels=labels,
                                **{"fidelity_warning": False, **options})
            peaks[lab] = peak_rotation(sweeps[lab])
    ref = peaks[names[0]]
    qs, ks, ksp, frag = {}, {}, {}, {}
    for lab in names:
        p = peaks[lab]
        qs[lab] = np.stack([_quantile(p[:, j], lv) for j in range(p.shape[1])], axis=1)
        pairs = [ks_distance(p[:, j], ref[:, j]) for j in range(p.shape[1])]
        ks[lab] = np.array([d for d, _ in pairs]) if lab != names[0] else np.full(
            p.shape[1], np.nan)
        ksp[lab] = np.array([q for _, q in pairs]) if lab != names[0] else np.full(
            p.shape[1], np.nan)
        frag[lab] = {}
        for lim in lims:
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)
                    frag[lab][lim] = fragility(sweeps[lab], im=im, limit=raw[lim],
                                               n_bootstrap=n_bootstrap, seed=seed)
            except ParameterError as e:
                frag[lab][lim] = str(e)
    first = sweeps[names[0]]
    return ModelComparison(labels=tuple(names), models=mods, records=tuple(first.labels),
                           scales=np.asarray(first.scales), limits=lims, im=im,
                           quantile_levels=lv, sweeps=sweeps, peak_theta=peaks, quantiles=qs,
                           ks=ks, ks_p=ksp, fragility=frag)


def _quantile(x, levels):
    """Quantiles of x with NaNs left out and +inf kept (np.quantile on the sorted finite
    and infinite values, the 'inverted_cdf' rule so that +inf is returned, not NaN)."""
    x = x[~np.isnan(x)]
    if x.size == 0:
        return np.full(len(levels), np.nan)
    return np.quantile(x, levels, method="inverted_cdf")
