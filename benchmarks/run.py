"""All of rockjax's speed and accuracy figures, measured side by side in one run.

    python benchmarks/run.py [--record PATH] [--quick] [--only yardstick]

Writes benchmarks/results.md and benchmarks/pareto.png (and prints the tables):

(a) one El Centro run (IELC180, x1.0, 40 s, Table 1 column, full time history): rockjax
    "diffrax", "dopri5" and "rk4" against scipy `solve_ivp` event-restart baselines (RK45
    and DOP853, the independent implementation in tests/test_reference_scipy.py);
(b) batches of 1,000 and 10,000 El Centro runs (scales 0.1-2.0), summary only;
(c) the speed/accuracy trade: peak-u error and RMS error of u(t) against a tight reference,
    against time per run, for several methods and settings, the models simplified / exact /
    smooth, and float32 against float64 (the Pareto plot);
(d) the gradient cost of the identification loss (value_and_grad / value);
(e) compile times and peak memory (each in a fresh process);
(g) the compiled yardstick: rockjax's default batch (`simplified` and `rigid_body`) against
    its floor (benchmarks/floor.py: the same RK4 without events, plain JAX arrays) and a
    hand-written numba peer of the same algorithm (benchmarks/numba_peer.py; needs the
    `bench` extra, else left out), 10,000 El Centro runs, ns per member-step and the ratios.
    `--only yardstick` runs just this section and keeps the others from results.json.

All on the CPU, as a user runs it: `import rockjax` gives JAX one CPU device per core (unless
XLA_FLAGS, JAX_NUM_CPU_DEVICES or ROCKJAX_CPU_DEVICES say otherwise), and batches are split
over them.
The tight references: scipy DOP853 at rtol 1e-12 (simplified model) and rockjax "diffrax" at
rtol 1e-12 (exact and smooth models, which the scipy reference does not implement).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import statistics
import subprocess
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np
from single_run import _load_reference  # noqa: E402  (benchmarks/ is the script's dir)

import rockjax
from rockjax._status import STATUS_NAMES

rockjax.configure()  # float64 and one CPU device per core, before any computation

REPO = pathlib.Path(__file__).resolve().parents[1]
HERE = pathlib.Path(__file__).resolve().parent
T1 = 40.0


def timed(fn, repeats=5, slow=1.0):
    """(compile-or-first call [s], median of the next calls [s], result)."""
    t0 = time.perf_counter()
    out = jax.block_until_ready(fn())
    first = time.perf_counter() - t0
    times = []
    for _ in range(1 if first > slow * 3 else repeats):
        t0 = time.perf_counter()
        out = jax.block_until_ready(fn())
        times.append(time.perf_counter() - t0)
    return first, statistics.median(times), out


def errors(u, peak, ref_u, ref_peak):
    u = np.asarray(u, float)
    return (
        abs(float(peak) - ref_peak) / ref_peak,
        float(np.sqrt(np.mean((u - ref_u) ** 2))) / ref_peak,
    )


def single_runs(s, gm, ref_mod, dt, accel, quick):
    """(a) and the simplified-model part of (c)."""
    fields = {k: float(v) for k, v in s.to_dict().items()}
    ts = np.arange(int(round(T1 / dt)) + 1) * dt
    print("tight scipy reference (DOP853, rtol 1e-12) ...", flush=True)
    t0 = time.perf_counter()
    ref = ref_mod.reference_simulate(fields, T1, dt=dt, accel=accel)
    t_ref = time.perf_counter() - t0
    ref_u = ref.u_at(ts)
    rows = []

    def add(name, method, setting, first, t_run, u, peak, n_imp, dtype="float64",
            model="simplified", compile_s=None):
        e_peak, e_rms = errors(u, peak, ref_u, ref.peak_u)
        rows.append(dict(name=name, method=method, setting=setting, model=model, dtype=dtype,
                         time_s=t_run, compile_s=compile_s if compile_s is not None else
                         max(first - t_run, 0.0), peak_err=e_peak, rms_err=e_rms,
                         n_impacts=int(n_imp)))
        print(f"  {name:28s} {t_run * 1e3:10.2f} ms  peak err {e_peak:.1e}  rms {e_rms:.1e}  "
              f"impacts {int(n_imp)}", flush=True)

    rtols = (1e-6, 1e-8) if quick else (1e-6, 1e-8, 1e-10)
    for method in ("RK45", "DOP853"):
        for rtol in rtols:
            first, t_run, res = timed(
                lambda m=method, r=rtol: ref_mod.reference_simulate(
                    fields, T1, dt=dt, accel=accel, rtol=r, atol=r * 1e-2, method=m),
                repeats=3,
            )
            add(f"scipy {method} rtol {rtol:.0e}", f"scipy {method}", f"rtol {rtol:.0e}", first,
                t_run, res.u_at(ts), res.peak_u, res.n_impacts, compile_s=0.0)
    # scipy stepping over the record's samples (no restart at each): cheaper per step, but
    # the forcing's kinks cost rejected steps and accuracy
    for method, tols in (("RK45", (1e-4, 1e-6, 1e-8)), ("DOP853", (1e-4, 1e-6))):
        for rtol in tols[:2] if quick else tols:
            first, t_run, res = timed(
                lambda m=method, r=rtol: ref_mod.reference_simulate(
                    fields, T1, dt=dt, accel=accel, rtol=r, atol=r * 1e-2, method=m,
                    split=False),
                repeats=1,
            )
            add(f"scipy {method} no split rtol {rtol:.0e}", f"scipy {method} no split",
                f"rtol {rtol:.0e}", first, t_run, res.u_at(ts), res.peak_u, res.n_impacts,
                compile_s=0.0)
    for rtol in rtols:
        first, t_run, res = timed(lambda r=rtol: rockjax.simulate(s, gm, T1, rtol=r,
                                                                  atol=r * 1e-2))
        add(f"rockjax diffrax rtol {rtol:.0e}", "diffrax", f"rtol {rtol:.0e}", first, t_run,
            res.u, res.peak_u, res.n_impacts)
    for rtol in (1e-5, 1e-7, 1e-9) if quick else (1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10):
        first, t_run, res = timed(lambda r=rtol: rockjax.simulate(
            s, gm, T1, method="dopri5", rtol=r, atol=r * 1e-2))
        add(f"rockjax dopri5 rtol {rtol:.0e}", "dopri5", f"rtol {rtol:.0e}", first, t_run,
            res.u, res.peak_u, res.n_impacts)
    for sub in (1, 2, 4, 8):
        first, t_run, res = timed(lambda n=sub: rockjax.simulate(s, gm, T1, method="rk4",
                                                                 substeps=n))
        add(f"rockjax rk4 substeps {sub}", "rk4", f"substeps {sub}", first, t_run, res.u,
            res.peak_u, res.n_impacts)
    s32 = s.astype(jnp.float32)
    gm32 = rockjax.GroundMotion(dt=jnp.float32(dt), accel=jnp.asarray(gm.accel, jnp.float32))
    for sub in (1, 2, 4):
        first, t_run, res = timed(lambda n=sub: rockjax.simulate(s32, gm32, T1, method="rk4",
                                                                 substeps=n))
        add(f"rockjax rk4 substeps {sub} f32", "rk4 float32", f"substeps {sub}", first, t_run,
            res.u, res.peak_u, res.n_impacts, dtype="float32")
    first, t_run, res = timed(lambda: rockjax.simulate(s32, gm32, T1, method="dopri5",
                                                       rtol=1e-6, atol=1e-8))
    add("rockjax dopri5 rtol 1e-06 f32", "dopri5 float32", "rtol 1e-06", first, t_run, res.u,
        res.peak_u, res.n_impacts, dtype="float32")
    return rows, dict(t_ref=t_ref, peak_u=ref.peak_u, n_impacts=ref.n_impacts)


def other_models(s, gm):
    """(c) for the exact and smooth models, against a tight diffrax reference of each."""
    rows = []
    for model in ("exact", "smooth"):
        ref = rockjax.simulate(s, gm, T1, model=model, rtol=1e-12, atol=1e-14)
        ref_u = np.asarray(ref.u)
        ref_peak = float(ref.peak_u)
        runs = [(f"rk4 substeps {n}", "rk4", dict(method="rk4", substeps=n)) for n in (1, 2, 4)]
        runs += [("dopri5 rtol 1e-08", "dopri5", dict(method="dopri5", rtol=1e-8, atol=1e-10)),
                 ("diffrax rtol 1e-08", "diffrax", dict(rtol=1e-8, atol=1e-10))]
        for setting, method, kw in runs:
            first, t_run, res = timed(lambda k=kw: rockjax.simulate(s, gm, T1, model=model, **k))
            e_peak, e_rms = errors(res.u, res.peak_u, ref_u, ref_peak)
            rows.append(dict(name=f"rockjax {setting} ({model})", method=method, setting=setting,
                             model=model, dtype="float64", time_s=t_run,
                             compile_s=max(first - t_run, 0.0), peak_err=e_peak, rms_err=e_rms,
                             n_impacts=int(res.n_impacts)))
            print(f"  {model:8s} {setting:20s} {t_run * 1e3:10.2f} ms  peak err {e_peak:.1e}  "
                  f"rms {e_rms:.1e}", flush=True)
    return rows


def batches(s, gm, sizes, configs):
    """(b): summary-only batches over scales 0.1-2.0, and their accuracy on a subsample."""
    out, accs = [], []
    sub = np.linspace(0.1, 2.0, sizes[-1])[:: max(1, sizes[-1] // 24)]
    tight = rockjax.simulate_batch(s, gm, T1, scale=sub, summary_only=True, method="diffrax",
                                   rtol=1e-12, atol=1e-14, progress=False)
    ok = np.asarray(tight.status) == 0
    for substeps, dtype in configs:
        if dtype == "float32":
            sd = s.astype(jnp.float32)
            gmd = rockjax.GroundMotion(dt=jnp.float32(gm.dt),
                                       accel=jnp.asarray(gm.accel, jnp.float32))
        else:
            sd, gmd = s, gm
        for n in sizes:
            scales = np.linspace(0.1, 2.0, n).astype(dtype)
            t0 = time.perf_counter()
            rockjax.simulate_batch(sd, gmd, T1, scale=scales, summary_only=True,
                                   substeps=substeps, chunk_size=n, progress=False)
            first = time.perf_counter() - t0
            t0 = time.perf_counter()
            res = rockjax.simulate_batch(sd, gmd, T1, scale=scales, summary_only=True,
                                         substeps=substeps, chunk_size=n, progress=False)
            wall = time.perf_counter() - t0
            out.append(dict(n=n, substeps=substeps, dtype=dtype, wall_s=wall,
                            compile_s=max(first - wall, 0.0), per_run_s=wall / n,
                            runs_per_s=n / wall,
                            overturned=int(np.sum(np.asarray(res.status) == 1))))
            print(f"  batch {n:6d} substeps {substeps} {dtype}: {wall:.2f} s "
                  f"({n / wall:.0f} runs/s), compile {max(first - wall, 0.0):.1f} s", flush=True)
        # accuracy of these settings: a subsample against tight diffrax references
        fast = rockjax.simulate_batch(sd, gmd, T1, scale=sub.astype(dtype), summary_only=True,
                                      substeps=substeps, progress=False)
        err = np.abs(np.asarray(fast.peak_u) / np.asarray(tight.peak_u) - 1)
        dt_ot = np.abs(np.asarray(fast.t_overturn)[~ok] - np.asarray(tight.t_overturn)[~ok])
        acc = dict(substeps=substeps, dtype=dtype, n_checked=len(sub), n_completed=int(ok.sum()),
                   status_agree=int(np.sum(np.asarray(fast.status) == np.asarray(tight.status))),
                   max_peak_err=float(err[ok].max()), median_peak_err=float(np.median(err[ok])),
                   worst_scale=float(sub[ok][np.argmax(err[ok])]),
                   max_t_overturn_diff=float(dt_ot.max()) if dt_ot.size else 0.0)
        accs.append(acc)
        print(f"  substeps {substeps} {dtype} accuracy on {len(sub)} scales: max peak err "
              f"{acc['max_peak_err']:.1e} (scale {acc['worst_scale']:.3f}), status agree "
              f"{acc['status_agree']}/{len(sub)}", flush=True)
    return out, accs


def gradient_cost():
    """(d): value, value_and_grad (reverse) and jacfwd of the identification loss."""
    import identification

    trace = identification.read_trace(identification.synthetic_trace_path("synthetic_decay_noisy"))
    s = rockjax.mcmanus_column()
    t = jnp.asarray(trace.t - trace.t[0])
    u_meas = jnp.asarray(trace.u)
    t1 = float(t[-1])
    dt = float(np.median(np.diff(np.asarray(t))))
    rows = []
    for label, kw in (("diffrax (reverse adjoint)", dict()),
                      ("rk4, dt = trace step", dict(method="rk4", dt=dt))):
        def loss(p, kw=kw):
            k_f, r, u0 = p
            res = rockjax.simulate(s.replace(k_f=k_f), rockjax.FreeVibration(u0), t1, ts=t, r=r,
                                   **kw)
            return jnp.sum((res.u - u_meas) ** 2)

        p0 = jnp.asarray([8.0e5, 0.85, 0.1])
        f_val = jax.jit(loss)
        f_vg = jax.jit(jax.value_and_grad(loss))
        fkw = dict(kw, adjoint="forward") if not kw else kw  # diffrax: ForwardMode for jacfwd

        def loss_f(p, kw=fkw):
            return loss(p, kw)

        f_fwd = jax.jit(lambda p: (loss_f(p), jax.jacfwd(loss_f)(p)))
        c_v, t_v, _ = timed(lambda: f_val(p0))
        c_g, t_g, _ = timed(lambda: f_vg(p0))
        c_f, t_f, _ = timed(lambda: f_fwd(p0))
        # the profile: how many HLO instructions each compiled program has
        def n_hlo(f):
            import re

            return len(re.findall(r"^\s+\S+ = ", f.lower(p0).compile().as_text(), re.M))

        rows.append(dict(loss=label, value_s=t_v, value_and_grad_s=t_g, jacfwd_s=t_f,
                         hlo_value=n_hlo(f_val), hlo_grad=n_hlo(f_vg), hlo_fwd=n_hlo(f_fwd),
                         ratio_reverse=t_g / t_v, ratio_forward=t_f / t_v,
                         compile_value_s=c_v - t_v, compile_grad_s=c_g - t_g))
        print(f"  {label}: value {t_v * 1e3:.1f} ms, value_and_grad {t_g * 1e3:.1f} ms "
              f"(x{t_g / t_v:.2f}), jacfwd {t_f * 1e3:.1f} ms (x{t_f / t_v:.2f})", flush=True)
    return rows


_MEM_SNIPPET = """
import resource, sys, time, numpy as np, rockjax
case = sys.argv[1]
s = rockjax.mcmanus_column()
gm = rockjax.GroundMotion.from_file(sys.argv[2], units="g")
t0 = time.perf_counter()
if case == "import":
    pass
elif case == "single dopri5":
    rockjax.simulate(s, gm, 40.0, method="dopri5").u.block_until_ready()
elif case == "single diffrax":
    rockjax.simulate(s, gm, 40.0).u.block_until_ready()
elif case == "10,000 summaries (rk4)":
    rockjax.simulate_batch(s, gm, 40.0, scale=np.linspace(0.1, 2, 10000), summary_only=True,
                           substeps=2, progress=False)
elif case == "1,000 full histories (rk4)":
    rockjax.simulate_batch(s, gm, 40.0, scale=np.linspace(0.1, 2, 1000), substeps=2,
                           progress=False)
hwm = [l for l in open("/proc/self/status") if l.startswith("VmHWM")]
rss = int(hwm[0].split()[1]) if hwm else resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(time.perf_counter() - t0, rss)
"""


def memory(record):
    rows = []
    for case in ("import", "single diffrax", "single dopri5", "10,000 summaries (rk4)",
                 "1,000 full histories (rk4)"):
        out = subprocess.run([sys.executable, "-c", _MEM_SNIPPET, case, str(record)],
                             capture_output=True, text=True, check=True)
        wall, rss = out.stdout.split()[-2:]
        rows.append(dict(case=case, first_call_s=float(wall), peak_rss_mb=int(rss) / 1024))
        print(f"  {case}: first call {float(wall):.2f} s, peak RSS {int(rss) / 1024:.0f} MB",
              flush=True)
    return rows


def yardstick(s, gm, n=10_000, repeats=3):
    """(g): rockjax's default batch against its floor and a hand-written numba peer, side by
    side in this process on the same inputs: n El Centro runs (scales 0.25-1.5, 40 s,
    summaries). The variants: the floor (benchmarks/floor.py: the same RK4 of the same
    SDOF without event location or impacts, plain JAX arrays in one `lax.fori_loop`) on
    all devices and on one; `simulate_batch` with the `simplified` model on all devices
    and on one, and with `rigid_body` on all devices; the numba peer
    (benchmarks/numba_peer.py) on all threads and on one. Each variant is compiled first,
    then the variants run interleaved, `repeats` rounds, and the best round counts (the
    machine is shared). Without numba the peer's rows are left out."""
    import warnings

    import floor

    try:
        import numba
        import numba_peer
    except ImportError as e:
        print(f"  numba is not installed ({e}): the peer is left out "
              "(pip install -e '.[bench]')", flush=True)
        numba = numba_peer = None
    scales = np.linspace(0.25, 1.5, n)
    n_dev = len(jax.local_devices())
    steps = floor.member_steps(T1, float(gm.dt), 4, n)  # default substeps: 4
    f_inp = floor.floor_inputs(s, gm, T1)

    def rockjax_batch(model, devices):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", rockjax.FidelityWarning)
            out = rockjax.simulate_batch(s, gm, T1, scale=scales, summary_only=True,
                                         model=model, devices=devices, progress=False)
        return jax.block_until_ready(out)

    variants = {
        f"floor, {n_dev} devices": lambda: floor.simulate_floor(**f_inp, scales=scales,
                                                               devices=n_dev),
        "floor, 1 device": lambda: floor.simulate_floor(**f_inp, scales=scales, devices=1),
        f"floor (2, N) state, {n_dev} devices": lambda: floor.simulate_floor(
            **f_inp, scales=scales, devices=n_dev, stacked=True),
        f"rockjax simplified, {n_dev} devices": lambda: rockjax_batch("simplified", None),
        "rockjax simplified, 1 device": lambda: rockjax_batch("simplified", 1),
        f"rockjax rigid_body, {n_dev} devices": lambda: rockjax_batch("rigid_body", None),
    }
    if numba is not None:
        n_thr = numba.config.NUMBA_NUM_THREADS
        inp = numba_peer.peer_inputs(s, gm, T1)
        variants[f"numba, {n_thr} threads"] = lambda: numba_peer.simulate_peer(**inp,
                                                                              scales=scales)
        variants["numba, 1 thread"] = lambda: numba_peer.simulate_peer(**inp, scales=scales,
                                                                        threads=1)
    first, best, outs = {}, {k: np.inf for k in variants}, {}
    cpu = dict(best)
    for name, fn in variants.items():
        t0 = time.perf_counter()
        outs[name] = fn()
        first[name] = time.perf_counter() - t0
    for _ in range(repeats):
        for name, fn in variants.items():
            t0, c0 = time.perf_counter(), time.process_time()
            fn()
            best[name] = min(best[name], time.perf_counter() - t0)
            cpu[name] = min(cpu[name], time.process_time() - c0)
    rows = [dict(name=k, per_run_ms=best[k] / n * 1e3, ns_per_member_step=best[k] / steps * 1e9,
                 wall_s=best[k], first_s=first[k], cpu_per_run_ms=cpu[k] / n * 1e3)
            for k in variants]
    for r in rows:
        print(f"  {r['name']:34s} {r['per_run_ms']:.4f} ms/run, {r['ns_per_member_step']:6.2f} "
              f"ns per member-step, CPU {r['cpu_per_run_ms']:.4f} ms/run (best of {repeats}; "
              f"first call {r['first_s']:.1f} s)", flush=True)
    simp = best[f"rockjax simplified, {n_dev} devices"]
    ratios = dict(
        simplified_over_floor=simp / best[f"floor, {n_dev} devices"],
        simplified_over_floor_one=best["rockjax simplified, 1 device"] / best["floor, 1 device"],
        rigid_body_over_simplified=best[f"rockjax rigid_body, {n_dev} devices"] / simp,
        simplified_over_stacked_floor=simp / best[f"floor (2, N) state, {n_dev} devices"],
    )
    rj = outs[f"rockjax simplified, {n_dev} devices"]
    acc, out = None, dict(n=n, repeats=repeats, devices=n_dev, member_steps=steps,
                          date=time.strftime("%Y-%m-%d %H:%M"))
    if numba is not None:
        peer = outs[f"numba, {n_thr} threads"]
        ratios["numba_over_simplified"] = best[f"numba, {n_thr} threads"] / simp
        ratios["numba_over_simplified_one"] = (best["numba, 1 thread"]
                                               / best["rockjax simplified, 1 device"])
        pu = np.asarray(rj.peak_u)
        rel = np.abs(peer["peak_u"] - pu) / pu
        over = np.isfinite(np.asarray(rj.t_overturn)) & np.isfinite(peer["t_overturn"])
        acc = dict(max_peak_rel=float(rel.max()), median_peak_rel=float(np.median(rel)),
                   status_mismatch=int(np.sum(np.asarray(rj.status) != peer["status"])),
                   impacts_mismatch=int(np.sum(np.asarray(rj.n_impacts) != peer["n_impacts"])),
                   max_t_overturn_diff=float(np.max(np.abs(np.asarray(rj.t_overturn)[over]
                                                           - peer["t_overturn"][over]),
                                                    initial=0.0)),
                   statuses={str(k): int(v) for k, v in
                             zip(*np.unique(np.asarray(rj.status), return_counts=True))})
        out.update(threads=n_thr, numba=numba.__version__)
    print("  " + ", ".join(f"{k} {v:.2f}x" for k, v in ratios.items()), flush=True)
    if acc is not None:
        print(f"  peak-u agreement with numba: max {acc['max_peak_rel']:.1e}, statuses "
              f"differ {acc['status_mismatch']}, impact counts differ "
              f"{acc['impacts_mismatch']}", flush=True)
    return dict(out, rows=rows, ratios=ratios, accuracy=acc)


def yardstick_markdown(y):
    """The lines of section (g)."""
    L = ["\n## (g) The compiled yardstick: rockjax against its floor and a numba peer\n"]
    if y is None:
        return L + ["Not measured.\n"]
    if "ratios" not in y:  # a result of the earlier yardstick (no floor)
        return L + ["Measured before the floor was added; rerun `python benchmarks/run.py "
                    "--only yardstick`.\n"]
    L.append(f"{y['n']:,} El Centro runs (IELC180, scales 0.25-1.5, 40 s, summaries only, "
             "Table 1 column, impact rule paper), rockjax `simulate_batch(..., "
             "summary_only=True)` with its default settings (rk4, substeps 4), models "
             "`simplified` and `rigid_body`, beside **the floor** (`benchmarks/floor.py`: "
             "the same RK4 of the same `simplified` SDOF without event location or "
             "impacts, plain JAX arrays of shape (N,) in one `lax.fori_loop`, sharded over "
             "the devices the way `simulate_batch` is; also with u and v as one (2, N) "
             "array, the stepper's layout, on which XLA evaluates the RK4 chain once "
             "instead of once per output) and `benchmarks/numba_peer.py`, the "
             "same algorithm as rockjax written by hand as a scalar loop per run with "
             "`numba.prange` over the runs"
             + (f" (numba {y['numba']})" if "numba" in y else " (numba not installed)")
             + f". Measured {y['date']} by `python benchmarks/run.py --only yardstick`, all "
             "variants in one process on the same inputs, compiled first, then interleaved; "
             f"the best of {y['repeats']} rounds. **The machine is shared** with other jobs "
             "(2 cores): the ratios, measured in the same rounds, mean more than the "
             f"absolute times. A member-step is one RK4 step of one run ({y['member_steps']:,}"
             " in all: 4,000 record intervals x 4 substeps x runs).\n")
    L.append("| variant | per run [ms] | ns per member-step | CPU time per run [ms] | "
             "wall [s] | first call [s] |")
    L.append("|---|---|---|---|---|---|")
    for r in y["rows"]:
        L.append(f"| {r['name']} | {r['per_run_ms']:.4f} | {r['ns_per_member_step']:.2f} | "
                 f"{r['cpu_per_run_ms']:.4f} | {r['wall_s']:.2f} | {r['first_s']:.1f} |")
    L.append("\nCPU time is the process's, summed over its threads: the work done, less "
             "sensitive than the wall time to other jobs on the machine.\n")
    names = dict(simplified_over_floor="`simplified` / floor, all devices (target <= 2.5)",
                 simplified_over_floor_one="`simplified` / floor, one device",
                 numba_over_simplified="numba / `simplified`, all cores (target >= 4)",
                 numba_over_simplified_one="numba / `simplified`, one core",
                 rigid_body_over_simplified="`rigid_body` / `simplified`, all devices "
                                            "(target <= 1.3)",
                 simplified_over_stacked_floor="`simplified` / the floor with its state "
                                               "as one (2, N) array, all devices")
    L.append("| ratio of times | measured |")
    L.append("|---|---|")
    for k, v in y["ratios"].items():
        L.append(f"| {names.get(k, k)} | {v:.2f} |")
    a = y["accuracy"]
    if a is not None:
        L.append("")
        L.append(f"Agreement of the {y['n']:,} runs (rockjax `simplified` on all devices "
                 f"against numba): peak |u| within {a['max_peak_rel']:.1e} relative (median "
                 f"{a['median_peak_rel']:.1e}); statuses differ in {a['status_mismatch']}, "
                 f"impact counts in {a['impacts_mismatch']} runs (statuses: "
                 + ", ".join(f"{STATUS_NAMES[int(k)]} {v:,}"
                             for k, v in a["statuses"].items())
                 + f"); overturning times within {a['max_t_overturn_diff']:.1e} s.")
    L.append("")
    return L


def pareto_plot(rows, path):
    from rockjax._plotting import new_figure

    fig = new_figure(figsize=(11, 4.5))
    axes = fig.subplots(1, 2)
    styles = {"scipy RK45": ("s", "tab:gray"), "scipy DOP853": ("D", "k"),
              "scipy RK45 no split": ("s", "tab:brown"),
              "scipy DOP853 no split": ("D", "tab:purple"),
              "diffrax": ("o", "tab:blue"), "dopri5": ("^", "tab:green"),
              "rk4": ("v", "tab:red"), "rk4 float32": ("x", "tab:orange"),
              "dopri5 float32": ("+", "tab:olive")}
    fills = {"simplified": None, "exact": "none", "smooth": "none"}
    for ax, key, label in ((axes[0], "peak_err", "relative error of peak |u|"),
                           (axes[1], "rms_err", "RMS error of u(t) / peak |u|")):
        seen = set()
        for r in rows:
            marker, color = styles[r["method"]]
            lab = r["method"] if r["model"] == "simplified" else f"{r['method']} ({r['model']})"
            kw = dict(marker=marker, color=color, linestyle="none", ms=7)
            if r["model"] != "simplified":
                kw.update(mfc=fills[r["model"]], ms=10 if r["model"] == "exact" else 13)
            ax.loglog(r["time_s"], max(r[key], 1e-16), label=None if lab in seen else lab, **kw)
            seen.add(lab)
        ax.set_xlabel("time per run [s] (El Centro, 40 s, full history)")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7, loc="lower left")
    fig.suptitle("Speed against accuracy (Table 1 column, El Centro x1.0); lower left is better")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def fmt(x, spec):
    return format(x, spec) if np.isfinite(x) else "-"


def write_markdown(path, info, single, models, batch, batch_acc, grads, mem, ref,
                   yard=None):
    L = []
    L.append("# rockjax benchmark results\n")
    L.append(f"Measured by `python benchmarks/run.py` on {info['date']}: {info['machine']}. "
             "Regenerate them with the same command; every figure here comes from one run.\n")
    L.append(f"Tight reference for the simplified model: scipy DOP853 rtol 1e-12 "
             f"({ref['t_ref']:.1f} s; peak |u| = {ref['peak_u']:.10f} m, "
             f"{ref['n_impacts']} impacts). Errors are relative to its peak |u|.\n")
    L.append("## (a) One El Centro run (IELC180 x1.0, 40 s, full time history)\n")
    L.append("| run | time per run [ms] | compile [s] | peak-u error | RMS error of u(t) | "
             "impacts |")
    L.append("|---|---|---|---|---|---|")
    for r in single:
        if r["dtype"] != "float64":
            continue
        L.append(f"| {r['name']} | {r['time_s'] * 1e3:.2f} | {r['compile_s']:.1f} | "
                 f"{r['peak_err']:.1e} | {r['rms_err']:.1e} | {r['n_impacts']} |")
    by = {r["name"]: r for r in single}
    L.append("")
    L.append("Speed-ups at the same tolerance (rockjax dopri5 and scipy RK45 are the same "
             "Dormand–Prince 5(4) pair; DOP853 is scipy's fastest method here):\n")
    L.append("| rtol | dopri5 [ms] | scipy RK45 [ms] | speed-up | scipy DOP853 [ms] | speed-up |")
    L.append("|---|---|---|---|---|---|")
    for rt in ("1e-06", "1e-08", "1e-10"):
        d = by.get(f"rockjax dopri5 rtol {rt}")
        a = by.get(f"scipy RK45 rtol {rt}")
        b = by.get(f"scipy DOP853 rtol {rt}")
        if d and a and b:
            L.append(f"| {rt} | {d['time_s'] * 1e3:.1f} | {a['time_s'] * 1e3:.0f} | "
                     f"{a['time_s'] / d['time_s']:.0f}x | {b['time_s'] * 1e3:.0f} | "
                     f"{b['time_s'] / d['time_s']:.0f}x |")
    L.append("\n## (b) Batches of El Centro runs, summary only\n")
    L.append("Scales 0.1 to 2.0 (linspace), `rockjax.simulate_batch(..., summary_only=True, "
             f"substeps=...)` on {info['devices']} CPU device(s); compile excluded (a first "
             "call of the same shape).\n")
    L.append("| runs | substeps | dtype | wall [s] | runs per second | per run [ms] | "
             "compile [s] | overturned |")
    L.append("|---|---|---|---|---|---|---|---|")
    for b in batch:
        L.append(f"| {b['n']:,} | {b['substeps']} | {b['dtype']} | {b['wall_s']:.2f} | "
                 f"{b['runs_per_s']:,.0f} | "
                 f"{b['per_run_s'] * 1e3:.3f} | {b['compile_s']:.1f} | {b['overturned']:,} |")
    L.append("")
    L.append("Accuracy of these settings on a subsample of the scales, against rockjax diffrax "
             "at rtol 1e-12 (peak-u error over the runs that complete; overturning times over "
             "those that overturn):\n")
    L.append("| substeps | dtype | scales checked | max peak-u error | median | worst at scale | "
             "status agrees | max t_overturn difference [s] |")
    L.append("|---|---|---|---|---|---|---|---|")
    for a in batch_acc:
        L.append(f"| {a['substeps']} | {a['dtype']} | {a['n_checked']} "
                 f"({a['n_completed']} complete) | "
                 f"{a['max_peak_err']:.1e} | {a['median_peak_err']:.1e} | "
                 f"{a['worst_scale']:.3f} | {a['status_agree']}/{a['n_checked']} | "
                 f"{a['max_t_overturn_diff']:.1e} |")
    L.append("")
    for a in batch_acc:
        scipy_ok = [r for r in single if r["method"].startswith("scipy")
                    and r["peak_err"] <= a["max_peak_err"]]
        runs = [b for b in batch if b["substeps"] == a["substeps"] and b["dtype"] == a["dtype"]]
        if scipy_ok and runs:
            best = min(scipy_ok, key=lambda r: r["time_s"])
            per = runs[-1]["per_run_s"]
            L.append(f"- substeps {a['substeps']}, {a['dtype']}: the cheapest scipy baseline "
                     f"at least as accurate on El Centro x1.0 ({best['name']}, peak error "
                     f"{best['peak_err']:.1e}) takes {best['time_s']:.3f} s per run; the "
                     f"{runs[-1]['n']:,}-run batch is **{best['time_s'] / per:,.0f}x** faster "
                     "per run.")
    L.append("")
    L.append("## (c) Speed against accuracy\n")
    L.append("![Pareto plot](pareto.png)\n")
    L.append("| run | model | dtype | time per run [ms] | peak-u error | RMS error |")
    L.append("|---|---|---|---|---|---|")
    for r in single + models:
        L.append(f"| {r['name']} | {r['model']} | {r['dtype']} | {r['time_s'] * 1e3:.2f} | "
                 f"{r['peak_err']:.1e} | {r['rms_err']:.1e} |")
    L.append("\nThe exact and smooth rows are measured against rockjax diffrax at rtol 1e-12 "
             "with the same model.\n")
    L.append("## (d) Gradient cost of the identification loss\n")
    L.append("Loss: sum of squared residuals of u on the noisy synthetic decay trace (8 s, 200 "
             "Hz) in (k_f, r, u0).\n")
    L.append("| integrator | value [ms] | value_and_grad [ms] | ratio | value + jacfwd [ms] | "
             "ratio | compile of grad [s] | HLO instructions: value / grad / jacfwd |")
    L.append("|---|---|---|---|---|---|---|---|")
    for g in grads:
        L.append(f"| {g['loss']} | {g['value_s'] * 1e3:.1f} | {g['value_and_grad_s'] * 1e3:.1f}"
                 f" | {g['ratio_reverse']:.2f} | {g['jacfwd_s'] * 1e3:.1f} | "
                 f"{g['ratio_forward']:.2f} | {g['compile_grad_s']:.1f} | "
                 f"{g['hlo_value']:,} / {g['hlo_grad']:,} / {g['hlo_fwd']:,} |")
    L.append("\n## (e) Compile time and peak memory\n")
    L.append("Each case in a fresh Python process: the first call (tracing, compilation and one "
             "run) and the process's peak resident memory.\n")
    L.append("| case | first call [s] | peak RSS [MB] |")
    L.append("|---|---|---|")
    for m in mem:
        L.append(f"| {m['case']} | {m['first_call_s']:.2f} | {m['peak_rss_mb']:.0f} |")
    L.append("\nCompile times of the single runs are in table (a) (first call minus a later "
             "call).\n")
    fid = path.parent / "fidelity.md"
    if fid.is_file():  # issue 6's study, from its own script: one results page
        body = fid.read_text().split("\n", 1)[1]
        L.append("\n## (f) Model fidelity: the SDOF reduction against the 2-DOF body\n")
        L.append("From `python benchmarks/fidelity.py` (its own run, also in "
                 "`benchmarks/fidelity.md`); figure `fidelity.png`.\n")
        L.append("![fidelity](fidelity.png)\n")
        L.append(body.replace("\n## ", "\n### ").replace("\n# ", "\n### "))
    L += yardstick_markdown(yard)
    path.write_text("\n".join(L) + "\n")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--record", default=str(REPO.parent / "shared" / "data" / "ground_motions"
                                            / "IELC180.AT2"),
                    help="El Centro IELC180 AT2 file (default: ../shared/data/ground_motions)")
    ap.add_argument("--quick", action="store_true", help="fewer settings (a smoke run)")
    ap.add_argument("--out", default=str(HERE), help="folder for results.md and pareto.png")
    ap.add_argument("--only", choices=("yardstick",),
                    help="run only this section; the others are kept from results.json")
    ap.add_argument("--runs", type=int, default=10_000, help="runs of the yardstick (g)")
    ap.add_argument("--repeats", type=int, default=3, help="timed rounds of the yardstick (g)")
    args = ap.parse_args(argv)
    record = pathlib.Path(args.record)
    if not record.is_file():
        sys.exit(f"benchmarks/run.py: record not found: {record} (pass --record)")
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    ref_mod = _load_reference()
    s = rockjax.mcmanus_column()
    gm = rockjax.GroundMotion.from_file(record, units="g")
    dt, accel = ref_mod.read_at2(record)
    info = dict(
        date=time.strftime("%Y-%m-%d"),
        machine=f"{os.cpu_count()} CPU cores ({platform.processor() or platform.machine()}), "
        f"jax {jax.__version__}, {len(jax.devices())} JAX CPU device(s), rockjax "
        f"{rockjax.__version__}, float64 unless marked",
        devices=len(jax.devices()),
    )
    if args.only == "yardstick":
        return only_yardstick(out, s, gm, args)
    print("(a)/(c) single runs", flush=True)
    single, ref = single_runs(s, gm, ref_mod, dt, accel, args.quick)
    print("(c) other models", flush=True)
    models = other_models(s, gm)
    print("(b) batches", flush=True)
    batch, batch_acc = batches(s, gm, (1000,) if args.quick else (1000, 10000),
                               ((2, "float64"), (4, "float64"), (4, "float32")))
    print("(d) gradient cost", flush=True)
    grads = gradient_cost()
    print("(e) memory", flush=True)
    mem = memory(record)
    print("(g) the yardstick: floor, rockjax, numba", flush=True)
    yard = yardstick(s, gm, 1000 if args.quick else args.runs, args.repeats)
    pareto_plot(single + models, out / "pareto.png")
    write_markdown(out / "results.md", info, single, models, batch, batch_acc, grads, mem, ref,
                   yard)
    (out / "results.json").write_text(json.dumps(dict(info=info, single=single, models=models,
                                                      batch=batch, batch_accuracy=batch_acc,
                                                      gradients=grads, memory=mem, reference=ref,
                                                      yardstick=yard),
                                                 indent=1))
    print(f"wrote {out / 'results.md'} and {out / 'pareto.png'}")


def only_yardstick(out, s, gm, args):
    """`--only yardstick`: measure (g), keep the other sections from results.json."""
    print("(g) the yardstick: floor, rockjax, numba", flush=True)
    yard = yardstick(s, gm, args.runs, args.repeats)
    path = out / "results.json"
    if not path.is_file():
        print(json.dumps(yard, indent=1))
        print(f"no {path} to update: run benchmarks/run.py without --only first")
        return
    d = json.loads(path.read_text())
    d["yardstick"] = yard
    write_markdown(out / "results.md", d["info"], d["single"], d["models"], d["batch"],
                   d["batch_accuracy"], d["gradients"], d["memory"], d["reference"], yard)
    path.write_text(json.dumps(d, indent=1))
    print(f"wrote {out / 'results.md'} and {path}")


if __name__ == "__main__":
    main()
