"""Issue 25 speed figure: a 4-chain x 1,000-draw NUTS posterior (`identification.
sample_posterior`, warmup 500) of an 8-s SYNTHETIC decay trace (McManus column, k_f 800
kN/m, r 0.85, 200 Hz, 0.5 mm noise), on the CPU. Reports the fit, the gradient of the log
density (one call, compiled), the first posterior (compile included) and a second one of
the same trace and shapes (the compiled program reused), with the machine's load.

    python benchmarks/posterior_time.py [--draws 1000] [--warmup 500] [--duration 8]

Writes benchmarks/posterior_time.md (and .json).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import time
import warnings

import jax

import identification
import rockjax

rockjax.configure()  # float64 and one CPU device per core, before any computation

HERE = pathlib.Path(__file__).resolve().parent


def load():
    return os.getloadavg()[0]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--draws", type=int, default=1000)
    ap.add_argument("--warmup", type=int, default=500)
    ap.add_argument("--chains", type=int, default=4)
    ap.add_argument("--duration", type=float, default=8.0)
    ap.add_argument("--second", action="store_true", help="time a second posterior too")
    ap.add_argument("--out", default=str(HERE / "posterior_time"))
    a = ap.parse_args()
    out = {"cpu_count": os.cpu_count(), "devices": [str(d) for d in jax.devices()],
           "settings": vars(a), "load_start": load()}
    trace, truth = identification.synthetic_trace(duration=a.duration, noise=5e-4, seed=0)
    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = identification.fit_decay(trace, rockjax.mcmanus_column())
    out["fit_s"] = time.perf_counter() - t
    pb = fit.posterior_problem()
    from identification._residuals import _checks_as_nan

    g = jax.jit(jax.value_and_grad(pb.log_density))
    z0 = jax.numpy.asarray(pb.z0)
    with _checks_as_nan():
        t = time.perf_counter()
        g(z0)[1].block_until_ready()
        out["grad_compile_s"] = time.perf_counter() - t
        t = time.perf_counter()
        for _ in range(5):
            g(z0 + 1e-3)[1].block_until_ready()
        out["grad_s"] = (time.perf_counter() - t) / 5
    print(json.dumps(out), flush=True)
    runs = []
    for k in range(2 if a.second else 1):
        c0, t = time.process_time(), time.perf_counter()
        post = identification.sample_posterior(fit, chains=a.chains, draws=a.draws,
                                               warmup=a.warmup, seed=k, progress=True)
        runs.append({"wall_s": time.perf_counter() - t, "cpu_s": time.process_time() - c0,
                     "warmup_s": post.seconds["warmup_s"], "ok": post.ok,
                     "problems": list(post.problems), "rhat_max": max(post.rhat.values()),
                     "ess_min": min(post.ess.values()), "divergences": post.divergences,
                     "mean_leapfrog": post.n_leapfrog, "load_after": load(),
                     "summary": post.summary()["parameters"]})
        print(json.dumps(runs[-1]), flush=True)
        print(post.report(), flush=True)
    out["runs"] = runs
    out["truth"] = {k: truth[k] for k in ("k_f", "r", "u0")}
    out["fit"] = {"values": fit.values, "stderr": fit.stderr}
    pathlib.Path(a.out + ".json").write_text(json.dumps(out, indent=1, default=float))
    lines = [f"# Posterior time (issue 25): {a.chains} chains x {a.draws} draws, warmup "
             f"{a.warmup}, {a.duration:g}-s synthetic decay trace",
             "", f"`python benchmarks/posterior_time.py --draws {a.draws} --warmup {a.warmup}`"
             f" on {out['cpu_count']} CPU cores; load average (1 min) at start "
             f"{out['load_start']:.1f}: the machine is shared, see each run's load.", "",
             f"- fit_decay: {out['fit_s']:.1f} s; gradient of the log density: compile "
             f"{out['grad_compile_s']:.1f} s, then {1e3 * out['grad_s']:.1f} ms per call",
             ]
    for k, r in enumerate(runs):
        lines.append(f"- posterior {k + 1} ({'compile included' if k == 0 else 'program reused'}"
                     f"): wall {r['wall_s']:.1f} s (warmup {r['warmup_s']:.1f} s), CPU "
                     f"{r['cpu_s']:.1f} s, load after {r['load_after']:.1f}; ok {r['ok']}, "
                     f"R-hat max {r['rhat_max']:.4f}, ESS min {r['ess_min']:.0f}, "
                     f"divergences {r['divergences']}, {r['mean_leapfrog']:.1f} leapfrog "
                     "steps per draw")
    pathlib.Path(a.out + ".md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
