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

**Biased residuals.** A constant offset of the sensor that the fit does not model leaves
residuals of one sign nearly everywhere: one long run, which the runs test cannot see
(1 run where $\mu = 1$ is expected when all signs are equal: z = 0). Two more statistics
catch it: the **sign test** $z_s = (n_+ - n_-)/\sqrt{n_+ + n_-}$ (N(0, 1) for residuals
of a median 0), and the **mean test** $z_m = \bar e\,\sqrt{n_{eff}}/s$ with $s$ the
residuals' standard deviation about their mean and $n_{eff} = n(1-\rho_1)/(1+\rho_1)$
(at most n) the effective number of independent samples. **The check also fires** when
$|z_s| > 5$ or $|z_m| > 5$ (two-sided $p < 6\times10^{-7}$ for noise; with the RMS
floor): a +4 mm offset gives $|z_s| \approx \sqrt n$. A fit with the offset fitted
(`fit_decay(..., offset=...)`) has residuals of mean 0 by construction.

When the check fires, `identification._diagnosis` says what the residuals look like (an
offset, a drift, a periodic component, a model that cannot follow the trace), and the
message gives that cause rather than always blaming the model.

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
BIAS_Z_MAX = 5.0
"""It also fires when the sign test's or the mean test's |z| exceeds this (RMS floor
too): residuals biased to one side, such as an unfitted sensor offset."""


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
    sign_z = (n_pos - n_neg) / math.sqrt(m) if m else 0.0
    sd = math.sqrt(den / n) if n and den > 0 else 0.0
    n_eff = min(float(n), max(1.0, n * (1 - rho1) / (1 + rho1))) if n else 0.0
    mean = float(np.mean(e)) if n else 0.0
    mean_z = mean * math.sqrt(n_eff) / sd if sd > 0 else (math.inf if mean else 0.0)
    return {"n": int(n), "lag1_autocorrelation": rho1,
            "mean": mean, "mean_z": float(mean_z), "n_positive": n_pos, "n_negative": n_neg,
            "sign_z": float(sign_z),
            "lag1_z": rho1 * math.sqrt(n),  # in standard deviations of white noise
            "runs": runs,
            "runs_expected": float(mu), "runs_sd": math.sqrt(max(var, 0.0)), "runs_z": float(z)}


def lack_of_fit(e: np.ndarray, rms: float, scale: float, model: str, above, t=None,
                fitted=()) -> dict:
    """The `FitResult.lack_of_fit` dict: the statistics of the displacement residuals `e`
    [m] (model - trace; kept samples, time order, at times `t` [s]), `fires`, the
    thresholds, `next_model` (the first of `above`, the models up the ladder in words,
    nearest first; None at the top), `diagnosis` (`identification._diagnosis.diagnose`:
    the cause named, when it fires; `fitted`, the sensor's terms the fit has) and
    `message` (None when the check does not fire)."""
    above = list(above or [])
    next_model = above[0] if above else None
    out = residual_statistics(e)
    out["rms_over_amplitude"] = float(rms / scale) if scale > 0 else 0.0
    out["thresholds"] = {"lag1_autocorrelation": RHO_MAX, "runs_z": RUNS_Z_MAX,
                         "rms_over_amplitude": RMS_FLOOR, "sign_z": BIAS_Z_MAX,
                         "mean_z": BIAS_Z_MAX}
    above_floor = out["rms_over_amplitude"] > RMS_FLOOR
    out["correlated"] = bool(out["lag1_autocorrelation"] > RHO_MAX
                             and out["runs_z"] < RUNS_Z_MAX and above_floor)
    out["biased"] = bool((abs(out["sign_z"]) > BIAS_Z_MAX or abs(out["mean_z"]) > BIAS_Z_MAX)
                         and above_floor)
    out["fires"] = out["correlated"] or out["biased"]
    out["next_model"] = next_model
    diag = None
    if out["fires"]:
        from ._diagnosis import diagnose

        tt = np.arange(e.size, dtype=float) if t is None else np.asarray(t, float)
        diag = diagnose(np.asarray(e, float), tt, model, fitted)
    out["diagnosis"] = diag
    out["message"] = _message(out, rms, model, above, diag) if out["fires"] else None
    return out


def _message(st: dict, rms: float, model: str, above: list, diag) -> str:
    stats = (f"lag-1 autocorrelation {st['lag1_autocorrelation']:.3f} (limit {RHO_MAX:g}); "
             f"{st['runs']} runs of residual signs where independent noise gives "
             f"{st['runs_expected']:.0f} +- {st['runs_sd']:.0f}, z = {st['runs_z']:.1f}; "
             f"signs {st['n_positive']} + / {st['n_negative']} -, z = {st['sign_z']:.1f}; "
             f"mean z = {st['mean_z']:.1f} (limits +-{BIAS_Z_MAX:g}); rms residual "
             f"{rms:.3g} m")
    head = f"lack of fit: the residuals are not noise ({stats})"
    if diag is not None and diag["cause"] != "model":
        return (f"{head}: they look like {diag['message']}; the standard errors do not "
                "hold until it is removed")
    then = "".join(f", then {m}" for m in above[1:])
    where = (f"the next model up the ladder is {above[0]}{then}" if above else
             "this is the top of rockjax's ladder: check the trace (filtered or coloured "
             "sensor noise, drift) and the structure")
    return (
        f"{head}: the {model} model cannot "
        "represent this trace (or the fit stopped in a local minimum: try more starts), and "
        f"the standard errors do not hold; {where}"
    )
