"""Time `identification.fit_decay` on the SYNTHETIC noisy decay trace (8 s at 200 Hz).

    python benchmarks/fit_time.py [--starts N] [--json]

Fits (k_f, r, and the nuisance u0) of the Table 1 column to `synthetic_decay_noisy`
(true k_f = 800 kN/m, r = 0.85) from 2x away: k_f = 1.6 MN/m (twice the truth) and r =
0.7. Reports the first fit's wall time in this fresh process (tracing and compiling
included), a second identical fit's wall time (compiled) and the time per optimiser
iteration (second fit / its `n_iterations`), and the recovered values against the truth
with their standard errors.
Prints a markdown table (and JSON with --json); writes no files.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
import warnings

import jax

import identification
import rockjax

NAME = "synthetic_decay_noisy"


PARAMS = ("k_f", "r", "u0")  # u0 as a nuisance: the first noisy sample would bias k_f and r


def timed_fit(trace, structure, initial, starts):
    kwargs = {} if starts is None else {"starts": starts}
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always", identification.IdentifiabilityWarning)
        t0 = time.perf_counter()
        fit = identification.fit_decay(
            trace, structure, params=PARAMS, initial=initial, progress=False, **kwargs
        )
        jax.block_until_ready(fit.response.u)
        return time.perf_counter() - t0, fit


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=None,
                    help="optimiser starts (default: fit_decay's default)")
    ap.add_argument("--json", action="store_true", help="also print the results as JSON")
    args = ap.parse_args(argv)

    trace = identification.read_trace(identification.synthetic_trace_path(NAME))
    truth = identification.synthetic_truth(NAME)
    s = rockjax.mcmanus_column()
    initial = {"k_f": 2.0 * truth["k_f"], "r": 0.7}

    t_first, fit1 = timed_fit(trace, s, initial, args.starts)
    t_second, fit = timed_fit(trace, s, initial, args.starts)
    per_iter = t_second / max(fit.n_iterations, 1)

    out = {
        "trace": NAME,
        "synthetic": True,
        "n_samples": trace.n,
        "duration_s": trace.duration,
        "initial": initial,
        "starts": args.starts,
        "first_fit_s_incl_compile": t_first,
        "second_fit_s": t_second,
        "n_iterations": fit.n_iterations,
        "s_per_iteration": per_iter,
        "converged": fit.converged,
        "loss": fit.loss,
        "rms_residual_m": fit.rms,
        "values": fit.values,
        "stderr": fit.stderr,
        "truth": {p: truth[p] for p in fit.names},
        "same_result_twice": fit.values == fit1.values,
        "warnings": list(fit.warnings),
    }

    dev = jax.devices()[0]
    print(
        f"\nfit_decay on the SYNTHETIC trace {NAME} ({trace.n} samples, {trace.duration:g} s), "
        f"from k_f = {initial['k_f']:.4g} N/m, r = {initial['r']}; rockjax "
        f"{rockjax.__version__}, jax {jax.__version__} on {dev.platform} ({dev.device_kind}), "
        f"{platform.processor() or platform.machine()}\n"
    )
    print("| first fit incl. compile [s] | second fit [s] | iterations | per iteration [ms] | "
          "converged |")
    print("|---|---|---|---|---|")
    print(f"| {t_first:.2f} | {t_second:.2f} | {fit.n_iterations} | {1e3 * per_iter:.1f} | "
          f"{fit.converged} |")
    print()
    print("| parameter | fitted | std. error | true | (fitted - true) / SE |")
    print("|---|---|---|---|---|")
    for p in fit.names:
        v, se, tv = fit.values[p], fit.stderr[p], truth[p]
        z = (v - tv) / se if se > 0 else float("nan")
        print(f"| {p} | {v:.6g} | {se:.3g} | {tv:.6g} | {z:.2f} |")
    for w in fit.warnings:
        print(f"\nIdentifiabilityWarning: {w}")
    if args.json:
        print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main()
