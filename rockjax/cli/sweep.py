"""`rockjax sweep`: peak responses over structures x scale factors x records (CSV, plot).

Reads the structures and records (each record's units from its file, `FILE:UNITS` or a
`--units` after it), runs each structure through `rockjax.sweep` (the library's one batch
engine; over several `jax.distributed` processes with `--distributed` or `--coordinator`,
started by `_distributed`), writes the CSV (`rockjax._sweep.write_csv`), the plot
(`_plotting.plot_sweeps`) and the report; process 0 writes them. With `--store` the runs
go through `rockjax.sweep_store` instead: written chunk by chunk into a Zarr store as they
go (each process its own chunks), a rerun of the command resuming it, and the report read
back from the store one structure at a time.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import pathlib
import shlex
import sys
import time

import numpy as np

import rockjax
from rockjax._batch import DEFAULT_TAIL
from rockjax._distributed import fingerprint
from rockjax._p695 import _SETS, SUITES
from rockjax._plotting import plot_sweeps
from rockjax._records import common_time_step, record_format
from rockjax._store import runs_done
from rockjax._suite import expand_folders, RecordFile, split_record_units, unique_labels
from rockjax._sweep import read_result, report_sweeps, status_totals, write_csv

from . import _distributed
from ._common import (
    add_model_arguments,
    add_outputs,
    add_plausibility_argument,
    add_time_tolerance_argument,
    check_outputs,
    CLIError,
    COMMON_FLAGS,
    converter,
    error_text,
    EXIT_USAGE,
    fidelity_note,
    first_line,
    load_structure,
    MAX_STEPS,
    model_info,
    model_line,
    positive_float,
    positive_int,
    RECORD_FLAGS,
    record_units,
    RECORD_UNITS_METAVAR,
    save,
    scale_list,
)

#: the library parameters that the options of `rockjax sweep` set (errors name the option)
FLAGS = {**COMMON_FLAGS, **RECORD_FLAGS, "scale": "--scales", "scales": "--scales",
         "tail": "--tail", "structure": "--structure", "records": "--record",
         "coordinator": "--coordinator", "store": "--store", "chunk_runs": "--chunk-runs"}


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
        "jax.distributed processes or machines and process 0 writes the outputs. With "
        "--store the runs go, as they finish, into a Zarr store instead (each process writing "
        "its own chunks), which the same command run again resumes after an interruption.",
    )
    add_input_arguments(w)
    add_run_arguments(w)
    add_outputs(w, "plot peak |u| and the fraction overturned against the scale",
                out="CSV of the summaries, one row per run (default ./sweep.csv; with "
                "--store only when given)",
                json="print one JSON object and nothing else (no progress bar)")
    add_store_arguments(w)
    _distributed.add_distributed_arguments(w)
    w.set_defaults(func=run)
    return w


def add_store_arguments(w):
    """--store PATH.zarr and --chunk-runs N (also `rockjax fragility`'s)."""
    w.add_argument(
        "--store", metavar="PATH.zarr",
        help="write the results as they go, chunk by chunk, into a Zarr store (a folder) of "
        "labelled arrays on (structure, record, scale), with units and provenance (read it "
        "with xarray.open_zarr); memory stays bounded by a chunk, and rerunning the same "
        "command resumes an interrupted sweep where it stopped (other arguments into the "
        "same store are refused). Needs pip install \"rockjax[store]\"")
    w.add_argument("--chunk-runs", type=positive_int("--chunk-runs"), metavar="N",
                   help="with --store: about N runs per chunk, each written at once (default "
                   "8192; every record at a block of scales of one structure)")


class _InOrder(argparse.Action):
    """Keep --record and --units in the order given: (dest, value) pairs in `inputs`."""

    def __call__(self, parser, namespace, values, option_string=None):
        namespace.inputs = [*(namespace.inputs or []), (self.dest, values)]


def add_input_arguments(w, structure="structure file, repeatable (default: Table 1)",
                        scales=None):
    """--structure, --record, --units, --record-dt, --scales (`scales`: its help, and then
    required, as `rockjax fragility` has it)."""
    w.set_defaults(inputs=None)
    w.add_argument("--structure", action="append", metavar="FILE.toml", help=structure)
    add_plausibility_argument(w)
    w.add_argument(
        "--record", action=_InOrder, metavar="FILE[:UNITS]|DIR",
        help="ground-motion record file, repeatable (at least one --record or --suite); "
        "FILE:g, FILE:m/s2, "
        "FILE:cm/s2 or FILE:gal states its units; a folder takes every record file in it "
        "(.AT2, .dat, .txt, .csv, .acc, ESM .ASC, K-NET .EW/.NS/.UD[12], .gz), sorted by "
        "name")
    w.add_argument(
        "--units", action=_InOrder, type=record_units, metavar=RECORD_UNITS_METAVAR,
        help="units of the --record just before it (before any --record: of every record "
        "that states no units of its own). A file that states its units (AT2 'UNITS OF "
        "G', a column title 'Accel[g]') is read in them; units given that contradict them "
        "are refused")
    w.add_argument(
        "--suite", action="append", type=suite_name, metavar="NAME[:normalized]",
        help=f"a standard record suite, repeatable, beside or instead of --record: "
        f"{', '.join(SUITES)} (rockjax.datasets.load_suite; needs pip install "
        "'rockjax[suites]'); NAME:normalized applies the FEMA P695 normalisation factor "
        "(median PGV_PEER / the record's PGV_PEER, Eq. A-1) to each record. Its "
        "components are labelled FF01a, FF01b, ... (NFP, NFN: near-field pulse, no-pulse); "
        "a component whose step has no common grid with the others is resampled onto one "
        "(the report says which)")
    w.add_argument("--record-dt", type=positive_float("--record-dt"), metavar="DT",
                   help="sample step [s] of the one-column records (the others state their own)")
    add_time_tolerance_argument(w)
    w.add_argument("--scales", type=scale_list, default=None if scales else [1.0],
                   required=bool(scales), metavar="LIST|START:STOP:N",
                   help=scales or 'scale factors: a comma list such as "0.5,1,1.5" or a range '
                   '"START:STOP:N" of N evenly spaced values, ends included (default 1)')


def add_run_arguments(w):
    """--tail, --t1, --model, --method, --substeps, --r, --impact."""
    w.add_argument(
        "--tail", default=DEFAULT_TAIL, metavar="S",
        type=converter("--tail", float, lambda x: math.isfinite(x) and x >= 0,
                       "be >= 0 and finite"),
        help=f"free vibration [s] after each record's end (default {DEFAULT_TAIL:g}); "
        "each run ends at its own record's end plus S, so shorter records are never "
        "padded with zeros")
    w.add_argument("--t1", type=positive_float("--t1"), metavar="T",
                   help="stop every run at T [s] at the latest (default: no cap)")
    add_model_arguments(w, "model of the fidelity ladder (default simplified; two_spring_2dof: "
                        "the 2-DOF rigid body on its springs, batched like the others)")
    w.add_argument("--method", choices=["rk4", "dopri5", "diffrax"], default="rk4",
                   help="integrator (default rk4, the fast fixed-step path)")
    w.add_argument(
        "--substeps", type=positive_int("--substeps"), default=4, metavar="N",
        help="RK4 steps per step of the records' common grid (default 4: peak |u| within "
        "about 2e-5 of a tight reference on El Centro scaled 0.1-2; 2 is twice as fast, "
        "within 4e-4)")


# ------------------------------------------------------------------------------ inputs
def _sweep_structures(paths, check_plausible=True):
    """(structures, labels) of the --structure files, or of Table 1 when there are none."""
    structures = []
    for path in paths or [None]:
        try:
            structures.append(load_structure(path, check_plausible))
        except (ValueError, OSError) as e:
            raise CLIError(f"--structure: {first_line(e)}") from None
    return structures, ["table1"] if paths is None else unique_labels(paths)


_SUITE_PREFIX = {name: prefix for name, (_, prefix, _) in _SETS.items()}


def suite_name(text):
    """(suite name, normalized) of --suite NAME[:normalized]."""
    name, sep, tail = str(text).partition(":")
    if name not in SUITES or (sep and tail not in ("normalized", "normalised")):
        raise argparse.ArgumentTypeError(
            f"expected one of {', '.join(SUITES)}, optionally with :normalized; got {text!r}")
    return name, bool(sep)


def _read_suites(suites):
    """(records, labels, notes) of the --suite values, in order."""
    records, labels, notes = [], [], []
    for name, normalized in suites or []:
        try:
            suite = rockjax.datasets.load_suite(name, normalized=normalized)
        except ImportError as e:
            raise CLIError(f"--suite {name}: {first_line(e)}") from None
        records += suite.records
        labels += suite.labels
    if records:
        records, resampled = rockjax.datasets.fit_common_step(records, labels=labels)
        notes += [f"resampled {n}" for n in resampled]
    return records, labels, notes


def _record_specs(inputs):
    """(the --record values in order, with their units, the --units given before any
    --record): FILE:UNITS, or a --units right after its --record."""
    specs, default = [], None
    for kind, value in inputs or []:
        if kind == "record":
            specs.append(RecordFile(*split_record_units(value)))
        elif not specs:
            if default is not None:
                raise CLIError("--units: given twice before the first --record")
            default = value
        elif specs[-1].units is not None:
            raise CLIError(f"--units {value}: the --record before it, {specs[-1].path}, "
                           f"already has units {specs[-1].units}")
        else:
            specs[-1].units = value
    return specs, default


def _read_records(specs, default_units, record_dt, check_plausible=True,
                  time_tolerance=1e-3):
    """The records, read with the units given for each (else --units before any
    --record, else the file's) and --record-dt for the one-column ones; errors in CLI
    syntax."""
    records = []
    for spec in specs:
        try:
            one_col = record_dt is not None and record_format(spec.path) == "one_column"
            records.append(rockjax.read_record(spec.path, units=spec.units or default_units,
                                               dt=record_dt if one_col else None,
                                               check_plausible=check_plausible,
                                               time_tolerance=time_tolerance))
        except (ValueError, OSError) as e:
            hint = ""
            if spec.folder is not None and getattr(e, "param", None) == "units":
                hint = (f" (a file of --record {spec.folder}: give its units with --record "
                        f"{spec.path}:g or :m/s2)")
            where = "" if isinstance(e, rockjax.ParameterError) else "--record: "
            raise CLIError(f"{where}{error_text(e, FLAGS)}{hint}") from None
    return records


# --------------------------------------------------------------------------------- run
@dataclasses.dataclass
class Sweep:
    """A sweep's inputs and, once `run_batches` has filled them, its results: one
    `rockjax.SweepResult` (records x scales) per structure."""

    structures: list
    struct_labels: list[str]
    records: list
    rec_labels: list[str]
    scales: np.ndarray
    tail: float
    t1: float | None
    skipped: dict = dataclasses.field(default_factory=dict)
    suites: list = dataclasses.field(default_factory=list)  # --suite (name, normalized)
    suite_notes: list[str] = dataclasses.field(default_factory=list)
    processes: int = 1
    found: int = 0  # --store: the runs found done there (a resumed sweep)
    results: list = dataclasses.field(default_factory=list)
    warnings: list[str] = dataclasses.field(default_factory=list)
    wall: float = 0.0

    @property
    def n_runs(self):
        return len(self.structures) * len(self.scales) * len(self.rec_labels)

    @property
    def runs(self):
        return f"{self.n_runs} run{'s' if self.n_runs != 1 else ''}"


def read_sweep(args):
    """The sweep's inputs, read and checked (no run yet); the records' common time step is
    checked here (a one-line error when there is none), and the length of the runs."""
    structures, struct_labels = _sweep_structures(args.structure, args.check_plausible)
    specs, default_units = _record_specs(args.inputs)
    if not specs and not getattr(args, "suite", None):
        raise CLIError("give at least one --record FILE or --suite NAME")
    specs, skipped = expand_folders(specs)
    records = _read_records(specs, default_units, args.record_dt, args.check_plausible,
                            args.time_tolerance)
    labels = unique_labels([s.path for s in specs])
    names = [pathlib.Path(s.path).name for s in specs]
    suite_records, suite_labels, suite_notes = _read_suites(getattr(args, "suite", None))
    if set(suite_labels) & set(labels) or len(set(suite_labels)) < len(suite_labels):
        raise CLIError("--suite: a suite given twice, or a record file labelled as one of "
                       "its components")
    records, labels, names = records + suite_records, labels + suite_labels, names + suite_labels
    try:
        grid = common_time_step([r.dt for r in records], names=names)
    except ValueError as e:
        raise CLIError(f"--record: {first_line(e)}") from None
    sweep = Sweep(structures, struct_labels, records, labels,
                  np.asarray(args.scales, float), args.tail, args.t1, skipped,
                  suites=list(getattr(args, "suite", None) or []), suite_notes=suite_notes)
    n = max(min(r.dt * (r.npts - 1) + sweep.tail, sweep.t1 or math.inf) for r in records) / grid
    if not n <= MAX_STEPS:  # a one-line error naming --tail, rather than numpy's size error
        raise CLIError(
            f"--tail {sweep.tail:g} s makes runs of {n:.3g} steps of the records' common grid "
            f"({grid:g} s), more than {MAX_STEPS:,}; shorten --tail or cap the runs with --t1")
    return sweep


def run_batches(args, sweep, cluster=None, full=False):
    """`rockjax.sweep` of each structure, its runs split over the processes of `cluster`
    (default: this one); fills sweep.results and sweep.warnings. With --store:
    `_run_store` (`full`: keep each structure's whole result, as `rockjax fragility`
    needs)."""
    cluster = cluster or _distributed.Cluster()
    if getattr(args, "store", None):
        return _run_store(args, sweep, cluster, full)
    t0 = time.perf_counter()
    quiet = args.json or cluster.index > 0
    for s in sweep.structures:
        with cluster.collective():
            res = rockjax.sweep(
                s, sweep.records, sweep.scales, model=args.model, tail=sweep.tail,
                t1=sweep.t1, labels=sweep.rec_labels, processes=cluster, r=args.r,
                impact=args.impact, method=args.method, substeps=args.substeps,
                progress=False if quiet else None, fidelity_warning=False)
        sweep.results.append(res)
        note = fidelity_note(args, s, True, res.peak_u.ravel())
        if note and note not in sweep.warnings:
            sweep.warnings.append(note)
            if cluster.index == 0:
                print(f"warning: {note}", file=sys.stderr)
    sweep.wall = time.perf_counter() - t0
    sweep.processes = cluster.count


def _run_store(args, sweep, cluster, full):
    """`rockjax.sweep_store` of every structure into --store (each process writes its own
    chunks; a rerun skips those done), then on process 0 each structure's result read
    back in turn: kept whole for `full`, --out or --plot, else only its totals
    (`_Totals`), so that memory stays bounded by one structure's runs."""
    t0, quiet = time.perf_counter(), args.json or cluster.index > 0
    sweep.found = runs_done(args.store) if cluster.index == 0 else 0
    options = {"r": args.r, "impact": args.impact, "method": args.method,
               "substeps": args.substeps}
    command = shlex.join(["rockjax", *getattr(args, "argv", [args.command])])
    with cluster.collective():
        rockjax.sweep_store(
            args.store, sweep.structures, sweep.records, sweep.scales,
            structure_labels=sweep.struct_labels, labels=sweep.rec_labels, model=args.model,
            tail=sweep.tail, t1=sweep.t1, processes=cluster, chunk_runs=args.chunk_runs,
            provenance={"command": command}, progress=False if quiet else None,
            fidelity_warning=False, **options)
    sweep.wall, sweep.processes = time.perf_counter() - t0, cluster.count
    if cluster.index != 0:
        return
    keep = full or args.out or args.plot
    for i, s in enumerate(sweep.structures):
        res = read_result(args.store, i, s, sweep.records, sweep.rec_labels, model=args.model,
                          tail=sweep.tail, t1=sweep.t1, options=options)
        sweep.results.append(res if keep else _Totals(res))
        note = fidelity_note(args, s, True, res.peak_u.ravel())
        if note and note not in sweep.warnings:
            sweep.warnings.append(note)
            print(f"warning: {note}", file=sys.stderr)


class _Totals:
    """What the report keeps of one structure's `SweepResult` read back from a store: its
    counts, its columns per scale and its inputs, not its per-run arrays."""

    def __init__(self, res):
        self.n_runs, self.n_records, self.n_scales = res.n_runs, res.n_records, res.n_scales
        self.scales, self.wall_time, self.grid_dt = res.scales, res.wall_time, res.grid_dt
        self._counts, self._fraction = res.status_counts(), res.fraction_overturned()
        self._failed, self._inputs = res.failed_by_scale(), res.report_inputs()
        self._info = res.record_info()

    def status_counts(self):
        return self._counts

    def fraction_overturned(self):
        return self._fraction

    def failed_by_scale(self):
        return self._failed

    def report_inputs(self):
        return self._inputs

    def record_info(self):
        return self._info


def check_store_arguments(args):
    """--chunk-runs needs --store; a --store path that is a file is refused."""
    if args.chunk_runs is not None and not args.store:
        raise CLIError("--chunk-runs: applies with --store")
    if args.store and pathlib.Path(args.store).is_file():
        raise CLIError(f"--store is a file: {args.store} (a store is a folder)")


def _load_sweep(args, cluster):
    """`read_sweep`, and (several processes) a check that every process read the same."""
    sweep = error = None
    try:
        sweep = read_sweep(args)
    except Exception as e:  # noqa: BLE001 - raised again by agree, after the others know
        error = e
    fp = None
    if cluster.active and sweep is not None:  # processes that read different files disagree
        fp = fingerprint([sweep.struct_labels, sweep.rec_labels, sweep.scales.tolist(),
                          sweep.tail, sweep.t1],
                         [(r.accel, float(r.dt)) for r in sweep.records] + sweep.structures)
    with cluster.collective():
        cluster.agree(fp, error)
    return sweep


# ---------------------------------------------------------------------------- outputs
def sweep_json(args, sweep):
    """The sweep's JSON object (`--json`; `rockjax fragility` shows part of it)."""
    n_runs, wall, first = sweep.n_runs, sweep.wall, sweep.results[0]
    return {
        "n_runs": n_runs, "n_structures": len(sweep.structures),
        "n_records": len(sweep.rec_labels), "n_scales": len(sweep.scales),
        "status_counts": status_totals(sweep.results), "wall_time_s": wall,
        "runs_per_s": n_runs / wall if wall > 0 else None, "processes": sweep.processes,
        "tail_s": sweep.tail, "t1": sweep.t1, "grid_dt_s": first.grid_dt, "model": args.model,
        "model_info": model_info(args), "method": args.method,
        "substeps": args.substeps if args.method == "rk4" else None,
        "csv": None if args.out is None else str(args.out),
        "store": getattr(args, "store", None), "runs_found_done": sweep.found,
        "plot": args.plot, "structures": sweep.struct_labels, "records": sweep.rec_labels,
        "record_info": first.record_info(), "skipped_files": sweep.skipped,
        "suites": [{"name": n, "normalized": z} for n, z in sweep.suites],
        "suite_notes": sweep.suite_notes,
        "scales": [float(x) for x in sweep.scales],
        "fraction_overturned": {lab: [None if np.isnan(x) else float(x)
                                      for x in r.fraction_overturned()]
                                for lab, r in zip(sweep.struct_labels, sweep.results)},
        "failed_by_scale": {lab: r.failed_by_scale().tolist()
                            for lab, r in zip(sweep.struct_labels, sweep.results)},
        "warnings": sweep.warnings,
    }


def print_inputs(sweep):
    """What was read and what produced the results: folders, records, their grid, the model."""
    for folder, names in sweep.skipped.items():
        taken = sum(pathlib.Path(r.source).parent == pathlib.Path(folder) for r in sweep.records)
        note = f"; skipped (not record files): {', '.join(names)}" if names else ""
        print(f"folder        {folder}: {taken} record file(s) taken{note}")
    for name, normalized in sweep.suites:
        n = sum(lab.startswith(_SUITE_PREFIX[name]) for lab in sweep.rec_labels)
        print(f"suite         {name}{' (normalized, FEMA P695 Eq. A-1)' if normalized else ''}"
              f": {n} components")
    for note in sweep.suite_notes:
        print(f"suite         {note} (no common grid with the others)")
    print(sweep.results[0].report_inputs())


def print_store(args, sweep):
    """--store: where the results are, and how many runs a resumed sweep found done."""
    if args.store:
        found = f"; {sweep.found} of them found done and skipped" if sweep.found else ""
        print(f"store         {args.store}: {sweep.n_runs} runs on (structure, record, scale)"
              f"{found}; xarray.open_zarr({str(args.store)!r})")


def run(args):
    """structures x scales x records through `rockjax.sweep`: CSV, plot; over several
    jax.distributed processes when asked (process 0 writes)."""
    check_store_arguments(args)
    if args.out is None and not args.store:
        args.out = "sweep.csv"
    check_outputs(args)
    cluster = _distributed.start(args)
    try:
        sweep = _load_sweep(args, cluster)
        run_batches(args, sweep, cluster)
    except Exception as e:
        if not cluster.active:
            raise
        # one of several processes failed: leave jax.distributed, say why, and end at once
        # (a process that returned to the interpreter's exit after a failed run has been
        # seen to hang there, under load, until killed)
        cluster.stop()
        print(f"rockjax sweep: error: {error_text(e, FLAGS)}", file=sys.stderr, flush=True)
        os._exit(EXIT_USAGE)
    finally:
        cluster.stop()
    if cluster.index != 0:
        return 0
    if args.out:
        write_csv(args.out, sweep.results, sweep.struct_labels)
    if args.plot:
        end = "its end + tail" if args.t1 is None else f"min(end + tail, {args.t1:g} s)"
        save(plot_sweeps(sweep.results, sweep.struct_labels, title=f"{sweep.runs}, each record "
                         f"to {end}, {model_line(model_info(args))}, {args.method}"),
             args.plot)
    if args.json:
        print(json.dumps(sweep_json(args, sweep)))
        return 0
    print_inputs(sweep)
    print(report_sweeps(sweep.results, sweep.struct_labels, wall_time=sweep.wall,
                        processes=sweep.processes, inputs=False,
                        runs_run=sweep.n_runs - sweep.found))
    print_store(args, sweep)
    if args.out:
        print(f"results written to {args.out}")
    if args.plot:
        print(f"plot written to {args.plot}")
    return 0
