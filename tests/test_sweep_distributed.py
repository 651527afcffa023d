"""`rockjax sweep` as several `jax.distributed` processes: the same CSV, byte for byte.

Two real processes of the console entry point connect on 127.0.0.1 (gloo over TCP, a free
port), each runs its block of 3 structures x 2 scales x 2 records (the blocks split the
middle structure), and process 0 writes the CSV and the JSON; they are compared with one
process's. Then the flags' errors: each a one-line message naming the flag, before any
connection is tried (in-process, fast) or after a short timeout (a coordinator that never
answers).
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import pathlib
import re
import socket
import subprocess
import sys
import time

import jax
import pytest
from conftest import REPO
from test_records import synthetic, write_at2, write_two_column

import rockjax
from rockjax.cli import main

#: seconds a launch may take before its processes are killed (a loaded 2-core machine)
LAUNCH_TIMEOUT = 300
#: the JSON keys that may differ between one process and two (with the same --out)
PER_RUN_KEYS = {"wall_time_s", "runs_per_s", "processes"}


def _free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _launch(argvs, cwds, env=None, timeout=LAUNCH_TIMEOUT, kill=None):
    """`_launch_envs` with one environment (None: this one's) for every process."""
    return _launch_envs(argvs, cwds, [env] * len(argvs), timeout, kill)


def _launch_envs(argvs, cwds, envs, timeout=LAUNCH_TIMEOUT, kill=None):
    """Start one `rockjax` process per argv (each in its cwd, output to files), wait for
    all; on a timeout kill them all and fail with every process's stderr. `kill=(i,
    text)`: kill process i once its stderr shows `text`. Returns [(exit code, stdout,
    stderr)]."""
    procs, files = [], []
    try:
        for i, (argv, cwd, env) in enumerate(zip(argvs, cwds, envs)):
            out, err = pathlib.Path(cwd) / f"stdout.{i}", pathlib.Path(cwd) / f"stderr.{i}"
            fo, fe = out.open("w"), err.open("w")
            files.append((out, err, fo, fe))
            procs.append(subprocess.Popen([sys.executable, "-m", "rockjax.cli", *argv],
                                          stdout=fo, stderr=fe, cwd=cwd, env=env))
        deadline = time.monotonic() + timeout
        if kill is not None:
            i, text = kill
            while text not in files[i][1].read_text() and procs[i].poll() is None:
                if time.monotonic() > deadline:
                    raise subprocess.TimeoutExpired(procs[i].args, timeout)
                time.sleep(0.1)
            procs[i].kill()
        for p in procs:
            p.wait(timeout=max(1.0, deadline - time.monotonic()))
    except subprocess.TimeoutExpired:
        pass
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait()
        for *_, fo, fe in files:
            fo.close()
            fe.close()
    results = [(p.returncode, out.read_text(), err.read_text())
               for p, (out, err, *_) in zip(procs, files)]
    killed = [i for i, (rc, *_) in enumerate(results) if rc is None or rc < 0]
    if killed != ([] if kill is None else [kill[0]]):  # killed by us, or by a signal
        pytest.fail("processes killed or crashed:\n" + _dump(results))
    return results


def _dump(results):
    return "\n".join(f"--- process {i}: exit {rc}\nstdout:\n{out}\nstderr:\n{err}"
                     for i, (rc, out, err) in enumerate(results))


def _flags(port, n, i, timeout=120):
    return ["--coordinator", f"127.0.0.1:{port}", "--num-processes", str(n),
            "--process-id", str(i), "--coordinator-timeout", str(timeout)]


@pytest.fixture(scope="module")
def sweep_args(tmp_path_factory):
    """3 structures (Table 1, a softer and a stiffer foundation) x 2 scales x 2 records (an
    AT2 of 2.5 s at 0.01 s and two columns of 1.5 s at 0.02 s): 12 runs, 1 s of tail."""
    d = tmp_path_factory.mktemp("inputs")
    toml = (REPO / "data" / "mcmanus_column.toml").read_text()
    for name, k_f in (("soft", "300.0e3"), ("stiff", "900.0e3")):
        (d / f"{name}.toml").write_text(toml.replace("k_f = 550.0e3", f"k_f = {k_f}"))
    at2 = write_at2(d / "quake.AT2", synthetic(seed=3, dt=0.01, duration=2.5, pga=3.0))
    two = write_two_column(d / "short.txt", synthetic(seed=4, dt=0.02, duration=1.5, pga=2.0))
    return ["sweep", "--structure", str(REPO / "data" / "mcmanus_column.toml"),
            "--structure", str(d / "soft.toml"), "--structure", str(d / "stiff.toml"),
            "--record", str(at2), "--record", str(two), "--scales", "0.6,1.4", "--tail", "1",
            "--out", "sweep.csv", "--plot", "sweep.png", "--json"]


@pytest.mark.slow  # moved out of the default suite (issue 23): compile-bound; CI runs it
def test_two_processes_write_what_one_writes(sweep_args, tmp_path):
    """Two jax.distributed processes: process 0 writes the CSV of one process byte for
    byte (the same rows, in the same order, to the last digit), the same plot and the same
    JSON; process 1 writes nothing, and no connection message reaches stdout."""
    one, two, two_1 = tmp_path / "one", tmp_path / "two", tmp_path / "two_1"
    one.mkdir(), two.mkdir(), two_1.mkdir()
    t0 = time.perf_counter()
    [(rc, out, err)] = _launch([sweep_args], [one])
    t_one = time.perf_counter() - t0
    assert rc == 0, err
    port = _free_port()
    t0 = time.perf_counter()
    results = _launch([sweep_args + _flags(port, 2, i) for i in range(2)], [two, two_1])
    t_two = time.perf_counter() - t0
    assert [r[0] for r in results] == [0, 0], _dump(results)
    (_, out0, _), (_, out1, _) = results
    assert (two / "sweep.csv").read_bytes() == (one / "sweep.csv").read_bytes()
    assert (two / "sweep.png").read_bytes() == (one / "sweep.png").read_bytes()
    with (two / "sweep.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 12
    a, b = json.loads(out), json.loads(out0)  # stdout is the JSON object alone
    assert (a["processes"], b["processes"]) == (1, 2)
    assert {k: v for k, v in a.items() if k not in PER_RUN_KEYS} == {
        k: v for k, v in b.items() if k not in PER_RUN_KEYS
    }
    assert out1 == "" and sorted(p.name for p in two_1.iterdir()) == ["stderr.1", "stdout.1"]
    print(f"one process {t_one:.1f} s, two processes {t_two:.1f} s (wall, with start-up)")


@pytest.mark.slow  # compile-bound, as the test above; CI runs it
def test_two_processes_write_one_store(sweep_args, tmp_path):
    """Two jax.distributed processes with --store: each writes its own chunks (one scale
    of one structure each) into one store, which is one process's store: every file but
    the attributes' command line byte for byte, and xarray's assert_identical."""
    xr = pytest.importorskip("xarray")
    one, two, two_1 = tmp_path / "one", tmp_path / "two", tmp_path / "two_1"
    one.mkdir(), two.mkdir(), two_1.mkdir()
    base = sweep_args[:-5] + ["--chunk-runs", "2", "--json", "--store"]
    [(rc, out, err)] = _launch([base + [str(one / "s.zarr")]], [one])
    assert rc == 0, err
    port = _free_port()
    results = _launch([base + [str(two / "s.zarr")] + _flags(port, 2, i) for i in range(2)],
                      [two, two_1])
    assert [r[0] for r in results] == [0, 0], _dump(results)
    a, b = json.loads(out), json.loads(results[0][1])
    assert a["status_counts"] == b["status_counts"] and b["processes"] == 2
    files = [{str(f.relative_to(d / "s.zarr")): f.read_bytes()
              for f in sorted((d / "s.zarr").rglob("*")) if f.is_file()} for d in (one, two)]
    assert files[0].keys() == files[1].keys() and len(files[0]) > 20
    assert [k for k in files[0] if files[0][k] != files[1][k]] == ["zarr.json"]
    da, db = (xr.open_zarr(d / "s.zarr", consolidated=False).load() for d in (one, two))
    assert "--process-id" in db.attrs["command"]
    da.attrs["command"] = db.attrs["command"]
    xr.testing.assert_identical(da, db)
    assert not (two_1 / "s.zarr").exists()


def _free_slurm_port():
    """A SLURM job id whose port (JAX: job id % 4096 + 61440) is free here, and the port."""
    for job in range(1000, 1000 + 4096):
        port = job % 4096 + 61440
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            try:
                s.bind(("", port))
            except OSError:
                continue
        return job, port
    pytest.skip("no free port in 61440-65535")


@pytest.mark.slow
def test_distributed_reads_slurm(tmp_path):
    """`--distributed` under SLURM (its variables set by hand, as `srun` sets them for 2
    tasks on this host): JAX's auto-detection finds the coordinator and each process's
    index, and process 0 writes the sweep."""
    rec = write_at2(tmp_path / "rec.AT2", synthetic(seed=9, duration=1.0))
    job, _ = _free_slurm_port()
    base = {k: v for k, v in os.environ.items() if not k.startswith("SLURM_")}
    envs = [{**base, "SLURM_JOB_ID": str(job), "SLURM_STEP_NODELIST": "127.0.0.1",
             "SLURM_NTASKS": "2", "SLURM_PROCID": str(i), "SLURM_LOCALID": str(i)}
            for i in range(2)]
    argv = ["sweep", "--record", str(rec), "--scales", "0.5,1", "--tail", "0.5", "--json",
            "--distributed", "--coordinator-timeout", "120"]
    results = _launch_envs([argv, argv], [tmp_path, tmp_path], envs)
    assert [r[0] for r in results] == [0, 0], _dump(results)
    assert json.loads(results[0][1])["processes"] == 2 and results[1][1] == ""
    with (tmp_path / "sweep.csv").open() as f:
        assert [r["scale"] for r in csv.DictReader(f)] == ["0.5", "1.0"]


@pytest.mark.parametrize("other, match0, match1", [
    pytest.param(["--scales", "0.5"], "the processes read different inputs",
                 "the processes read different inputs", marks=pytest.mark.slow),
    (["--scales", "0.5,1", "--record", "missing.AT2"], r"process 1 of 2 failed; see its error",
     r"--record: .*missing\.AT2"),
])
def test_processes_that_disagree(tmp_path, other, match0, match1):
    """Process 1 reads other scales, or fails to read a record: both processes stop
    before any run with a one-line error (process 0 naming process 1), nothing written."""
    rec = write_at2(tmp_path / "rec.AT2", synthetic(seed=9, duration=1.0))
    port = _free_port()
    argv = ["sweep", "--record", str(rec), "--scales", "0.5,1"]
    results = _launch([argv + _flags(port, 2, 0), ["sweep", "--record", str(rec), *other,
                                                   *_flags(port, 2, 1)]],
                      [tmp_path, tmp_path], timeout=120)
    for (rc, out, err), match in zip(results, (match0, match1)):
        lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("[Gloo]")]
        assert rc == 2 and out == "" and len(lines) == 1, _dump(results)
        assert re.search(match, lines[0]), _dump(results)
    assert not (tmp_path / "sweep.csv").exists()


@pytest.mark.slow
def test_a_process_that_dies(sweep_args, tmp_path):
    """Process 1 killed once connected (its first gather done): process 0 ends at its
    gather with one error line and exit 2, well before JAX's 100-s heartbeat timeout, and
    writes nothing."""
    port = _free_port()
    t0 = time.perf_counter()
    (rc, out, err), _ = _launch([sweep_args + _flags(port, 2, i) for i in range(2)],
                                [tmp_path, tmp_path], kill=(1, "[Gloo] Rank 1"))
    assert time.perf_counter() - t0 < 80
    assert rc == 2 and out == "" and not (tmp_path / "sweep.csv").exists()
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("[Gloo]")]
    assert len(lines) == 1 and "Traceback" not in err, err
    assert re.search(r"error: process 0 of 2: gathering from the other processes failed "
                     r"\(.*\); another process has ended", lines[0]), err


def _main(argv):
    """main() in-process, argparse's exit turned into the exit code: (code, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(argv)
        except SystemExit as e:
            rc = e.code
    assert out.getvalue() == ""
    return rc, err.getvalue()


def _one_line(rc, stderr, match):
    assert rc == 2 and "Traceback" not in stderr, stderr
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and re.search(match, lines[0]), stderr


BAD_FLAGS = [
    (["--coordinator", "127.0.0.1:1234"], r"--num-processes, --process-id missing"),
    (["--num-processes", "2", "--process-id", "0"], r"--coordinator missing"),
    (["--coordinator", "h:1", "--num-processes", "2", "--process-id", "2"],
     r"--process-id 2 is out of range for --num-processes 2 \(0 to 1\)"),
    (["--coordinator", "h:1", "--num-processes", "0", "--process-id", "0"],
     r"--num-processes must be a positive integer, got 0"),
    (["--coordinator", "h:1", "--num-processes", "2", "--process-id", "-1"],
     r"--process-id must be 0 or more"),
    (["--coordinator", "nohostport", "--num-processes", "2", "--process-id", "1"],
     r"--coordinator must be HOST:PORT"),
    (["--coordinator", "h:99999", "--num-processes", "2", "--process-id", "1"],
     r"--coordinator must be HOST:PORT with a port 1-65535"),
    (["--coordinator-timeout", "5"], r"--coordinator-timeout applies with --distributed"),
    (["--distributed", "--coordinator-timeout", "0"], r"--coordinator-timeout must be a "
                                                      "positive number"),
]


@pytest.mark.parametrize("flags, match", BAD_FLAGS)
def test_distributed_flag_errors(flags, match, tmp_path, monkeypatch):
    """Flags given partly or out of range: one line naming the flag, nothing connects,
    nothing is written."""
    monkeypatch.chdir(tmp_path)
    rec = write_at2(tmp_path / "rec.AT2", synthetic(seed=9, duration=1.0))
    rc, err = _main(["sweep", "--record", str(rec), *flags])
    _one_line(rc, err, match)
    assert not (tmp_path / "sweep.csv").exists()


def test_coordinator_that_never_answers(tmp_path):
    """Process 1 of 2 with nobody at --coordinator: a one-line error naming it after
    --coordinator-timeout (not JAX's abort with a stack trace), exit 2; the real entry
    point, since JAX must not have started."""
    rec = write_at2(tmp_path / "rec.AT2", synthetic(seed=9, duration=1.0))
    t0 = time.perf_counter()
    [(rc, out, err)] = _launch([["sweep", "--record", str(rec), *_flags(_free_port(), 2, 1, 1)]],
                               [tmp_path], timeout=120)
    assert time.perf_counter() - t0 < 60
    _one_line(rc, err, r"--coordinator 127\.0\.0\.1:\d+: no coordinator answered within 1 s")
    assert out == "" and not (tmp_path / "sweep.csv").exists()


def test_coordinator_port_taken(tmp_path, monkeypatch):
    """Process 0 cannot listen on the --coordinator port: a one-line error naming it."""
    monkeypatch.chdir(tmp_path)
    rec = write_at2(tmp_path / "rec.AT2", synthetic(seed=9, duration=1.0))
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("", 0))
        s.listen()
        port = s.getsockname()[1]
        rc, err = _main(["sweep", "--record", str(rec), *_flags(port, 2, 0, 1)])
    _one_line(rc, err, rf"--coordinator 127\.0\.0\.1:{port}: process 0 cannot listen on port")


def test_processes_start_checks_the_coordinator_first():
    """`rockjax.Processes.start`: a bad address, a port process 0 cannot listen on and a
    coordinator that never answers are `ParameterError`s naming `coordinator` (its value
    too), raised before JAX is asked to connect."""
    from rockjax._distributed import NoCoordinator

    with pytest.raises(rockjax.ParameterError, match="must be HOST:PORT") as e:
        rockjax.Processes.start("nohost", 2, 1, timeout=1)
    assert e.value.param == "coordinator"
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("", 0))
        s.listen()
        port = s.getsockname()[1]
        with pytest.raises(rockjax.ParameterError, match="process 0 cannot listen") as e:
            rockjax.Processes.start(f"127.0.0.1:{port}", 2, 0, timeout=1)
    assert e.value.param == "coordinator" and e.value.value == f"127.0.0.1:{port}"
    with pytest.raises(NoCoordinator, match="no coordinator answered within 0.5 s"):
        rockjax.Processes.start(f"127.0.0.1:{_free_port()}", 2, 1, timeout=0.5)
    assert not rockjax.Processes().active and rockjax.Processes().stop() is None


def test_jax_already_started(tmp_path, monkeypatch):
    """In a process where JAX has run (this one), --coordinator is refused in one line
    rather than JAX's RuntimeError."""
    jax.devices()  # JAX has started here, whatever ran before
    monkeypatch.chdir(tmp_path)
    rec = write_at2(tmp_path / "rec.AT2", synthetic(seed=9, duration=1.0))
    rc, err = _main(["sweep", "--record", str(rec), *_flags(_free_port(), 1, 0, 1)])
    _one_line(rc, err, r"JAX has already started in this process")


def test_distributed_without_a_cluster(tmp_path):
    """--distributed outside a cluster (no SLURM, Open MPI, ... variables): a one-line
    error naming --distributed and the explicit flags; nothing connects."""
    rec = write_at2(tmp_path / "rec.AT2", synthetic(seed=9, duration=1.0))
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("SLURM_", "OMPI_", "PMI_", "JAX_COORDINATOR", "KUBERNETES_"))}
    [(rc, out, err)] = _launch([["sweep", "--record", str(rec), "--distributed"]], [tmp_path],
                               env=env, timeout=120)
    _one_line(rc, err, r"--distributed: JAX found no cluster in the environment .*give "
                       r"--coordinator, --num-processes and --process-id")
    assert out == ""


def test_help_describes_the_flags():
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        main(["sweep", "--help"])
    text = " ".join(out.getvalue().split())
    for flag in ("--distributed", "--coordinator HOST:PORT", "--num-processes N",
                 "--process-id I", "--coordinator-timeout S", "jax.distributed"):
        assert flag in text
