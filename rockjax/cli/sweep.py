"""`rockjax sweep`: peak responses over structures x scale factors x records (CSV, plot).

Every combination runs through `rockjax.simulate_batch(summary_only=True)`, one batch per
structure; the stages are: check the inputs, load structures and records, run, write the
CSV, then plot and report.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import pathlib
import time

import numpy as np

import rockjax
from rockjax import _plotting

from ._common import (
    _check_out_dir,
    _check_png,
    _check_r,
    _check_t1_steps,
    _first_line,
    _load_structure,
    _positive_float,
    _positive_int,
    _scales,
    add_model_arguments,
    CLIError,
)

SWEEP_COLUMNS = (
    "structure",
    "record",
    "scale",
    "peak_u_m",
    "peak_uplift_m",
    "n_impacts",
    "status",
    "t_overturn_s",
)
#: the Summary fields kept per run, each reshaped to (n_scales, n_records)
_FIELDS = ("peak_u", "peak_uplift", "n_impacts", "status", "t_overturn")
#: integer status code -> name ("completed", "overturned", ...)
_STATUS_NAMES = {code: name for name, code in rockjax.STATUS.items()}


# ------------------------------------------------------------------------------ parser
def add_parser(subparsers):
    w = subparsers.add_parser(
        "sweep",
        help="peak responses over structures x scale factors x records (CSV and plot)",
        description="Run every combination of structure, scale factor and ground-motion "
        "record with the fast batched integrator (rockjax.simulate_batch, summaries only) "
        "and write one CSV row per run: structure, record, scale, peak_u_m, peak_uplift_m, "
        "n_impacts, status, t_overturn_s. The records (PEER AT2, two columns t a, or one "
        "column with --record-dt) must share one time step; shorter ones are padded with "
        "zeros.",
    )
    _add_input_arguments(w)
    _add_run_arguments(w)
    _add_output_arguments(w)
    w.set_defaults(func=run)
    return w


def _add_input_arguments(w):
    """--structure, --record, --units, --record-dt, --scales."""
    w.add_argument(
        "--structure",
        action="append",
        metavar="FILE.toml",
        help="structure file, repeatable (default: Table 1)",
    )
    w.add_argument(
        "--record",
        action="append",
        required=True,
        metavar="FILE",
        help="ground-motion record file, repeatable (at least one)",
    )
    w.add_argument("--units", choices=["g", "m/s2"], help="units of the records' values")
    w.add_argument(
        "--record-dt",
        type=_positive_float("--record-dt"),
        metavar="DT",
        help="sample step [s] of one-column records",
    )
    w.add_argument(
        "--scales",
        type=_scales,
        default=[1.0],
        metavar="LIST|START:STOP:N",
        help='scale factors: a comma list such as "0.5,1,1.5" or a range '
        '"START:STOP:N" of N evenly spaced values, ends included (default 1)',
    )


def _add_run_arguments(w):
    """--t1, --model, --method, --substeps, --r, --impact."""
    w.add_argument(
        "--t1",
        type=_positive_float("--t1"),
        metavar="T",
        help="end time [s] (default: the longest record's length)",
    )
    add_model_arguments(
        w,
        "model of the fidelity ladder (default simplified; two_spring_2dof: the 2-DOF "
        "rigid body on its springs, batched like the others)",
    )
    w.add_argument(
        "--method",
        choices=["rk4", "dopri5", "diffrax"],
        default="rk4",
        help="integrator (default rk4, the fast fixed-step path)",
    )
    w.add_argument(
        "--substeps",
        type=_positive_int("--substeps"),
        default=4,
        metavar="N",
        help="RK4 steps per record interval (default 4: peak |u| within about 2e-5 of a "
        "tight reference on El Centro scaled 0.1-2; 2 is twice as fast, within 4e-4)",
    )


def _add_output_arguments(w):
    """--out, --plot, --json."""
    w.add_argument(
        "--out",
        default="sweep.csv",
        metavar="FILE.csv",
        help="CSV of the summaries (default ./sweep.csv)",
    )
    w.add_argument(
        "--plot",
        metavar="FILE.png",
        help="plot peak |u| and the fraction overturned against the scale",
    )
    w.add_argument(
        "--json",
        action="store_true",
        help="print one JSON object and nothing else (no progress bar)",
    )


# ------------------------------------------------------------------------------ inputs
def _unique_labels(paths):
    """File stems as labels; the path as given where stems collide, then a #k suffix."""
    stems = [pathlib.Path(p).stem for p in paths]
    labels = [str(p) if stems.count(s) > 1 else s for p, s in zip(paths, stems)]
    out = []
    for i, lab in enumerate(labels):
        k = labels[:i].count(lab)
        out.append(f"{lab}#{k + 1}" if k or labels.count(lab) > 1 else lab)
    return out


def _check_args(args):
    """The checks that need no file read: plot suffix, --r, output folders."""
    _check_png(args.plot)
    _check_r(args.r)
    _check_out_dir("--out", args.out)
    _check_out_dir("--plot", args.plot)


def _sweep_structures(paths):
    """(structures, labels) of the --structure files, or of Table 1 when there are none."""
    structures = []
    for path in paths or [None]:
        try:
            structures.append(_load_structure(path))
        except (ValueError, OSError) as e:
            raise CLIError(f"--structure: {_first_line(e)}") from None
    labels = ["table1"] if paths is None else _unique_labels(paths)
    return structures, labels


def _sweep_records(paths, units, dt):
    """The records as one GroundMotion (accel (n_records, n_samples), zero-padded)."""
    recs = []
    for path in paths:
        try:
            recs.append(rockjax.read_record(path, units=units, dt=dt))
        except (ValueError, OSError) as e:
            raise CLIError(f"--record: {_first_line(e)}") from None
    dts = [float(r.dt) for r in recs]
    if any(not math.isclose(d, dts[0], rel_tol=1e-6) for d in dts):
        detail = ", ".join(f"{pathlib.Path(p).name} dt = {d:g} s" for p, d in zip(paths, dts))
        raise CLIError(f"--record: the records must share one time step, got {detail}")
    n = max(r.accel.size for r in recs)
    accel = np.zeros((len(recs), n))
    for i, r in enumerate(recs):
        accel[i, : r.accel.size] = np.asarray(r.accel)
    return rockjax.GroundMotion(dt=dts[0], accel=accel)


# --------------------------------------------------------------------------------- run
@dataclasses.dataclass
class _Sweep:
    """A sweep's inputs and, once `_run_batches` has filled them, its results:
    `results[i][field]` has shape (n_scales, n_records) for structure i."""

    structures: list
    struct_labels: list[str]
    rec_labels: list[str]
    scales: np.ndarray
    t1: float
    results: list[dict] = dataclasses.field(default_factory=list)
    wall: float = 0.0

    @property
    def n_runs(self):
        return len(self.structures) * len(self.scales) * len(self.rec_labels)

    @property
    def runs(self):
        return f"{self.n_runs} run{'s' if self.n_runs != 1 else ''}"

    def status_counts(self):
        counts = {name: 0 for name in rockjax.STATUS}
        for res in self.results:
            for code in res["status"].ravel():
                counts[_STATUS_NAMES[int(code)]] += 1
        return counts

    def fractions_overturned(self):
        """Per structure label, the fraction of records overturned at each scale."""
        over = rockjax.STATUS["overturned"]
        return {
            lab: [float(x) for x in np.mean(res["status"] == over, axis=1)]
            for lab, res in zip(self.struct_labels, self.results)
        }


def _run_batches(args, sweep, gm):
    """One `simulate_batch` per structure over every (scale, record); fills sweep.results."""
    n_s, n_r = len(sweep.scales), len(sweep.rec_labels)
    scale_b = np.repeat(sweep.scales, n_r)  # scale-major: run k is scale k // n_r, record k % n_r
    record_b = np.tile(np.arange(n_r), n_s)
    t0 = time.perf_counter()
    for s in sweep.structures:
        out = rockjax.simulate_batch(
            s,
            gm,
            sweep.t1,
            scale=scale_b,
            record=record_b,
            r=args.r,
            model=args.model,
            impact=args.impact,
            method=args.method,
            substeps=args.substeps,
            summary_only=True,
            progress=False if args.json else None,
        )
        sweep.results.append({k: np.asarray(getattr(out, k)).reshape(n_s, n_r) for k in _FIELDS})
    sweep.wall = time.perf_counter() - t0


def _csv_rows(sweep):
    for lab_s, res in zip(sweep.struct_labels, sweep.results):
        for i, scale in enumerate(sweep.scales):
            for j, lab_r in enumerate(sweep.rec_labels):
                t_ov = float(res["t_overturn"][i, j])
                yield [
                    lab_s,
                    lab_r,
                    repr(float(scale)),
                    repr(float(res["peak_u"][i, j])),
                    repr(float(res["peak_uplift"][i, j])),
                    int(res["n_impacts"][i, j]),
                    _STATUS_NAMES[int(res["status"][i, j])],
                    repr(t_ov) if math.isfinite(t_ov) else "",
                ]


def _write_sweep_csv(path, sweep):
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(SWEEP_COLUMNS)
        w.writerows(_csv_rows(sweep))


# ---------------------------------------------------------------------------- outputs
def _plot_peaks(ax_u, ax_f, xs, order, results, structures, records, u_overturn):
    """Peak |u| per structure x record (overturned runs as x at u_overturn, other failures
    as open squares) and the fraction overturned per structure. Returns (any overturned,
    any other failure)."""
    styles = ["-", "--", ":", "-."]
    many = len(structures) > 1
    any_over = any_other = False
    for si, (res, lab_s) in enumerate(zip(results, structures)):
        status = np.asarray(res["status"])[order]
        peak = 1e3 * np.asarray(res["peak_u"])[order]
        over = status == rockjax.STATUS["overturned"]
        other = (status != rockjax.STATUS["overturned"]) & (status != rockjax.STATUS["completed"])
        u_ov = 1e3 * float(u_overturn[si])
        for ri, lab_r in enumerate(records):
            color = f"C{ri % 10}"
            label = f"{lab_s} / {lab_r}" if many else lab_r
            ax_u.plot(
                xs,
                np.where(over[:, ri], np.nan, peak[:, ri]),
                styles[si % 4],
                marker="o",
                ms=3,
                lw=1.2,
                color=color,
                label=label,
            )
            if over[:, ri].any():
                any_over = True
                ax_u.plot(
                    xs[over[:, ri]],
                    np.full(int(over[:, ri].sum()), u_ov),
                    "x",
                    ms=8,
                    mew=1.6,
                    color=color,
                )
            if other[:, ri].any():
                any_other = True
                ax_u.plot(
                    xs[other[:, ri]], peak[other[:, ri], ri], "s", ms=7, mfc="none", color=color
                )
        frac = np.mean(over, axis=1)
        ax_f.plot(xs, frac, styles[si % 4], marker="o", ms=4, color=f"C{si % 10}", label=lab_s)
    return any_over, any_other


def _plot_overturn_levels(ax_u, u_overturn, structures):
    """One dashed line per distinct u_overturn, labelled with its structures when several."""
    levels = {}
    for u_ov, lab_s in zip(u_overturn, structures):
        key = next((k for k in levels if math.isclose(k, float(u_ov), rel_tol=1e-9)), None)
        levels.setdefault(float(u_ov) if key is None else key, []).append(lab_s)
    for u_ov, labs in levels.items():
        label = "u_overturn" if len(levels) == 1 else f"u_overturn ({', '.join(labs)})"
        ax_u.axhline(1e3 * u_ov, color="0.45", lw=0.9, ls=(0, (5, 3)), label=label)


def _peak_legend(ax_u, any_over, any_other, n_lines):
    """The legend of the peak panel, with the marker keys; none beyond 24 lines."""
    handles, labels = ax_u.get_legend_handles_labels()
    if any_over:
        handles.append(ax_u.plot([], [], "x", color="k", ms=8, mew=1.6)[0])
        labels.append("overturned (at u_overturn)")
    if any_other:
        handles.append(ax_u.plot([], [], "s", color="k", ms=7, mfc="none")[0])
        labels.append("max_impacts / solver_failure")
    if n_lines <= 24:
        ax_u.legend(handles, labels, fontsize=7, ncol=2 if len(labels) > 6 else 1, loc="upper left")


def plot_sweep(scales, results, *, u_overturn, structures, records, title=None):
    """Peak |u| against scale (one line per structure x record; overturned runs as x at
    u_overturn) and the fraction overturned against scale (per structure).

    `results[i]` holds arrays of shape (n_scales, n_records) `peak_u` [m] and `status` for
    structure i. Returns a matplotlib Figure (no pyplot)."""
    x = np.asarray(scales, float)
    order = np.argsort(x, kind="stable")
    fig = _plotting.new_figure(figsize=(8.5, 7.5), layout="constrained")
    ax_u, ax_f = fig.subplots(2, 1, sharex=True)
    any_over, any_other = _plot_peaks(
        ax_u, ax_f, x[order], order, results, structures, records, u_overturn
    )
    _plot_overturn_levels(ax_u, u_overturn, structures)
    _peak_legend(ax_u, any_over, any_other, len(structures) * len(records))
    ax_u.set_ylabel("peak |u| [mm]")
    ax_u.set_title(title or "peak displacement against scale", fontsize=10)
    ax_f.set_ylim(-0.03, 1.03)
    ax_f.set_ylabel(f"fraction overturned\n(over {len(records)} record(s))")
    ax_f.set_xlabel("scale factor on the records")
    if len(structures) > 1:
        ax_f.legend(fontsize=8)
    for ax in (ax_u, ax_f):
        ax.grid(alpha=0.3)
    return fig


def _print_json(args, sweep, counts, fractions):
    n_runs, wall = sweep.n_runs, sweep.wall
    out = {
        "n_runs": n_runs,
        "n_structures": len(sweep.structures),
        "n_records": len(sweep.rec_labels),
        "n_scales": len(sweep.scales),
        "status_counts": counts,
        "wall_time_s": wall,
        "runs_per_s": n_runs / wall if wall > 0 else None,
        "t1": sweep.t1,
        "model": args.model,
        "method": args.method,
        "csv": str(args.out),
        "plot": args.plot,
        "structures": sweep.struct_labels,
        "records": sweep.rec_labels,
        "scales": [float(x) for x in sweep.scales],
        "fraction_overturned": fractions,
    }
    print(json.dumps(out))


def _print_report(args, sweep, counts, fractions):
    n_runs, n_s, n_r = sweep.n_runs, len(sweep.scales), len(sweep.rec_labels)
    n_over = counts["overturned"]
    print(
        f"sweep         {sweep.runs}: {len(sweep.structures)} structure(s) x {n_r} record(s) x "
        f"{n_s} scale(s), t1 = {sweep.t1:g} s, {args.model} model, {args.method}"
        + (f" ({args.substeps} substeps)" if args.method == "rk4" else "")
    )
    print(
        f"time          {sweep.wall:.3g} s ({n_runs / sweep.wall:.3g} runs/s, compilation included)"
    )
    print("status        " + ", ".join(f"{k} {v}" for k, v in counts.items() if v))
    print(f"overturned    {n_over} of {n_runs} ({n_over / n_runs:.1%})")
    _print_fraction_table(sweep.scales, sweep.struct_labels, fractions)
    print(f"results written to {args.out}")
    if args.plot:
        print(f"plot written to {args.plot}")


def _print_fraction_table(scales, struct_labels, fractions):
    """Fraction overturned by scale, one column per structure (the middle elided past 25)."""
    n_s = len(scales)
    width = max(8, *(len(lab) + 2 for lab in struct_labels))
    print(
        f"fraction overturned by scale:\n{'scale':>10}"
        + "".join(f"{lab:>{width}}" for lab in struct_labels)
    )
    shown = range(n_s) if n_s <= 25 else [*range(12), None, *range(n_s - 12, n_s)]
    for i in shown:
        if i is None:
            print(f"{'...':>10}")
            continue
        print(
            f"{scales[i]:>10.4g}"
            + "".join(f"{fractions[lab][i]:>{width}.3f}" for lab in struct_labels)
        )


def run(args):
    """structures x scales x records through `simulate_batch(summary_only=True)`: CSV, plot."""
    _check_args(args)
    structures, struct_labels = _sweep_structures(args.structure)
    gm = _sweep_records(args.record, args.units, args.record_dt)
    t1 = args.t1 if args.t1 is not None else float(gm.duration)
    _check_t1_steps(t1, float(gm.dt), "record steps")
    sweep = _Sweep(
        structures=structures,
        struct_labels=struct_labels,
        rec_labels=_unique_labels(args.record),
        scales=np.asarray(args.scales, float),
        t1=t1,
    )
    _run_batches(args, sweep, gm)
    _write_sweep_csv(args.out, sweep)
    counts, fractions = sweep.status_counts(), sweep.fractions_overturned()
    if args.plot:
        fig = plot_sweep(
            sweep.scales,
            sweep.results,
            u_overturn=[float(s.u_overturn) for s in structures],
            structures=struct_labels,
            records=sweep.rec_labels,
            title=f"{sweep.runs} to t1 = {t1:g} s, {args.model} model, {args.method}",
        )
        fig.savefig(args.plot, dpi=150)
    if args.json:
        _print_json(args, sweep, counts, fractions)
        return 0
    _print_report(args, sweep, counts, fractions)
    return 0
