"""What `fit_decay` returns (`FitResult`) and the warnings it raises."""

from __future__ import annotations

import dataclasses

import numpy as np

from ._problem import PARAM_NAMES, Problem, UNITS
from ._stages import Best, Run
from ._uncertainty import Uncertainty


class IdentifiabilityWarning(UserWarning):
    """The trace does not pin a parameter down (large standard error or correlation)."""


class LackOfFitWarning(IdentifiabilityWarning):
    """The residuals are not noise: the model cannot represent the trace (or the fit is in
    a local minimum), and the standard errors do not hold (`FitResult.lack_of_fit`)."""


class ConvergenceWarning(UserWarning):
    """The fit ended without converging (`FitResult.converged` is False): its values are
    not a minimum, whatever the optimiser."""


class OutlierWarning(UserWarning):
    """Samples of the trace lie far from the fit (spikes): they were left out of it."""



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
    - `diagnosis` (property): when the lack-of-fit check fires, what the residuals look like
      (`identification._diagnosis`): a dict with `cause` ("offset", "drift", "periodic"
      or "model") and `message`; None when the residuals are noise.
    - `ranking`: with `model="auto"`, the rungs fitted, best first (`identification._auto`:
      model, parameters k, AIC, its difference from the best, rms, lack of fit,
      converged, k_f, seconds); empty otherwise.
    - `model`: the model fitted, in words; `notes`: default parameters left out because
      they do not act in it (r with continuous contact, say).
    - `channels`: the channels of the trace fitted, in order ("u", "theta", "uplift");
      without u, `rms` and `sigma` are of the first (the rotation [rad], the uplift [m]).
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
    ranking: tuple = ()
    channels: tuple = ("u",)
    #: what `posterior_problem` needs: (the Problem, the optimum z, the kept samples)
    fit_state: tuple | None = dataclasses.field(default=None, repr=False, compare=False)

    def posterior_problem(self, priors=None):
        """The fit's posterior as an `identification.PosteriorProblem` (for
        `identification.sample_posterior`): the likelihood of the trace with each
        channel's noise level marginalised (Jeffreys prior), the fit's optimum and its
        Laplace covariance, and `priors` (None: the documented defaults, or a dict
        name -> `Prior` or text); see `identification._posterior_decay`."""
        from ._posterior_decay import decay_problem

        if self.fit_state is None:
            raise ValueError("this FitResult holds no fit state (made by hand, or by an "
                             "older version): fit the trace again with fit_decay")
        return decay_problem(*self.fit_state, priors)

    @property
    def diagnosis(self) -> dict | None:
        """What the residuals look like when they are not noise (None when they are)."""
        return self.lack_of_fit.get("diagnosis")

    def ranking_text(self) -> str:
        """The ranking of `model="auto"` (`ranking`: every rung fitted, best first) as a
        markdown table: rank, model, parameters k, AIC, dAIC, rms, lack of fit,
        converged, k_f, time; "" for a fit of one model."""
        from ._auto import ranking_table

        return ranking_table(self.ranking) if self.ranking else ""

    def release_text(self) -> str:
        """Where the release was found in the trace (after a hold, or at the first sample)
        and the t0 the fit used, in one line."""
        from ._report import release_line

        return release_line(self)

    def report(self, truth=None, read_warnings=()) -> str:
        """The fit as text (what `rockjax fit` prints): the values with their standard
        errors (with `truth`, a dict of true values: also the truth and error/SE; 0 for an
        absent nuisance parameter), then `read_warnings` (messages of reading the trace),
        the k_f correlations, loss, rms residual, convergence, the lack-of-fit check, notes
        and warnings.

        ```python
        path = identification.synthetic_trace_path("synthetic_decay_noisy")
        fit = identification.fit_decay(identification.read_trace(path),
                                        rockjax.mcmanus_column())
        print(fit.report())
        ```
        """
        from ._report import fit_report

        return fit_report(self, truth, read_warnings)

    def summary(self) -> dict:
        """A JSON-ready dict: values, standard errors, held and starting values,
        correlation, loss, converged, the release, the lack-of-fit check, the model fitted
        (`fitted_model`), notes, and `units` (of the parameters, `rms_residual` and
        `sigma`)."""
        unit = "rad" if self.channels[:1] == ("theta",) else "m"
        units = {**UNITS, "rms_residual": unit, "sigma": unit, "loss": "-"}
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
            "diagnosis": self.diagnosis,
            "ranking": [dict(r) for r in self.ranking],
            "fitted_model": self.model,
            "notes": list(self.notes),
            **({} if self.channels == ("u",) else {"channels": list(self.channels)}),
        }



def result(problem: Problem, run: Run, best: Best, unc: Uncertainty, ident: dict,
           messages: list, response, lack: dict) -> FitResult:
    params, vals_nat, loss, keep = problem.params, unc.values, best.loss, run.keep
    u_fit = np.asarray(getattr(response, problem.channels[0]))
    converged = bool(run.converged[best.index]) and np.isfinite(loss) and loss < 1e5
    return FitResult(
        names=params,
        values={p: vals_nat[p] for p in params},
        stderr={p: float(unc.se[j]) for j, p in enumerate(params)},
        fixed={p: vals_nat[p] for p in PARAM_NAMES
               if p not in params and p in problem.fit_model.acting},
        correlation=np.asarray(unc.corr),
        loss=loss,
        rms=float(np.sqrt(np.mean((u_fit - problem.measured(problem.channels[0]))[keep]
                                  ** 2))),
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
        channels=problem.channels,
        fit_state=(problem, np.asarray(best.z, float), np.asarray(keep, bool)),
    )
