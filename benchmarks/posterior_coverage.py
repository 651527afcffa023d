"""Issue 25 acceptance figure: coverage of the NUTS posteriors on SYNTHETIC decay traces.

For each seed: a synthetic decay of the McManus column (`identification.synthetic_trace`)
with its own truth (k_f log-uniform in [500, 1200] kN/m, r uniform in [0.75, 0.92], u0
uniform in [0.06, 0.12] m) and noise (0.3, 0.5 or 1 mm), fitted by `fit_decay` from the
structure's k_f (550 kN/m) and Eq 3 r (the default parameters k_f, r, u0, t0, and the
sensor's offset where the trace pins it), then `sample_posterior` with the default priors.
Records whether the 90 % central credible intervals of k_f and r cover the truth, R-hat,
ESS, divergences, ok and the wall time, one JSON line per trace (appended: a run can be
resumed), and writes the table to benchmarks/posterior_coverage.md.

    python benchmarks/posterior_coverage.py [--n 40] [--duration 3] [--rate 100]
        [--draws 300] [--warmup 200] [--chains 4] [--out PREFIX] [--first SEED] [--report]

The traces all have the same length, so the compiled fit and the compiled sampler are
reused from the second trace on.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import time
import warnings

import numpy as np

import identification
import rockjax

HERE = pathlib.Path(__file__).resolve().parent
NOISES = (3e-4, 5e-4, 1e-3)


def truth_of(seed: int) -> dict:
    rng = np.random.default_rng(1000 + seed)
    return {"k_f": float(np.exp(rng.uniform(np.log(500e3), np.log(1200e3)))),
            "r": float(rng.uniform(0.75, 0.92)), "u0": float(rng.uniform(0.06, 0.12)),
            "noise": NOISES[seed % len(NOISES)]}


def one(seed: int, a) -> dict:
    tr = truth_of(seed)
    trace, _ = identification.synthetic_trace(k_f=tr["k_f"], r=tr["r"], u0=tr["u0"],
                                              noise=tr["noise"], duration=a.duration,
                                              rate_hz=a.rate, seed=seed)
    t = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = identification.fit_decay(trace, rockjax.mcmanus_column())
    t_fit = time.perf_counter() - t
    t = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", identification.PosteriorWarning)
        post = identification.sample_posterior(fit, chains=a.chains, draws=a.draws,
                                               warmup=a.warmup, seed=seed, progress=False)
    row = {"seed": seed, "truth": tr, "fit_s": t_fit, "posterior_s": time.perf_counter() - t,
           "ok": post.ok, "problems": list(post.problems),
           "warned": any(issubclass(w.category, identification.PosteriorWarning)
                         for w in caught),
           "rhat_max": max(post.rhat.values()), "ess_min": min(post.ess.values()),
           "divergences": post.divergences, "params": list(post.names), "load": os.getloadavg()[0],
           "likelihood": post.settings.get("likelihood", "")}
    for p in ("k_f", "r"):
        lo, hi = post.interval(p, 0.9)
        row[p] = {"lo": lo, "hi": hi, "covers": bool(lo <= tr[p] <= hi),
                  "mean": float(np.mean(post.draws[p])), "sd": float(np.std(post.draws[p])),
                  "fit": fit.values[p], "se": fit.stderr[p],
                  "laplace_covers": bool(abs(fit.values[p] - tr[p]) <= 1.645 * fit.stderr[p])}
    return row


def write_md(rows, a, path):
    n = len(rows)
    cov = {p: sum(r[p]["covers"] for r in rows) for p in ("k_f", "r")}
    lap = {p: sum(r[p]["laplace_covers"] for r in rows) for p in ("k_f", "r")}
    rmax = max(r["rhat_max"] for r in rows)
    lines = [
        "# Posterior coverage on SYNTHETIC decay traces (issue 25)", "",
        f"`python benchmarks/posterior_coverage.py --n {a.n} --duration {a.duration:g} --rate "
        f"{a.rate:g} --draws {a.draws} --warmup {a.warmup} --chains {a.chains}`", "",
        f"Traces run: **{n}** (of {a.n} asked). Each: {a.duration:g} s at {a.rate:g} Hz, "
        "truth and noise per seed (see the script), fitted from the Table 1 start, "
        f"{a.chains} chains x {a.draws} draws (warmup {a.warmup}), default priors.", "",
        f"- 90 % credible interval covers the truth: k_f {cov['k_f']}/{n} "
        f"({100 * cov['k_f'] / n:.0f} %), r {cov['r']}/{n} ({100 * cov['r'] / n:.0f} %)",
        f"- the Laplace 90 % interval (value +- 1.645 SE) for comparison: k_f "
        f"{lap['k_f']}/{n}, r {lap['r']}/{n}",
        f"- R-hat max over all traces and parameters: {rmax:.4f}; traces with R-hat > 1.01: "
        f"{sum(r['rhat_max'] > 1.01 for r in rows)}; not ok (any diagnostic): "
        f"{sum(not r['ok'] for r in rows)}; divergences in all: "
        f"{sum(r['divergences'] for r in rows)}",
        f"- wall time per trace: fit median {np.median([r['fit_s'] for r in rows]):.1f} s, "
        f"posterior median {np.median([r['posterior_s'] for r in rows]):.1f} s (first, "
        f"compile included: {rows[0]['posterior_s']:.1f} s); load average (1 min) "
        f"{min(r['load'] for r in rows):.1f} to {max(r['load'] for r in rows):.1f} on "
        f"{os.cpu_count()} cores (shared machine)", "",
        "| seed | noise [mm] | k_f true | k_f 90 % | r true | r 90 % | R-hat max | ESS min | ok |",
        "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        t = r["truth"]
        lines.append(f"| {r['seed']} | {1e3 * t['noise']:g} | {t['k_f']:.4g} | "
                     f"[{r['k_f']['lo']:.4g}, {r['k_f']['hi']:.4g}]"
                     f"{'' if r['k_f']['covers'] else ' MISS'} | {t['r']:.4f} | "
                     f"[{r['r']['lo']:.4f}, {r['r']['hi']:.4f}]"
                     f"{'' if r['r']['covers'] else ' MISS'} | {r['rhat_max']:.4f} | "
                     f"{r['ess_min']:.0f} | {r['ok']} |")
    path.write_text("\n".join(lines) + "\n")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=40)
    ap.add_argument("--duration", type=float, default=3.0)
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--draws", type=int, default=300)
    ap.add_argument("--warmup", type=int, default=200)
    ap.add_argument("--chains", type=int, default=4)
    ap.add_argument("--out", default=str(HERE / "posterior_coverage"))
    ap.add_argument("--first", type=int, default=0,
                    help="the first seed (two processes on two cores: --first 0 and --first 20 "
                    "with their own --out, then their .jsonl lines joined and --report)")
    ap.add_argument("--report", action="store_true",
                    help="only write the .md from the .jsonl (no runs)")
    a = ap.parse_args()
    jl = pathlib.Path(a.out + ".jsonl")
    rows = [json.loads(x) for x in jl.read_text().splitlines()] if jl.exists() else []
    rows.sort(key=lambda r: r["seed"])
    if a.report:
        write_md(rows, a, pathlib.Path(a.out + ".md"))
        return
    done = {r["seed"] for r in rows}
    for seed in range(a.first, a.n):
        if seed in done:
            continue
        row = one(seed, a)
        rows.append(row)
        with jl.open("a") as f:
            f.write(json.dumps(row) + "\n")
        print(json.dumps({k: row[k] for k in ("seed", "ok", "rhat_max", "posterior_s")}
                         | {p: row[p]["covers"] for p in ("k_f", "r")}), flush=True)
        write_md(rows, a, pathlib.Path(a.out + ".md"))


if __name__ == "__main__":
    main()
