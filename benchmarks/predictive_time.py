"""The time of a posterior-predictive fragility curve (issue 25's figure): 200 draws x 6
records x 40 scales, `rockjax.fragility_band` with its default settings.

    python benchmarks/predictive_time.py [--records DIR] [--draws 200] [--scales 0.2:6:40]
        [--repeats 1] [--out benchmarks/predictive_time.md]

The six shared records of `fragility_time.py` (El Centro twice, Kobe, Loma Prieta, Chi-Chi,
Northridge) at 40 scale factors on the Table 1 column, model rigid_body, draws of k_f
(lognormal, 20 % about Table 1's) and r (normal 0.735 ± 0.03) made here with a fixed seed
(stand-ins for a posterior: the time does not depend on where they come from). Prints and
writes (--out) the first call (it compiles) and the best later one, the wall and CPU
times, the core count and the load average (the machine may be shared), and the result.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time

import numpy as np

import rockjax

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from _shared import shared_folder  # noqa: E402
from fragility_time import RECORDS, scales  # noqa: E402

rockjax.configure()  # float64 and one CPU device per core, before any computation


def draws_of(n, seed=0):
    """Stand-in posterior draws of k_f [N/m] and r [-] about Table 1's values."""
    rng = np.random.default_rng(seed)
    s = rockjax.mcmanus_column()
    return {"k_f": float(s.k_f) * np.exp(0.2 * rng.standard_normal(n)),
            "r": np.clip(0.735 + 0.03 * rng.standard_normal(n), 0.0, 1.0)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=pathlib.Path, default=shared_folder())
    ap.add_argument("--draws", type=int, default=200)
    ap.add_argument("--scales", type=scales, default=scales("0.2:6:40"))
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--out", type=pathlib.Path,
                    default=pathlib.Path(__file__).resolve().parent / "predictive_time.md")
    a = ap.parse_args(argv)
    if not a.records.is_dir():
        sys.exit(f"records folder not found: {a.records} (--records DIR)")
    recs = [rockjax.read_record(a.records / name, units=units) for name, units in RECORDS]
    s, draws = rockjax.mcmanus_column(), draws_of(a.draws)
    load0 = os.getloadavg()[0]
    rows, band = [], None
    for i in range(1 + a.repeats):
        t0, c0 = time.perf_counter(), os.times()
        band = rockjax.fragility_band(s, recs, a.scales, draws, model="rigid_body",
                                      progress=False)
        c1 = os.times()
        rows.append((time.perf_counter() - t0, c1.user + c1.system - c0.user - c0.system))
        print(f"call {i + 1}: {rows[-1][0]:.1f} s wall, {rows[-1][1]:.1f} s CPU "
              f"(load average {os.getloadavg()[0]:.2f})", flush=True)
    n = band.n_runs
    later = min(rows[1:], key=lambda r: r[0]) if a.repeats else (float("nan"),) * 2
    text = [
        "# Posterior-predictive fragility: time",
        "",
        f"`python benchmarks/predictive_time.py` ({time.strftime('%Y-%m-%d')}): "
        f"`rockjax.fragility_band` of the Table 1 column, model rigid_body, {a.draws} draws "
        f"of k_f and r x {len(recs)} shared records x {a.scales.size} scales "
        f"({a.scales[0]:g} to {a.scales[-1]:g}), default settings (each record on its own "
        f"step to its end + 5 s, rk4, 4 substeps), plus the point estimate: {n} runs and "
        f"{a.draws + 1} maximum-likelihood fits.",
        "",
        f"Machine: {os.cpu_count()} cores (usable {len(os.sched_getaffinity(0))}), "
        f"load average {load0:.2f} at the start, {os.getloadavg()[0]:.2f} at the end "
        "(shared with other work: the CPU time is the figure that does not depend on it).",
        "",
        "| call | wall [s] | CPU (user + system) [s] |",
        "|---|---|---|",
        f"| first (compiles) | {rows[0][0]:.1f} | {rows[0][1]:.1f} |",
        f"| best later | {later[0]:.1f} | {later[1]:.1f} |",
        "",
        "The result:",
        "",
        "```",
        band.report(),
        "```",
        "",
    ]
    a.out.write_text("\n".join(text))
    print("\n".join(text))


if __name__ == "__main__":
    main()
