r"""`fit_outcomes`: the parameters of a rocking specimen from pass/fail runs (issue 25, item 2).

The model (`identification._outcome_model`): $P(\text{topple}) = \Phi(\ln(A/A_c(T;\theta))
/\beta)$, $A_c$ rockjax's own overturning threshold of the pulse (`rockjax.overturning_spectrum`,
model `rigid_body` by default) computed once on a grid and interpolated smoothly
(`identification._outcome_grid`). The fit minimises the negative log-likelihood from a
grid of starts (BFGS with exact gradients of the interpolant); the 90 % intervals are the
Laplace approximation in the unconstrained coordinates (the inverse Hessian of the NLL at
the optimum, by central differences of the exact gradient; ±1.645 standard deviations,
mapped back: asymmetric for R and β, kept inside the grid for α, k_f, r). The baselines: a
constant and a three-parameter probit in (ln PGA, ln PGV/PGA), each with its NLL;
`OutcomeFit.cross_validate` compares their held-out log loss.
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings

import jax
import jax.numpy as jnp
import numpy as np
from scipy.optimize import minimize

from . import _outcome_baselines as _base
from ._bayes import parse_priors, PosteriorProblem, Prior
from ._outcome_grid import block_threshold_grid, structure_threshold_grid, ThresholdGrid
from ._outcome_model import BLOCK_PARAMS, PhysicsModel, STRUCTURE_PARAMS, UNITS
from ._outcome_table import G, OutcomeError, OutcomeTable, read_outcomes
from ._result import IdentifiabilityWarning

Z90 = 1.6448536269514722
_GRIDS: dict = {}  # (kind, model) -> the default block grid, built once per process
_MODELS: dict = {}  # the physics models made, by grid and setting (they keep their grid)


def _block_grid(kind, model):
    key = (kind, model)
    if key not in _GRIDS:
        _GRIDS[key] = block_threshold_grid(kind, model=model)
    return _GRIDS[key]


def _model(table, structure, free, fixed, model, grid):
    names = BLOCK_PARAMS if structure is None else STRUCTURE_PARAMS
    free = tuple(names if free is None else free)
    fixed = dict(fixed or {})
    bad = sorted(set(free) - set(names))
    if bad or not free:
        raise ValueError(f"free parameters {bad or '()'}: "
                         f"{'a block' if structure is None else 'a known structure'} has "
                         f"{', '.join(names)}", )
    if structure is not None:
        fixed.setdefault("k_f", float(structure.k_f))
        fixed.setdefault("r", float(structure.restitution))
    fixed = {n: float(v) for n, v in fixed.items() if n not in free}
    missing = [n for n in names if n not in free and n not in fixed]
    if missing:
        raise ValueError(f"parameters {missing} are neither free nor fixed: give them in "
                         "fixed={name: value}")
    if grid is None:
        grid = (_block_grid(table.kind, model) if structure is None else
                structure_threshold_grid(structure, table.kind, periods=table.period,
                                         free=[n for n in free if n != "beta"], model=model))
    if grid.kind != table.kind:
        raise ValueError(f"grid: built for {grid.kind} pulses, the table has {table.kind}")
    g = G if structure is None else float(structure.g)
    key = (id(grid), table.kind, free, tuple(sorted(fixed.items())), g, id(structure))
    if key not in _MODELS:  # one model (and its compiled functions) per grid and setting
        _MODELS[key] = PhysicsModel(grid, table.kind, names, free, fixed, g, structure)
    return _MODELS[key]


def _optimise(pm, data, starts):
    def fun(z):
        v, g = pm.value_and_grad(jnp.asarray(z), *data)
        v = float(v)
        return (v, np.asarray(g, float)) if np.isfinite(v) else (1e300, np.zeros_like(z))

    best = None
    for z0 in starts:
        res = minimize(fun, z0, jac=True, method="BFGS", options={"gtol": 1e-6})
        if best is None or res.fun < best.fun:
            best = res
    return best


@dataclasses.dataclass(frozen=True, eq=False)
class OutcomeFit:
    """The result of `fit_outcomes` (SI units; the names in `UNITS`).

    - `estimates`: every parameter (free and fixed); `free`: the fitted ones; `interval90`:
      name -> (low, high), 90 % Laplace intervals in z mapped back; `stderr`: the delta
      method's standard errors; `cov_z`: the covariance in z.
    - `nll`: the negative log-likelihood; `nll_probit`, `probit_coef` (b0, b1, b2 of
      Φ(b0 + b1 ln A + b2 ln T), A [m/s²], T [s]); `nll_constant`, `p_constant`.
    - `table`, `model` (the rockjax model name), `grid` (`ThresholdGrid`), `physics`
      (`identification._outcome_model.PhysicsModel`), `wall_time` [s] (grid included when
      it was built here), `converged`, `warnings` (text).
    """

    table: OutcomeTable
    model: str
    physics: PhysicsModel
    z: np.ndarray
    cov_z: np.ndarray
    estimates: dict
    interval90: dict
    stderr: dict
    nll: float
    nll_probit: float
    probit_coef: np.ndarray
    nll_constant: float
    p_constant: float
    wall_time: float
    converged: bool
    warnings: tuple = ()

    @property
    def free(self) -> tuple:
        return self.physics.free

    @property
    def grid(self) -> ThresholdGrid:
        return self.physics.grid

    def _params(self, draws=None):
        if draws is None:
            return {n: jnp.asarray(v) for n, v in self.estimates.items()}
        out = {}
        for n in self.estimates:
            v = draws.get(n, self.estimates[n]) if hasattr(draws, "get") else draws[n]
            out[n] = jnp.asarray(v, float)
        return out

    def threshold(self, period, params=None) -> np.ndarray:
        """The model's lowest overturning amplitude [m/s²] of pulses of `period` [s]
        (`params`: name -> value, default the estimates)."""
        p = self._params(params)
        return np.asarray(jnp.exp(self.physics.jit_log_threshold(p, jnp.asarray(period,
                                                                                 float))))

    def probability(self, amplitude, period, draws=None) -> np.ndarray:
        """P(topple) of pulses of `amplitude` [m/s²] and `period` [s] (broadcast): at the
        estimates, or averaged over `draws` (name -> 1-D array of equal lengths, e.g.
        `Posterior.draws_dict()`; a name missing from it keeps its estimate), the
        posterior-predictive probability."""
        A = jnp.asarray(amplitude, float)
        T = jnp.asarray(period, float)
        if draws is None:
            return np.asarray(self.physics.jit_probability(self._params(), A, T))
        d = {n: jnp.atleast_1d(jnp.asarray(draws[n], float)) for n in self.estimates
             if n in draws}
        if not d:
            raise ValueError(f"draws: none of the parameters {list(self.estimates)}")
        n = {len(v) for v in d.values()}
        if len(n) != 1:
            raise ValueError(f"draws: arrays of different lengths {sorted(n)}")
        fixed = {k: jnp.asarray(v) for k, v in self.estimates.items() if k not in d}
        return np.asarray(self.physics.jit_mean_probability(d, fixed, A, T))

    def log_likelihood_terms(self, table=None) -> np.ndarray:
        """log P of each run's outcome at the estimates (`table` default: the fitted one)."""
        t = self.table if table is None else table
        return np.asarray(self.physics.jit_log_lik_terms(
            self._params(), t.amplitude, t.period, t.toppled))

    def posterior_problem(self, priors=None) -> PosteriorProblem:
        """The posterior of the free parameters for `identification.sample_posterior`.

        Default priors (`priors=None`; a dict name -> `Prior` or text replaces them):
        alpha uniform over the grid (0.04-0.64 rad), R lognormal(median 0.3 m, sigma_ln
        1.5), beta halfnormal(0.5), k_f lognormal(the structure's, 1.0) and r uniform over
        the grid (0.3-0.98) — held inside the grid by the coordinates z either way."""
        pm, t = self.physics, self.table
        b = pm.bounds
        defaults = {"alpha": Prior.uniform(*b.get("alpha", (0.04, 0.64))),
                    "R": Prior.lognormal(0.3, 1.5), "beta": Prior.halfnormal(0.5),
                    "k_f": Prior.lognormal(float(pm.structure.k_f) if pm.structure is not None
                                           else 1e6, 1.0),
                    "r": Prior.uniform(*b.get("r", (0.3, 0.98)))}
        pri = parse_priors(priors, pm.free, {n: defaults[n] for n in pm.free})
        data = (jnp.asarray(t.amplitude), jnp.asarray(t.period), jnp.asarray(t.toppled),
                jnp.ones(t.n))
        return PosteriorProblem(
            names=pm.free, log_likelihood=lambda z: -pm.nll(z, *data),
            to_physical=lambda z: {n: v for n, v in pm.to_physical(z).items() if n in pm.free},
            z0=np.asarray(self.z), cov0=np.asarray(self.cov_z), priors=pri,
            units={n: UNITS[n] for n in pm.free}, source="outcomes")

    def cross_validate(self, k=5, seed=0) -> dict:
        """k-fold cross-validation (folds shuffled with `seed`): each fold's runs predicted
        by the physics model, the probit and the constant refitted on the other folds (the
        physics model from the same grid of starts, the grid reused). Returns the held-out
        log loss (mean −log P per run) of each model, and per fold."""
        return _cross_validate(self, k, seed)

    def summary(self, cv=None) -> dict:
        """JSON-ready: the estimates, 90 % intervals, standard errors, the NLL of each
        model (and AIC), the table, the grid, the methods; `cv` a `cross_validate` result."""
        from ._outcome_report import summary

        return summary(self, cv)

    def report(self, cv=None) -> str:
        """A text report (the table, the estimates with 90 % intervals, the models' NLL,
        `cv` if given, how A_c and its gradients were obtained)."""
        from ._outcome_report import report

        return report(self, cv)

    def plot(self, ax=None, axes="pga-ratio", draws=None):
        """The runs (toppled ×, stood ○) with the fitted boundary (P = 0.5) and the band
        P = 0.1-0.9; `axes` "pga-ratio" (PGA [g] against PGV/PGA [s]) or "dimensionless"
        (a/(g tan α) against ω_p/p; a block or a structure). `draws` (name -> array): the
        posterior-predictive P = 0.5 boundary is drawn too. Returns the matplotlib axes."""
        from ._outcome_report import plot

        return plot(self, ax, axes, draws)


def fit_outcomes(table, structure=None, *, free=None, fixed=None, model="rigid_body",
                 grid=None, drop_unknown_labels=False) -> OutcomeFit:
    r"""Fit a rocking specimen to pass/fail runs (`read_outcomes`).

    **Arguments:**

    - `table`: an `OutcomeTable`, or the path of one (`read_outcomes(path,
      drop_unknown_labels=...)`).
    - `structure`: None for a uniform rectangular block of unknown shape (parameters
      `alpha` [rad], `R` [m] the half-diagonal, `beta`), or a `rockjax.RockingStructure`
      of known geometry (parameters `k_f` [N/m], `r`, `beta`).
    - `free`: the fitted parameters (default all three); the others from `fixed`
      (name -> value; for a structure its k_f and Eq. 3's r by default).
    - `model`: the rockjax model of the thresholds (default "rigid_body").
    - `grid`: a `ThresholdGrid` (`block_threshold_grid`, `structure_threshold_grid`) to
      reuse; default built here (a block's once per process and pulse kind: about 40 s on
      2 cores).

    **Model:** $P = \Phi(\ln(A/A_c(T;\theta))/\beta)$, $A_c$ interpolated on the grid of
    rockjax overturning spectra (module `_outcome_grid`: PCHIP in ln x and α, exact
    derivatives of the interpolant). **Returns** an `OutcomeFit` with the estimates,
    90 % Laplace intervals, the NLL beside a constant and a three-parameter probit.
    """
    start = time.perf_counter()
    if not isinstance(table, OutcomeTable):
        table = read_outcomes(table, drop_unknown_labels=drop_unknown_labels)
    pm = _model(table, structure, free, fixed, model, grid)
    data = _data(table)
    best = _optimise(pm, data, pm.starts())
    z = np.asarray(best.x, float)
    notes = []
    H = _hessian(pm, z, data)
    try:
        cov = np.linalg.inv(H)
        ok = np.all(np.linalg.eigvalsh(0.5 * (H + H.T)) > 0)
    except np.linalg.LinAlgError:
        cov, ok = np.full_like(H, np.nan), False
    if not ok:
        cov = np.full_like(H, np.nan)
        notes.append("the NLL's Hessian at the optimum is not positive definite: the "
                     "parameters are not identifiable from these runs (intervals NaN)")
        warnings.warn(notes[-1], IdentifiabilityWarning, stacklevel=2)
    est, lo_hi, se = _intervals(pm, z, cov)
    for n in pm.free:
        b = pm.bounds.get(n)
        if b is not None and not (b[0] + 0.01 * (b[1] - b[0]) < est[n]
                                  < b[1] - 0.01 * (b[1] - b[0])):
            notes.append(f"{n} = {est[n]:.4g} is at the edge of the grid ({b[0]:.4g}-"
                         f"{b[1]:.4g}): widen the grid")
            warnings.warn(notes[-1], IdentifiabilityWarning, stacklevel=2)
    w = np.ones(table.n)
    nll_c, p_c = _base.constant_nll(table.toppled, w)
    nll_p, coef = _base.probit_fit(table.amplitude, table.period, table.toppled, w)
    return OutcomeFit(table, model, pm, z, cov, est, lo_hi, se, float(best.fun), nll_p, coef,
                      nll_c, p_c, time.perf_counter() - start, bool(best.success),
                      tuple(notes))


def _hessian(pm, z, data, h=1e-5):
    """The NLL's Hessian by central differences of its exact (jitted) gradient."""
    cols = []
    for e in np.eye(len(z)):
        gp = np.asarray(pm.value_and_grad(jnp.asarray(z + h * e), *data)[1])
        gm = np.asarray(pm.value_and_grad(jnp.asarray(z - h * e), *data)[1])
        cols.append((gp - gm) / (2 * h))
    H = np.stack(cols, 1)
    return 0.5 * (H + H.T)


def _data(table, weight=None):
    return (jnp.asarray(table.amplitude), jnp.asarray(table.period),
            jnp.asarray(table.toppled), jnp.asarray(np.ones(table.n) if weight is None
                                                    else weight, float))


def _intervals(pm, z, cov):
    phys = {n: float(v) for n, v in pm.to_physical(jnp.asarray(z)).items()}
    J = np.asarray(jax.jacfwd(lambda v: jnp.stack([pm.to_physical(v)[n]
                                                   for n in pm.free]))(jnp.asarray(z)))
    var = np.diag(J @ cov @ J.T) if np.all(np.isfinite(cov)) else np.full(len(z), np.nan)
    lo_hi, se = {}, {}
    for i, n in enumerate(pm.free):
        sd = math.sqrt(cov[i, i]) if np.isfinite(cov[i, i]) and cov[i, i] > 0 else math.nan
        ends = []
        for sign in (-1, 1):
            zz = np.array(z, float)
            zz[i] += sign * Z90 * sd
            ends.append(float(pm.to_physical(jnp.asarray(zz))[n]))
        lo_hi[n] = (min(ends), max(ends))
        se[n] = float(math.sqrt(var[i])) if np.isfinite(var[i]) else math.nan
    return phys, lo_hi, se


def _cross_validate(fit, k, seed):
    t, pm = fit.table, fit.physics
    losses = {"physics": np.zeros(t.n), "probit": np.zeros(t.n), "constant": np.zeros(t.n)}
    per_fold = []
    for fold in _base.folds(t.n, k, seed):
        w = np.ones(t.n)
        w[fold] = 0.0
        train = t.toppled[w > 0]
        if np.all(train == train[0]):
            raise OutcomeError(f"cross-validation: a training set of fold {len(per_fold)} "
                               "has one class only; use fewer folds")
        best = _optimise(pm, _data(t, w), pm.starts())
        params = pm.to_physical(jnp.asarray(best.x))
        sub = t.subset(fold)
        losses["physics"][fold] = -np.asarray(pm.jit_log_lik_terms(
            params, sub.amplitude, sub.period, sub.toppled))
        _, b = _base.probit_fit(t.amplitude, t.period, t.toppled, w)
        losses["probit"][fold] = -_base.probit_log_lik(b, sub.amplitude, sub.period,
                                                       sub.toppled)
        _, p = _base.constant_nll(t.toppled, w)
        losses["constant"][fold] = -(sub.toppled * np.log(p) + (1 - sub.toppled)
                                     * np.log1p(-p))
        per_fold.append({m: float(np.mean(v[fold])) for m, v in losses.items()})
    return {"k": k, "seed": seed, "n": t.n,
            "log_loss": {m: float(np.mean(v)) for m, v in losses.items()},
            "per_fold": per_fold,
            "winner": min(losses, key=lambda m: float(np.mean(losses[m])))}
