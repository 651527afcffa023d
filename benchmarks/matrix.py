"""Every model of the ladder on every integrator, on ordinary and adversarial inputs.

    python benchmarks/matrix.py                      # writes docs/matrix.md
    python benchmarks/matrix.py --real ../shared/data/ground_motions   # adds IELC180
                                      # with leading zeros and ChiChi.dat (real records)

The corpus and the agreement rule live in tests/helpers/matrix.py (imported here), which
`tests/test_matrix.py` asserts on; this script writes the table of `docs/matrix.md`.
"""

from __future__ import annotations

import argparse
import pathlib
import sys

import numpy as np

import rockjax

rockjax.configure()  # float64 and one CPU device per core, before any computation

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))
from helpers.matrix import (  # noqa: E402
    agreement,
    matrix,
    METHODS,
    PEAK_RTOL,
    quiet_starts,
    T1,
)


def markdown(results, times):
    cases = list(next(iter(results.values())))
    lines = [
        "# Every model on every integrator",
        "",
        "Made by `python benchmarks/matrix.py` (Table 1 column, float64, default settings of "
        "`rockjax.simulate_batch`, `max_impacts=512`); asserted by `tests/test_matrix.py`. "
        "Each cell: peak |u| [mm] / impacts / status (c = completed, o = overturned, "
        "m = max_impacts, f = solver_failure). Ground motions: the synthetic record of "
        "`rockjax.datasets.synthetic_ground_motion(duration=4, pga=3, seed=0)` with the "
        f"changes named; every case runs to {T1:g} s (releases: u0 on a zero record).",
        "",
        f"Agreement with diffrax that the tests require: the same status; the same impact "
        f"count (within 2 for housner on rk4 and dopri5, whose settling impacts are counted "
        f"down to a rest speed, and within 8 for two_spring_2dof, whose free rocking ends in "
        f"grazing landings near u_crit); peak within {PEAK_RTOL['rk4']:g} (rk4) and "
        f"{PEAK_RTOL['dopri5']:g} (dopri5) relative.",
        "",
    ]
    for model in dict.fromkeys(m for m, _ in results):
        methods = [me for (mo, me) in results if mo == model]
        lines += [f"## {model}", "", "| case | " + " | ".join(methods) + " |",
                  "|---|" + "---|" * len(methods)]
        for case in cases:
            cells = []
            for me in methods:
                p, n, st = results[model, me][case]
                cells.append(f"{1e3 * p:.4f} / {n} / {st[0]}")
            lines.append(f"| {case} | " + " | ".join(cells) + " |")
        worst = max(agreement(results, model, me, c)[2] for me in methods if me != "diffrax"
                    for c in cases)
        lines += ["", f"Largest relative peak difference from diffrax: {worst:.1e}. "
                  "Time per cell (compile included): "
                  + ", ".join(f"{me} {times[model, me]:.1f} s" for me in methods), ""]
    return "\n".join(lines)


def real_records(folder):
    """The default model on IELC180 with 0 to 1000 zeros in front and on ChiChi.dat (2 s of
    zeros at its start), every integrator at `simulate`'s defaults: a markdown table."""
    s = rockjax.mcmanus_column()
    lines = ["## Real records with quiet starts (model simplified, `rockjax.simulate` "
             "defaults)", "", "| record | " + " | ".join(METHODS) + " | largest relative "
             "peak difference |", "|---|" + "---|" * (len(METHODS) + 1)]
    for name, dt, accel, n in quiet_starts(folder):
        gm = rockjax.GroundMotion(dt=dt, accel=np.concatenate([np.zeros(n), accel]))
        t1 = float(gm.duration)
        cells = [rockjax.simulate(s, gm, t1, method=m) for m in METHODS]
        peaks = np.array([float(r.peak_u) for r in cells])
        worst = np.max(np.abs(peaks - peaks[0])) / peaks[0]
        lines.append(f"| {name} | " + " | ".join(
            f"{1e3 * float(r.peak_u):.5f} mm / {int(r.n_impacts)} / {r.status_name}"
            for r in cells) + f" | {worst:.1e} |")
    return "\n".join(lines + [""])


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=str(pathlib.Path(__file__).parents[1] / "docs" /
                                         "matrix.md"))
    ap.add_argument("--real", metavar="DIR", help="folder with IELC180.AT2 and ChiChi.dat")
    args = ap.parse_args()
    results, times = matrix()
    text = markdown(results, times)
    if args.real:
        text += "\n" + real_records(args.real)
    pathlib.Path(args.out).write_text(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
