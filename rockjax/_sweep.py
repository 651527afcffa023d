"""`rockjax.sweep`: every record at every scale factor, the one batch engine behind
fragility curves and the `rockjax sweep` / `rockjax fragility` commands.

The runs go through `rockjax.simulate_batch(summary_only=True)` as one flat batch (run k:
record k % n_records at scale k // n_records, the order of the CSV rows) and a `SweepResult`
holds arrays of shape (n_records, n_scales), the one orientation of the API and the CLI.
Over several `jax.distributed` processes (`processes=rockjax.Processes.current()`) each
process runs a contiguous block of the runs and every process ends with the whole result.
The status counting (the fraction overturned among the runs that completed or overturned,
the failed runs per scale) is written here once.

`rockjax.sweep_store` (and `sweep(..., store=path)`) runs structures x records x scales
chunk by chunk instead, each chunk (every record at a block of scales, one structure) one
`simulate_batch` call written at once into a Zarr store (`_store`): memory bounded by a
chunk, and a rerun skips the chunks already written.
"""

from __future__ import annotations

import csv
import dataclasses
import importlib.metadata
import os
import pathlib
import sys
import time

import numpy as np

from ._batch import DEFAULT_TAIL, simulate_batch
from ._checks import check_one_structure, check_scales
from ._config import ensure_x64, stack_versions
from ._distributed import Processes
from ._errors import ParameterError
from ._excitation import GroundMotion
from ._fidelity import warn_sdof_lift_off
from ._records import common_time_step, G_STANDARD, read_record, Record
from ._report import model_info, model_line, record_info, status_line
from ._status import STATUS, STATUS_NAMES
from ._store import (
    array_sha256,
    DEFAULT_CHUNK_RUNS,
    jsonable,
    open_dataset,
    scale_chunk,
    SweepStore,
    VARIABLES,
)
from ._structure import RockingStructure
from .models import get_model

#: the Summary fields a SweepResult keeps, each of shape (n_records, n_scales)
SWEEP_FIELDS = ("peak_u", "peak_uplift", "n_impacts", "status", "t_overturn", "t_end")
#: the statuses of a run that the fit uses; the others are failures, left out and counted
USABLE = (STATUS["completed"], STATUS["overturned"])
FAILED = tuple(name for name, code in STATUS.items() if code not in USABLE)
#: the columns of `SweepResult.to_csv` (and `rockjax sweep --out`), one row per run
CSV_COLUMNS = ("structure", "record", "scale", "peak_u_m", "peak_uplift_m", "n_impacts",
               "status", "t_overturn_s", "t_end_s", "record_file", "record_units",
               "record_units_from", "record_dt_s", "record_npts", "record_duration_s",
               "record_pga_g", "model", "impact", "r", "method")
#: a sweep's batches are padded to a multiple of this many runs (`_run`)
_VECTOR = 8
#: simulate_batch arguments that `sweep` sets itself
_SET_BY_SWEEP = ("scale", "record", "summary_only", "ts", "excitation", "structure", "u0", "v0")
#: simulate_batch arguments that change how a sweep runs, not its results: a rerun into a
#: store may change them (the others must be the stored ones)
_HOW = ("progress", "devices", "chunk_size", "execution", "fidelity_warning")
#: called after each chunk written to a store, with (structure, chunk): tests interrupt
#: a sweep here
_AFTER_CHUNK = None


def overturned_fraction(status, axis=-1):
    """The fraction overturned along `axis` among the runs that completed or overturned
    (failed runs left out); NaN where no run did."""
    status = np.asarray(status)
    usable = np.isin(status, USABLE).sum(axis=axis)
    over = (status == STATUS["overturned"]).sum(axis=axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(usable > 0, over / np.maximum(usable, 1), np.nan)


def failed_runs(status, axis=None):
    """The runs that failed (max_impacts, solver_failure: neither completed nor overturned)
    along `axis` (None: all)."""
    return (~np.isin(np.asarray(status), USABLE)).sum(axis=axis)


@dataclasses.dataclass(frozen=True, eq=False)
class SweepResult:
    """Every record at every scale factor (`rockjax.sweep`), SI units.

    - `structure`, `model` (as given to `sweep`), `impact`; `records` (the `Record`s or
      `GroundMotion`s run, which `fragility` takes its intensity measures from), `labels`
      (one per record), `scales` (n_scales,).
    - `peak_u` [m], `peak_uplift` [m], `n_impacts`, `status` (0 completed, 1 overturned,
      2 max_impacts, 3 solver_failure; `rockjax.STATUS`), `t_overturn` [s], `t_end` [s]:
      arrays of shape (n_records, n_scales), as `rockjax.Summary`.
    - `tail`, `t1` [s] and `options` (the other `simulate_batch` arguments), `wall_time` [s].
    """

    structure: RockingStructure
    records: tuple
    labels: tuple
    scales: np.ndarray
    peak_u: np.ndarray
    peak_uplift: np.ndarray
    n_impacts: np.ndarray
    status: np.ndarray
    t_overturn: np.ndarray
    t_end: np.ndarray
    model: object = "simplified"
    impact: str = "paper"
    tail: float | None = DEFAULT_TAIL
    t1: float | None = None
    options: dict = dataclasses.field(default_factory=dict)
    wall_time: float = 0.0

    def __post_init__(self):
        set_ = object.__setattr__
        set_(self, "records", tuple(self.records))
        set_(self, "labels", tuple(str(x) for x in self.labels))
        set_(self, "scales", check_scales(self.scales))
        shape = (len(self.records), self.scales.size)
        if len(self.labels) != shape[0]:
            raise ParameterError(f"labels: {len(self.labels)} for {shape[0]} records",
                                 param="labels")
        for name in SWEEP_FIELDS:
            a = np.asarray(getattr(self, name))
            if a.shape != shape:
                raise ParameterError(f"{name} must have shape (n_records, n_scales) = {shape}, "
                                     f"got {a.shape}", param=name)
            set_(self, name, a.astype(np.int64) if name in ("status", "n_impacts") else a)

    @property
    def n_records(self) -> int:
        return len(self.records)

    @property
    def n_scales(self) -> int:
        return int(self.scales.size)

    @property
    def n_runs(self) -> int:
        return self.n_records * self.n_scales

    @property
    def model_name(self) -> str:
        return self.model if isinstance(self.model, str) else type(self.model).__name__

    def __repr__(self):
        counts = ", ".join(f"{k} {v}" for k, v in self.status_counts().items() if v)
        return (f"SweepResult({self.n_records} records x {self.n_scales} scales, model "
                f"{self.model_name!r}: {counts})")

    def status_counts(self) -> dict[str, int]:
        """Runs per status name (every name of `rockjax.STATUS`, zeros included)."""
        return {name: int(np.sum(self.status == code)) for name, code in STATUS.items()}

    def fraction_overturned(self) -> np.ndarray:
        """Per scale, the fraction of the records that overturned, among the runs that
        completed or overturned (failed runs left out; NaN at a scale where every run
        failed)."""
        return overturned_fraction(self.status, axis=0)

    def failed_by_scale(self) -> np.ndarray:
        """Per scale, the number of failed runs (max_impacts, solver_failure)."""
        return failed_runs(self.status, axis=0)

    def to_dict(self) -> dict:
        """Plain Python values for JSON: the counts per status, per scale the fraction
        overturned (None where every run failed) and the failed runs, and the per-run
        arrays as nested lists (record-major, status as names)."""
        def floats(a):
            return [None if np.isnan(v) else float(v) for v in np.ravel(a)]

        return {
            "n_runs": self.n_runs, "n_records": self.n_records, "n_scales": self.n_scales,
            "model": self.model_name, "impact": self.impact, "records": list(self.labels),
            "scales": self.scales.tolist(), "status_counts": self.status_counts(),
            "fraction_overturned": floats(self.fraction_overturned()),
            "failed_by_scale": self.failed_by_scale().tolist(),
            **{f: self.status_names().tolist() if f == "status" else getattr(self, f).tolist()
               for f in SWEEP_FIELDS},
            "wall_time_s": self.wall_time,
        }

    def to_csv(self, path, label="structure"):
        """Write `csv_rows` under the header `CSV_COLUMNS` (`write_csv`: several sweeps)."""
        write_csv(path, [self], [label])

    def csv_rows(self, label="structure"):
        """One row per run, scale-major then record (the order of `rockjax sweep --out`):
        `label`, the record's label, the scale and the summaries (SI units, floats as
        repr, status as text, t_overturn empty if it did not overturn), then what produced
        it: the record's file, units, where they came from, dt, points, duration, PGA [g];
        the model, impact rule ("landings" for the body models), r ("Eq 3": the
        structure's) and method."""
        names, opts = self.status_names(), self.options
        r = "Eq 3" if opts.get("r") is None else repr(float(opts["r"]))
        tail = [self.model_name, model_info(self.model_name, self.impact)["impact"], r,
                opts.get("method", "rk4")]
        recs = [_provenance(rec) for rec in self.records]
        for i, scale in enumerate(self.scales):
            for j, (lab, rec) in enumerate(zip(self.labels, recs)):
                t_ov = float(self.t_overturn[j, i])
                yield [label, lab, repr(float(scale)), repr(float(self.peak_u[j, i])),
                       repr(float(self.peak_uplift[j, i])), int(self.n_impacts[j, i]),
                       names[j, i], repr(t_ov) if np.isfinite(t_ov) else "",
                       repr(float(self.t_end[j, i])), *rec, *tail]

    def status_names(self) -> np.ndarray:
        """The status of each run as text, (n_records, n_scales)."""
        return np.vectorize(STATUS_NAMES.__getitem__, otypes=[str])(self.status)

    @property
    def grid_dt(self) -> float:
        """The records' common time step [s] (`rockjax.common_time_step`), the grid of
        every run."""
        return common_time_step([float(r.dt) for r in self.records])

    def record_info(self) -> list[dict]:
        """Per record: its `label`, what was read (file, units and where they came from,
        `dt_s`, `n_points`, `duration_s` [s], `pga_m_s2`, `pga_g`) and `t_end_s`, the end
        of its runs [s] (its end plus `tail`, at most `t1`)."""
        out = []
        for lab, rec in zip(self.labels, self.records):
            info = record_info(rec)
            end = info["dt_s"] * (info["n_points"] - 1) + (self.tail or 0.0)
            out.append({"label": lab, **{k: v for k, v in info.items()
                                         if k not in ("scale", "scaled_pga_g")},
                        "t_end_s": end if self.t1 is None else min(end, self.t1)})
        return out

    def report_inputs(self) -> str:
        """What produced the results, as text: one line per record (units, dt, points,
        duration, PGA [g], end of its runs), the grid and the model."""
        lines = []
        for i in self.record_info():
            src = f" ({i['units_from']})" if i["units_from"] else ""
            lines.append(f"record        {i['label']}: units {i['units_in_file']}{src}, dt "
                         f"{i['dt_s']:g} s, {i['n_points']} points, {i['duration_s']:g} s, PGA "
                         f"{i['pga_g']:.4g} g, run to {i['t_end_s']:g} s")
        cap = "" if self.t1 is None else f", at most t1 = {self.t1:g} s"
        dts = ", ".join(f"{d:g}" for d in sorted({float(r.dt) for r in self.records}))
        method, opts = self.options.get("method", "rk4"), self.options
        substeps = f" ({opts['substeps']} substeps)" if method == "rk4" and opts.get(
            "substeps") else ""
        info = model_info(self.model_name, self.impact, opts.get("r"))
        return "\n".join([*lines, f"grid          {self.grid_dt:g} s (record steps {dts} s, "
                          f"resampled exactly); each run to its record's end + tail "
                          f"{self.tail or 0.0:g} s{cap}",
                          f"model         {model_line(info)}, {method}{substeps}"])

    def report(self, label="structure") -> str:
        """A text report: `report_inputs`, the runs and their time, the runs per status,
        the fraction overturned (of the runs that completed or overturned) and the failed
        runs, per scale (`label` heads the column).

        ```python
        record = rockjax.datasets.synthetic_ground_motion(duration=2.0, dt=0.01, pga=3.0)
        res = rockjax.sweep(rockjax.mcmanus_column(), [record], [0.5, 2.0], substeps=2)
        print(res.report())
        ```
        """
        return report_sweeps([self], [label])

    def plot(self, title=None, label="structure"):
        """Peak |u| against the scale (one line per record; overturned runs as x at
        u_overturn, other failures as open squares) over the fraction overturned (of the
        runs that completed or overturned; the fraction that failed as a grey line):
        a matplotlib Figure (`rockjax._plotting.plot_sweeps` draws several structures)."""
        from ._plotting import plot_sweeps

        return plot_sweeps([self], [label], title=title)


def _provenance(rec):
    """The record columns of a CSV row: file, units, their source, dt, points, duration,
    PGA [g] (a GroundMotion: no file, m/s2, its own scale applied)."""
    dt, acc = float(rec.dt), np.asarray(rec.accel)
    pga = float(np.max(np.abs(acc)) * getattr(rec, "scale", 1.0))
    return [str(getattr(rec, "source", "")), getattr(rec, "units_in_file", "m/s2"),
            getattr(rec, "units_source", "") or "", repr(dt), int(acc.size),
            repr(dt * (acc.size - 1)), repr(pga / G_STANDARD)]


def write_csv(path, results, labels):
    """Sweeps (one per structure, `labels` their names) as one CSV: `CSV_COLUMNS`, then
    `SweepResult.csv_rows` of each."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(CSV_COLUMNS)
        for res, lab in zip(results, labels):
            w.writerows(res.csv_rows(lab))


def status_totals(results) -> dict[str, int]:
    """`SweepResult.status_counts` summed over several sweeps."""
    return {k: sum(r.status_counts()[k] for r in results) for k in STATUS}


def report_sweeps(results, labels, *, wall_time=None, processes=1, inputs=True,
                  runs_run=None) -> str:
    """`SweepResult.report` of sweeps of the same records and scales over several
    structures (`labels` their names, one column each); `wall_time` [s] (default: the
    sweeps' sum), `runs_run` (default: every run; fewer when a store was resumed) and
    `processes` for the time line; `inputs`: begin with `report_inputs`."""
    first, n_s, counts = results[0], results[0].n_scales, status_totals(results)
    n_runs = sum(r.n_runs for r in results)
    wall = sum(r.wall_time for r in results) if wall_time is None else wall_time
    failed = {k: v for k, v in counts.items() if STATUS[k] not in USABLE and v}
    n_over, n_used = counts["overturned"], n_runs - sum(failed.values())
    procs = f", {processes} processes" if processes > 1 else ""
    ran = n_runs if runs_run is None else runs_run
    rate = f"{ran / wall:.3g}" if wall > 0 else "-"
    resumed = "" if ran == n_runs else f", {ran} runs run now, the others found done"
    lines = [first.report_inputs()] if inputs else []
    lines += [f"sweep         {n_runs} run{'s' if n_runs != 1 else ''}: {len(results)} "
              f"structure(s) x {first.n_records} record(s) x {n_s} scale(s)",
              f"time          {wall:.3g} s ({rate} runs/s, compilation included{procs}"
              f"{resumed})",
              f"status        {status_line(counts)}"]
    share = f"{n_over / n_used:.1%}" if n_used else "-"
    if failed:
        lines.append(f"overturned    {n_over} of the {n_used} runs that completed or overturned "
                     f"({share}); {n_runs - n_used} failed runs left out ({status_line(failed)})")
    else:
        lines.append(f"overturned    {n_over} of {n_runs} ({share})")
    width = max(8, *(len(lab) + 2 for lab in labels))
    head = f"{'scale':>10}" + "".join(f"{lab:>{width}}" for lab in labels)
    lines += ["fraction overturned by scale (of the runs that completed or overturned):", head]
    fractions = [r.fraction_overturned() for r in results]
    for i in range(n_s) if n_s <= 25 else [*range(12), None, *range(n_s - 12, n_s)]:
        lines.append(f"{'...':>10}" if i is None else f"{first.scales[i]:>10.4g}" + "".join(
            f"{'-' if np.isnan(x := f[i]) else f'{float(x):.3f}':>{width}}" for f in fractions))
    if failed:
        by_scale = [r.failed_by_scale() for r in results]
        lines += ["failed runs by scale (max_impacts, solver_failure; left out of the "
                  "fractions):", head]
        lines += [f"{scale:>10.4g}" + "".join(f"{int(b[i]):>{width}d}" for b in by_scale)
                  for i, scale in enumerate(first.scales) if any(b[i] for b in by_scale)]
    return "\n".join(lines)


def _unique(labels):
    """Labels made unique with a #k suffix where they repeat."""
    out = []
    for i, lab in enumerate(labels):
        k = labels[:i].count(lab)
        out.append(f"{lab}#{k + 1}" if k or labels.count(lab) > 1 else lab)
    return tuple(out)


def _as_records(records, labels):
    """(Records or GroundMotions, labels) of `records`: one or a sequence of Records,
    single-record GroundMotions and paths (read with `rockjax.read_record`)."""
    if isinstance(records, (Record, GroundMotion, str, os.PathLike)):
        records = [records]
    try:
        items = list(records)
    except TypeError:
        raise TypeError(f"records must be a sequence of Records, GroundMotions or paths, got "
                        f"{type(records).__name__}") from None
    if not items:
        raise ParameterError("records: the sequence is empty", param="records")
    out, names = [], []
    for i, item in enumerate(items):
        if isinstance(item, (str, os.PathLike)):
            item = read_record(item)
        if isinstance(item, GroundMotion) and (np.ndim(item.accel) != 1 or np.ndim(item.scale)):
            raise ParameterError(f"records: GroundMotion {i} must hold one record (1-D accel)",
                                 param="records")
        if not isinstance(item, (Record, GroundMotion)):
            raise TypeError(f"records: item {i} is a {type(item).__name__}, not a Record, "
                            "GroundMotion or path")
        out.append(item)
        src = getattr(item, "source", "")
        names.append(pathlib.Path(src).stem if src else f"record {i}")
    if labels is None:
        return tuple(out), _unique(names)
    labels = [str(x) for x in labels]
    if len(labels) != len(out):
        raise ParameterError(f"labels: {len(labels)} labels for {len(out)} records",
                             param="labels")
    return tuple(out), tuple(labels)


def sweep(structure, records, scales, *, model="simplified", tail=DEFAULT_TAIL, t1=None,
          labels=None, processes=None, store=None, chunk_runs=None,
          **options) -> SweepResult:
    """Every record at every scale factor: `rockjax.simulate_batch(summary_only=True)`.

    **Arguments:** `structure`, one `RockingStructure`; `records`, a sequence of
    `rockjax.Record`s, single-record `GroundMotion`s (their own scale applied) or paths
    (read with `rockjax.read_record`, units from the file), of any time steps and lengths;
    `scales` (n_scales,) factors on every record; `model` (default `"simplified"`, as
    `simulate_batch` and `rockjax sweep`; `"rigid_body"` is the one recommended for
    fragility, docs/models.md); each run lasts its record plus `tail` [s] (capped at
    `t1` [s] if given); `labels` (default: the file names); `**options`: the other
    keyword arguments of `simulate_batch` (`impact`, `r`, `method`, `substeps`,
    `max_impacts`, `progress`, `devices`, `fidelity_warning`, ...); `processes`: a
    `rockjax.Processes` (default: this process alone) to split the runs over
    `jax.distributed` processes, each running a contiguous block, every one returning the
    whole result (`Processes.current()` once `jax.distributed.initialize` has run);
    `store`: a path, to write the runs as they go into a Zarr store that a rerun resumes
    (`rockjax.sweep_store`, one structure; `chunk_runs` runs per chunk), the result then
    read back from it.

    **Returns:** a `SweepResult`, arrays of shape (n_records, n_scales).

    **Example:** `rockjax.sweep(rockjax.mcmanus_column(), ["IELC180.AT2", "elCentro.AT2"],
    np.linspace(0.2, 3.0, 40), model="rigid_body")`.
    """
    ensure_x64()
    check_one_structure(structure, "sweep one structure at a time")
    recs, labs = _as_records(records, labels)
    sc = check_scales(scales)
    _check_options(options)
    t0 = time.perf_counter()
    if store is not None:
        sweep_store(store, [structure], recs, sc, model=model, tail=tail, t1=t1,
                    labels=labs, processes=processes, chunk_runs=chunk_runs,
                    **{**options, "fidelity_warning": False})
        res = read_result(store, 0, structure, recs, labs, model=model, tail=tail, t1=t1,
                          options=options, wall_time=time.perf_counter() - t0)
        warn_sdof_lift_off(get_model(model, options.get("impact", "paper")), structure, True,
                           res.peak_u.ravel(), options.get("fidelity_warning", True), 3)
        return res
    if chunk_runs is not None:
        raise ParameterError("chunk_runs: applies to a sweep written to a store (store=)",
                             param="chunk_runs")
    fields = _run(structure, recs, sc, t1, tail, model, options,
                  Processes() if processes is None else processes)
    return SweepResult(structure=structure, records=recs, labels=labs, scales=sc, model=model,
                       impact=options.get("impact", "paper"), tail=tail, t1=t1,
                       options=dict(options), wall_time=time.perf_counter() - t0, **fields)


def _run(structure, records, scales, t1, tail, model, options, processes):
    """The SWEEP_FIELDS of every run, (n_records, n_scales): this process's block of the
    runs, gathered from every process. Run k is record k % n_records at scale
    k // n_records: a block of at least n_records runs holds every record, so that its
    batch runs as the whole sweep's does (per-record ends); and every batch is padded to a
    multiple of `_VECTOR` runs (the last one repeated), which keeps every member on XLA's
    vectorised path: a block gives the bits of the whole sweep (CPU, measured)."""
    n_r, n_s = len(records), scales.size
    lo, hi = processes.block(n_r * n_s)
    k = np.arange(lo, hi)
    k = np.concatenate([k, np.repeat(k[-1:], (-k.size) % _VECTOR)])
    part, error = np.zeros((1 + len(SWEEP_FIELDS), hi - lo)), None  # row 0: failed
    try:
        if hi > lo:
            out = simulate_batch(structure, list(records), t1, tail=tail, scale=scales[k // n_r],
                                 record=k % n_r, model=model, summary_only=True,
                                 **{**options, "fidelity_warning": False})
            part[1:] = [np.asarray(getattr(out, f))[: hi - lo] for f in SWEEP_FIELDS]
    except Exception as e:  # noqa: BLE001 - raised again by gather, after the others know
        part[0], error = 1, e
    full = processes.gather(part, n_r * n_s, error)
    k = np.arange(n_r * n_s)
    fields = {f: np.empty((n_r, n_s)) for f in SWEEP_FIELDS}
    for i, f in enumerate(SWEEP_FIELDS):
        fields[f][k % n_r, k // n_r] = full[1 + i]
    warn_sdof_lift_off(get_model(model, options.get("impact", "paper")), structure, True,
                       fields["peak_u"].ravel(), options.get("fidelity_warning", True), 4)
    return fields


def _check_options(options):
    """Refuse the simulate_batch arguments that a sweep sets itself."""
    clash = [k for k in options if k in _SET_BY_SWEEP]
    if clash:
        raise TypeError(f"sweep sets {', '.join(clash)} itself (every record at every scale, "
                        "summaries only); use simulate_batch for other batches")


# ---------------------------------------------------------------------------- the store
def sweep_store(path, structures, records, scales, *, structure_labels=None,
                model="simplified", tail=DEFAULT_TAIL, t1=None, labels=None, processes=None,
                chunk_runs=None, provenance=None, **options):
    """Every structure x record x scale, written into a Zarr store at `path` chunk by
    chunk as the runs go (never the whole result in memory); a rerun of the same sweep
    resumes where it stopped and ends with the store of an uninterrupted run.

    **Arguments:** `path` of the store (a folder, e.g. `"sweep.zarr"`); `structures`, one
    `RockingStructure` or a sequence of them, labelled `structure_labels` (default
    "structure 0", "structure 1", ...; "structure" for one); `records`, `scales`, `model`,
    `tail`, `t1`, `labels`, `processes` and `**options` as `rockjax.sweep`; `chunk_runs`
    (default 8,192): about that many runs per chunk, every record at a block of scales of
    one structure, one `simulate_batch` call each; `provenance`: a dict of attributes to
    add (the command line puts its `command` there). `progress` (an option): a bar of the
    runs done and the time left (default: when stderr is a terminal). With `processes`
    each `jax.distributed` process runs and writes its share of the chunks (process 0
    creates the store; a shared file system for several machines).

    **Store:** variables `peak_u` [m], `peak_uplift` [m], `n_impacts`, `status` (int8,
    -1 not run yet; `flag_values`/`flag_meanings`), `t_overturn` [s], `t_end` [s] on
    (structure, record, scale), each with `units`; `done` (structure, scale); the record
    coordinates `record_file`, `record_sha256`, `record_dt` [s], `record_npts`,
    `record_pga` [g]; attributes: the rockjax and JAX versions, the command, the model,
    the integrator's settings, the records and structures, and `parameters`, which a
    rerun must repeat: one that differs (the model, a record's samples, the scales, ...)
    is refused with a `ParameterError` naming it.

    **Returns:** the store as an `xarray.Dataset`, lazy (nothing read until used).

    **Example:** `ds = rockjax.sweep_store("sweep.zarr", [s1, s2], ["IELC180.AT2"],
    np.linspace(0.1, 2.0, 5_000), model="rigid_body")`, then
    `ds.status.isel(structure=0)` or `(ds.status == 1).mean("record")`.
    """
    ensure_x64()
    structs, s_labels = _as_structures(structures, structure_labels)
    recs, labs = _as_records(records, labels)
    sc = check_scales(scales)
    _check_options(options)
    procs = Processes() if processes is None else processes
    chunk = scale_chunk(len(recs), sc.size,
                        DEFAULT_CHUNK_RUNS if chunk_runs is None else chunk_runs)
    params = _store_parameters(structs, s_labels, recs, labs, sc, model, tail, t1, options,
                               DEFAULT_CHUNK_RUNS if chunk_runs is None else chunk_runs)
    attrs = _store_provenance(structs, s_labels, recs, labs, model, tail, t1, options,
                              provenance)
    st = _open_store(path, _store_coords(s_labels, labs, recs, sc), params, attrs, chunk,
                     procs)
    _run_store(st, structs, recs, sc, t1, tail, model, options, procs)
    if options.get("fidelity_warning", True):
        law = get_model(model, options.get("impact", "paper"))
        for i, s in enumerate(structs):
            warn_sdof_lift_off(law, s, True, np.ravel(st.group["peak_u"][i]), True, 3)
    return open_dataset(st.path)


def _as_structures(structures, labels):
    """(structures, labels) of one RockingStructure or a sequence of them."""
    items = [structures] if isinstance(structures, RockingStructure) else list(structures)
    if not items:
        raise ParameterError("structures: the sequence is empty", param="structure")
    for s in items:
        check_one_structure(s, "give a sequence of structures")
    if labels is None:
        labels = ["structure"] if len(items) == 1 else [f"structure {i}"
                                                        for i in range(len(items))]
    labels = [str(x) for x in labels]
    if len(labels) != len(items) or len(set(labels)) != len(labels):
        raise ParameterError(f"structure_labels: {len(labels)} labels for {len(items)} "
                             "structures, each label once", param="structure_labels")
    return items, labels


def _version():
    try:
        return importlib.metadata.version("rockjax")
    except importlib.metadata.PackageNotFoundError:  # pragma: no cover - not installed
        return "unknown"


def _record_sha(rec):
    """The SHA-256 of the samples a record runs with (float64), its dt and scale."""
    return array_sha256(rec.accel, [float(rec.dt), float(np.asarray(getattr(rec, "scale",
                                                                              1.0)))])


def _store_parameters(structs, s_labels, recs, labs, sc, model, tail, t1, options, runs):
    """What a rerun into the store must repeat, as JSON: every input of the results."""
    return jsonable({
        "rockjax_version": _version(),
        "structure": {lab: s.to_dict() for lab, s in zip(s_labels, structs)},
        "records": [{"label": lab, "sha256": _record_sha(r)} for lab, r in zip(labs, recs)],
        "scales": {"n": int(sc.size), "first": float(sc[0]), "last": float(sc[-1]),
                   "sha256": array_sha256(sc)},
        "model": model if isinstance(model, str) else repr(model),
        "tail": tail, "t1": t1,
        **{k: v for k, v in sorted(options.items()) if k not in _HOW},
        **({"record_steps": options["execution"].record_steps}  # the one that may change bits
           if options.get("execution") is not None else {}),
        "chunk_runs": runs})


def _store_provenance(structs, s_labels, recs, labs, model, tail, t1, options, extra):
    """The store's descriptive attributes (written once, when it is created)."""
    name = model if isinstance(model, str) else type(model).__name__
    info = []
    for lab, rec in zip(labs, recs):
        i = record_info(rec)
        info.append({"label": lab, "sha256": _record_sha(rec),
                     **{k: v for k, v in i.items() if k not in ("scale", "scaled_pga_g")}})
    return jsonable({
        "title": "rockjax sweep: summaries of every structure x record x scale",
        "rockjax_version": _version(), "software": f"rockjax {_version()}, {stack_versions()}"
        f", zarr {importlib.metadata.version('zarr')}, Python {sys.version.split()[0]}",
        "command": "rockjax.sweep_store (Python)", **(extra or {}),
        "model": model_info(name, options.get("impact", "paper"), options.get("r")),
        "integrator": {k: v for k, v in sorted(options.items()) if k not in _HOW},
        "tail_s": tail, "t1_s": t1, "grid_dt_s": common_time_step([float(r.dt) for r in recs]),
        "records": info,
        "structures": {lab: s.to_dict() for lab, s in zip(s_labels, structs)},
        "structure_units": "SI (m, kg, N/m, s)",
        "run_order": "chunks of every record at a block of scales of one structure, one "
        "simulate_batch(summary_only=True) call each"})


def _store_coords(s_labels, labs, recs, sc):
    """The store's coordinates and per-record variables."""
    infos = [record_info(r) for r in recs]
    return {"structure": list(s_labels), "record": list(labs), "scale": sc, "per_record": {
        "record_file": ([i["file"] for i in infos], {"long_name": "file read"}),
        "record_sha256": ([_record_sha(r) for r in recs], {
            "long_name": "SHA-256 of the samples run (float64), dt and scale"}),
        "record_dt": ([i["dt_s"] for i in infos], {"units": "s", "long_name": "time step"}),
        "record_npts": ([i["n_points"] for i in infos], {"units": "1",
                                                          "long_name": "samples"}),
        "record_pga": ([i["pga_g"] for i in infos], {
            "units": "g", "long_name": "peak ground acceleration at scale 1"})}}


def _barrier(procs, error=None):
    """Every process waits for the others; `error` raised on its process, a ProcessError
    naming it on the others."""
    procs.gather(np.array([[0.0 if error is None else 1.0]]), procs.count, error)


def _open_store(path, coords, params, attrs, chunk, procs):
    """The store, created or checked by process 0, then opened by the others."""
    st = error = None
    if procs.index == 0:
        try:
            st = SweepStore.open(path, coords, params, attrs, chunk)
        except Exception as e:  # noqa: BLE001 - raised again by the barrier
            error = e
    _barrier(procs, error)
    return st or SweepStore.open(path, coords, params, attrs, chunk, create=False)


def _quiet(options):
    """(simulate_batch's options with no bar and no warning, the progress asked for)."""
    opts = {**options, "fidelity_warning": False}
    ex = opts.get("execution")
    if ex is not None:
        opts["execution"] = dataclasses.replace(ex, progress=False)
        return opts, ex.progress
    progress, opts["progress"] = opts.get("progress"), False
    return opts, progress


def _store_bar(st, procs, mine, n_r, progress):
    """A bar of the runs done (those already in the store included) and the time left."""
    if not (progress if progress is not None else sys.stderr.isatty()):
        return None
    from tqdm.auto import tqdm

    todo = n_r * sum(hi - lo for lo, hi in (st.scales_of(c) for _, c in mine))
    total = st.n_structures * n_r * st.n_scales if procs.count == 1 else todo
    return tqdm(total=total, initial=total - todo, desc="sweep", unit="run",
                file=sys.stderr, leave=False, dynamic_ncols=True)


def _run_store(st, structs, recs, sc, t1, tail, model, options, procs):
    """This process's share of the chunks not yet written, each run and written. Every
    chunk pads to the same number of runs (a multiple of `_VECTOR`, the last run
    repeated): one compiled program, and each run's bits those of the whole sweep."""
    pending = st.pending()  # every process reads the same mask, after the barrier
    lo, hi = procs.block(len(pending))
    n_r, (batch, progress) = len(recs), _quiet(options)
    size = -(-n_r * st.chunk // _VECTOR) * _VECTOR
    bar, error = _store_bar(st, procs, pending[lo:hi], n_r, progress), None
    try:
        for s, c in pending[lo:hi]:
            j0, j1 = st.scales_of(c)
            n = (j1 - j0) * n_r
            k = np.minimum(np.arange(size), n - 1)
            out = simulate_batch(structs[s], list(recs), t1, tail=tail, scale=sc[j0 + k // n_r],
                                 record=k % n_r, model=model, summary_only=True, **batch)
            st.write(s, c, {f: np.asarray(getattr(out, f))[:n].reshape(j1 - j0, n_r).T
                            for f in VARIABLES})
            if bar is not None:
                bar.update(n)
            if _AFTER_CHUNK is not None:
                _AFTER_CHUNK(s, c)
    except Exception as e:  # noqa: BLE001 - raised again by the barrier, after the others know
        error = e
    finally:
        if bar is not None:
            bar.close()
    _barrier(procs, error)


def read_result(path, index, structure, records, labels, *, model="simplified",
                tail=DEFAULT_TAIL, t1=None, options=None, wall_time=0.0) -> SweepResult:
    """The `SweepResult` of structure `index` of the store at `path` (its arrays read,
    n_records x n_scales), given the structure and records it ran; every run must be
    done."""
    st = SweepStore.open(path, create=False)
    if not st.done()[index].all():
        raise ParameterError(f"the store {path} holds unfinished runs of structure {index}; "
                             "rerun the sweep to finish it", param="store")
    fields = {f: np.asarray(st.group[f][index]) for f in SWEEP_FIELDS}
    options = dict(options or {})
    return SweepResult(structure=structure, records=tuple(records), labels=labels,
                       scales=np.asarray(st.group["scale"][...]), model=model,
                       impact=options.get("impact", "paper"), tail=tail, t1=t1,
                       options=options, wall_time=wall_time, **fields)
