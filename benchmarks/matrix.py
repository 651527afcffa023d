"""Every model of the ladder on every integrator, on ordinary and adversarial inputs.

    python benchmarks/matrix.py                      # writes docs/matrix.md
    python benchmarks/matrix.py --real ../shared/data/ground_motions   # adds IELC180
                                      # with leading zeros and ChiChi.dat (real records)

The corpus is made by the project (`rockjax.datasets.synthetic_ground_motion`, seed 0),
so it needs no file from outside the repository: leading zeros (0, 1, 10, 100 and 1000
samples), trailing zeros, a record that ends mid-rock, a body at rest at u = 0 under zero
forcing, a record with a constant offset, and releases at rest, at exactly u_crit and at
u_overturn. `tests/test_matrix.py` runs the same corpus (imported from this file) and
asserts the agreement; this script writes the table of `docs/matrix.md`.

`quiet_starts()` adds long records that start quietly: the real IELC180 (with 0 to 1000
zeros in front) and ChiChi.dat (2 s of zeros in the file) from a folder (`--real`), or,
without one, generated stand-ins of the same length, step and PGA (what the test uses).
"""

from __future__ import annotations

import argparse
import pathlib
import time

import numpy as np

import rockjax

rockjax.configure()  # float64 and one CPU device per core, before any computation

MODELS = ("housner", "simplified", "exact", "smooth", "rigid_body", "two_spring_2dof")
METHODS = ("diffrax", "rk4", "dopri5")
DT = 0.01
T1 = 14.0  # s: the longest record (1000 leading zeros and 4 s of motion)
#: relative peak-|u| agreement with the diffrax reference that each integrator promises
PEAK_RTOL = {"rk4": 1e-4, "dopri5": 1e-5}
#: impact counts agree exactly, except where a count is a threshold crossing: the rigid
#: block's settling impacts are counted down to a rest speed (the last one or two are
#: rounding-sensitive), and the 2-DOF body's free rocking ends in a train of grazing
#: landings: its amplitude hovers just above lift-off (u_crit), each crossing lifts a corner
#: by microns, and whether a given crossing lifts off at all is a grazing condition that no
#: two integrators resolve alike (the peaks agree to 1e-5; `docs/models.md`).
IMPACT_TOL = {("housner", "rk4"): 2, ("housner", "dopri5"): 2,
              ("two_spring_2dof", "rk4"): 8, ("two_spring_2dof", "dopri5"): 8}


def records():
    """Named ground-acceleration records [m/s²] at DT, all in one table (zero-padded)."""
    base = np.asarray(rockjax.datasets.synthetic_ground_motion(
        duration=4.0, dt=DT, pga=3.0, seed=0).accel)
    base = base[1:]  # the generator's first sample is 0: start on a non-zero sample
    cases = {f"leading zeros {n}": np.concatenate([np.zeros(n), base])
             for n in (0, 1, 10, 100, 1000)}
    cases["trailing zeros"] = np.concatenate([base, np.zeros(300)])
    cases["ends mid-rock"] = base[:200]
    cases["zero forcing, at rest"] = np.zeros(200)
    cases["constant offset"] = base + 0.3
    return cases


#: generated stand-ins for the real quiet-start records: (duration [s], PGA [m/s²], seed)
#: like IELC180 (40 s, 3.068 m/s²; the tests' record, tests/conftest.py) and ChiChi.dat
#: (50.8 s of motion after 2 s of zeros, 3.540 m/s²)
QUIET_START_SYNTHETIC = {"IELC180": (40.0, 3.068, 20), "ChiChi": (50.8, 3.540, 21)}
QUIET_START_ZEROS = (0, 1, 10, 100, 1000)


def quiet_starts(folder=None):
    """[(name, dt [s], accel [m/s²], zeros in front)]: a 40 s record with 0 to 1000 zeros
    in front, and a record whose file starts with 2 s of zeros. The real IELC180.AT2 and
    ChiChi.dat from `folder`; without it, generated records like them
    (`QUIET_START_SYNTHETIC`, the second one behind 2 s of zeros)."""
    if folder is not None:
        el = rockjax.read_record(pathlib.Path(folder) / "IELC180.AT2", units="g")
        cc = rockjax.read_record(pathlib.Path(folder) / "ChiChi.dat", units="g")
        first, second = ("IELC180", el.dt, el.accel), ("ChiChi.dat", cc.dt, cc.accel)
        quiet = "starts with 2 s of zeros"
    else:
        recs = {k: rockjax.datasets.synthetic_ground_motion(duration=d, dt=DT, pga=p, seed=s)
                for k, (d, p, s) in QUIET_START_SYNTHETIC.items()}
        first = ("synthetic like IELC180 (seed 20)", DT, recs["IELC180"].accel)
        second = ("synthetic like ChiChi.dat (seed 21)", DT,
                  np.concatenate([np.zeros(200), recs["ChiChi"].accel]))
        quiet = "2 s of zeros in front"
    runs = [(f"{first[0]}, {n} zeros in front", first[1], np.asarray(first[2]), n)
            for n in QUIET_START_ZEROS]
    return runs + [(f"{second[0]} ({quiet})", second[1], np.asarray(second[2]), 0)]


def releases(structure):
    """Named releases u0 [m] (at rest, no ground motion)."""
    s = structure
    return {
        "release at rest": 0.0,
        "release at u_crit": float(s.u_crit),
        "release at 0.5 u_overturn": 0.5 * float(s.u_overturn),
        "release at u_overturn": float(s.u_overturn),
    }


def run_cell(structure, model, method, cases, rel):
    """Peak |u| [m], impact count and status of every case, for one model and method: one
    batch (one compilation), the releases as members at rest on a zero record."""
    n = max(len(a) for a in cases.values())
    table = np.stack([np.concatenate([a, np.zeros(n - len(a))]) for a in cases.values()]
                     + [np.zeros(n)])
    record = np.array([*range(len(cases)), *[len(cases)] * len(rel)])
    u0 = np.array([0.0] * len(cases) + list(rel.values()))
    res = rockjax.simulate_batch(structure, rockjax.GroundMotion(dt=DT, accel=table), T1,
                                 record=record, u0=u0, model=model, method=method,
                                 summary_only=True, progress=False, max_impacts=512)
    names = [*cases, *rel]
    return {name: (float(res.peak_u[i]), int(res.n_impacts[i]), res.status_names[i])
            for i, name in enumerate(names)}


def matrix(structure=None, models=MODELS, methods=METHODS):
    """{(model, method): {case: (peak_u, n_impacts, status)}} and the time of each cell."""
    s = rockjax.mcmanus_column() if structure is None else structure
    cases, rel = records(), releases(s)
    results, times = {}, {}
    for model in models:
        for method in methods:
            t = time.perf_counter()
            results[model, method] = run_cell(s, model, method, cases, rel)
            times[model, method] = time.perf_counter() - t
    return results, times


def agreement(results, model, method, case):
    """(status agrees, impacts agree within IMPACT_TOL, relative peak difference) against
    diffrax."""
    p0, n0, s0 = results[model, "diffrax"][case]
    p, n, st = results[model, method][case]
    rel = abs(p - p0) / p0 if p0 > 0 else abs(p - p0)
    return st == s0, abs(n - n0) <= IMPACT_TOL.get((model, method), 0), rel


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
