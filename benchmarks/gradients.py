"""The price of a gradient: value, value_and_grad (reverse) and value + jacfwd (forward) of
the identification loss, on the rk4 stepper and on the default method (diffrax).

Loss: sum((simulate(...).u - u_meas)**2) of a free-vibration decay of the Table 1 column
on the noisy synthetic trace shipped with `identification` (8 s, 200 Hz), in
(k_f, r, u0). The three programs of each method are compiled first, then timed
interleaved (value, grad, jacfwd, value, ...), best of `--repeats` rounds: the machine
may be shared, and the best of interleaved rounds is the least disturbed comparison.

    python benchmarks/gradients.py [--repeats 7] [--out benchmarks]

Writes gradients.md and gradients.json next to this file (or into --out).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import time

import jax
import jax.numpy as jnp
import numpy as np

import identification
import rockjax

rockjax.configure()  # float64 and one CPU device per core, before any computation

HERE = pathlib.Path(__file__).resolve().parent
P0 = jnp.asarray([8.0e5, 0.85, 0.1])  # k_f [N/m], r, u0 [m]


def losses():
    """{label: (loss for reverse mode, loss for forward mode)} on the synthetic trace."""
    trace = identification.read_trace(
        identification.synthetic_trace_path("synthetic_decay_noisy"))
    s = rockjax.mcmanus_column()
    t = jnp.asarray(trace.t - trace.t[0])
    u_meas = jnp.asarray(trace.u)
    t1 = float(t[-1])
    dt = float(np.median(np.diff(np.asarray(t))))

    def make(**kw):
        def loss(p):
            k_f, r, u0 = p
            res = rockjax.simulate(s.replace(k_f=k_f), rockjax.FreeVibration(u0), t1, ts=t,
                                   r=r, **kw)
            return jnp.sum((res.u - u_meas) ** 2)

        return loss

    rk4 = make(method="rk4", dt=dt)
    return {
        "rk4, dt = trace step": (rk4, rk4),
        "diffrax (default)": (make(), make(adjoint="forward")),
    }


def programs(loss, loss_fwd):
    return {
        "value": jax.jit(loss),
        "value_and_grad": jax.jit(jax.value_and_grad(loss)),
        "value + jacfwd": jax.jit(lambda p: (loss_fwd(p), jax.jacfwd(loss_fwd)(p))),
    }


def measure(repeats):
    rows = []
    for label, (loss, loss_fwd) in losses().items():
        progs = programs(loss, loss_fwd)
        compile_s, best, results = {}, {}, {}
        for name, f in progs.items():
            t0 = time.perf_counter()
            results[name] = jax.block_until_ready(f(P0))
            compile_s[name] = time.perf_counter() - t0
        for _ in range(repeats):
            for name, f in progs.items():
                t0 = time.perf_counter()
                jax.block_until_ready(f(P0))
                best[name] = min(best.get(name, np.inf), time.perf_counter() - t0)
        g_rev = np.asarray(results["value_and_grad"][1])
        g_fwd = np.asarray(results["value + jacfwd"][1])
        v = best["value"]
        rows.append(dict(
            method=label, value_ms=1e3 * v,
            value_and_grad_ms=1e3 * best["value_and_grad"],
            value_jacfwd_ms=1e3 * best["value + jacfwd"],
            ratio_reverse=best["value_and_grad"] / v, ratio_forward=best["value + jacfwd"] / v,
            compile_s={k: compile_s[k] - best[k] for k in progs},
            grad_rev_vs_fwd=float(np.max(np.abs(g_rev - g_fwd) / np.abs(g_fwd))),
        ))
        print(f"{label}: value {1e3 * v:.2f} ms, value_and_grad "
              f"{1e3 * best['value_and_grad']:.1f} ms (x{rows[-1]['ratio_reverse']:.1f}), "
              f"value + jacfwd {1e3 * best['value + jacfwd']:.1f} ms "
              f"(x{rows[-1]['ratio_forward']:.1f})", flush=True)
    return rows


def markdown(rows, meta):
    lines = [
        "# Gradient cost of the identification loss",
        "",
        "Written by `python benchmarks/gradients.py`. Loss: sum of squared residuals of u "
        "on the noisy synthetic decay trace (8 s, 200 Hz, 1601 samples) in (k_f, r, u0) "
        "of the Table 1 column. Times are the best of "
        f"{meta['repeats']} interleaved rounds after compilation, on {meta['machine']} "
        f"({meta['cpus']} CPUs, {meta['load']}); the machine was shared with other jobs, "
        "so compare ratios within a row rather than absolute times across runs.",
        "",
        "| method | value [ms] | value_and_grad [ms] | ratio | value + jacfwd [ms] | ratio "
        "| compile value / grad / jacfwd [s] | max rel. diff grad vs jacfwd |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        c = r["compile_s"]
        lines.append(
            f"| {r['method']} | {r['value_ms']:.2f} | {r['value_and_grad_ms']:.1f} | "
            f"{r['ratio_reverse']:.1f} | {r['value_jacfwd_ms']:.1f} | {r['ratio_forward']:.1f} "
            f"| {c['value']:.1f} / {c['value_and_grad']:.1f} / {c['value + jacfwd']:.1f} | "
            f"{r['grad_rev_vs_fwd']:.1e} |")
    lines += [
        "",
        "diffrax's forward mode uses `adjoint=\"forward\"` (`diffrax.ForwardMode`); its "
        "reverse mode the default `adjoint=\"reverse\"`. The rk4 stepper serves both modes "
        "with the same call. For a handful of parameters forward mode is the cheaper "
        "derivative on both methods; reverse mode pays off for many inputs and one output "
        "(`notebooks/07_sensitivity.ipynb`: the peak's sensitivity to every sample of a "
        "record).",
        "",
    ]
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--out", type=pathlib.Path, default=HERE)
    a = ap.parse_args(argv)
    rows = measure(a.repeats)
    meta = dict(repeats=a.repeats, machine=platform.machine(), cpus=os.cpu_count(),
                load=f"load average {os.getloadavg()[0]:.1f} at the end",
                jax=jax.__version__)
    a.out.mkdir(parents=True, exist_ok=True)
    (a.out / "gradients.json").write_text(json.dumps(dict(meta=meta, rows=rows), indent=1))
    (a.out / "gradients.md").write_text(markdown(rows, meta))
    print(f"wrote {a.out / 'gradients.md'} and gradients.json")
    return rows


if __name__ == "__main__":
    main()
