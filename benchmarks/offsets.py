"""Fits of SYNTHETIC decay traces with a sensor offset: k_f, r and the offset recovered?

    python benchmarks/offsets.py [--seeds 20] [--offsets 4,-4,8,-8] [--u0 0.1] [--unfitted]

Each trace is `identification.synthetic_trace` (the Table 1 column, simplified model,
k_f = 800 kN/m, r = 0.85, released from u0 at rest, 8 s at 200 Hz, Gaussian noise 0.5 mm)
with a constant offset added to the displacement; `fit_decay` with its defaults (k_f, r,
u0, t0, and the offset, fitted since the trace pins it). Per offset, over the seeds: the
largest error of k_f and r [%], the share of seeds whose k_f and r lie within 2 standard
errors of the truth (and within 1), the largest |error| / standard error (z), the largest
error of the fitted offset [mm], how often the lack-of-fit check fired, and the mean fit
time (the first fit compiles; excluded).
`--unfitted`: also one fit per offset with `offset=False` (what the fit did before the
offset was a parameter; slow: k_f can run away). Prints a markdown table.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import identification
import rockjax

rockjax.configure()

K_F, R = 800e3, 0.85


def fit(offset_mm: float, seed: int, u0: float, **kw):
    trace, truth = identification.synthetic_trace(k_f=K_F, r=R, u0=u0, offset=offset_mm * 1e-3,
                                                  seed=seed)
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        f = identification.fit_decay(trace, rockjax.mcmanus_column(), **kw)
    return f, time.perf_counter() - t0, caught


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--offsets", default="4,-4,8,-8", help="offsets [mm], comma-separated")
    ap.add_argument("--u0", type=float, default=0.1, help="release displacement [m]")
    ap.add_argument("--unfitted", action="store_true")
    a = ap.parse_args(argv)
    offsets = [float(x) for x in a.offsets.split(",")]
    fit(offsets[0], 10_000, a.u0)  # compile
    print(f"SYNTHETIC traces: k_f = {K_F:g} N/m, r = {R}, u0 = {a.u0} m, 8 s at 200 Hz, "
          f"noise 0.5 mm; {a.seeds} seeds per offset; fit_decay defaults\n")
    print("| offset [mm] | max abs k_f err [%] | max abs r err [%] | k_f within 2 se (1 se) "
          "| r within 2 se (1 se) | max abs z k_f, r | max abs offset err [mm] | "
          "lack of fit fired | converged | mean fit [s] |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for off in offsets:
        rows = []
        for seed in range(a.seeds):
            f, wall, _ = fit(off, seed, a.u0)
            ek = f.values["k_f"] / K_F - 1
            er = f.values["r"] / R - 1
            rows.append((ek, er, abs(ek * K_F) / f.stderr["k_f"], abs(er * R) / f.stderr["r"],
                         f.values.get("offset", np.nan) - off * 1e-3,
                         f.lack_of_fit["fires"], f.converged, wall))
        x = np.array(rows, float)
        n = len(rows)
        print(f"| {off:+g} | {100 * np.max(np.abs(x[:, 0])):.3f} | "
              f"{100 * np.max(np.abs(x[:, 1])):.3f} | "
              f"{np.sum(x[:, 2] <= 2)}/{n} ({np.sum(x[:, 2] <= 1)}/{n}) | "
              f"{np.sum(x[:, 3] <= 2)}/{n} ({np.sum(x[:, 3] <= 1)}/{n}) | "
              f"{np.max(x[:, 2]):.2f}, {np.max(x[:, 3]):.2f} | "
              f"{1e3 * np.max(np.abs(x[:, 4])):.3f} | {int(x[:, 5].sum())}/{n} | "
              f"{int(x[:, 6].sum())}/{n} | {x[:, 7].mean():.2f} |")
    if a.unfitted:
        print("\nThe same traces fitted with offset=False (seed 0):\n")
        print("| offset [mm] | k_f err [%] | r err [%] | lack of fit fired | diagnosis | "
              "fit [s] |")
        print("|---|---|---|---|---|---|")
        for off in offsets:
            f, wall, _ = fit(off, 0, a.u0, offset=False)
            d = f.diagnosis or {}
            print(f"| {off:+g} | {100 * (f.values['k_f'] / K_F - 1):+.2f} | "
                  f"{100 * (f.values['r'] / R - 1):+.3f} | {f.lack_of_fit['fires']} | "
                  f"{d.get('cause')} | {wall:.1f} |")


if __name__ == "__main__":
    main()
