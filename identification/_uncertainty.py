"""What the fit tells: standard errors, identifiability and the lack-of-fit check.

Standard errors and correlations come from the Gauss-Newton approximation of the Fisher
information at the optimum (`uncertainty`: a sandwich over the channels); `identifiability`
gives the sensitivity of the trace to each parameter and the messages of the
`IdentifiabilityWarning`s; they hold only if the residuals are noise, which the lack-of-fit
check (`lack_of_fit`, `identification._lack`) tests.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from . import _lack, _models
from ._problem import NUISANCE, Problem, UNITS
from ._stages import Best
from ._transforms import Transform


@dataclasses.dataclass(frozen=True, eq=False)
class Uncertainty:
    values: dict  # natural values of all of PARAM_NAMES at the optimum
    derivatives: list  # d(natural value)/dz of each fitted parameter
    se: np.ndarray  # standard errors (natural units)
    corr: np.ndarray  # correlation matrix
    sigma: float  # estimated noise std of the primary channel (u [m], theta [rad], uplift [m])


def uncertainty(problem: Problem, transform: Transform, best: Best,
                keep: np.ndarray) -> Uncertainty:
    """Standard errors and correlations at the optimum (Gauss-Newton / Fisher information).

    In natural coordinates. The fit minimises unweighted least squares over the channels
    (displacement, uplift), whose noise levels differ, so the covariance is the sandwich
    A^-1 B A^-1 with A = J^T J, B = J^T diag(sigma_c^2) J and sigma_c^2 = RSS_c / (N_c - P
    share) for each channel.
    """
    J, r = best.J, best.r
    n_res, n_par = J.shape
    n_u = problem.t.size
    channels = [slice(k * n_u, (k + 1) * n_u) for k in range(max(n_res // n_u, 1))]
    var = np.empty(n_res)
    sig2 = []
    for ch in channels:
        n_c = int(np.count_nonzero(keep))  # samples in the fit, per channel
        dof_c = max(n_c - n_par / len(channels), 1.0)
        s2 = max(float(np.sum(r[ch] ** 2)) / dof_c, 1e-300)
        sig2.append(s2)
        var[ch] = s2
    sigma2 = sig2[0]
    vals_nat = transform.decode(best.z)
    dtheta_dz = transform.derivatives(best.z)
    D = np.diag(dtheta_dz)
    try:
        a_inv = np.linalg.inv(J.T @ J)
        cov = D @ (a_inv @ (J.T @ (var[:, None] * J)) @ a_inv) @ D
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
        corr = cov / np.outer(np.where(se > 0, se, 1.0), np.where(se > 0, se, 1.0))
    except np.linalg.LinAlgError:
        se = np.full(n_par, np.inf)
        corr = np.full((n_par, n_par), np.nan)
    scale, w = problem.unit_of(problem.channels[0])
    return Uncertainty(values=vals_nat, derivatives=dtheta_dz, se=se, corr=corr,
                        sigma=math.sqrt(sigma2) * problem.scale if problem.channels[0] == "u"
                        else math.sqrt(sigma2) * scale / max(w, 1e-300))


def identifiability(problem: Problem, best: Best, unc: Uncertainty):
    """(the `FitResult.identifiability` dict, the messages of the IdentifiabilityWarning's).

    The sensitivity of a parameter is the RMS change of the displacement trace [m] for a
    1 % change of it (t0: for 1 ms), to compare with the noise level; of the primary
    channel without u (the rotation [rad], the uplift [m]).
    """
    params, vals_nat, se, sigma = problem.params, unc.values, unc.se, unc.sigma
    n = problem.t.size
    chans = problem.channels
    if chans[0] == "u":
        Ju = best.J[:n] * problem.scale  # d u / d z [m]
    else:
        s0, w0 = problem.unit_of(chans[0])
        Ju = best.J[:n] * s0 / max(w0, 1e-300)  # d (primary channel) / d z
    for p, ch in (("offset_uplift", "uplift"), ("offset_theta", "theta")):
        if p in params and ch in chans and chans[0] != ch:  # acts on its channel only
            j, k = params.index(p), chans.index(ch)
            s_c, w_c = problem.unit_of(ch)
            Ju = Ju.copy()
            Ju[:, j] = best.J[k * n:(k + 1) * n, j] * s_c / max(w_c, 1e-300)
    sens = {}
    for j, p in enumerate(params):
        # t0: for 1 ms; the sensor's offsets: 1 % of the amplitude (drift: per second)
        per = (1e-3 if p == "t0" else 0.01 * problem.scale if p in NUISANCE
               else 0.01 * abs(vals_nat[p]))
        sens[p] = float(np.sqrt(np.mean((Ju[:, j] / unc.derivatives[j] * per) ** 2)))
    ident = {
        "sensitivity_per_percent": sens,
        "noise_sigma": sigma,
        "relative_stderr": {p: float(se[j] / abs(vals_nat[p]))
                            if vals_nat[p] and p not in NUISANCE else None
                            for j, p in enumerate(params)},
    }
    for other in ("r", "c_f"):
        if "k_f" in params and other in params:
            ident[f"corr_k_f_{other}"] = float(unc.corr[params.index("k_f"),
                                                        params.index(other)])
    messages = []
    for j, p in enumerate(params):
        rel = se[j] / abs(vals_nat[p]) if vals_nat[p] else np.inf
        if sens[p] == 0.0:  # an exactly zero Jacobian column
            messages.append(
                f"the trace does not pin {p} down: it does not depend on {p} at all "
                f"(nothing in this trace, or in the {problem.fit_model.describe()} model, "
                f"brings {p} into play: an impact for r, say); leave it out of params"
            )
        elif p in NUISANCE:
            if not se[j] < 0.1 * (problem.theta_scale if p == "offset_theta"
                                  else problem.scale):
                messages.append(
                    f"the trace does not pin the sensor's {p} down: standard error "
                    f"{se[j]:.3g} {UNITS[p]}, {100 * se[j] / problem.scale:.3g} % of the "
                    "amplitude; fit without it (offset=False, drift=False)")
        elif p != "t0" and not rel < 0.1:
            messages.append(
                f"the trace does not pin {p} down: standard error {100 * rel:.3g} % of its "
                f"value (a 1 % change moves the trace by {sens[p]:.3g} m RMS, noise "
                f"{sigma:.3g} m)"
            )
    for other in ("r", "c_f"):
        rho = ident.get(f"corr_k_f_{other}", 0.0)
        if abs(rho) > 0.95:
            messages.append(
                f"k_f and {other} are strongly correlated (rho = {rho:.3f}): the trace "
                "constrains a combination of them, not each"
            )
    return ident, messages


def lack_of_fit(problem: Problem, u_fit: np.ndarray, keep: np.ndarray) -> dict:
    r"""The lack-of-fit check of the displacement residuals (kept samples, time order); of
    the primary channel without u (`u_fit`: that channel, as the sensor reads it): the
    rotation's residuals as displacements at the top, $H_e\,\Delta\theta$ [m] (the
    statistics do not depend on the factor; the sizes in the message are then in m)."""
    ch = problem.channels[0]
    e = (u_fit - problem.measured(ch))[keep]  # u_fit: as the sensor reads it
    if ch == "theta":
        e = e * float(problem.structure.H_e)
    rms = float(np.sqrt(np.mean(e**2)))
    fm = problem.fit_model
    out = _lack.lack_of_fit(e, rms, problem.scale, fm.describe(),
                            _models.models_above(fm, problem.params), t=problem.t[keep],
                            fitted=tuple(p for p in problem.params if p in NUISANCE))
    return out if ch == "u" else {**out, "channel": ch}
