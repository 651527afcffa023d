"""A sweep of many runs written to a Zarr store (`rockjax sweep --store`): wall time, peak
memory, the store's size, and a resume after the process is killed half-way, which must
leave the store of the uninterrupted run.

Structures: Table 1's column on `--structures` foundations (k_f from 0.5x to 2x Table 1's,
geometric); records: the seven shared ones ($ROCKJAX_SHARED_DATA, default
../shared/data/ground_motions; the two headerless .dat files with their units from
PROVENANCE.md); scales: `--scales` from 0.05 to 3.0. Every run goes through the command
line as a user runs it, in a fresh process:

1. the whole sweep, uninterrupted, into a/sweep.zarr (wall time, peak RSS of the process);
2. the same command into b/sweep.zarr, killed (SIGKILL) once `--kill-at` of the runs are
   in the store, then the same command again, which resumes;
3. the two stores compared: `xarray.testing.assert_identical` and every file byte for
   byte (the same relative --store path in both, so the command attribute is the same).

    python benchmarks/sweep_store.py                       # 25 x 7 x 5,700 = 997,500 runs
    python benchmarks/sweep_store.py --scales 572          # 25 x 7 x 572 = 100,100 runs

Prints one JSON line and appends it to benchmarks/sweep_store.jsonl.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import pathlib
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
from _shared import shared_folder

HERE = pathlib.Path(__file__).resolve().parent
REPO = HERE.parent
#: the seven shared records and the units of those that do not state theirs
RECORDS = {"ChiChi.dat": None, "IELC180.AT2": None, "Northridge_Sylmar_County.dat": "m/s2",
           "RSN1106_KOBE_KJM000.AT2": None, "RSN753_LOMAP_CLS000.AT2": None,
           "elCentro.AT2": None, "elcentro_NS_full.dat": "g"}


def shared_records():
    folder = shared_folder()
    missing = [n for n in RECORDS if not (folder / n).is_file()]
    if missing:
        sys.exit(f"records missing in {folder}: {missing} (set ROCKJAX_SHARED_DATA)")
    return [f"{folder / n}:{u}" if u else str(folder / n) for n, u in RECORDS.items()]


def structures(folder, n):
    """n structure files: Table 1 with k_f from 0.5x to 2x."""
    toml = (REPO / "data" / "mcmanus_column.toml").read_text()
    assert "k_f = 550.0e3" in toml
    paths = []
    for i, k in enumerate(np.geomspace(0.5, 2.0, n)):
        p = folder / f"s{i:02d}.toml"
        p.write_text(toml.replace("k_f = 550.0e3", f"k_f = {float(550.0e3 * k)!r}"))
        paths.append(str(p))
    return paths


def command(args, folder):
    argv = ["sweep"]
    for p in structures(folder, args.structures):
        argv += ["--structure", p]
    for r in shared_records():
        argv += ["--record", r]
    argv += ["--scales", f"0.05:3.0:{args.scales}", "--substeps", str(args.substeps),
             "--model", args.model, "--store", "sweep.zarr", "--json", "--no-fidelity-warning"]
    if args.t1 is not None:
        argv += ["--t1", str(args.t1)]
    if args.chunk_runs is not None:
        argv += ["--chunk-runs", str(args.chunk_runs)]
    return [sys.executable, "-m", "rockjax.cli", *argv]


def start(cmd, cwd):
    cwd.mkdir(parents=True, exist_ok=True)
    out = open(cwd / "stdout.txt", "a")
    err = open(cwd / "stderr.txt", "a")
    return subprocess.Popen(cmd, cwd=cwd, stdout=out, stderr=err), time.perf_counter()


def finish(proc, t0):
    """(exit code, wall [s], peak RSS [MB]) of a child, waited for with os.wait4."""
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return proc.returncode, time.perf_counter() - t0, usage.ru_maxrss / 1024


def runs_done(store):
    from rockjax._store import runs_done as done

    try:
        return done(store)
    except Exception:  # noqa: BLE001 - a store being written: try again
        return 0


def store_files(path):
    return {str(f.relative_to(path)): f for f in sorted(path.rglob("*")) if f.is_file()}


def same_files(a, b):
    fa, fb = store_files(a), store_files(b)
    if fa.keys() != fb.keys():
        return False
    return all(hashlib.sha256(fa[k].read_bytes()).digest()
               == hashlib.sha256(fb[k].read_bytes()).digest() for k in fa)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--structures", type=int, default=25)
    p.add_argument("--scales", type=int, default=5700)
    p.add_argument("--t1", type=float, default=None, help="cap every run at T1 s")
    p.add_argument("--substeps", type=int, default=4)
    p.add_argument("--model", default="simplified")
    p.add_argument("--chunk-runs", type=int, default=None)
    p.add_argument("--kill-at", type=float, default=0.5)
    p.add_argument("--folder", type=pathlib.Path, default=pathlib.Path("/tmp/sweep_store_bench"))
    p.add_argument("--keep", action="store_true", help="keep the stores")
    args = p.parse_args()
    shutil.rmtree(args.folder, ignore_errors=True)
    (args.folder / "inputs").mkdir(parents=True)
    cmd = command(args, args.folder / "inputs")
    n_runs = args.structures * len(RECORDS) * args.scales
    print(f"{n_runs} runs: {' '.join(cmd[3:])}", file=sys.stderr, flush=True)

    proc, t0 = start(cmd, args.folder / "a")
    rc, wall, rss = finish(proc, t0)
    assert rc == 0, (args.folder / "a" / "stderr.txt").read_text()[-2000:]
    info = json.loads((args.folder / "a" / "stdout.txt").read_text())
    a = args.folder / "a" / "sweep.zarr"
    size = sum(f.stat().st_size for f in store_files(a).values())
    print(f"whole: {wall:.1f} s, peak RSS {rss:.0f} MB, store {size / 1e6:.1f} MB",
          file=sys.stderr, flush=True)

    b = args.folder / "b" / "sweep.zarr"
    proc, t0 = start(cmd, args.folder / "b")
    while runs_done(b) < args.kill_at * n_runs and proc.poll() is None:
        time.sleep(0.5)
    proc.send_signal(signal.SIGKILL)
    _, wall_killed, rss_killed = finish(proc, t0)
    at_kill = runs_done(b)
    proc, t0 = start(cmd, args.folder / "b")
    rc, wall_resume, rss_resume = finish(proc, t0)
    assert rc == 0, (args.folder / "b" / "stderr.txt").read_text()[-2000:]
    resumed = json.loads((args.folder / "b" / "stdout.txt").read_text().splitlines()[-1])

    import xarray as xr

    xr.testing.assert_identical(xr.open_zarr(a, consolidated=False).load(),
                                xr.open_zarr(b, consolidated=False).load())
    identical = same_files(a, b)
    out = {
        "runs": n_runs, "structures": args.structures, "records": len(RECORDS),
        "scales": args.scales, "model": args.model, "substeps": args.substeps, "t1": args.t1,
        "chunk_runs": args.chunk_runs, "wall_s": round(wall, 1), "runs_per_s": round(
            n_runs / wall), "peak_rss_mb": round(rss), "store_mb": round(size / 1e6, 2),
        "store_files": len(store_files(a)), "status_counts": info["status_counts"],
        "killed_after_s": round(wall_killed, 1), "runs_in_store_at_kill": at_kill,
        "resume_wall_s": round(wall_resume, 1), "resume_found_done": resumed["runs_found_done"],
        "resume_peak_rss_mb": round(rss_resume), "assert_identical": True,
        "files_byte_identical": identical, "cpus": os.cpu_count(),
        "load_1min_at_end": round(os.getloadavg()[0], 2),
    }
    line = json.dumps(out)
    print(line)
    with open(HERE / "sweep_store.jsonl", "a") as f:
        f.write(line + "\n")
    if not args.keep:
        shutil.rmtree(args.folder / "a", ignore_errors=True)
        shutil.rmtree(args.folder / "b", ignore_errors=True)
    return 0 if identical else 1


if __name__ == "__main__":
    sys.exit(main())
