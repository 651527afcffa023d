"""Fidelity on an ensemble (issue 14): every model of the ladder against the 2-DOF body.

    python benchmarks/fidelity.py [--records DIR] [--scales 0.5,1,1.5,2] [--quick] [--out DIR]

The reference is the rigid body itself on two compression-only springs,
`rockjax.TwoSpring2DOF()` (contact="impact": Housner's rocking impact, Eqs 2-3, when a
landing changes the rocking side; a plastic impact of one corner at a re-landing after a
hop). Every record of the shared folder with a known unit runs at every scale; each run
lasts its record plus `rockjax.DEFAULT_TAIL` (5 s) and uses the batched fast path
(`rockjax.simulate_batch`, default settings: RK4, 4 substeps per record interval).

Rows, each against the reference:

- the paper's SDOF Eq. 1 with the laws "housner", "simplified", "exact", "smooth";
- "simplified x Gamma": the paper's SDOF with the record scaled by the body's
  participation factor Gamma = H_e (m_e H_e + m_b H_b) / I_c (I_c about the base centre),
  the correction `benchmarks/fidelity.md` of issue 6 found;
- "rigid_body": the body's own one-DOF equation (`rockjax.RigidBody`, `docs/rigid_body.md`);
- "2-DOF continuous": the same body with continuous contact and compression-only dashpots
  of 5 % of critical for the vertical mode, the spread of the reference's own contact law.

Per row: the median |peak ratio - 1| (peak |u| of the top mass), the fraction of cases
within +-25 %, the agreement of the overturning verdict, the failed runs, and the cost per
run, batched (the ensemble in one `simulate_batch` call, after a warm-up call) and single
(`rockjax.simulate`, default diffrax, IELC180 x1, after a warm-up). A case where exactly one
of the pair overturns counts as outside +-25 % with an infinite |ratio - 1|; a case where
both overturn counts as agreeing (ratio 1). It also measures the batched cost per 40-s El
Centro run of the 2-DOF body, `rigid_body` and `simplified` (64 scales 0.25-1.5), and checks
the batched reference against the adaptive diffrax integrator on IELC180.

Writes `benchmarks/fidelity.md`, `benchmarks/fidelity.json` and `benchmarks/fidelity.png`
(with --quick, a 2-record x 2-scale smoke test, into a temporary folder or --out).
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import platform
import sys
import tempfile
import time

import jax
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import rockjax  # noqa: E402

rockjax.configure()  # float64 and one CPU device per core, before any computation

HERE = pathlib.Path(__file__).resolve().parent
SHARED = HERE.parent.parent / "shared" / "data" / "ground_motions"
#: units of the shared records whose files do not state them (from PROVENANCE.md)
UNITS = {"elcentro_NS_full.dat": "g", "Northridge_Sylmar_County.dat": "m/s2"}
SCALES = (0.5, 1.0, 1.5, 2.0)
WITHIN = 0.25
MAX_IMPACTS = 2048
REF = "2-DOF impact (ref.)"


def gamma(s):
    """The body's participation factor Gamma = H_e (m_e H_e + m_b H_b) / I_c."""
    i_c = s.I_eg + s.I_bg + s.m_e * s.H_e**2 + s.m_b * s.H_b**2
    return float(s.H_e * (s.m_e * s.H_e + s.m_b * s.H_b) / i_c)


def rows(s):
    """(name, model, factor on the record) of every row; the reference first."""
    c_f = 2 * 0.05 * float(np.sqrt(float(s.k_f) * float(s.mass) / 2))
    return [
        (REF, rockjax.TwoSpring2DOF(), 1.0),
        ("housner", "housner", 1.0),
        ("simplified", "simplified", 1.0),
        ("exact", "exact", 1.0),
        ("smooth", "smooth", 1.0),
        ("simplified x Gamma", "simplified", gamma(s)),
        ("rigid_body", "rigid_body", 1.0),
        ("2-DOF continuous, 5 % dashpots",
         rockjax.TwoSpring2DOF(damping=c_f, contact="continuous"), 1.0),
    ]


def read_records(folder):
    """Every record of `folder` whose unit is known (stated in the file or in UNITS);
    returns (records, notes on the skipped files)."""
    recs, notes = [], []
    for path in sorted(pathlib.Path(folder).iterdir()):
        if path.suffix.lower() not in (".at2", ".dat", ".txt", ".csv"):
            continue
        try:
            recs.append(rockjax.read_record(path, units=UNITS.get(path.name)))
        except ValueError as e:
            notes.append(f"{path.name}: skipped ({str(e).splitlines()[0]})")
    return recs, notes


def timed(fn, repeat=1):
    """(result, seconds of the fastest of `repeat` calls after one warm-up call, warm-up)."""
    t0 = time.perf_counter()
    jax.block_until_ready(fn())
    warm = time.perf_counter() - t0
    best, out = np.inf, None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = jax.block_until_ready(fn())
        best = min(best, time.perf_counter() - t0)
    return out, best, warm


def run_ensemble(s, recs, scales):
    """Every row on every (record, scale): {row: dict of arrays and costs}."""
    n_rec = len(recs)
    rec_idx = np.repeat(np.arange(n_rec), len(scales))
    scale = np.tile(np.asarray(scales, float), n_rec)
    out = {}
    for name, model, factor in rows(s):
        def batch(model=model, factor=factor):
            return rockjax.simulate_batch(s, recs, record=rec_idx, scale=factor * scale,
                                          model=model, summary_only=True,
                                          max_impacts=MAX_IMPACTS, progress=False,
                                          fidelity_warning=False)
        res, wall, warm = timed(batch)
        out[name] = dict(peak=np.asarray(res.peak_u), status=np.asarray(res.status),
                         impacts=np.asarray(res.n_impacts), batch_s=wall, compile_s=warm,
                         per_run_s=wall / len(scale))
        print(f"  {name:32s} {len(scale)} runs in {wall:.2f} s (first call {warm:.1f} s)",
              flush=True)
    return out, rec_idx, scale


def compare(out):
    """Per row: the statistics against the reference."""
    ref = out[REF]
    ref_over = ref["status"] == 1
    stats = {}
    for name, r in out.items():
        over = r["status"] == 1
        both = over & ref_over
        ratio = np.where(both, 1.0, np.where(over | ref_over, np.inf, r["peak"] / ref["peak"]))
        dev = np.abs(ratio - 1.0)
        ok = (r["status"] <= 1) & (ref["status"] <= 1)
        stats[name] = dict(
            median=float(np.median(dev[ok])), within=float(np.mean(dev[ok] <= WITHIN)),
            verdict=float(np.mean(over[ok] == ref_over[ok])), failed=int(np.sum(~ok)),
            n=int(np.sum(ok)), ratio=ratio,
            overturned=int(np.sum(over)))
    return stats


def single_costs(s, rec):
    """Wall time [s] of one `rockjax.simulate` (default diffrax) of each row on `rec` x1."""
    gm = rockjax.GroundMotion.from_record(rec)
    t1 = float(gm.duration)
    cost = {}
    for name, model, factor in rows(s):
        exc = rockjax.GroundMotion(dt=gm.dt, accel=gm.accel, scale=factor)
        _, wall, _ = timed(lambda exc=exc, model=model: rockjax.simulate(
            s, exc, t1, model=model, max_impacts=MAX_IMPACTS, fidelity_warning=False).peak_u)
        cost[name] = wall
    return cost


def el_centro_costs(s, rec, n=64):
    """Batched cost per 40-s run [s] of the record at n scales 0.25-1.5, per model."""
    gm = rockjax.GroundMotion.from_record(rec)
    scales = np.linspace(0.25, 1.5, n)
    cost = {}
    for name, model in (("simplified", "simplified"), ("rigid_body", "rigid_body"),
                        ("two_spring_2dof", rockjax.TwoSpring2DOF())):
        _, wall, warm = timed(lambda model=model: rockjax.simulate_batch(
            s, gm, float(gm.duration), scale=scales, model=model, summary_only=True,
            progress=False, fidelity_warning=False).peak_u)
        cost[name] = dict(per_run_s=wall / n, compile_s=warm)
    return cost


def reference_check(s, rec):
    """The batched 2-DOF reference (RK4, 4 substeps) against the adaptive diffrax solve of
    the same body on `rec` at 0.5 and 1.0: relative peak differences and impact counts."""
    gm = rockjax.GroundMotion.from_record(rec)
    t1 = float(gm.duration) + rockjax.DEFAULT_TAIL
    out = []
    for scale in (0.5, 1.0):
        exc = rockjax.GroundMotion(dt=gm.dt, accel=gm.accel, scale=scale)
        a = rockjax.simulate(s, exc, t1, model="two_spring_2dof", max_impacts=MAX_IMPACTS)
        b = rockjax.simulate_batch(s, exc, t1, model="two_spring_2dof", summary_only=True,
                                   max_impacts=MAX_IMPACTS, progress=False)
        out.append(dict(scale=scale, diffrax_peak=float(a.peak_u), batch_peak=float(b.peak_u[0]),
                        rel=abs(float(b.peak_u[0]) / float(a.peak_u) - 1),
                        diffrax_impacts=int(a.n_impacts), batch_impacts=int(b.n_impacts[0])))
    return out


def split_by_amplitude(s, out, stats, limit=5.0):
    """Median |ratio - 1| of each row over the cases where the 2-DOF body peaks below and
    above `limit` u_crit (both overturned cases go with the large ones)."""
    ref = out[REF]
    big = (ref["status"] == 1) | (ref["peak"] > limit * float(s.u_crit))
    res = {}
    for name, st in stats.items():
        dev = np.abs(st["ratio"] - 1.0)
        res[name] = dict(n_small=int(np.sum(~big)), n_big=int(np.sum(big)),
                         small=float(np.median(dev[~big])) if np.any(~big) else np.nan,
                         big=float(np.median(dev[big])) if np.any(big) else np.nan,
                         within_big=float(np.mean(dev[big] <= WITHIN)) if np.any(big) else np.nan)
    return res


#: the spring-stiffness diagnostic: k_f factors and the RK4 substeps the 2-DOF body's
#: vertical mode (sqrt(2 k_f / M), 81 rad/s for Table 1) needs on the 0.005 s grid
STIFFER = ((1.0, 4), (10.0, 8), (100.0, 16))


def stiffness_trend(s, recs, scales):
    """Median |ratio - 1| and the fraction within +-25 % of rigid_body and of the paper's SDOF
    x Gamma against the 2-DOF body, as the springs stiffen (the rigid limit of all three is
    Housner's block, so what remains at x1 and vanishes with stiffness is the springs':
    the vertical dynamics and the landing on a spring)."""
    n_rec = len(recs)
    rec_idx = np.repeat(np.arange(n_rec), len(scales))
    scale = np.tile(np.asarray(scales, float), n_rec)
    trend = []
    for factor, sub in STIFFER:
        sf = s.replace(k_f=float(s.k_f) * factor)
        peaks = {}
        for name, model, g in ((REF, rockjax.TwoSpring2DOF(), 1.0),
                               ("rigid_body", "rigid_body", 1.0),
                               ("simplified x Gamma", "simplified", gamma(sf))):
            res = rockjax.simulate_batch(sf, recs, record=rec_idx, scale=g * scale, model=model,
                                         summary_only=True, max_impacts=MAX_IMPACTS,
                                         substeps=sub, progress=False, fidelity_warning=False)
            peaks[name] = dict(peak=np.asarray(res.peak_u), status=np.asarray(res.status))
        st = compare(peaks)
        trend.append(dict(k_f_factor=factor, substeps=sub, **{
            k: dict(median=v["median"], within=v["within"], verdict=v["verdict"],
                    failed=v["failed"]) for k, v in st.items() if k != REF}))
        print(f"  k_f x{factor:g}: " + ", ".join(
            f"{k} {pct(v['median'])}" for k, v in st.items() if k != REF), flush=True)
    return trend


def free_decay(s, t1=4.0, u0=0.10):
    """Free rocking from u0: the peak |u| [m] of each half-cycle (between zero crossings)
    of the reference, rigid_body, the SDOF exact model and the dashpot 2-DOF body."""
    ts = np.linspace(0.0, t1, 8001)
    out = {}
    for name, model, _ in rows(s):
        if name not in (REF, "rigid_body", "exact", "2-DOF continuous, 5 % dashpots"):
            continue
        res = rockjax.simulate(s, rockjax.FreeVibration(u0), t1, ts=ts, model=model)
        u = np.asarray(res.u)
        i = np.nonzero(np.sign(u[:-1]) * np.sign(u[1:]) < 0)[0]
        edges = np.concatenate([[0], i + 1, [len(u)]])
        out[name] = dict(amps=[float(np.max(np.abs(u[a:b]))) for a, b in
                               zip(edges[:-1], edges[1:]) if b > a][:7],
                         impacts=int(res.n_impacts))
    return out


def diagnosis_lines(s, split, trend, decay):
    """The report's section on where the remaining differences come from."""
    lines = ["## Where the remaining differences come from", "",
             "**Barely rocking cases.** The median |peak ratio − 1| over the cases where the "
             "2-DOF body peaks below 5 u_crit (the onset of rocking, where single histories "
             "are most sensitive) and above it (or overturns):", "",
             "| model | below 5 u_crit | above 5 u_crit | above: within ±25 % |",
             "|---|---|---|---|"]
    for name, v in split.items():
        if name == REF:
            continue
        lines.append(f"| {name} | {pct(v['small'])} (n = {v['n_small']}) | "
                     f"{pct(v['big'])} (n = {v['n_big']}) | {100 * v['within_big']:.0f} % |")
    lines += ["", "**The springs.** The same ensemble with the springs stiffened (k_f × 10, × "
              "100; RK4 substeps for the 2-DOF body's vertical mode in brackets). All three "
              "models tend to Housner's block, so what vanishes with stiffness is what the "
              "springs add to the 2-DOF body: its vertical motion and its landings on a spring:",
              "", "| k_f factor (substeps) | rigid_body: median, within ±25 %, verdict "
              "| simplified x Gamma: median, within ±25 %, verdict |", "|---|---|---|"]
    for t in trend:
        cells = [f"{pct(t[k]['median'])}, {100 * t[k]['within']:.0f} %, "
                 f"{100 * t[k]['verdict']:.0f} %" for k in ("rigid_body", "simplified x Gamma")]
        lines.append(f"| × {t['k_f_factor']:g} ({t['substeps']}) | " + " | ".join(cells) + " |")
    lines += ["", "**The landing.** Free rocking from u0 = 0.10 m: the peak |u| [mm] of each "
              "half-cycle. rigid_body loses exactly the factor r of Eq. 2 at each landing, as "
              "Housner's block; the 2-DOF body with the impact law loses more, because after "
              "each rocking impact the corner that landed sits on an unloaded spring and the "
              "body rings vertically on its springs (the ringing leaves at re-landings, and "
              "stays with continuous contact):", "",
              "| model | impacts in 4 s | half-cycle peaks [mm] |", "|---|---|---|"]
    for name, v in decay.items():
        lines.append(f"| {name} | {v['impacts']} | "
                     + ", ".join(f"{1e3 * a:.1f}" for a in v["amps"]) + " |")
    return lines + [""]


def pct(x):
    return "∞" if not np.isfinite(x) else f"{100 * x:.1f} %"


def report(s, recs, notes, scales, out, stats, single, quake, check, info):
    """The markdown report."""
    names = [pathlib.Path(r.source).name for r in recs]
    n = len(recs) * len(scales)
    lines = [
        "# Fidelity on an ensemble: the ladder against the 2-DOF body",
        "",
        f"Made by `python benchmarks/fidelity.py` ({info}). Table 1 column "
        f"(u_crit = {1e3 * float(s.u_crit):.2f} mm, r = {float(s.restitution):.3f} from Eq. 3, "
        f"Gamma = {gamma(s):.3f}). Records: {', '.join(names)} (every record of the shared "
        f"folder with a known unit; {'; '.join(notes) if notes else 'none skipped'}) at scales "
        f"{', '.join(f'{x:g}' for x in scales)}: {n} cases, each run to its record's end + "
        f"{rockjax.DEFAULT_TAIL:g} s. Reference: `rockjax.TwoSpring2DOF()` (impact contact, "
        "the landing law of issue 14), batched with the default settings like every row.",
        "",
        "A case where exactly one of the pair overturns counts as outside ±25 % (|ratio − 1| "
        "infinite); where both overturn, as agreeing. Failed runs (max_impacts, "
        "solver_failure) are left out and counted.",
        "",
        "| model | median \\|peak ratio − 1\\| | within ±25 % | same overturning verdict "
        "| overturned | failed | batched cost per run | single run (diffrax, IELC180 x1) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, st in stats.items():
        r = out[name]
        lines.append(
            f"| {name} | {pct(st['median'])} | {100 * st['within']:.0f} % | "
            f"{100 * st['verdict']:.0f} % | {st['overturned']}/{n} | {st['failed']} | "
            f"{1e3 * r['per_run_s']:.1f} ms | {1e3 * single[name]:.0f} ms |")
    lines += ["", "Peak ratio (model / 2-DOF body) per case:", "",
              "| record | scale | 2-DOF peak [mm] | " + " | ".join(
                  k for k in stats if k != REF) + " |",
              "|---|---|---|" + "---|" * (len(stats) - 1)]
    ref = out[REF]
    for i, (rec, sc) in enumerate(zip(np.repeat(names, len(scales)),
                                      np.tile(scales, len(recs)))):
        cell = "overturned" if ref["status"][i] == 1 else f"{1e3 * ref['peak'][i]:.1f}"
        vals = []
        for k, st in stats.items():
            if k == REF:
                continue
            o = out[k]["status"][i]
            vals.append("o" if o == 1 and ref["status"][i] == 1 else
                        ("o ≠" if o == 1 else ("≠ o" if ref["status"][i] == 1 else
                                               f"{st['ratio'][i]:.2f}")))
        lines.append(f"| {rec} | {sc:g} | {cell} | " + " | ".join(vals) + " |")
    lines += ["", "(o: both overturn; o ≠: only the model overturns; ≠ o: only the 2-DOF "
              "body overturns.)", ""]
    if quake:
        lines += ["## Cost per 40-s El Centro run, batched", "",
                  "`rockjax.simulate_batch(s, IELC180, 40.0, scale=np.linspace(0.25, 1.5, 64), "
                  "model=..., summary_only=True)`, default settings, after a warm-up call:", "",
                  "| model | per run | first call (compiles) |", "|---|---|---|"]
        for k, v in quake.items():
            lines.append(f"| {k} | {1e3 * v['per_run_s']:.2f} ms | {v['compile_s']:.1f} s |")
        base = quake["simplified"]["per_run_s"]
        lines += ["", f"rigid_body / simplified = {quake['rigid_body']['per_run_s'] / base:.2f}; "
                  f"two_spring_2dof / simplified = "
                  f"{quake['two_spring_2dof']['per_run_s'] / base:.2f}.", ""]
    if check:
        lines += ["## The reference checked against the adaptive integrator", "",
                  "The batched 2-DOF body (RK4, 4 substeps) against `rockjax.simulate(..., "
                  "model=\"two_spring_2dof\")` (diffrax, rtol 1e-10) on IELC180 + 5 s:", "",
                  "| scale | diffrax peak [mm] | batched peak [mm] | rel. difference "
                  "| impacts (diffrax / batched) |", "|---|---|---|---|---|"]
        for c in check:
            lines.append(f"| {c['scale']:g} | {1e3 * c['diffrax_peak']:.3f} | "
                         f"{1e3 * c['batch_peak']:.3f} | {c['rel']:.1e} | "
                         f"{c['diffrax_impacts']} / {c['batch_impacts']} |")
        lines.append("")
    return lines


def figure(path, s, out, stats, scales, n_rec):
    """Peak ratio against the 2-DOF body's peak (in u_crit), one panel per row."""
    names = [k for k in stats if k != REF]
    fig, axes = plt.subplots(2, (len(names) + 1) // 2, figsize=(14, 6.5), sharex=True,
                             sharey=True)
    ref = out[REF]
    x = np.where(ref["status"] == 1, np.nan, ref["peak"] / float(s.u_crit))
    for ax, name in zip(axes.flat, names):
        ratio = stats[name]["ratio"]
        fin = np.isfinite(ratio) & np.isfinite(x)
        ax.axhspan(1 - WITHIN, 1 + WITHIN, color="C2", alpha=0.15, lw=0)
        ax.scatter(x[fin], ratio[fin], s=14, c=np.tile(scales, n_rec)[fin], cmap="viridis",
                   vmin=min(scales), vmax=max(scales))
        ax.axhline(1, color="k", lw=0.6)
        st = stats[name]
        ax.set_title(f"{name}\nmedian {pct(st['median'])}, {100 * st['within']:.0f} % in ±25 %, "
                     f"verdict {100 * st['verdict']:.0f} %", fontsize=8)
        ax.set(xscale="log", yscale="log")
        ax.grid(alpha=0.3, which="both")
    for ax in axes[-1]:
        ax.set_xlabel("2-DOF peak |u| / u_crit")
    for ax in axes[:, 0]:
        ax.set_ylabel("peak ratio model / 2-DOF")
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    fig.suptitle("Fidelity on the ensemble (colour: scale; both-overturned cases not drawn)",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--records", default=os.environ.get("ROCKJAX_SHARED_DATA", str(SHARED)))
    p.add_argument("--scales", default=",".join(f"{x:g}" for x in SCALES))
    p.add_argument("--quick", action="store_true", help="2 records x 2 scales, no costs")
    p.add_argument("--out", help="folder for the report (default: benchmarks/, or a "
                   "temporary folder with --quick)")
    a = p.parse_args(argv)
    s = rockjax.mcmanus_column()
    recs, notes = read_records(a.records)
    if not recs:
        sys.exit(f"no records with a known unit in {a.records}")
    scales = [float(x) for x in a.scales.split(",")]
    if a.quick:
        recs, scales = recs[:2], scales[:2]
    out_dir = pathlib.Path(a.out or (tempfile.mkdtemp() if a.quick else HERE))
    out_dir.mkdir(parents=True, exist_ok=True)
    info = (f"{platform.machine()}, {os.cpu_count()} cores, jax {jax.__version__}, "
            f"{jax.local_device_count()} device(s), float64")
    print(f"{len(recs)} records x {len(scales)} scales ({info})", flush=True)
    out, _, _ = run_ensemble(s, recs, scales)
    stats = compare(out)
    ielc = next((r for r in recs if pathlib.Path(r.source).name == "IELC180.AT2"), recs[0])
    single = single_costs(s, ielc)
    quake = None if a.quick else el_centro_costs(s, ielc)
    check = None if a.quick else reference_check(s, ielc)
    lines = report(s, recs, notes, scales, out, stats, single, quake, check, info)
    split = split_by_amplitude(s, out, stats)
    trend = None if a.quick else stiffness_trend(s, recs, scales)
    decay = None if a.quick else free_decay(s)
    if trend is not None:
        lines += diagnosis_lines(s, split, trend, decay)
    (out_dir / "fidelity.md").write_text("\n".join(lines) + "\n")
    figure(out_dir / "fidelity.png", s, out, stats, scales, len(recs))
    summary = {k: {kk: vv for kk, vv in v.items() if kk != "ratio"} for k, v in stats.items()}
    for k in summary:
        summary[k].update(per_run_s=out[k]["per_run_s"], single_s=single[k],
                          peaks=out[k]["peak"].tolist(), status=out[k]["status"].tolist())
    (out_dir / "fidelity.json").write_text(json.dumps(
        dict(records=[pathlib.Path(r.source).name for r in recs], scales=scales, info=info, rows=summary,
             el_centro_batched=quake, reference_check=check, by_amplitude=split,
             stiffness_trend=trend, free_decay=decay), indent=1))
    print("\n".join(lines[:12 + len(stats)]))
    print(f"wrote {out_dir / 'fidelity.md'}")


if __name__ == "__main__":
    main()
