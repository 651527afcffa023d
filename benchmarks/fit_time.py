"""Time `identification.fit_decay` and `rockjax fit` on the SYNTHETIC noisy decay trace
(8 s at 200 Hz, 1601 samples).

    python benchmarks/fit_time.py [--starts N] [--repeats N] [--json] [--no-cli] [--no-joint]
                                  [--optimizer lm|optimistix]

Fits (k_f, r, and the nuisance u0) of the Table 1 column to `synthetic_decay_noisy`
(true k_f = 800 kN/m, r = 0.85) from 2x away: k_f = 1.6 MN/m (twice the truth) and r =
0.7. Measures, all wall time [s]:

- the first fit in this fresh process (tracing and compiling included), and a second
  identical fit (`--repeats` times: the machine may be shared, so the spread is shown),
  with the JAX trace / compile events counted during the second fit (there should be none);
- `rockjax fit TRACE.csv --json` in a new process, twice with a fresh persistent
  compilation cache (ROCKJAX_COMPILE_CACHE pointed at a temporary directory): the first
  fills it, the second reads it; the second's breakdown (interpreter + imports, tracing,
  lowering to MLIR, cache retrieval, the rest: running the fit) comes from a third run in a
  subprocess that records JAX's monitoring events;
- a joint fit of 4 traces (the shipped trace and three more noise draws on it: 4 x 1601
  samples with uplift, shared k_f, r; u0 of each) against the single fit, both compiled
  (second runs).

Prints markdown tables (and JSON with --json); writes no files.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
import warnings

import jax
import jax.monitoring
import numpy as np

import identification
import rockjax

rockjax.configure()  # float64 and one CPU device per core, before any computation

NAME = "synthetic_decay_noisy"
PARAMS = ("k_f", "r", "u0")  # u0 as a nuisance: the first noisy sample would bias k_f and r


class Events:
    """JAX's compile-path monitoring events (count and seconds by name) while active."""

    def __init__(self):
        self.count = collections.Counter()
        self.secs = collections.defaultdict(float)

    def __call__(self, name, secs, **kw):
        if name.startswith(("/jax/core/compile/", "/jax/compilation_cache/")):
            self.count[name] += 1
            self.secs[name] += secs

    def __enter__(self):
        jax.monitoring.register_event_duration_secs_listener(self)
        return self

    def __exit__(self, *exc):
        jax.monitoring.unregister_event_duration_listener(self)


OPTIMIZER = {}  # fit_decay's optimizer= (--optimizer optimistix), none by default


def timed_fit(trace, structure, initial, starts):
    """(wall time [s], the fit, its compile events) of one fit_decay."""
    kwargs = {**OPTIMIZER, **({} if starts is None else {"starts": starts})}
    with warnings.catch_warnings(record=True), Events() as ev:
        warnings.simplefilter("always", identification.IdentifiabilityWarning)
        t0 = time.perf_counter()
        fit = identification.fit_decay(
            trace, structure, params=PARAMS, initial=initial, progress=False, **kwargs
        )
        jax.block_until_ready(fit.response.u if hasattr(fit, "response") else 0)
        return time.perf_counter() - t0, fit, ev


def joint_traces(trace, n=4):
    """The shipped trace and `n - 1` more noise draws on it (0.5 mm on u, 0.1 mm on the
    uplift, seeds 1, 2, ...)."""
    out = [trace]
    for seed in range(1, n):
        rng = np.random.default_rng(seed)
        out.append(identification.DecayTrace(
            trace.t, trace.u + rng.normal(0, 5e-4, trace.n),
            trace.uplift + rng.normal(0, 1e-4, trace.n), source=f"{NAME} + noise seed {seed}"))
    return out


def cli_times(path, repeats):
    """Wall times of `rockjax fit PATH --json` in new processes: the first with an empty
    persistent cache, then `repeats` with it warm; and the breakdown of one warm run."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, ROCKJAX_COMPILE_CACHE=cache)
        cmd = [sys.executable, "-m", "rockjax.cli", "fit", str(path), "--json"]
        walls = []
        for _ in range(1 + repeats):
            t0 = time.perf_counter()
            subprocess.run(cmd, check=True, capture_output=True, env=env)
            walls.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        r = subprocess.run([sys.executable, "-c", _BREAKDOWN, str(path)], check=True,
                           capture_output=True, text=True, env=env)
        wall = time.perf_counter() - t0
    parts = json.loads(r.stdout.strip().splitlines()[-1])
    parts["wall_s"] = wall
    parts["startup_s"] = wall - parts["main_s"] - parts["import_s"]
    parts["run_s"] = parts["main_s"] - parts["trace_s"] - parts["lower_s"] - parts["compile_s"]
    return walls, parts


_BREAKDOWN = """
import time
t0 = time.perf_counter()
import contextlib, io, json, sys, collections
import jax.monitoring
import rockjax.cli
import identification
t_import = time.perf_counter() - t0
secs = collections.defaultdict(float)
jax.monitoring.register_event_duration_secs_listener(
    lambda name, s, **kw: secs.__setitem__(name, secs[name] + s))
with contextlib.redirect_stdout(io.StringIO()):
    t1 = time.perf_counter()
    rockjax.cli.main(["fit", sys.argv[1], "--json"])
    t_main = time.perf_counter() - t1
print(json.dumps({"import_s": t_import, "main_s": t_main,
                  "trace_s": secs["/jax/core/compile/jaxpr_trace_duration"],
                  "lower_s": secs["/jax/core/compile/jaxpr_to_mlir_module_duration"],
                  "cache_load_s": secs["/jax/compilation_cache/cache_retrieval_time_sec"],
                  "compile_s": secs["/jax/core/compile/backend_compile_duration"]}))
"""
"""(Run in a new process) `rockjax.cli.main(["fit", PATH, "--json"])` with the time of
its imports and JAX's trace / lowering / cache-retrieval / compile times; one JSON line.
(XLA's compile time includes the cache retrieval when the cache is hit.)"""


def _spread(xs):
    return f"{np.median(xs):.2f} (min {min(xs):.2f}, max {max(xs):.2f}, n={len(xs)})"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=None,
                    help="optimiser starts (default: fit_decay's default)")
    ap.add_argument("--repeats", type=int, default=3, help="repeats of the compiled timings")
    ap.add_argument("--json", action="store_true", help="also print the results as JSON")
    ap.add_argument("--no-cli", action="store_true", help="skip the `rockjax fit` timings")
    ap.add_argument("--no-joint", action="store_true", help="skip the joint fit")
    ap.add_argument("--optimizer", choices=("lm", "optimistix"), default="lm",
                    help="fit_decay's default Levenberg-Marquardt (lm), or "
                         "optimistix.LevenbergMarquardt(1e-6, 1e-9) (the CLI: always lm)")
    args = ap.parse_args(argv)
    if args.optimizer == "optimistix":
        import optimistix

        OPTIMIZER["optimizer"] = optimistix.LevenbergMarquardt(rtol=1e-6, atol=1e-9)
    else:
        OPTIMIZER.clear()

    path = identification.synthetic_trace_path(NAME)
    trace = identification.read_trace(path)
    truth = {**dict.fromkeys(identification.NUISANCE, 0.0),  # no sensor offset or drift
             **identification.synthetic_truth(NAME)}
    s = rockjax.mcmanus_column()
    initial = {"k_f": 2.0 * truth["k_f"], "r": 0.7}

    t_first, fit1, _ = timed_fit(trace, s, initial, args.starts)
    seconds = [timed_fit(trace, s, initial, args.starts) for _ in range(args.repeats)]
    t_second = [t for t, _, _ in seconds]
    fit, events = seconds[-1][1], seconds[-1][2]
    out = {
        "trace": NAME, "synthetic": True, "n_samples": trace.n,
        "duration_s": trace.duration, "initial": initial, "starts": args.starts,
        "first_fit_s_incl_compile": t_first, "second_fit_s": t_second,
        "compile_events_in_second_fit": dict(events.count),
        "n_iterations": fit.n_iterations,
        "s_per_iteration": float(np.median(t_second)) / max(fit.n_iterations, 1),
        "converged": fit.converged, "loss": fit.loss, "rms_residual_m": fit.rms,
        "values": fit.values, "stderr": fit.stderr,
        "truth": {p: truth[p] for p in fit.names},
        "same_result_twice": fit.values == fit1.values, "warnings": list(fit.warnings),
    }
    if not args.no_cli:
        out["cli_walls_s"], out["cli_breakdown"] = cli_times(path, args.repeats)
    if not args.no_joint:
        four = joint_traces(trace)
        t_j_first, _, _ = timed_fit(four, s, initial, args.starts)
        joint = [timed_fit(four, s, initial, args.starts) for _ in range(args.repeats)]
        out["joint_first_s"] = t_j_first
        out["joint_4_s"] = [t for t, _, _ in joint]
        jf = joint[-1][1]
        out["joint_values"], out["joint_stderr"] = jf.values, jf.stderr
        out["joint_n_iterations"] = jf.n_iterations
    report(out, trace, initial, fit, truth)
    if args.json:
        print(json.dumps(out, indent=2))
    return out


def report(out, trace, initial, fit, truth):
    dev = jax.devices()[0]
    print(
        f"\nfit_decay on the SYNTHETIC trace {NAME} ({trace.n} samples, {trace.duration:g} s), "
        f"params {', '.join(PARAMS)}, from k_f = {initial['k_f']:.4g} N/m, r = "
        f"{initial['r']}; rockjax {rockjax.__version__}, jax {jax.__version__} on "
        f"{dev.platform} ({dev.device_kind}), {platform.processor() or platform.machine()}, "
        f"{os.cpu_count()} cores\n"
    )
    print("| measurement | wall time [s]: median (min, max, n) |")
    print("|---|---|")
    print(f"| first `fit_decay` in a fresh process (trace + compile) | "
          f"{out['first_fit_s_incl_compile']:.2f} |")
    print(f"| second `fit_decay`, same process ({fit.n_iterations} iterations; compile "
          f"events: {sum(out['compile_events_in_second_fit'].values())}) | "
          f"{_spread(out['second_fit_s'])} |")
    if "cli_walls_s" in out:
        w, b = out["cli_walls_s"], out["cli_breakdown"]
        print(f"| `rockjax fit --json`, new process, empty compile cache | {w[0]:.2f} |")
        print(f"| `rockjax fit --json`, new process, warm compile cache | {_spread(w[1:])} |")
        print(f"| of which (one more warm run): interpreter start {b['startup_s']:.2f}, "
              f"imports {b['import_s']:.2f}, tracing {b['trace_s']:.2f}, lowering "
              f"{b['lower_s']:.2f}, cache load {b['cache_load_s']:.2f}, compile "
              f"{b['compile_s']:.2f}, run and the rest {b['run_s']:.2f} | {b['wall_s']:.2f} |")
    if "joint_4_s" in out:
        ratio = np.median(out["joint_4_s"]) / np.median(out["second_fit_s"])
        print(f"| joint fit of 4 traces, first (trace + compile) | {out['joint_first_s']:.2f} |")
        print(f"| joint fit of 4 traces, second ({out['joint_n_iterations']} iterations; "
              f"{ratio:.2f} x the single fit) | {_spread(out['joint_4_s'])} |")
    print()
    print("| parameter | fitted | std. error | true | (fitted - true) / SE |")
    print("|---|---|---|---|---|")
    for p in fit.names:
        v, se, tv = fit.values[p], fit.stderr[p], truth[p]
        z = (v - tv) / se if se > 0 else float("nan")
        print(f"| {p} | {v:.6g} | {se:.3g} | {tv:.6g} | {z:.2f} |")
    if "joint_values" in out:
        for p, v in out["joint_values"].items():
            se = out["joint_stderr"][p]
            print(f"| {p} (joint, 4 traces) | {v:.6g} | {se:.3g} | {truth[p]:.6g} | "
                  f"{(v - truth[p]) / se:.2f} |")
    for w in fit.warnings:
        print(f"\nIdentifiabilityWarning: {w}")


if __name__ == "__main__":
    main()
