r"""Lack of fit: are the residuals of a fit noise, or a misfit the model cannot remove?

The standard errors of `fit_decay` assume the residuals are independent noise. A model that
cannot represent the trace leaves a smooth, systematic residual instead: neighbouring
residuals are alike and their signs come in long runs. Two statistics of the displacement
residuals (the samples in the fit, in time order) measure it:

- the lag-1 autocorrelation $\rho_1 = \sum_i e_i e_{i+1} / \sum_i e_i^2$ (mean removed).
  For white noise $\rho_1 \approx N(-1/n, 1/n)$: 0.05 for n = 400 samples
  (`lag1_z` = $\rho_1\sqrt n$, in those standard deviations). A systematic
  misfit $s(t)$, smooth on the sampling interval, on top of noise of variance $\sigma^2$
  gives $\rho_1 \approx \overline{s^2}/(\overline{s^2} + \sigma^2)$: the fraction of the
  residual variance that is misfit.
- the Wald–Wolfowitz runs test on the signs of the residuals: $R$ runs of equal signs
  against $\mu = 2n_+n_-/n + 1$ with variance $(\mu - 1)(\mu - 2)/(n - 1)$ for independent
  signs; $z = (R - \mu)/\sqrt{\operatorname{var}}$. It does not depend on the residuals'
  size, so a few large residuals (spikes) cannot drive it.

**The check fires** when both $\rho_1 > 0.5$ and $z < -4$ (and the RMS residual is above
$10^{-4}$ of the trace amplitude). Why these thresholds:

- $\rho_1 > 0.5$ is 10 standard deviations of white noise at n = 400 samples (5 at the
  smallest fittable n = 100; one-sided $p < 3\times10^{-7}$), so noise alone does not fire
  it; and it means the misfit carries more of the residual variance than the noise does.
  For AR(1)-like residuals the standard errors computed as if independent are then too
  small by $\sqrt{(1+\rho_1)/(1-\rho_1)}$ = 1.7 or more, on top of the bias of the misfit:
  they do not hold. A milder misfit ($\rho_1$ below 0.5) is reported in the statistics,
  not flagged.
- $z < -4$ (one-sided $p = 3\times10^{-5}$) confirms that the signs, not only the sizes,
  are correlated.
- Below $10^{-4}$ of the amplitude (10 µm for a 0.1 m release) the residual of a noise-free
  trace is the integrator's own error, smooth by nature: a fit that close is exact for any
  practical purpose, and is not flagged.

Correlated noise (a sensor's low-pass filter, drift) also fires the check: the standard
errors do not hold then either. `tests/test_fit_models.py` checks that it stays quiet on
correct models with white noise (an SDOF fit of an SDOF trace, the 2-DOF body on its own
trace) and fires on the SDOF fit of a 2-DOF trace.
"""

from __future__ import annotations

import math

import numpy as np

RHO_MAX = 0.5
"""The check fires when the lag-1 autocorrelation of the residuals exceeds this..."""
RUNS_Z_MAX = -4.0
"""...and the runs test's z (too few runs of residual signs) is below this."""
RMS_FLOOR = 1e-4
"""...and the RMS residual exceeds this fraction of the trace amplitude."""


def residual_statistics(e: np.ndarray) -> dict:
    """Lag-1 autocorrelation and the Wald–Wolfowitz runs test of the residuals `e` (1-D,
    in time order)."""
    e = np.asarray(e, float)
    n = e.size
    d = e - np.mean(e) if n else e
    den = float(np.sum(d**2))
    rho1 = float(np.sum(d[1:] * d[:-1]) / den) if n > 2 and den > 0 else 0.0
    s = np.sign(e[e != 0])
    n_pos, n_neg = int(np.count_nonzero(s > 0)), int(np.count_nonzero(s < 0))
    m = n_pos + n_neg
    runs = int(1 + np.count_nonzero(s[1:] != s[:-1])) if m else 0
    mu = 2.0 * n_pos * n_neg / m + 1.0 if m else 0.0
    var = (mu - 1.0) * (mu - 2.0) / (m - 1) if m > 1 else 0.0
    z = (runs - mu) / math.sqrt(var) if var > 0 else 0.0
    return {"n": int(n), "lag1_autocorrelation": rho1,
            "lag1_z": rho1 * math.sqrt(n),  # in standard deviations of white noise
            "runs": runs,
            "runs_expected": float(mu), "runs_sd": math.sqrt(max(var, 0.0)), "runs_z": float(z)}


def lack_of_fit(e: np.ndarray, rms: float, scale: float, model: str, above) -> dict:
    """The `FitResult.lack_of_fit` dict: the statistics of the displacement residuals `e`
    [m] (kept samples, time order), `fires`, the thresholds, `next_model` (the first of
    `above`, the models up the ladder in words, nearest first; None at the top), and
    `message` (None when the check does not fire)."""
    above = list(above or [])
    next_model = above[0] if above else None
    out = residual_statistics(e)
    out["rms_over_amplitude"] = float(rms / scale) if scale > 0 else 0.0
    out["thresholds"] = {"lag1_autocorrelation": RHO_MAX, "runs_z": RUNS_Z_MAX,
                         "rms_over_amplitude": RMS_FLOOR}
    out["fires"] = bool(out["lag1_autocorrelation"] > RHO_MAX and out["runs_z"] < RUNS_Z_MAX
                        and out["rms_over_amplitude"] > RMS_FLOOR)
    out["next_model"] = next_model
    out["message"] = _message(out, rms, model, above) if out["fires"] else None
    return out


def _message(st: dict, rms: float, model: str, above: list) -> str:
    then = "".join(f", then {m}" for m in above[1:])
    where = (f"the next model up the ladder is {above[0]}{then}" if above else
             "this is the top of rockjax's ladder: check the trace (filtered or coloured "
             "sensor noise, drift) and the structure")
    return (
        f"lack of fit: the residuals are not noise (lag-1 autocorrelation "
        f"{st['lag1_autocorrelation']:.3f} > {RHO_MAX:g}; {st['runs']} runs of residual signs "
        f"where independent noise gives {st['runs_expected']:.0f} +- {st['runs_sd']:.0f}, "
        f"z = {st['runs_z']:.1f}; rms residual {rms:.3g} m): the {model} model cannot "
        "represent this trace (or the fit stopped in a local minimum: try more starts), and "
        f"the standard errors do not hold; {where}"
    )
