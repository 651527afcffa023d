"""`rockjax sweep`: peak responses over structures x scale factors x records (CSV, plot).

Every combination runs through `rockjax.simulate_batch(summary_only=True)`, one batch per
structure; the stages are: check the inputs, load structures and records, run, write the
CSV, then plot and report.

Records may differ in time step and length: they run together on their common time step
(each resampled exactly), and each run ends at its own record's end plus `--tail`. The
units of each record come from its file, or from `FILE:UNITS` / a `--units` after it.

With `--distributed` or `--coordinator/--num-processes/--process-id` the sweep runs as
several `jax.distributed` processes (`_distributed`): each runs a contiguous block of the
runs, process 0 gathers them and writes the same outputs as one process would.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
import pathlib
import sys
import time
import zlib

import jax
import numpy as np

import rockjax
from rockjax import _plotting
from rockjax._batch import DEFAULT_TAIL
from rockjax._fragility import overturned_fraction, USABLE
from rockjax._records import common_time_step, record_format

from . import _distributed
from ._common import (
    _check_out_dir,
    _check_png,
    _check_r,
    _first_line,
    _load_structure,
    _MAX_STEPS,
    _positive_float,
    _positive_int,
    _scales,
    add_model_arguments,
    CLIError,
    COMMON_FLAGS,
    converter,
    error_text,
    fidelity_note,
    model_info,
    model_line,
    RECORD_FLAGS,
    record_info,
    split_record_units,
)

#: the library parameters that the options of `rockjax sweep` set (errors name the option)
FLAGS = {**COMMON_FLAGS, **RECORD_FLAGS, "scale": "--scales", "scales": "--scales",
         "tail": "--tail", "structure": "--structure", "records": "--record"}

SWEEP_COLUMNS = (
    "structure",
    "record",
    "scale",
    "peak_u_m",
    "peak_uplift_m",
    "n_impacts",
    "status",
    "t_overturn_s",
    "t_end_s",
    "record_file",
    "record_units",
    "record_units_from",
    "record_dt_s",
    "record_npts",
    "record_duration_s",
    "record_pga_g",
    "model",
    "impact",
    "r",
    "method",
)
#: the Summary fields kept per run, each reshaped to (n_scales, n_records)
_FIELDS = ("peak_u", "peak_uplift", "n_impacts", "status", "t_overturn", "t_end")
#: integer status code -> name ("completed", "overturned", ...)
_STATUS_NAMES = {code: name for name, code in rockjax.STATUS.items()}
#: the files a `--record DIR` takes (by suffix, case-insensitive); others are skipped
RECORD_SUFFIXES = (".at2", ".dat", ".txt", ".csv", ".acc")


# ------------------------------------------------------------------------------ parser
def add_parser(subparsers):
    w = subparsers.add_parser(
        "sweep",
        help="peak responses over structures x scale factors x records (CSV and plot)",
        description="Run every combination of structure, scale factor and ground-motion "
        "record with the fast batched integrator (rockjax.simulate_batch, summaries only) "
        "and write one CSV row per run: structure, record, scale, peak_u_m, peak_uplift_m, "
        "n_impacts, status, t_overturn_s, t_end_s, then what produced it (the record's file, "
        "units and where they came from, dt, points, duration, PGA; model, impact rule, r, "
        "method). Records (PEER AT2, two columns t a, or one column with --record-dt) may "
        "differ in time step and length: they run on their common step, each resampled "
        "exactly, and each run ends at its own record's end plus --tail. With --distributed "
        "(or --coordinator, --num-processes, --process-id) the runs are split over several "
        "jax.distributed processes or machines and process 0 writes the outputs.",
    )
    w.set_defaults(inputs=None)
    _add_input_arguments(w)
    _add_run_arguments(w)
    _add_output_arguments(w)
    _distributed.add_distributed_arguments(w)
    w.set_defaults(func=run)
    return w


class _InOrder(argparse.Action):
    """Keep --record and --units in the order given: (dest, value) pairs in `inputs`."""

    def __call__(self, parser, namespace, values, option_string=None):
        namespace.inputs = [*(namespace.inputs or []), (self.dest, values)]


_tail = converter("--tail", float, lambda x: math.isfinite(x) and x >= 0, "be >= 0 and finite")


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
        action=_InOrder,
        required=True,
        metavar="FILE[:UNITS]|DIR",
        help="ground-motion record file, repeatable (at least one); FILE:g or FILE:m/s2 "
        "states its units; a folder takes every record file in it (.AT2, .dat, .txt, "
        ".csv, .acc), sorted by name",
    )
    w.add_argument(
        "--units",
        action=_InOrder,
        choices=["g", "m/s2"],
        help="units of the --record just before it (before any --record: of every record "
        "that states no units of its own). A file that states its units (AT2 'UNITS OF "
        "G', a column title 'Accel[g]') is read in them; units given that contradict them "
        "are refused",
    )
    w.add_argument(
        "--record-dt",
        type=_positive_float("--record-dt"),
        metavar="DT",
        help="sample step [s] of the one-column records (the others state their own)",
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
    """--tail, --t1, --model, --method, --substeps, --r, --impact."""
    w.add_argument(
        "--tail",
        type=_tail,
        default=DEFAULT_TAIL,
        metavar="S",
        help=f"free vibration [s] after each record's end (default {DEFAULT_TAIL:g}); "
        "each run ends at its own record's end plus S, so shorter records are never "
        "padded with zeros",
    )
    w.add_argument(
        "--t1",
        type=_positive_float("--t1"),
        metavar="T",
        help="stop every run at T [s] at the latest (default: no cap)",
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
        help="RK4 steps per step of the records' common grid (default 4: peak |u| within "
        "about 2e-5 of a tight reference on El Centro scaled 0.1-2; 2 is twice as fast, "
        "within 4e-4)",
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


@dataclasses.dataclass
class _Spec:
    """One record to read: its path, the units given for it (None: the file's own, or
    the default --units), and the --record folder it came from (None: named itself)."""

    path: str
    units: str | None = None
    folder: str | None = None


def _record_specs(inputs):
    """(the --record values in order, with their units, the --units given before any
    --record): FILE:UNITS, or a --units right after its --record."""
    specs, default = [], None
    for kind, value in inputs or []:
        if kind == "record":
            path, units = split_record_units(value)
            specs.append(_Spec(path, units))
        elif not specs:
            if default is not None:
                raise CLIError("--units: given twice before the first --record")
            default = value
        elif specs[-1].units is not None:
            raise CLIError(
                f"--units {value}: the --record before it, {specs[-1].path}, already has "
                f"units {specs[-1].units}"
            )
        else:
            specs[-1].units = value
    return specs, default


def _folder_files(spec):
    """(the record files of a --record folder, sorted, as specs; the names skipped)."""
    folder = pathlib.Path(spec.path)
    files = sorted(p for p in folder.iterdir() if p.is_file() and not p.name.startswith("."))
    taken = [p for p in files if p.suffix.lower() in RECORD_SUFFIXES]
    skipped = [p.name for p in files if p.suffix.lower() not in RECORD_SUFFIXES]
    if not taken:
        raise CLIError(
            f"--record {spec.path}: no record files in this folder (looked for "
            f"{', '.join(RECORD_SUFFIXES)}; found {', '.join(skipped) or 'nothing'})"
        )
    return [_Spec(str(p), spec.units, spec.path) for p in taken], skipped


def _expand_folders(specs):
    """Folders replaced by their record files; a file also named itself takes the units
    given there. Returns (specs, {folder: names skipped})."""
    named = {}
    for spec in specs:
        if not pathlib.Path(spec.path).is_dir():
            key = pathlib.Path(spec.path).resolve()
            if key in named:
                raise CLIError(f"--record {spec.path}: given twice")
            named[key] = spec
    out, skipped, seen = [], {}, set()
    for spec in specs:
        if pathlib.Path(spec.path).is_dir():
            files, skipped[spec.path] = _folder_files(spec)
        else:
            files = [spec]
        for f in files:
            key = pathlib.Path(f.path).resolve()
            if key in seen:
                continue
            seen.add(key)
            own = named.get(key)
            out.append(f if own is None else dataclasses.replace(own, folder=f.folder))
    return out, skipped


def _read_records(specs, default_units, record_dt):
    """The records, read with the units given for each (else --units before any
    --record, else the file's) and --record-dt for the one-column ones; errors in CLI
    syntax."""
    records = []
    for spec in specs:
        units = spec.units or default_units
        try:
            one_col = record_dt is not None and record_format(spec.path) == "one_column"
            dt = record_dt if one_col else None
            records.append(rockjax.read_record(spec.path, units=units, dt=dt))
        except (ValueError, OSError) as e:
            hint = ""
            if spec.folder is not None and getattr(e, "param", None) == "units":
                hint = (
                    f" (a file of --record {spec.folder}: give its units with --record "
                    f"{spec.path}:g or :m/s2)"
                )
            where = "" if isinstance(e, rockjax.ParameterError) else "--record: "
            raise CLIError(f"{where}{error_text(e, FLAGS)}{hint}") from None
    return records


def _sweep_records(args):
    """(records, labels, {folder: files skipped}) of the --record/--units arguments; the
    records' common time step is checked here (a one-line error when there is none)."""
    specs, default_units = _record_specs(args.inputs)
    specs, skipped = _expand_folders(specs)
    records = _read_records(specs, default_units, args.record_dt)
    labels = _unique_labels([s.path for s in specs])
    try:
        common_time_step([r.dt for r in records], names=[pathlib.Path(s.path).name for s in specs])
    except ValueError as e:
        raise CLIError(f"--record: {_first_line(e)}") from None
    return records, labels, skipped


# --------------------------------------------------------------------------------- run
@dataclasses.dataclass
class _Sweep:
    """A sweep's inputs and, once `_run_batches` has filled them, its results:
    `results[i][field]` has shape (n_scales, n_records) for structure i."""

    structures: list
    struct_labels: list[str]
    records: list
    rec_labels: list[str]
    scales: np.ndarray
    tail: float
    t1: float | None
    skipped: dict = dataclasses.field(default_factory=dict)
    processes: int = 1
    results: list[dict] = dataclasses.field(default_factory=list)
    warnings: list[str] = dataclasses.field(default_factory=list)
    wall: float = 0.0

    @property
    def n_runs(self):
        return len(self.structures) * len(self.scales) * len(self.rec_labels)

    @property
    def runs(self):
        return f"{self.n_runs} run{'s' if self.n_runs != 1 else ''}"

    @property
    def grid_dt(self):
        """The records' common time step [s]."""
        return common_time_step([r.dt for r in self.records])

    @property
    def t_ends(self):
        """Each record's end of run [s]: its end plus the tail, capped at --t1."""
        ends = [r.dt * (r.npts - 1) + self.tail for r in self.records]
        return [e if self.t1 is None else min(e, self.t1) for e in ends]

    def record_infos(self):
        """`record_info` of each record, with its label and end of run."""
        infos = []
        for lab, rec, t_end in zip(self.rec_labels, self.records, self.t_ends):
            info = {"label": lab, **record_info(rec), "t_end_s": t_end}
            for key in ("scale", "scaled_pga_g"):  # the scales are the sweep's
                info.pop(key)
            infos.append(info)
        return infos

    def status_counts(self):
        counts = {name: 0 for name in rockjax.STATUS}
        for res in self.results:
            for code in res["status"].ravel():
                counts[_STATUS_NAMES[int(code)]] += 1
        return counts

    def fractions_overturned(self):
        """Per structure label, the fraction of records overturned at each scale, among
        the runs that completed or overturned (failed runs left out, as `rockjax.sweep`);
        None at a scale where every run failed."""
        return {
            lab: [None if np.isnan(x) else float(x)
                  for x in overturned_fraction(res["status"], axis=1)]
            for lab, res in zip(self.struct_labels, self.results)
        }

    def failed_by_scale(self):
        """Per structure label, the failed runs (max_impacts, solver_failure) at each
        scale: left out of the fractions."""
        return {
            lab: [int(k) for k in (~np.isin(res["status"], USABLE)).sum(axis=1)]
            for lab, res in zip(self.struct_labels, self.results)
        }


def _check_run_length(sweep):
    """A one-line error naming --tail, rather than numpy's size error, for absurd runs."""
    n = max(sweep.t_ends) / sweep.grid_dt
    if not n <= _MAX_STEPS:
        raise CLIError(
            f"--tail {sweep.tail:g} s makes runs of {n:.3g} steps of the records' common grid "
            f"({sweep.grid_dt:g} s), more than {_MAX_STEPS:,}; shorten --tail or cap the runs "
            "with --t1"
        )


def _fingerprint(sweep):
    """A checksum of what was read (labels, scales, records, structures): processes that
    read different files disagree on it."""
    h = zlib.crc32(json.dumps([sweep.struct_labels, sweep.rec_labels, sweep.scales.tolist(),
                               sweep.tail, sweep.t1]).encode())
    for rec in sweep.records:
        h = zlib.crc32(np.ascontiguousarray(rec.accel, float).tobytes(), h)
        h = zlib.crc32(repr(float(rec.dt)).encode(), h)
    for s in sweep.structures:
        for leaf in jax.tree_util.tree_leaves(s):
            try:
                data = np.ascontiguousarray(leaf, float).tobytes()
            except (TypeError, ValueError):
                data = repr(leaf).encode()
            h = zlib.crc32(data, h)
    return h


def _run_block(args, sweep, lo, hi, out, quiet):
    """Runs lo..hi-1 of the sweep (run k: structure k // (n_scales n_records), then scale,
    then record) into out[field, k - lo]: one `simulate_batch` per structure touched."""
    n_r = len(sweep.rec_labels)
    m = len(sweep.scales) * n_r
    for i, s in enumerate(sweep.structures):
        a, b = max(lo, i * m), min(hi, (i + 1) * m)
        if a >= b:
            continue
        k = np.arange(a, b) - i * m  # scale-major: scale k // n_r, record k % n_r
        res = rockjax.simulate_batch(
            s,
            sweep.records,
            sweep.t1,
            tail=sweep.tail,
            scale=sweep.scales[k // n_r],
            record=k % n_r,
            r=args.r,
            model=args.model,
            impact=args.impact,
            method=args.method,
            substeps=args.substeps,
            summary_only=True,
            progress=False if quiet else None,
            fidelity_warning=False,
        )
        for f, name in enumerate(_FIELDS):
            out[f, a - lo : b - lo] = np.asarray(getattr(res, name))


def _run_batches(args, sweep, cluster):
    """This process's block of the runs, gathered from every process (one process: all of
    them); fills sweep.results and sweep.warnings."""
    n_s, n_r = len(sweep.scales), len(sweep.rec_labels)
    n = len(sweep.structures) * n_s * n_r
    lo, hi = cluster.block(n)
    part, error = np.zeros((1 + len(_FIELDS), hi - lo)), None  # row 0: failed
    t0 = time.perf_counter()
    try:
        _run_block(args, sweep, lo, hi, part[1:], quiet=args.json or cluster.index > 0)
    except Exception as e:  # noqa: BLE001 - raised again by gather, after the others know
        part[0], error = 1, e
    full = cluster.gather(part, n, error)
    sweep.wall = time.perf_counter() - t0
    sweep.processes = cluster.count
    m = n_s * n_r
    for i, s in enumerate(sweep.structures):
        res = {k: full[1 + f, i * m : (i + 1) * m].reshape(n_s, n_r) for f, k in enumerate(_FIELDS)}
        for k in ("n_impacts", "status"):
            res[k] = res[k].astype(np.int64)
        sweep.results.append(res)
        note = fidelity_note(args, s, True, res["peak_u"].ravel())
        if note and note not in sweep.warnings:
            sweep.warnings.append(note)
            if cluster.index == 0:
                print(f"warning: {note}", file=sys.stderr)


def _csv_rows(args, sweep):
    infos, model = sweep.record_infos(), model_info(args)
    r = model["r"] if isinstance(model["r"], str) else repr(float(model["r"]))
    for lab_s, res in zip(sweep.struct_labels, sweep.results):
        for i, scale in enumerate(sweep.scales):
            for j, info in enumerate(infos):
                t_ov = float(res["t_overturn"][i, j])
                yield [
                    lab_s,
                    info["label"],
                    repr(float(scale)),
                    repr(float(res["peak_u"][i, j])),
                    repr(float(res["peak_uplift"][i, j])),
                    int(res["n_impacts"][i, j]),
                    _STATUS_NAMES[int(res["status"][i, j])],
                    repr(t_ov) if math.isfinite(t_ov) else "",
                    repr(float(res["t_end"][i, j])),
                    info["file"],
                    info["units_in_file"],
                    info["units_from"] or "",
                    repr(info["dt_s"]),
                    info["n_points"],
                    repr(info["duration_s"]),
                    repr(info["pga_g"]),
                    model["model"],
                    model["impact"],
                    r,
                    args.method,
                ]


def _write_sweep_csv(args, sweep):
    with open(args.out, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(SWEEP_COLUMNS)
        w.writerows(_csv_rows(args, sweep))


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
        ax_f.plot(xs, overturned_fraction(status, axis=1), styles[si % 4], marker="o", ms=4,
                  color=f"C{si % 10}", label=lab_s)
        if other.any():  # the failed runs, left out of the fraction
            ax_f.plot(xs, np.mean(other, axis=1), styles[si % 4], marker="s", ms=4, mfc="none",
                      lw=0.8, color="0.5", label=f"{lab_s}: fraction failed (left out)"
                      if many else "fraction failed (left out)")
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
    u_overturn) and the fraction overturned against scale (per structure, of the runs that
    completed or overturned; the fraction that failed, left out, as a grey line).

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
    ax_f.set_ylabel(f"fraction overturned (of {len(records)}\nrecord(s), failed runs left out)")
    ax_f.set_xlabel("scale factor on the records")
    if len(structures) > 1 or any_other:
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
        "processes": sweep.processes,
        "tail_s": sweep.tail,
        "t1": sweep.t1,
        "grid_dt_s": sweep.grid_dt,
        "model": args.model,
        "model_info": model_info(args),
        "method": args.method,
        "substeps": args.substeps if args.method == "rk4" else None,
        "csv": str(args.out),
        "plot": args.plot,
        "structures": sweep.struct_labels,
        "records": sweep.rec_labels,
        "record_info": sweep.record_infos(),
        "skipped_files": sweep.skipped,
        "scales": [float(x) for x in sweep.scales],
        "fraction_overturned": fractions,
        "failed_by_scale": sweep.failed_by_scale(),
        "warnings": sweep.warnings,
    }
    print(json.dumps(out))


def _print_inputs(args, sweep):
    """What was read and what produced the results: records, their grid, the model."""
    for folder, names in sweep.skipped.items():
        taken = sum(
            1 for r in sweep.records if pathlib.Path(r.source).parent == pathlib.Path(folder)
        )
        note = f"; skipped (not record files): {', '.join(names)}" if names else ""
        print(f"folder        {folder}: {taken} record file(s) taken{note}")
    for i in sweep.record_infos():
        src = f" ({i['units_from']})" if i["units_from"] else ""
        print(
            f"record        {i['label']}: units {i['units_in_file']}{src}, dt {i['dt_s']:g} s, "
            f"{i['n_points']} points, {i['duration_s']:g} s, PGA {i['pga_g']:.4g} g, "
            f"run to {i['t_end_s']:g} s"
        )
    cap = "" if sweep.t1 is None else f", at most t1 = {sweep.t1:g} s"
    dts = sorted({r.dt for r in sweep.records})
    print(
        f"grid          {sweep.grid_dt:g} s (record steps {', '.join(f'{d:g}' for d in dts)} s"
        f", resampled exactly); each run to its record's end + tail {sweep.tail:g} s{cap}"
    )
    print(
        f"model         {model_line(model_info(args))}, {args.method}"
        + (f" ({args.substeps} substeps)" if args.method == "rk4" else "")
    )


def _print_report(args, sweep, counts, fractions):
    n_runs, n_s, n_r = sweep.n_runs, len(sweep.scales), len(sweep.rec_labels)
    n_over = counts["overturned"]
    failed = {k: v for k, v in counts.items() if rockjax.STATUS[k] not in USABLE and v}
    n_used = n_runs - sum(failed.values())
    _print_inputs(args, sweep)
    print(
        f"sweep         {sweep.runs}: {len(sweep.structures)} structure(s) x {n_r} record(s) x "
        f"{n_s} scale(s)"
    )
    procs = f", {sweep.processes} processes" if sweep.processes > 1 else ""
    print(
        f"time          {sweep.wall:.3g} s ({n_runs / sweep.wall:.3g} runs/s, compilation "
        f"included{procs})"
    )
    print("status        " + ", ".join(f"{k} {v}" for k, v in counts.items() if v))
    share = f"{n_over / n_used:.1%}" if n_used else "-"
    if failed:
        left = ", ".join(f"{k} {v}" for k, v in failed.items())
        print(f"overturned    {n_over} of the {n_used} runs that completed or overturned "
              f"({share}); {n_runs - n_used} failed runs left out ({left})")
    else:
        print(f"overturned    {n_over} of {n_runs} ({share})")
    _print_fraction_table(sweep.scales, sweep.struct_labels, fractions)
    if failed:
        _print_failed_table(sweep.scales, sweep.struct_labels, sweep.failed_by_scale())
    print(f"results written to {args.out}")
    if args.plot:
        print(f"plot written to {args.plot}")


def _print_fraction_table(scales, struct_labels, fractions):
    """Fraction overturned by scale, one column per structure (the middle elided past 25)."""
    n_s = len(scales)
    width = max(8, *(len(lab) + 2 for lab in struct_labels))
    print(
        f"fraction overturned by scale (of the runs that completed or overturned):\n"
        f"{'scale':>10}"
        + "".join(f"{lab:>{width}}" for lab in struct_labels)
    )
    shown = range(n_s) if n_s <= 25 else [*range(12), None, *range(n_s - 12, n_s)]
    for i in shown:
        if i is None:
            print(f"{'...':>10}")
            continue
        print(
            f"{scales[i]:>10.4g}"
            + "".join(f"{_fraction(fractions[lab][i]):>{width}}" for lab in struct_labels)
        )


def _fraction(x):
    """A fraction in the table: three decimals, '-' where every run failed."""
    return "-" if x is None else f"{x:.3f}"


def _print_failed_table(scales, struct_labels, failed):
    """Failed runs by scale, one column per structure (the scales with failures only)."""
    width = max(8, *(len(lab) + 2 for lab in struct_labels))
    print(
        "failed runs by scale (max_impacts, solver_failure; left out of the fractions):\n"
        f"{'scale':>10}" + "".join(f"{lab:>{width}}" for lab in struct_labels)
    )
    for i, scale in enumerate(scales):
        if any(failed[lab][i] for lab in struct_labels):
            print(f"{scale:>10.4g}" + "".join(f"{failed[lab][i]:>{width}d}"
                                              for lab in struct_labels))


def _read_sweep(args):
    """The sweep's inputs, read and checked (no run yet)."""
    structures, struct_labels = _sweep_structures(args.structure)
    records, rec_labels, skipped = _sweep_records(args)
    sweep = _Sweep(
        structures=structures,
        struct_labels=struct_labels,
        records=records,
        rec_labels=rec_labels,
        scales=np.asarray(args.scales, float),
        tail=args.tail,
        t1=args.t1,
        skipped=skipped,
    )
    _check_run_length(sweep)
    return sweep


def _load_sweep(args, cluster):
    """`_read_sweep`, and (several processes) a check that every process read the same."""
    sweep = error = None
    try:
        sweep = _read_sweep(args)
    except Exception as e:  # noqa: BLE001 - raised again by agree, after the others know
        error = e
    cluster.agree(_fingerprint(sweep) if cluster.active and sweep is not None else None, error)
    return sweep


def run(args):
    """structures x scales x records through `simulate_batch(summary_only=True)`: CSV, plot;
    over several jax.distributed processes when asked (process 0 writes)."""
    _check_args(args)
    cluster = _distributed.start(args)
    try:
        sweep = _load_sweep(args, cluster)
        _run_batches(args, sweep, cluster)
    finally:
        cluster.stop()
    if cluster.index != 0:
        return 0
    _write_sweep_csv(args, sweep)
    counts, fractions = sweep.status_counts(), sweep.fractions_overturned()
    if args.plot:
        end = "its end + tail" if args.t1 is None else f"min(end + tail, {args.t1:g} s)"
        fig = plot_sweep(
            sweep.scales,
            sweep.results,
            u_overturn=[float(s.u_overturn) for s in sweep.structures],
            structures=sweep.struct_labels,
            records=sweep.rec_labels,
            title=f"{sweep.runs}, each record to {end}, {args.model} model, "
            f"impact rule {args.impact}, {args.method}",
        )
        fig.savefig(args.plot, dpi=150)
    if args.json:
        _print_json(args, sweep, counts, fractions)
        return 0
    _print_report(args, sweep, counts, fractions)
    return 0
