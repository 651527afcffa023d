"""`rockjax sweep`: structure x scales x records -> CSV, JSON summary, plot; one-line errors.

The successful sweeps run in-process (one compilation, shared with the direct
`rockjax.simulate_batch` call they are checked against); the errors and --help run the real
entry point in a subprocess, as a user would.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math

import numpy as np
import pytest
from conftest import run_cli

import rockjax
from rockjax.cli import main
from rockjax.cli._common import _scales

SCALES = [0.5, 1.0, 2.5]
T1 = 6.0
COLUMNS = [
    "structure",
    "record",
    "scale",
    "peak_u_m",
    "peak_uplift_m",
    "n_impacts",
    "status",
    "t_overturn_s",
]


def _write_two_column(path, dt=0.01, duration=3.0, amp_g=0.05):
    """A small sine record (t a, in g) that rocks nothing over: no overturning at 2.5x."""
    t = np.arange(int(round(duration / dt)) + 1) * dt
    np.savetxt(path, np.column_stack([t, amp_g * np.sin(2 * np.pi * 2.0 * t)]), fmt="%.4f %.8g")
    return path


def _main(argv):
    """main() in-process: (exit code, stdout, stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(argv)
    return rc, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def sweep(tmp_path_factory, ground_motions_dir):
    """One sweep over El Centro + a synthetic record x 3 scales, with --json and --plot."""
    d = tmp_path_factory.mktemp("sweep")
    records = [ground_motions_dir / "IELC180.AT2", _write_two_column(d / "sine.txt")]
    base = ["sweep", "--units", "g", "--scales", ",".join(map(str, SCALES)), "--t1", str(T1)]
    for rec in records:
        base += ["--record", str(rec)]
    csv_path, png = d / "out.csv", d / "out.png"
    rc, out, err = _main(base + ["--out", str(csv_path), "--plot", str(png), "--json"])
    assert rc == 0, err
    with open(csv_path, newline="") as f:
        rows = list(csv.reader(f))
    return {
        "dir": d,
        "records": records,
        "base": base,
        "csv": csv_path,
        "png": png,
        "rows": rows,
        "json": out,
        "stderr": err,
    }


def _direct(records):
    """The same runs through rockjax.simulate_batch (records padded, scale-major order)."""
    recs = [rockjax.read_record(p, units="g") for p in records]
    n = max(r.accel.size for r in recs)
    accel = np.zeros((len(recs), n))
    for i, r in enumerate(recs):
        accel[i, : r.accel.size] = r.accel
    gm = rockjax.GroundMotion(dt=recs[0].dt, accel=accel)
    scale = np.repeat(SCALES, len(recs))
    record = np.tile(np.arange(len(recs)), len(SCALES))
    out = rockjax.simulate_batch(
        rockjax.mcmanus_column(), gm, T1, scale=scale, record=record, substeps=4, summary_only=True
    )
    return scale, record, out.to_dict()


def test_sweep_csv_matches_simulate_batch(sweep):
    rows = sweep["rows"]
    assert rows[0] == COLUMNS
    body = rows[1:]
    assert len(body) == 6
    scale, record, ref = _direct(sweep["records"])
    labels = ["IELC180", "sine"]
    for k, row in enumerate(body):
        got = dict(zip(COLUMNS, row))
        assert got["structure"] == "table1"
        assert got["record"] == labels[record[k]]
        assert float(got["scale"]) == scale[k]
        assert float(got["peak_u_m"]) == ref["peak_u"][k]
        assert float(got["peak_uplift_m"]) == ref["peak_uplift"][k]
        assert int(got["n_impacts"]) == ref["n_impacts"][k]
        assert got["status"] == ref["status"][k]
        if got["status"] == "overturned":
            assert float(got["t_overturn_s"]) == ref["t_overturn"][k]
        else:
            assert got["t_overturn_s"] == "" and math.isinf(ref["t_overturn"][k])
    over = [dict(zip(COLUMNS, r)) for r in body if r[6] == "overturned"]
    assert [(r["record"], float(r["scale"])) for r in over] == [("IELC180", 2.5)]
    assert 0.0 < float(over[0]["t_overturn_s"]) < T1
    assert float(over[0]["peak_u_m"]) > float(body[2][3])  # beyond the 1.0x El Centro peak


def test_sweep_json_and_plot(sweep):
    out = json.loads(sweep["json"])  # one JSON object, nothing else on stdout
    assert out["n_runs"] == 6 and (out["n_records"], out["n_scales"]) == (2, 3)
    counts = out["status_counts"]
    assert sum(counts.values()) == out["n_runs"]
    assert counts["overturned"] == 1 and counts["completed"] == 5
    assert out["scales"] == SCALES and out["csv"] == str(sweep["csv"])
    assert out["fraction_overturned"] == {"table1": [0.0, 0.0, 0.5]}
    assert out["wall_time_s"] > 0
    assert "rk4 batch" not in sweep["stderr"]  # no progress bar with --json
    assert sweep["png"].stat().st_size > 10_000


def test_sweep_text_summary_default_out(sweep, monkeypatch):
    monkeypatch.chdir(sweep["dir"])
    rc, out, err = _main(sweep["base"])  # same shapes: no new compilation
    assert rc == 0, err
    assert "6 runs" in out and "overturned    1 of 6" in out and "runs/s" in out
    assert "rk4 batch" in err  # the tqdm bar, on stderr
    assert (sweep["dir"] / "sweep.csv").read_text() == sweep["csv"].read_text()


def test_scales_parsing():
    assert _scales("0.5,1,1.5") == [0.5, 1.0, 1.5]
    assert _scales("0.5:1.5:3") == [0.5, 1.0, 1.5]
    assert _scales("2:1:2") == [2.0, 1.0]
    assert _scales("0.7:0.7:1") == [0.7]
    assert _scales("1.25") == [1.25]


def test_sweep_help():
    r = run_cli("sweep", "--help")
    assert r.returncode == 0 and "--scales" in r.stdout and "START:STOP:N" in r.stdout


def _main_exit(argv):
    """_main, with argparse's SystemExit turned into the exit code."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(argv)
        except SystemExit as e:
            rc = e.code
    return rc, out.getvalue(), err.getvalue()


def _one_line(rc, stderr, match):
    assert rc == 2
    assert "Traceback" not in stderr
    lines = [ln for ln in stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, stderr
    assert match in lines[0]
    return lines[0]


BAD = [
    (["--scales", "a:b"], "--scales"),
    (["--scales", "1:0.5:0"], "--scales"),
    (["--scales", "-1"], "--scales"),
    (["--scales", "nan"], "--scales"),
    (["--scales", "1,x"], "--scales"),
    (["--record", "slow.txt"], "--record"),
    (["--record", "missing.at2"], "--record"),
    (["--substeps", "0"], "--substeps"),
    (["--r", "1.5"], "--r"),
    (["--plot", "x.txt"], "--plot"),
    (["--out", "nodir/x.csv"], "--out"),
    (["--structure", "missing.toml"], "--structure"),
]


@pytest.mark.parametrize("args, match", BAD)
def test_sweep_errors_one_line(tmp_path, monkeypatch, ground_motions_dir, args, match):
    """In-process (fast): exit 2 and one line naming the parameter, before any run."""
    monkeypatch.chdir(tmp_path)
    _write_two_column(tmp_path / "slow.txt", dt=0.02)
    base = ["sweep", "--units", "g", "--record", str(ground_motions_dir / "IELC180.AT2")]
    rc, out, err = _main_exit(base + args)
    line = _one_line(rc, err, match)
    assert out == "" and "rk4 batch" not in err
    if args == ["--record", "slow.txt"]:
        assert "IELC180.AT2 dt = 0.01 s" in line and "slow.txt dt = 0.02 s" in line
    assert not (tmp_path / "sweep.csv").exists()


@pytest.mark.parametrize("args, match", [BAD[0], BAD[5]])
def test_sweep_errors_no_traceback_subprocess(tmp_path, ground_motions_dir, args, match):
    """The real entry point: an argparse error and a record error."""
    _write_two_column(tmp_path / "slow.txt", dt=0.02)
    base = ["sweep", "--units", "g", "--record", str(ground_motions_dir / "IELC180.AT2")]
    r = run_cli(*base, *args, cwd=tmp_path)
    _one_line(r.returncode, r.stderr, match)


def test_sweep_runs_the_2dof_body(tmp_path):
    """`--model two_spring_2dof`: the 2-DOF body is batched like the SDOF models, and the
    CSV rows equal rockjax.simulate_batch's summaries."""
    rec = _write_two_column(tmp_path / "sine.txt", amp_g=0.3, duration=2.0)
    out = tmp_path / "sweep.csv"
    rc, stdout, _ = _main(["sweep", "--record", str(rec), "--units", "g", "--scales", "0.5,1.0",
                           "--model", "two_spring_2dof", "--out", str(out), "--json"])
    assert rc == 0 and json.loads(stdout)["model"] == "two_spring_2dof"
    with out.open() as f:
        rows = list(csv.DictReader(f))
    r = rockjax.read_record(rec, units="g")
    gm = rockjax.GroundMotion(dt=r.dt, accel=r.accel)
    ref = rockjax.simulate_batch(rockjax.mcmanus_column(), gm, float(gm.duration),
                                 scale=np.array([0.5, 1.0]),
        model="two_spring_2dof", summary_only=True, progress=False)
    np.testing.assert_allclose([float(x["peak_u_m"]) for x in rows], ref.peak_u, rtol=1e-9)
    assert [int(x["n_impacts"]) for x in rows] == list(ref.n_impacts)
    assert max(ref.peak_u) > 0
