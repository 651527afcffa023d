"""The report, summary and figure of an `OutcomeFit`."""

from __future__ import annotations

import math

import numpy as np

from ._outcome_model import UNITS
from ._outcome_table import _RATIO_TO_PERIOD, G

Z10 = 1.2815515655446004  # Φ⁻¹(0.9): the band P = 0.1-0.9 is A_c exp(±1.2816 β)
GRADIENTS = ("A_c interpolated on a grid of rockjax overturning spectra (PCHIP in ln x and "
             "alpha, or ln T and the structure's parameters); gradients are exact "
             "derivatives of the interpolant (jax.grad)")
INTERVALS = "Laplace: the inverse Hessian of the NLL in the unconstrained z, ±1.645 sd, mapped"


def _aic(nll, k):
    return 2 * nll + 2 * k


def summary(fit, cv=None) -> dict:
    t = fit.table
    out = {
        "table": {"source": t.source, "meaning": t.meaning, "n": t.n,
                  "toppled": int(t.toppled.sum()), "dropped": [list(d) for d in t.dropped],
                  "zero_amplitude_runs": int(np.sum(t.amplitude == 0))},
        "structure": "uniform block of unknown shape" if fit.physics.structure is None
        else "given structure", "model": fit.model, "kind": t.kind,
        "free": list(fit.free),
        "estimates": {n: float(v) for n, v in fit.estimates.items()},
        "interval90": {n: list(v) for n, v in fit.interval90.items()},
        "stderr": fit.stderr, "units": {n: UNITS[n] for n in fit.estimates},
        "nll": {"physics": fit.nll, "probit3": fit.nll_probit, "constant": fit.nll_constant},
        "aic": {"physics": _aic(fit.nll, len(fit.free)), "probit3": _aic(fit.nll_probit, 3),
                "constant": _aic(fit.nll_constant, 1)},
        "probit_coef": [float(c) for c in fit.probit_coef], "p_constant": fit.p_constant,
        "interval_method": INTERVALS, "gradients": GRADIENTS,
        "grid": fit.grid.summary(), "wall_time_s": fit.wall_time,
        "converged": fit.converged, "warnings": list(fit.warnings),
    }
    if cv is not None:
        out["cross_validation"] = cv
    return _plain(out)


def _plain(x):
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return None if not math.isfinite(float(x)) else float(x)
    if isinstance(x, np.integer):
        return int(x)
    return x


def report(fit, cv=None) -> str:
    t = fit.table
    what = ("a uniform block of unknown shape" if fit.physics.structure is None
            else "the given structure")
    lines = [t.describe(),
             f"model: P(topple) = Phi(ln(A / A_c(T)) / beta), A_c of {what} on the "
             f"{fit.model} model ({t.kind} pulses)",
             f"{'parameter':<10}{'estimate':>12}{'90 % interval':>26}  unit"]
    for n, v in fit.estimates.items():
        if n in fit.free:
            lo, hi = fit.interval90[n]
            lines.append(f"{n:<10}{v:12.4g}   [{lo:10.4g}, {hi:10.4g}]  {UNITS[n]}")
        else:
            lines.append(f"{n:<10}{v:12.4g}   {'(fixed)':>23}  {UNITS[n]}")
    lines += [f"negative log-likelihood: physics {fit.nll:.2f} ({len(fit.free)} parameters), "
              f"probit in (ln PGA, ln PGV/PGA) {fit.nll_probit:.2f} (3), constant "
              f"{fit.nll_constant:.2f} (1)"]
    if cv is not None:
        ll = cv["log_loss"]
        lines.append(f"{cv['k']}-fold cross-validation (seed {cv['seed']}), held-out log loss "
                     f"per run: physics {ll['physics']:.4f}, probit {ll['probit']:.4f}, "
                     f"constant {ll['constant']:.4f}: {cv['winner']} best")
    lines += [f"intervals: {INTERVALS}", f"gradients: {GRADIENTS}",
              f"fit in {fit.wall_time:.1f} s (grid: {fit.grid.n_runs} runs, "
              f"{fit.grid.build_time:.1f} s when built)"]
    lines += [f"warning: {w}" for w in fit.warnings]
    return "\n".join(lines)


def _dimensionless(fit, period, amplitude, A_c=None):
    """(x, y) of the dimensionless axes: omega_p/p (p t1) and a / (g tan alpha)."""
    pm = fit.physics
    if pm.structure is None:
        e = fit.estimates
        g, tan_a = pm.g, math.tan(e["alpha"])
        p = math.sqrt(3 * g / (4 * e["R"]))
    else:
        s = pm.structure
        g, tan_a = float(s.g), float(s.B / s.H_c)
        p = math.sqrt(float(s.W * s.R_c / s.I_O))
    x = p * period if fit.table.kind == "rectangular" else 2 * np.pi / (p * period)
    return x, amplitude / (g * tan_a)


def plot(fit, ax=None, axes="pga-ratio", draws=None):
    import matplotlib.pyplot as plt

    if axes not in ("pga-ratio", "dimensionless"):
        raise ValueError(f"axes {axes!r}: 'pga-ratio' or 'dimensionless'")
    if ax is None:
        _, ax = plt.subplots(figsize=(6.4, 4.6))
    t = fit.table
    c = _RATIO_TO_PERIOD[t.kind]
    ratio = np.geomspace(0.8 * t.ratio.min(), 1.25 * t.ratio.max(), 200)
    T = c * ratio
    A_c = fit.threshold(T)
    beta = fit.estimates["beta"]

    def xy(period, amp):
        if axes == "pga-ratio":
            return period / c, amp / G
        return _dimensionless(fit, period, amp)

    x, y = xy(T, A_c)
    _, lo = xy(T, A_c * math.exp(-Z10 * beta))
    _, hi = xy(T, A_c * math.exp(Z10 * beta))
    ax.fill_between(x, lo, hi, color="0.6", alpha=0.35, lw=0,
                    label=f"P = 0.1-0.9 (beta = {beta:.3g})")
    ax.plot(x, y, "k-", lw=1.8, label="fitted boundary, P = 0.5")
    if draws is not None:
        A = _predictive_boundary(fit, T, A_c, draws)
        ax.plot(*xy(T, A), "k--", lw=1.2, label="posterior-predictive P = 0.5")
    pos = t.amplitude > 0
    for flag, style, label in ((1, dict(marker="x", color="tab:red", ls=""), "toppled"),
                               (0, dict(marker="o", mfc="none", color="tab:blue", ls=""),
                                "stood")):
        m = pos & (t.toppled == flag)
        ax.plot(*xy(t.period[m], t.amplitude[m]), ms=6, label=f"{label} ({int(m.sum())})",
                **style)
    ax.set_xscale("log")
    ax.set_yscale("log")
    from matplotlib.ticker import NullFormatter

    ax.xaxis.set_minor_formatter(NullFormatter())
    zero = int(np.sum(~pos))
    if zero:
        ax.plot([], [], ls="", label=f"(not drawn: {zero} run(s) at zero amplitude, stood)")
    if axes == "pga-ratio":
        ax.set_xlabel("PGV/PGA [s]")
        ax.set_ylabel("PGA [g]")
    else:
        ax.set_xlabel("$\\omega_p / p$" if t.kind != "rectangular" else "$p\\,t_1$")
        ax.set_ylabel("$a / (g \\tan\\alpha)$")
    est = ", ".join(f"{n} = {fit.estimates[n]:.3g}" for n in fit.free)
    ax.set_title(f"{t.kind} pulses, {fit.model}: {est}", fontsize=9)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    return ax


def _predictive_boundary(fit, T, A_c, draws):
    """The amplitude at which the posterior-predictive probability is 0.5, per period
    (bisection in ln A within A_c exp(±4 beta))."""
    beta = fit.estimates["beta"]
    lo, hi = np.log(A_c) - 6 * beta, np.log(A_c) + 6 * beta
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        p = fit.probability(np.exp(mid), T, draws=draws)
        lo, hi = np.where(p < 0.5, mid, lo), np.where(p < 0.5, hi, mid)
    return np.exp(0.5 * (lo + hi))
