r"""`fit_decay(..., model="auto")`: fit the rungs of the ladder that apply and keep the one
the trace requires.

Each rung of `RUNGS` that rockjax has (`rockjax.MODELS`) is fitted with its default
parameters (and the sensor's offsets where the trace pins them) and ranked:

1. fits that converged and pass the lack-of-fit check (their residuals are noise) first;
2. within those, and then among all the others, by Akaike's information criterion of the
   displacement residuals, $\mathrm{AIC} = n \ln(\mathrm{RSS}/n) + 2k$ ($n$ samples in
   the fit, $k$ parameters fitted): a rung with more parameters must lower the misfit by
   more than its extra parameters buy by chance. An unconverged fit is not put below a
   converged one: its AIC is an upper bound of its rung's (the optimiser stopped before
   the minimum), so a lower AIC still means the rung follows the trace better. (On the
   2-DOF body's dashpot traces of `benchmarks/model_auto.py` the true rung's fit can stop
   unconverged at 1.7 mm rms where the converged SDOF fit leaves 3.8 mm: ranking the
   converged first chose the SDOF.)

The first is returned, its `ranking` holding the table of every rung (`model`, `k`,
`aic`, `delta_aic` from the best, `rms`, `lack_of_fit`, `converged`, `k_f`, `seconds`,
`error` for a rung whose fit raised). Only the chosen fit's warnings are raised. Every rung
is a full fit: the 2-DOF body's take minutes on a laptop.
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings

import numpy as np

import rockjax

RUNGS = (("simplified", None), ("rigid_body", None), ("two_spring_2dof", "impact"),
         ("two_spring_2dof", "continuous"))
"""(model, contact) of each rung `model="auto"` fits, lowest first."""


def describe(model: str, contact) -> str:
    return model + (f" (contact {contact})" if contact else "")


def rank(rows: list) -> list:
    """`rows` (dicts with `aic`, `lack_of_fit`, `converged`, or `error`) best first, with
    `delta_aic` from the best AIC and `rank` (1 = chosen)."""
    ok = [r for r in rows if "error" not in r]

    def key(r):
        good = r["converged"] and not r["lack_of_fit"]
        return (0 if good else 1, r["aic"])

    ok.sort(key=key)
    best = min((r["aic"] for r in ok), default=math.nan)
    for i, r in enumerate(ok, 1):
        r["rank"], r["delta_aic"] = i, r["aic"] - best
    return ok + [r for r in rows if "error" in r]


def _row(model, contact, fit, seconds) -> dict:
    keep = np.ones(fit.response.u.shape, bool)
    keep[fit.outliers] = False
    n = int(np.count_nonzero(keep))
    rss = max(fit.rms**2 * n, 1e-300)
    k = len(fit.names)
    return {"model": describe(model, contact), "k": k,
            "aic": float(n * math.log(rss / n) + 2 * k), "rms": fit.rms,
            "lack_of_fit": bool(fit.lack_of_fit.get("fires")), "converged": fit.converged,
            "k_f": fit.values.get("k_f", fit.fixed.get("k_f")), "seconds": seconds}


def fit_auto(trace, structure, params, settings, optimizer, fit_single):
    """The fit of `model="auto"` (module docstring); `fit_single`: `_fit.fit_single`."""
    if params is not None:
        raise ValueError("model='auto' fits each rung with its own default parameters: "
                         f"leave params out (got {params})")
    if settings.contact is not None:
        raise ValueError("model='auto' fits each contact law of the 2-DOF body: leave "
                         "contact out")
    rows, fits = [], {}
    for model, contact in RUNGS:
        if model not in rockjax.MODELS:
            continue
        st = dataclasses.replace(settings, model=model, contact=contact)
        t0 = time.perf_counter()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                fit = fit_single(trace, structure, None, st, optimizer)
            except (ValueError, RuntimeError) as e:
                rows.append({"model": describe(model, contact), "error": str(e)})
                continue
        row = _row(model, contact, fit, time.perf_counter() - t0)
        rows.append(row)
        fits[row["model"]] = (fit, caught)
    ranked = rank(rows)
    if not fits:
        raise ValueError("model='auto': no rung could be fitted: "
                         + "; ".join(f"{r['model']}: {r['error']}" for r in ranked))
    fit, caught = fits[ranked[0]["model"]]
    for w in caught:
        warnings.warn(w.message, w.category, stacklevel=4)
    return dataclasses.replace(fit, ranking=tuple(ranked))


def ranking_table(ranking) -> str:
    """The ranking as a markdown table."""
    lines = ["| rank | model | k | AIC | dAIC | rms [mm] | lack of fit | converged | "
             "k_f [N/m] | time [s] |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in ranking:
        if "error" in r:
            lines.append(f"| - | {r['model']} | | | | | | | | refused: {r['error'][:60]} |")
            continue
        kf = "-" if r["k_f"] is None else f"{r['k_f']:.4g}"
        lines.append(f"| {r['rank']} | {r['model']} | {r['k']} | {r['aic']:.1f} | "
                     f"{r['delta_aic']:.1f} | {1e3 * r['rms']:.3g} | "
                     f"{'FIRES' if r['lack_of_fit'] else 'no'} | "
                     f"{'yes' if r['converged'] else 'NO'} | {kf} | {r['seconds']:.1f} |")
    return "\n".join(lines)
