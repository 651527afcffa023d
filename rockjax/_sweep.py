"""`rockjax.sweep`: every record at every scale factor, the one batch engine behind
fragility curves and the `rockjax sweep` / `rockjax fragility` commands.

The runs go through `rockjax.simulate_batch(summary_only=True)` as one flat batch (run k:
record k % n_records at scale k // n_records, the order of the CSV rows) and a `SweepResult`
holds arrays of shape (n_records, n_scales), the one orientation of the API and the CLI.
Over several `jax.distributed` processes (`processes=rockjax.Processes.current()`) each
process runs a contiguous block of the runs and every process ends with the whole result.
The status counting (the fraction overturned among the runs that completed or overturned,
the failed runs per scale) is written here once.
"""

from __future__ import annotations

import csv
import dataclasses
import os
import pathlib
import time

import numpy as np

from ._batch import DEFAULT_TAIL, simulate_batch
from ._checks import check_one_structure, check_scales
from ._config import ensure_x64
from ._distributed import Processes
from ._errors import ParameterError
from ._excitation import GroundMotion
from ._fidelity import warn_sdof_lift_off
from ._records import common_time_step, G_STANDARD, read_record, Record
from ._report import model_info, model_line, record_info, status_line
from ._status import STATUS, STATUS_NAMES
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


def report_sweeps(results, labels, *, wall_time=None, processes=1, inputs=True) -> str:
    """`SweepResult.report` of sweeps of the same records and scales over several
    structures (`labels` their names, one column each); `wall_time` [s] (default: the
    sweeps' sum) and `processes` for the time line; `inputs`: begin with `report_inputs`."""
    first, n_s, counts = results[0], results[0].n_scales, status_totals(results)
    n_runs = sum(r.n_runs for r in results)
    wall = sum(r.wall_time for r in results) if wall_time is None else wall_time
    failed = {k: v for k, v in counts.items() if STATUS[k] not in USABLE and v}
    n_over, n_used = counts["overturned"], n_runs - sum(failed.values())
    procs = f", {processes} processes" if processes > 1 else ""
    rate = f"{n_runs / wall:.3g}" if wall > 0 else "-"
    lines = [first.report_inputs()] if inputs else []
    lines += [f"sweep         {n_runs} run{'s' if n_runs != 1 else ''}: {len(results)} "
              f"structure(s) x {first.n_records} record(s) x {n_s} scale(s)",
              f"time          {wall:.3g} s ({rate} runs/s, compilation included{procs})",
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
          labels=None, processes=None, **options) -> SweepResult:
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
    whole result (`Processes.current()` once `jax.distributed.initialize` has run).

    **Returns:** a `SweepResult`, arrays of shape (n_records, n_scales).

    **Example:** `rockjax.sweep(rockjax.mcmanus_column(), ["IELC180.AT2", "elCentro.AT2"],
    np.linspace(0.2, 3.0, 40), model="rigid_body")`.
    """
    ensure_x64()
    check_one_structure(structure, "sweep one structure at a time")
    recs, labs = _as_records(records, labels)
    sc = check_scales(scales)
    clash = [k for k in options if k in _SET_BY_SWEEP]
    if clash:
        raise TypeError(f"sweep sets {', '.join(clash)} itself (every record at every scale, "
                        "summaries only); use simulate_batch for other batches")
    t0 = time.perf_counter()
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
