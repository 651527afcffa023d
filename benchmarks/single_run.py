"""Time one rockjax simulation against a scipy event-restart baseline (Table 1 column).

    python benchmarks/single_run.py [--record PATH] [--repeats 5] [--json]

Cases: (a) free vibration from u0 = 0.10 m, 4 s; (b) El Centro IELC180 (scale 1.0), 40 s.
For each: rockjax compile time (first call, includes tracing and the run), rockjax run time
(median of `--repeats` calls after compiling, `jax.block_until_ready`), the scipy baseline
(`solve_ivp` DOP853, rtol=1e-8, atol=1e-10, a Python loop restarting at every impact and
every lift-off, split at every record sample; median of 3), and the accuracy of both
against a tight scipy reference (DOP853, rtol=1e-12, atol=1e-14): relative error of the
peak |u| and the impact count. The reference implementation is the independent one in
tests/test_reference_scipy.py. Prints a markdown table (and JSON with --json); writes no
files.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import pathlib
import platform
import statistics
import time

import jax
import numpy as np

import rockjax

rockjax.configure()  # float64 and one CPU device per core, before any computation

REPO = pathlib.Path(__file__).resolve().parents[1]


def _load_reference():
    path = REPO / "tests" / "test_reference_scipy.py"
    spec = importlib.util.spec_from_file_location("_rockjax_scipy_reference", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _time(fn, repeats):
    times = []
    out = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def bench_case(name, structure, excitation, t1, ts, ref_kwargs, ref, repeats):
    fields = {k: float(v) for k, v in structure.to_dict().items()}

    def run_jax():
        return jax.block_until_ready(rockjax.simulate(structure, excitation, t1, ts=ts))

    t0 = time.perf_counter()
    run_jax()
    t_compile = time.perf_counter() - t0
    t_run, res = _time(run_jax, repeats)

    t_tight, tight = _time(lambda: ref.reference_simulate(fields, t1, **ref_kwargs), 1)

    def run_scipy():
        return ref.reference_simulate(
            fields, t1, rtol=1e-8, atol=1e-10, method="DOP853", dense=False, **ref_kwargs
        )

    t_scipy, base = _time(run_scipy, 3)

    du = float(np.max(np.abs(np.asarray(res.u) - tight.u_at(ts))))
    same = int(res.n_impacts) == tight.n_impacts
    dti = float(np.max(np.abs(res.impacts - tight.impacts), initial=0.0)) if same else float("nan")

    def rel(x):
        return abs(float(x) - tight.peak_u) / tight.peak_u

    return {
        "case": name,
        "rockjax_compile_s": t_compile,
        "rockjax_run_s": t_run,
        "rockjax_peak_u": float(res.peak_u),
        "rockjax_peak_rel_err": rel(res.peak_u),
        "rockjax_n_impacts": int(res.n_impacts),
        "rockjax_max_abs_du_m": du,
        "rockjax_max_abs_dt_impact_s": dti,
        "rockjax_status": res.status_name,
        "scipy_baseline_s": t_scipy,
        "scipy_baseline_peak_rel_err": rel(base.peak_u),
        "scipy_baseline_n_impacts": base.n_impacts,
        "reference_s": t_tight,
        "reference_peak_u": tight.peak_u,
        "reference_n_impacts": tight.n_impacts,
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--record",
        default=str(REPO.parent / "shared" / "data" / "ground_motions" / "IELC180.AT2"),
        help="PEER AT2 record in g (default: ../shared/data/ground_motions/IELC180.AT2)",
    )
    ap.add_argument("--repeats", type=int, default=5, help="timed rockjax calls (median)")
    ap.add_argument("--json", action="store_true", help="also print the results as JSON")
    args = ap.parse_args(argv)

    ref = _load_reference()
    s = rockjax.mcmanus_column()
    rows = []

    rows.append(
        bench_case(
            "free vibration u0=0.10 m, 4 s",
            s,
            rockjax.FreeVibration(0.10),
            4.0,
            np.linspace(0.0, 4.0, 2001),
            dict(u0=0.10),
            ref,
            args.repeats,
        )
    )

    record = pathlib.Path(args.record)
    if record.is_file():
        gm = rockjax.GroundMotion.from_file(record, units="g")
        dt, accel = ref.read_at2(record)
        t1 = 40.0
        ts = np.linspace(0.0, t1, int(round(t1 / dt)) + 1)  # the record grid
        rows.append(
            bench_case(
                f"El Centro {record.name} x1.0, 40 s",
                s,
                gm,
                t1,
                ts,
                dict(dt=dt, accel=accel),
                ref,
                args.repeats,
            )
        )
    else:
        print(f"(record {record} not found: El Centro case skipped)")

    dev = jax.devices()[0]
    print(
        f"\nrockjax {rockjax.__version__}, jax {jax.__version__} on {dev.platform} "
        f"({dev.device_kind}), {platform.processor() or platform.machine()}; "
        "rockjax: Tsit5 rtol=1e-10 atol=1e-12; scipy baseline: DOP853 rtol=1e-8 atol=1e-10; "
        "reference: DOP853 rtol=1e-12 atol=1e-14\n"
    )
    print(
        "| case | rockjax compile [s] | rockjax run [s] | scipy baseline [s] | "
        "peak rel err rockjax | peak rel err scipy | impacts rockjax / scipy / ref | "
        "rockjax max abs du on ts [m] | rockjax max abs dt impact [s] |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['case']} | {r['rockjax_compile_s']:.2f} | {r['rockjax_run_s']:.4f} | "
            f"{r['scipy_baseline_s']:.3f} | {r['rockjax_peak_rel_err']:.1e} | "
            f"{r['scipy_baseline_peak_rel_err']:.1e} | {r['rockjax_n_impacts']} / "
            f"{r['scipy_baseline_n_impacts']} / {r['reference_n_impacts']} | "
            f"{r['rockjax_max_abs_du_m']:.1e} | {r['rockjax_max_abs_dt_impact_s']:.1e} |"
        )
    if args.json:
        print(json.dumps(rows, indent=2))
    return rows


if __name__ == "__main__":
    main()
