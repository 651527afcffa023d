"""Which model of the ladder recovers k_f and r (or c_f) from which SYNTHETIC decay trace,
and whether the lack-of-fit check of `identification.fit_decay` fires.

    python benchmarks/fit_models.py [--traces NAME ...] [--models NAME ...] [--json FILE]
                                    [--optimizer lm|optimistix]

The traces are the SYNTHETIC decay traces of the model ladder (`sdof`, `2dof_continuous`,
`2dof_impact`, `rigid_body`) that `tests/helpers/fit_models.py` makes and describes; the fits
integrate with diffrax's Tsit5 at rtol 1e-9.

Every fit uses `fit_decay`'s defaults (the model's parameters, starts and horizons) from
k_f = 2 x the truth, r from Eq. 3 and, for the dashpots, 5 % of critical at that k_f.
Prints a markdown table: each parameter's estimate +- standard error (truth in the
header; a k_f beyond 1000 x the truth as "-> inf", the rigid limit), the rms residual,
the lack-of-fit statistics (lag-1 autocorrelation of the residuals, runs-test z), whether
the check fires, and the fit's wall time, compile included (JAX's caches are cleared
before each fit). The traces are made by `make_trace` of tests/helpers/fit_models.py,
which tests/test_fit_models.py uses too.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import sys
import time
import warnings

import jax

import identification
import rockjax

rockjax.configure()  # float64 and one CPU device per core, before any computation

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))
from helpers.fit_models import make_trace, TRACES  # noqa: E402

#: the model configurations fitted: (label, model, contact)
MODELS = (
    ("housner", "housner", None),
    ("simplified", "simplified", None),
    ("exact", "exact", None),
    ("smooth", "smooth", None),
    ("rigid_body", "rigid_body", None),
    ("2dof impact", "two_spring_2dof", "impact"),
    ("2dof continuous", "two_spring_2dof", "continuous"),
)


def optimistix_lm():
    """The optimistix solver compared with fit_decay's own Levenberg-Marquardt."""
    import optimistix

    return optimistix.LevenbergMarquardt(rtol=1e-6, atol=1e-9)


def fit_one(trace, truth, model, contact, **kwargs):
    """(fit, wall time [s], warning messages) of one model from k_f = 2 x the truth."""
    s = rockjax.mcmanus_column()
    initial = {"k_f": 2.0 * truth["k_f"]}
    jax.clear_caches()  # every fit's time includes its compile
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", identification.IdentifiabilityWarning)
        warnings.simplefilter("always", identification.OutlierWarning)
        t0 = time.perf_counter()
        fit = identification.fit_decay(trace, s, model=model, contact=contact,
                                       initial=initial, progress=False, **kwargs)
        wall = time.perf_counter() - t0
    return fit, wall, [str(w.message) for w in caught]


def _estimate(fit, p, truth):
    if p not in fit.values:
        return "held" if p in fit.fixed else "-"
    v, se = fit.values[p], fit.stderr[p]
    if p == "k_f" and v > 1e3 * truth["k_f"]:
        return f"-> inf ({v:.0e})"
    if p == "k_f":
        return f"{v / 1e3:.1f} ± {se / 1e3:.2g}"
    return f"{v:.3f} ± {se:.2g}" if p == "r" else f"{v:.0f} ± {se:.2g}"


def row(trace_name, truth, label, fit, wall):
    lack = fit.lack_of_fit
    err = (f"{100 * (fit.values['k_f'] / truth['k_f'] - 1):+.1f} %" if "k_f" in fit.values
           else "-")
    if "k_f" in fit.values and fit.values["k_f"] > 1e3 * truth["k_f"]:
        err = "rigid limit"
    return {
        "trace": trace_name, "model": label, "k_f": _estimate(fit, "k_f", truth),
        "k_f_error": err, "r": _estimate(fit, "r", truth), "c_f": _estimate(fit, "c_f", truth),
        "rms_mm": 1e3 * fit.rms, "rho1": lack["lag1_autocorrelation"],
        "runs_z": lack["runs_z"], "fires": lack["fires"], "converged": fit.converged,
        "time_s": wall, "values": fit.values, "stderr": fit.stderr,
        "next_model": lack["next_model"],
    }


def _truth_text(truth):
    parts = [f"k_f {truth['k_f'] / 1e3:g} kN/m"]
    if truth["r"] is not None:
        parts.append(f"r {truth['r']:.3f}")
    if truth["c_f"]:
        parts.append(f"c_f {truth['c_f']:.0f} N s/m")
    return ", ".join(parts)


def print_table(rows, truths):
    print("| trace (truth) | model | k_f [kN/m] ± SE | k_f error | r ± SE | c_f [N s/m] ± SE "
          "| rms [mm] | lag-1 autocorr. | runs z | lack of fit | converged | time [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        fires = "**fires**" if r["fires"] else "no"
        print(f"| {r['trace']} ({_truth_text(truths[r['trace']])}) | {r['model']} | {r['k_f']} "
              f"| {r['k_f_error']} | {r['r']} | {r['c_f']} | {r['rms_mm']:.2f} "
              f"| {r['rho1']:+.2f} | {r['runs_z']:+.1f} | {fires} | "
              f"{'yes' if r['converged'] else 'no'} | {r['time_s']:.0f} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--traces", nargs="+", choices=TRACES, default=list(TRACES))
    labels = [m[0] for m in MODELS]
    ap.add_argument("--models", nargs="+", choices=labels, default=labels)
    ap.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    ap.add_argument("--optimizer", choices=("lm", "optimistix"), default="lm",
                    help="fit_decay's default Levenberg-Marquardt (lm), or optimistix."
                         "LevenbergMarquardt(1e-6, 1e-9) run by optimistix.least_squares")
    args = ap.parse_args(argv)
    kwargs = {} if args.optimizer == "lm" else {"optimizer": optimistix_lm()}
    models = [m for m in MODELS if m[0] in args.models and m[1] in rockjax.MODELS]
    rows, truths = [], {}
    for name in args.traces:
        trace, truth = make_trace(name)
        truths[name] = truth
        for label, model, contact in models:
            fit, wall, _ = fit_one(trace, truth, model, contact, **kwargs)
            rows.append(row(name, truth, label, fit, wall))
            print(f"{name:16s} {label:16s} k_f {rows[-1]['k_f']:>16s} r {rows[-1]['r']:>14s} "
                  f"c_f {rows[-1]['c_f']:>10s} rms {rows[-1]['rms_mm']:.2f} mm fires "
                  f"{rows[-1]['fires']} {wall:.0f} s", flush=True)
    print()
    print_table(rows, truths)
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump({"rows": rows, "truths": truths}, f, indent=1, default=str)
    return rows


if __name__ == "__main__":
    main()
