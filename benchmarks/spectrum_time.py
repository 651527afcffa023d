"""The time to compute a 50-period overturning spectrum (issue 16's figure).

    python benchmarks/spectrum_time.py [--periods 50] [--repeats 2]

For the Table 1 column and a slender block (2b x 2h = 0.3 x 2 m, k_f = 1e10 N/m), each
pulse kind, omega_p / p (p t1 for the rectangular pulse) from 1 to 10: the first call (it
compiles) and the best of the later ones, default settings (rigid_body, rtol 1e-3), with
the machine's core count and load. Prints a Markdown table.
"""

from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np

import rockjax

rockjax.configure()  # float64 and one CPU device per core, before any computation


def slender_block(k_f=1e10, b=0.15, h=1.0, m=1000.0):
    """A uniform block 2b x 2h [m], m [kg], as two halves at its centroid."""
    inertia = 0.5 * m * (b * b + h * h) / 3.0
    return rockjax.RockingStructure(m_e=m / 2, m_b=m / 2, H_e=h, H_b=h, B=b, I_eg=inertia,
                                    I_bg=inertia, k_f=k_f)


def periods(s, kind, n):
    p = math.sqrt(float(s.W * s.R_c / s.I_O))
    x = np.linspace(1.0, 10.0, n)
    return x / p if kind == "rectangular" else 2 * np.pi / (p * x)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--periods", type=int, default=50)
    ap.add_argument("--repeats", type=int, default=2)
    a = ap.parse_args(argv)
    print(f"cores: {os.cpu_count()} (usable {len(os.sched_getaffinity(0))}), CPU devices: "
          f"{rockjax._devices.DEVICE_CHOICE}, load average {os.getloadavg()[0]:.2f}")
    print("\n| structure | pulse | first call [s] | later call [s] | runs | runs/s |")
    print("|---|---|---|---|---|---|")
    for name, s in (("Table 1 column", rockjax.mcmanus_column()),
                    ("slender block, k_f 1e10", slender_block())):
        for kind in ("rectangular", "one_sine", "one_cosine"):
            T = periods(s, kind, a.periods)
            times = []
            for _ in range(1 + a.repeats):
                t0 = time.perf_counter()
                sp = rockjax.overturning_spectrum(s, kind, T, progress=False)
                times.append(time.perf_counter() - t0)
            best = min(times[1:]) if a.repeats else float("nan")
            print(f"| {name} | {kind} | {times[0]:.2f} | {best:.2f} | {sp.n_runs} | "
                  f"{sp.n_runs / best:.0f} |", flush=True)
    print(f"\nload average at the end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
