"""Outliers: samples of a trace far from the converged fit (spikes of a faulty sensor).

After a converged fit, the residuals of each channel (displacement, uplift) are compared
with their robust spread (`find_outliers`); the samples far outside it are left out and
the whole trace is fitted again (`check_outliers`, called by `_stages.run_stages`), at
most `MAX_REFITS` times; `outlier_message` is the `OutlierWarning`'s text.

Gross spikes are left out from the start (`gross_spikes`): a sample further than
max(`GROSS_SIGMAS` sigma, 5 % of the amplitude) from the median of its five neighbours (a
decay trace is smooth on that scale). A spike five times the amplitude would otherwise
pull the first horizons of the fit into another minimum before the check after the fit
could find it.
"""

from __future__ import annotations

import numpy as np

import rockjax

from ._problem import Problem
from ._release import _noise_sigma
from ._residuals import channels, observed, TraceModel

OUTLIER_SIGMAS = 6.0
"""A residual more than this many robust standard deviations from its channel's median
(and above `_OUTLIER_FLOOR` of the trace amplitude) marks an outlier."""
_OUTLIER_FLOOR = 1e-6
MAX_REFITS = 3
GROSS_SIGMAS = 30.0


def gross_spikes(problem: Problem) -> np.ndarray:
    """Samples (boolean) whose displacement or uplift lies further than
    max(GROSS_SIGMAS noise sigma, 5 % of the amplitude) from the 5-point running median."""
    out = np.zeros(problem.t.size, bool)
    sigma = float(problem.release.sigma)
    for ch in problem.channels:
        x = problem.measured(ch)
        if x is None or x.size < 5:
            continue
        pad = np.pad(x, 2, mode="edge")
        med = np.median(np.lib.stride_tricks.sliding_window_view(pad, 5), axis=1)
        if ch == "theta":  # its own units: sigma and amplitude of the rotation
            s_ch = sigma if problem.primary == "theta" else _noise_sigma(x)
            out |= np.abs(x - med) > max(GROSS_SIGMAS * s_ch, 0.05 * problem.theta_scale)
            continue
        out |= np.abs(x - med) > max(GROSS_SIGMAS * sigma, 0.05 * problem.scale)
    return out
MAX_OUTLIER_FRACTION = 0.05


def find_outliers(channels, excluded, within, sigmas=OUTLIER_SIGMAS):
    """Samples whose residual is an outlier, as a boolean array (n samples).

    `channels`: residual arrays (n,) scaled by the trace amplitude (displacement, and
    uplift when measured); `excluded`: samples already left out of the fit; `within`: the
    samples the fit covers (its last horizon), the only ones considered. The scale of
    each channel is the median absolute deviation (x 1.4826, the standard deviation for
    Gaussian noise) over its kept samples (for uplift, those with a non-zero residual: the
    model and a noise-free trace both have exactly zero uplift before lift-off). A sample
    is an outlier when its residual lies more than `sigmas` of these, and more than
    `_OUTLIER_FLOOR`, from the median, and - since a few large spikes pull the fit and
    spread the residuals of the other samples - within a factor 10 of the largest such
    deviation among the kept samples. Excluded samples stay out while they remain
    outliers: the search converges in a few refits, largest spikes first.
    """
    flag = np.zeros(channels[0].shape, bool)
    for k, res in enumerate(channels):
        kept = within & ~excluded & ((res != 0) if k > 0 else True)
        if np.count_nonzero(kept) < 10:
            continue
        med = float(np.median(res[kept]))
        mad = 1.4826 * float(np.median(np.abs(res[kept] - med)))
        dev = np.abs(res - med)
        z = dev / max(mad, 1e-300)
        big = (dev > sigmas * mad) & (dev > _OUTLIER_FLOOR) & within
        if not np.any(big & ~excluded):
            flag |= big & excluded
            continue
        z_top = float(np.max(np.where(within & ~excluded, z, 0.0)))
        flag |= big & (excluded | (z >= 0.1 * z_top))
    return flag



def check_outliers(problem: Problem, model: TraceModel, run) -> bool:
    """Look for outliers in the fit just finished; update `run.keep`. True: fit again.

    Outliers (spikes) are residuals of the converged fit far outside the spread of the
    others. They pull a least-squares fit off (a few 0.3 m spikes bias k_f by 5 %): leave
    them out and fit the whole trace again (see find_outliers). An unconverged fit is not
    checked: its residuals are a misfit, not noise.
    """
    z_now = np.asarray(run.best_params())
    last = np.asarray(run.opt_state.best_value) if run.lm else run.vals[:, -1]
    i_now = int(np.argmin(np.where(np.isfinite(last), last, np.inf)))
    res_now = observed(model, z_now[i_now])
    if not (run.converged[i_now] and int(res_now.status) == rockjax.STATUS["completed"]):
        return False
    found = find_outliers(channels(problem, res_now), ~run.keep,
                           problem.within(problem.horizons[-1]))
    # more than a few is a misfit (a wrong minimum, a wrong model), not spikes
    if (np.count_nonzero(found) > MAX_OUTLIER_FRACTION * problem.t.size
            or np.array_equal(found, ~run.keep)):
        return False
    run.keep = ~found  # after the last refit: the final statistics only
    if run.n_refits >= MAX_REFITS:
        return False
    run.n_refits += 1
    return True


def outlier_message(problem: Problem, u_fit: np.ndarray, keep: np.ndarray,
                     sigma: float) -> str | None:
    """The OutlierWarning's message, or None when no sample was left out."""
    outliers = np.flatnonzero(~keep)
    if not outliers.size:
        return None
    ch = problem.channels[0]
    t, u_meas = problem.t, problem.measured(ch)
    worst = outliers[np.argmax(np.abs(u_fit - u_meas)[outliers])]
    what, unit = {"u": ("displacement", "m"), "theta": ("rotation", "rad"),
                  "uplift": ("uplift", "m")}[ch]
    return (
        f"{outliers.size} sample(s) of the trace lie more than {OUTLIER_SIGMAS:g} robust "
        f"standard deviations from the fit (largest {what} residual "
        f"{abs(u_fit[worst] - u_meas[worst]):.3g} {unit} at t = {t[worst]:.6g} s; noise "
        f"sigma {sigma:.3g} {unit}): they were left out and the fit repeated without them "
        "(indices in FitResult.outliers)"
    )


# ---------------------------------------------------------------------- result
