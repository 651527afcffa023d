"""The time to compute a 6-record x 40-scale fragility curve (issue 16's figure).

    python benchmarks/fragility_time.py [--records DIR] [--scales 0.2:6:40] [--repeats 2]

Six real records of the shared folder (El Centro twice, Kobe, Loma Prieta, Chi-Chi,
Northridge: 0.005 to 0.02 s, 31 to 150 s) at 40 scale factors on the Table 1 column,
`rockjax.sweep(..., model="rigid_body")` with its other defaults (each run to its record's
end + 5 s, rk4, 4 substeps) and `rockjax.fragility(..., "PGA")` with its defaults (1000
bootstrap resamples of the records). Prints the first call of each (it compiles) and the
best of the later ones, the fit, the core count and the load average (the machine may be
shared), as a Markdown table.
"""

from __future__ import annotations

import argparse
import os
import pathlib
import sys
import time

import numpy as np
from _shared import shared_folder

import rockjax

rockjax.configure()  # float64 and one CPU device per core, before any computation

RECORDS = (
    ("IELC180.AT2", None),
    ("elCentro.AT2", None),
    ("RSN1106_KOBE_KJM000.AT2", None),
    ("RSN753_LOMAP_CLS000.AT2", None),
    ("ChiChi.dat", None),
    ("Northridge_Sylmar_County.dat", "m/s2"),
)


def scales(text):
    a, b, n = text.split(":")
    return np.linspace(float(a), float(b), int(n))


def timed(fn, repeats):
    """(first call [s], best later call [s], the last result)."""
    times, out = [], None
    for _ in range(1 + repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return times[0], (min(times[1:]) if repeats else float("nan")), out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=pathlib.Path, default=shared_folder())
    ap.add_argument("--scales", type=scales, default=scales("0.2:6:40"))
    ap.add_argument("--repeats", type=int, default=2)
    a = ap.parse_args(argv)
    if not a.records.is_dir():
        sys.exit(f"records folder not found: {a.records} (--records DIR)")
    recs = [rockjax.read_record(a.records / name, units=units) for name, units in RECORDS]
    s = rockjax.mcmanus_column()
    print(f"cores: {os.cpu_count()} (usable {len(os.sched_getaffinity(0))}), CPU devices: "
          f"{rockjax._devices.DEVICE_CHOICE}, load average {os.getloadavg()[0]:.2f}")
    n = len(recs) * a.scales.size
    t_sw = timed(lambda: rockjax.sweep(s, recs, a.scales, model="rigid_body", progress=False),
                 a.repeats)
    sw = t_sw[2]
    t_fit = timed(lambda: rockjax.fragility(sw, "PGA"), a.repeats)
    f = t_fit[2]
    print(f"\n{len(recs)} records x {a.scales.size} scales = {n} runs; status "
          + ", ".join(f"{k} {v}" for k, v in sw.status_counts().items() if v))
    print(f"median {f.median:.4g} g (90 % interval {f.median_ci[0]:.4g} to {f.median_ci[1]:.4g}),"
          f" beta {f.beta:.3g} ({f.beta_ci[0]:.3g} to {f.beta_ci[1]:.3g}); bootstrap "
          + ", ".join(f"{k} {v}" for k, v in f.bootstrap_counts.items() if v))
    print("\n| step | first call (compiles) [s] | later call [s] |")
    print("|---|---|---|")
    print(f"| rockjax.sweep ({n} runs, rigid_body) | {t_sw[0]:.2f} | {t_sw[1]:.2f} |")
    print(f"| rockjax.fragility (PGA, 1000 resamples) | {t_fit[0]:.2f} | {t_fit[1]:.2f} |")
    print(f"| total | {t_sw[0] + t_fit[0]:.2f} | {t_sw[1] + t_fit[1]:.2f} |")
    print(f"\nload average at the end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
