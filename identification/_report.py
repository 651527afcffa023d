"""A fit as text: the tables and lines that `FitResult.report`, `JointFitResult.report`
and `DecayTrace.report` print (and `rockjax fit` shows)."""

from __future__ import annotations

import math
import pathlib

from ._problem import NUISANCE, UNITS

_LOSS = "loss          {:.6g}  (1/2 sum of squared residuals / scale^2)"


def value_table(fit, truth=None) -> str:
    """The fitted values, their standard errors (and the truth, error/SE) as a table; the
    truth of an absent nuisance parameter is 0, of any other parameter missing from
    `truth` blank."""
    head = f"{'parameter':<10}{'fitted':>14}{'std. error':>14}"
    lines = [head + (f"{'true':>14}{'error/SE':>10}" if truth is not None else "") + "  unit"]
    for p in fit.names:
        v, se = fit.values[p], fit.stderr[p]
        row = f"{p:<10}{v:>14.6g}{se:>14.3g}"
        if truth is not None:
            tv = truth.get(p, 0.0 if p.split("[")[0] in NUISANCE else None)
            if tv is None:  # not given: nothing to compare with
                row += f"{'':>14}{'':>10}"
            else:
                z = (v - tv) / se if se > 0 and math.isfinite(se) else float("nan")
                row += f"{tv:>14.6g}{z:>10.2f}"
        lines.append(row + f"  {UNITS[p.split('[')[0]]}")
    return "\n".join(lines)


def _corr_lines(rho_of):
    return [f"{f'corr(k_f, {o})':<13} {rho:+.4f}" for o in ("r", "c_f")
            if (rho := rho_of(o)) is not None]


def _closing_lines(fit):
    """Convergence, then the fit's notes and warnings."""
    return ([f"converged     {'yes' if fit.converged else 'NO'}  ({fit.n_iterations} iterations)"]
            + [f"note: {n}" for n in fit.notes] + [f"warning: {w}" for w in fit.warnings])


def _rms_unit(fit):
    """The unit of `fit.rms` and `fit.sigma`: of its first channel (rad for a rotation)."""
    return "rad" if getattr(fit, "channels", ("u",))[:1] == ("theta",) else "m"


def stats_lines(fit) -> list[str]:
    """Correlation, loss, rms residual, convergence, lack of fit, notes and warnings."""
    closing = _closing_lines(fit)
    return [*_corr_lines(lambda o: fit.identifiability.get(f"corr_k_f_{o}")),
            _LOSS.format(fit.loss),
            f"rms residual  {fit.rms:.4g} {_rms_unit(fit)}  (noise sigma estimate "
            f"{fit.sigma:.3g} {_rms_unit(fit)})",
            closing[0], lack_of_fit_line(fit.lack_of_fit), *closing[1:]]


def lack_of_fit_line(lack) -> str:
    """The lack-of-fit check in one line: its statistics, thresholds and verdict."""
    if not lack:
        return "lack of fit   not checked"
    th = lack["thresholds"]
    diag = lack.get("diagnosis") or {}
    cause = ("the model cannot represent the trace" if diag.get("cause", "model") == "model"
             else f"the residuals look like {diag['message']}")
    verdict = (f"FIRES: {cause}, standard errors do not hold"
               if lack["fires"] else "no (residuals consistent with noise)")
    return (f"lack of fit   {verdict}; lag-1 autocorrelation "
            f"{lack['lag1_autocorrelation']:+.3f} (limit {th['lag1_autocorrelation']:g}), "
            f"runs z {lack['runs_z']:+.1f} (limit {th['runs_z']:g})")


def release_line(fit) -> str:
    """Where the release was found, and the t0 the fit used."""
    rel = fit.release
    if rel["held"]:
        ch, unit = rel.get("channel", "u"), "rad" if "level_rad" in rel else "m"
        found = (f"detected at t = {rel['release_time_s']:.6g} s, after a hold at {ch} = "
                 f"{rel['level_' + unit]:.6g} {unit} (noise sigma "
                 f"{rel['noise_sigma_' + unit]:.3g} {unit})")
    else:
        found = (f"at the first sample, t = {rel['release_time_s']:.6g} s (no hold before "
                 "the motion)")
    used = (f"t0 fitted from there: {fit.values['t0']:.6g} s" if "t0" in fit.values
            else f"t0 held there: {fit.fixed['t0']:.6g} s")
    return f"{found}; {used}"


def fit_report(fit, truth=None, read_warnings=()) -> str:
    """One trace's fit: the values table, then (after a blank line) the warnings of reading
    the trace, the fit's statistics, notes and warnings."""
    return "\n".join([value_table(fit, truth), "", *(f"warning: {w}" for w in read_warnings),
                      *stats_lines(fit)])


def joint_report(fit, read_warnings=()) -> str:
    """A joint fit: the shared values, each trace's u0, t0, rms and lack of fit, then the
    correlation, loss, convergence, notes and warnings."""
    out = [value_table(fit), "",
           f"{'trace':<28}{'u0 [m]':>12}{'SE':>10}{'t0 [s]':>12}{'SE':>10}{'rms [m]':>11}"
           "  lack of fit"]
    for d in fit.per_trace:
        row = f"{pathlib.Path(d['source']).name[:27]:<28}"
        for p in ("u0", "t0"):
            row += (f"{d['values'][p]:>12.6g}{d['stderr'][p]:>10.2g}" if p in d["values"]
                    else f"{d['fixed'][p]:>12.6g}{'held':>10}")
        out.append(row + f"{d['rms']:>11.3g}  {'FIRES' if d['lack_of_fit']['fires'] else 'no'}")
    names = fit.joint_names
    shared = "k_f" in fit.names
    corr = _corr_lines(lambda o: fit.correlation[names.index("k_f"), names.index(o)]
                       if shared and o in fit.names else None)
    out += ["", *(f"warning: {w}" for w in read_warnings), *corr,
            _LOSS.format(fit.loss), *_closing_lines(fit)]
    return "\n".join(out)
