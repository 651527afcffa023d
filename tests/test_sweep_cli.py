"""`rockjax sweep`: structure x scales x records -> CSV, JSON summary, plot; one-line errors.

The records are synthetic (`rockjax.datasets.synthetic_ground_motion`, written by the
writers of tests/test_records.py), of different time steps and units, so the file runs
without the shared records. The successful sweeps run in-process (one compilation, shared
with the direct `rockjax.simulate_batch` call they are checked against); the errors and
--help run the real entry point in a subprocess, as a user would.
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
from test_records import synthetic, write_at2, write_one_column, write_two_column

import rockjax
from rockjax._sweep import report_sweeps
from rockjax.cli import main
from rockjax.cli._common import parameter_message, scale_list as _scales, split_record_units
from rockjax.cli.sweep import FLAGS

SCALES = [0.5, 1.0, 2.5]
T1 = 6.0  # the cap: the 10-s record stops here, the 2-s one at its end + TAIL
TAIL = 1.0
COLUMNS = [
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
]


def _write_two_column(path, dt=0.02, duration=2.0, amp_g=0.05):
    """A small sine record (t a, in g, no header) that rocks nothing over at 2.5x."""
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
def sweep(tmp_path_factory):
    """One sweep over a synthetic AT2 record (0.01 s, 10 s, units g in its header) and a
    headerless sine (0.02 s, 2 s, `:g` on the command line) x 3 scales, --json, --plot."""
    d = tmp_path_factory.mktemp("sweep")
    at2 = write_at2(d / "quake.AT2", synthetic(seed=1, dt=0.01, duration=10.0, pga=3.07))
    sine = _write_two_column(d / "sine.txt")
    base = ["sweep", "--scales", ",".join(map(str, SCALES)), "--t1", str(T1), "--tail",
            str(TAIL), "--record", str(at2), "--record", f"{sine}:g"]
    csv_path, png = d / "out.csv", d / "out.png"
    rc, out, err = _main(base + ["--out", str(csv_path), "--plot", str(png), "--json"])
    assert rc == 0, err
    with open(csv_path, newline="") as f:
        rows = list(csv.reader(f))
    return {"dir": d, "records": [at2, sine], "base": base, "csv": csv_path, "png": png,
            "rows": rows, "json": out, "stderr": err}


def _direct(records):
    """The same runs through rockjax.simulate_batch (scale-major order)."""
    recs = [rockjax.read_record(records[0]), rockjax.read_record(records[1], units="g")]
    scale = np.repeat(SCALES, len(recs))
    record = np.tile(np.arange(len(recs)), len(SCALES))
    out = rockjax.simulate_batch(rockjax.mcmanus_column(), recs, T1, tail=TAIL, scale=scale,
                                 record=record, substeps=4, summary_only=True)
    return scale, record, out.to_dict()


def test_sweep_csv_matches_simulate_batch(sweep):
    """Records of 0.01 and 0.02 s in one sweep (refused before), each run to its own end
    (the sine to 2 s + tail, not padded to the cap), every row saying what produced it."""
    rows = sweep["rows"]
    assert rows[0] == COLUMNS
    body = [dict(zip(COLUMNS, row)) for row in rows[1:]]
    assert len(body) == 6
    scale, record, ref = _direct(sweep["records"])
    labels = ["quake", "sine"]
    for k, got in enumerate(body):
        assert got["structure"] == "table1"
        assert got["record"] == labels[record[k]]
        assert float(got["scale"]) == scale[k]
        assert float(got["peak_u_m"]) == ref["peak_u"][k]
        assert float(got["peak_uplift_m"]) == ref["peak_uplift"][k]
        assert int(got["n_impacts"]) == ref["n_impacts"][k]
        assert got["status"] == ref["status"][k]
        assert float(got["t_end_s"]) == ref["t_end"][k] == [T1, 2.0 + TAIL][record[k]]
        if got["status"] == "overturned":
            assert float(got["t_overturn_s"]) == ref["t_overturn"][k]
        else:
            assert got["t_overturn_s"] == "" and math.isinf(ref["t_overturn"][k])
        assert got["record_file"] == str(sweep["records"][record[k]])
        assert (got["record_units"], got["record_units_from"]) == [
            ("g", "file header"), ("g", "given")][record[k]]
        assert float(got["record_dt_s"]) == pytest.approx([0.01, 0.02][record[k]])
        assert int(got["record_npts"]) == [1001, 101][record[k]]
        assert float(got["record_duration_s"]) == pytest.approx([10.0, 2.0][record[k]])
        assert (got["model"], got["impact"], got["r"], got["method"]) == (
            "simplified", "paper", "Eq 3", "rk4")
    assert float(body[0]["record_pga_g"]) == pytest.approx(3.07 / rockjax.G_STANDARD, 1e-8)
    over = [r for r in body if r["status"] == "overturned"]
    assert [(r["record"], float(r["scale"])) for r in over] == [("quake", 2.5)]
    assert 0.0 < float(over[0]["t_overturn_s"]) < T1


def test_sweep_json_and_plot(sweep):
    out = json.loads(sweep["json"])  # one JSON object, nothing else on stdout
    assert out["n_runs"] == 6 and (out["n_records"], out["n_scales"]) == (2, 3)
    counts = out["status_counts"]
    assert sum(counts.values()) == out["n_runs"]
    assert counts["overturned"] == 1 and counts["completed"] == 5
    assert out["scales"] == SCALES and out["csv"] == str(sweep["csv"])
    assert out["fraction_overturned"] == {"table1": [0.0, 0.0, 0.5]}
    assert out["wall_time_s"] > 0
    assert (out["tail_s"], out["t1"], out["grid_dt_s"]) == (TAIL, T1, 0.01)
    assert out["model_info"] == {"model": "simplified", "impact": "paper", "r": "Eq 3"}
    quake, sine = out["record_info"]
    assert quake["label"] == "quake" and quake["units_in_file"] == "g"
    assert quake["units_from"] == "file header" and quake["t_end_s"] == T1
    assert (sine["units_from"], sine["dt_s"], sine["n_points"]) == ("given", 0.02, 101)
    assert sine["t_end_s"] == pytest.approx(2.0 + TAIL)
    assert "rk4 batch" not in sweep["stderr"]  # no progress bar with --json
    assert sweep["png"].stat().st_size > 10_000


def test_sweep_text_summary_default_out(sweep, monkeypatch):
    monkeypatch.chdir(sweep["dir"])
    rc, out, err = _main(sweep["base"])  # same shapes: no new compilation
    assert rc == 0, err
    assert "6 runs" in out and "overturned    1 of 6" in out and "runs/s" in out
    assert "record        quake: units g (file header), dt 0.01 s, 1001 points" in out
    assert "record        sine: units g (given), dt 0.02 s, 101 points, 2 s" in out
    assert "run to 3 s" in out and "run to 6 s" in out
    assert "grid          0.01 s (record steps 0.01, 0.02 s, resampled exactly)" in out
    assert "model         simplified model, impact rule paper, r Eq 3, rk4" in out
    assert "\r" not in err  # no progress bar when stderr is not a terminal
    assert (sweep["dir"] / "sweep.csv").read_text() == sweep["csv"].read_text()


def _records_of(argv, tmp_path):
    """The record_info of a --json sweep of `argv` (one scale, t1 0.2 s: fast)."""
    rc, out, err = _main(["sweep", *argv, "--t1", "0.2", "--out", str(tmp_path / "o.csv"),
                          "--json"])
    assert rc == 0, err
    info = json.loads(out)
    return info["record_info"], info


def test_units_per_record(tmp_path):
    """FILE:UNITS, a --units after its --record, and one --units before every record;
    units that a file states come from the file (before, one --units applied to all)."""
    rec = synthetic(seed=5, dt=0.01, duration=1.0)
    at2 = write_at2(tmp_path / "g.AT2", rec)
    si = write_two_column(tmp_path / "si.dat", rec, header="", in_g=False)
    g2 = write_two_column(tmp_path / "g2.dat", rec, header="", in_g=True)
    infos, _ = _records_of(["--record", str(at2), "--record", f"{si}:m/s2", "--record",
                            str(g2), "--units", "g"], tmp_path)
    assert [(i["units_in_file"], i["units_from"]) for i in infos] == [
        ("g", "file header"), ("m/s2", "given"), ("g", "given")]
    pgas = [i["pga_m_s2"] for i in infos]
    np.testing.assert_allclose(pgas, rec.pga, rtol=1e-8)  # the same motion, three files
    infos, _ = _records_of(["--units", "m/s2", "--record", str(si), "--record", f"{g2}:g"],
                           tmp_path)
    assert [i["units_in_file"] for i in infos] == ["m/s2", "g"]


def test_record_folder(tmp_path):
    """--record DIR takes every record file in it, sorted, says which and what it skipped;
    a file of the folder named itself takes the units given there."""
    d = tmp_path / "records"
    d.mkdir()
    write_at2(d / "b.AT2", synthetic(seed=6, dt=0.02, duration=1.0))
    write_two_column(d / "a.dat", synthetic(seed=7, dt=0.005, duration=0.5),
                     header="Time[s] Accel[m/s2]", in_g=False)
    write_one_column(d / "c.txt", synthetic(seed=8, dt=0.01, duration=0.5), in_g=False)
    (d / "NOTES.md").write_text("not a record\n")
    (d / ".hidden.dat").write_text("0 0\n")
    argv = ["--record", str(d), "--record", f"{d / 'c.txt'}:m/s2", "--record-dt", "0.01"]
    infos, out = _records_of(argv, tmp_path)
    assert [i["label"] for i in infos] == ["a", "b", "c"]
    assert [i["units_from"] for i in infos] == ["file header", "file header", "given"]
    assert out["skipped_files"] == {str(d): ["NOTES.md"]} and out["grid_dt_s"] == 0.005
    rc, text, err = _main(["sweep", *argv, "--t1", "0.2", "--out", str(tmp_path / "o.csv")])
    assert rc == 0, err
    taken = f"folder        {d}: 3 record file(s) taken; skipped (not record files): NOTES.md"
    assert taken in text
    # without units for c.txt, the folder is refused naming the file, in CLI syntax
    rc, _, err = _main_exit(["sweep", "--record", str(d), "--record-dt", "0.01"])
    line = _one_line(rc, err, "c.txt: the units of the acceleration are not stated")
    assert "pass --units g or --units m/s2" in line and "units=" not in line


def test_record_errors_in_cli_terms_and_record_units_suffix(tmp_path):
    """read_record's errors name their parameter; the CLI names its option for it, with
    the advice in its own syntax (no rewriting of the message)."""
    def error(name, text, **kw):
        path = tmp_path / name
        path.write_text(text)
        with pytest.raises(rockjax.ParameterError) as e:
            rockjax.read_record(path, **kw)
        return e.value

    e = error("x.dat", "0 0.1\n0.01 0.2\n")
    assert str(e) == (f"{tmp_path / 'x.dat'}: the units of the acceleration are not stated "
                      "in the file; pass units='g' or units='m/s2'")
    assert parameter_message(e, FLAGS) == (
        f"--units: {tmp_path / 'x.dat'}: the units of the acceleration are not stated in the "
        "file; pass --units g or --units m/s2")
    e = error("one.txt", "0.1\n0.2\n", units="g")
    assert str(e).endswith("no time information; pass dt=<time step in s>")
    assert parameter_message(e, FLAGS).endswith("; pass --record-dt <time step in s>")
    e = error("c.dat", "0 0.1\n0.01 0.2\n", units="g", dt=0.02)
    assert str(e).endswith("has a time step of 0.01 s; omit dt=")
    assert parameter_message(e, FLAGS).startswith("--record-dt: ")
    assert parameter_message(e, FLAGS).endswith("; omit --record-dt")
    e = error("m.dat", "0 1 2\n", units="g")  # no option for format=: the message alone
    assert "pass format='at2'" in str(e)
    assert parameter_message(e, FLAGS) == e.message and "format=" not in e.message
    assert split_record_units("a.dat:g") == ("a.dat", "g")
    assert split_record_units("C:/data/a.dat:M/S^2") == ("C:/data/a.dat", "m/s2")
    assert split_record_units("a.dat") == ("a.dat", None)
    assert split_record_units("dir:x/a.dat") == ("dir:x/a.dat", None)
    odd = tmp_path / "odd:g"
    odd.write_text("")
    assert split_record_units(str(odd)) == (str(odd), None)  # an existing file keeps its name


def test_scales_parsing():
    assert _scales("0.5,1,1.5") == [0.5, 1.0, 1.5]
    assert _scales("0.5:1.5:3") == [0.5, 1.0, 1.5]
    assert _scales("2:1:2") == [2.0, 1.0]
    assert _scales("0.7:0.7:1") == [0.7]
    assert _scales("1.25") == [1.25]
    # ranges print as typed: 0.8, not linspace's 0.7999999999999999
    assert _scales("0.1:2.0:20")[7] == 0.8 and str(_scales("0.1:2.0:20")[7]) == "0.8"


def test_sweep_help():
    r = run_cli("sweep", "--help")
    assert r.returncode == 0 and "--scales" in r.stdout and "START:STOP:N" in r.stdout
    assert "--tail" in r.stdout and "FILE[:UNITS]|DIR" in r.stdout


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
    (["--record", "rec.AT2", "--record", "odd.txt"],
     "--record: the records' time steps (rec.AT2 dt = 0.01 s, odd.txt dt = 0.0073 s) have no "
     "common step coarser than"),
    (["--record", "missing.at2"], "--record"),
    (["--record", "rec.AT2:m/s2"], "--units: rec.AT2: the file states units g ('UNITS OF G' "
                                   "in its header) but m/s2 was given; omit --units"),
    (["--record", "sine.txt"], "sine.txt: the units of the acceleration are not stated in "
                               "the file; pass --units g or --units m/s2"),
    (["--record", "sine.txt", "--units", "g", "--units", "g"],
     "--units g: the --record before it, sine.txt, already has units g"),
    (["--record", "emptydir"], "--record emptydir: no record files in this folder"),
    (["--record", "rec.AT2", "--record", "./rec.AT2"], "--record ./rec.AT2: given twice"),
    (["--tail", "-1"], "--tail"),
    (["--tail", "1e300"], "--tail 1e+300 s makes runs of 1e+302 steps of the records' common"),
    (["--substeps", "0"], "--substeps"),
    (["--r", "1.5"], "--r"),
    (["--plot", "x.txt"], "--plot"),
    (["--out", "nodir/x.csv"], "--out"),
    (["--structure", "missing.toml"], "--structure"),
]


def _bad_inputs(tmp_path):
    """rec.AT2 (0.01 s, g), sine.txt (no header), odd.txt (0.0073 s, g), an empty folder."""
    write_at2(tmp_path / "rec.AT2", synthetic(seed=9, duration=1.0))
    _write_two_column(tmp_path / "sine.txt")
    _write_two_column(tmp_path / "odd.txt", dt=0.0073)
    with open(tmp_path / "odd.txt") as f:
        text = f.read()
    (tmp_path / "odd.txt").write_text("Accel[g]\n" + text)
    (tmp_path / "emptydir").mkdir()


def _with_record(args):
    """`args`, after a `--record rec.AT2` when they name no record."""
    return args if "--record" in args else ["--record", "rec.AT2", *args]


@pytest.mark.parametrize("args, match", BAD)
def test_sweep_errors_one_line(tmp_path, monkeypatch, args, match):
    """In-process (fast): exit 2 and one line naming the parameter, before any run."""
    monkeypatch.chdir(tmp_path)
    _bad_inputs(tmp_path)
    rc, out, err = _main_exit(["sweep", *_with_record(args)])
    _one_line(rc, err, match)
    assert out == "" and "rk4 batch" not in err
    assert not (tmp_path / "sweep.csv").exists()


@pytest.mark.parametrize("args, match", [BAD[0], BAD[7]])
def test_sweep_errors_no_traceback_subprocess(tmp_path, args, match):
    """The real entry point: an argparse error and a record error."""
    _bad_inputs(tmp_path)
    r = run_cli("sweep", *_with_record(args), cwd=tmp_path)
    _one_line(r.returncode, r.stderr, match)


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes); CI runs it
def test_sweep_runs_the_2dof_body(tmp_path):
    """`--model two_spring_2dof`: the 2-DOF body is batched like the SDOF models, and the
    CSV rows equal rockjax.simulate_batch's summaries."""
    rec = _write_two_column(tmp_path / "sine.txt", dt=0.01, amp_g=0.3, duration=2.0)
    out = tmp_path / "sweep.csv"
    rc, stdout, _ = _main(["sweep", "--record", str(rec), "--units", "g", "--scales", "0.5,1.0",
                           "--model", "two_spring_2dof", "--tail", "0.5", "--out", str(out),
                           "--json"])
    assert rc == 0 and json.loads(stdout)["model"] == "two_spring_2dof"
    with out.open() as f:
        rows = list(csv.DictReader(f))
    r = rockjax.read_record(rec, units="g")
    ref = rockjax.simulate_batch(rockjax.mcmanus_column(), [r], tail=0.5,
                                 scale=np.array([0.5, 1.0]), model="two_spring_2dof",
                                 summary_only=True, progress=False)
    np.testing.assert_allclose([float(x["peak_u_m"]) for x in rows], ref.peak_u, rtol=1e-9)
    assert [int(x["n_impacts"]) for x in rows] == list(ref.n_impacts)
    assert [x["model"] for x in rows] == ["two_spring_2dof"] * 2
    assert max(ref.peak_u) > 0


def test_fraction_overturned_leaves_failed_runs_out(sweep, monkeypatch, tmp_path):
    """Runs that fail (here max_impacts, from a bound of 14 impacts put on every batch) are
    left out of the fraction overturned and reported apart (JSON, text, plot); before, they
    counted as survivors."""
    import functools

    monkeypatch.setattr(rockjax._sweep, "simulate_batch",  # the engine behind every sweep
                        functools.partial(rockjax.simulate_batch, max_impacts=14))
    csv_path, png = tmp_path / "out.csv", tmp_path / "out.png"
    rc, out, err = _main(sweep["base"] + ["--out", str(csv_path), "--plot", str(png), "--json"])
    assert rc == 0, err
    info = json.loads(out)
    with open(csv_path, newline="") as f:
        rows = list(csv.DictReader(f))
    status = np.array([r["status"] for r in rows]).reshape(len(SCALES), 2)
    over = (status == "overturned").sum(1)
    usable = np.isin(status, ["completed", "overturned"]).sum(1)
    failed = (~np.isin(status, ["completed", "overturned"])).sum(1)
    assert info["status_counts"]["max_impacts"] == failed.sum() > 0
    want = [None if u == 0 else float(o / u) for o, u in zip(over, usable)]
    assert info["fraction_overturned"] == {"table1": want}
    assert info["failed_by_scale"] == {"table1": failed.tolist()}
    # the old rule (failed runs as survivors, over every record) differs here
    assert any(w is not None and w != o / 2 for w, o in zip(want, over))
    assert png.stat().st_size > 10_000
    monkeypatch.chdir(tmp_path)
    rc, text, err = _main(sweep["base"])
    assert rc == 0, err
    n_used = int(usable.sum())
    assert (f"overturned    {over.sum()} of the {n_used} runs that completed or overturned"
            in text)
    assert f"{failed.sum()} failed runs left out (max_impacts {failed.sum()})" in text
    assert "failed runs by scale (max_impacts, solver_failure; left out of the fractions)" in text
    assert "fraction overturned by scale (of the runs that completed or overturned)" in text


def test_fractions_unit():
    """`SweepResult.fraction_overturned` (the CLI's fractions): over completed + overturned;
    None where all failed. Records x scales, as every sweep."""
    status = np.array([[0, 1, 2], [2, 0, 3], [0, 3, 2]])  # (n_records, n_scales)
    z = np.zeros(status.shape)
    res = rockjax.SweepResult(structure=rockjax.mcmanus_column(), records=[None] * 3,
                              labels=["a", "b", "c"], scales=[1.0, 2.0, 3.0], peak_u=z,
                              peak_uplift=z, n_impacts=z, status=status, t_overturn=z, t_end=z)
    assert res.to_dict()["fraction_overturned"] == [0.0, 0.5, None]
    assert res.failed_by_scale().tolist() == [1, 1, 3]


def test_sweep_report_unit():
    """`SweepResult.report` (the text of `rockjax sweep`): the records, their grid and the
    model, the counts, the fractions of the runs that completed or overturned (``-`` where
    every run failed) and the failed runs by scale; no simulation."""
    status = np.array([[0, 1, 2], [2, 0, 3], [0, 3, 2]])  # (n_records, n_scales)
    z = np.zeros(status.shape)
    recs = [rockjax.Record(dt=dt, accel=np.linspace(0, 1.0, n), source=f"/x/{lab}.AT2",
                           units_in_file="g", units_source="file header")
            for dt, n, lab in ((0.01, 101, "a"), (0.02, 51, "b"), (0.005, 11, "c"))]
    res = rockjax.SweepResult(structure=rockjax.mcmanus_column(), records=recs,
                              labels=["a", "b", "c"], scales=[1.0, 2.0, 3.0], peak_u=z,
                              peak_uplift=z, n_impacts=z, status=status, t_overturn=z, t_end=z,
                              model="rigid_body", tail=2.0, t1=2.5, wall_time=2.0,
                              options={"method": "rk4", "substeps": 4, "r": 0.9})
    assert res.grid_dt == 0.005
    info = res.record_info()
    assert [i["t_end_s"] for i in info] == pytest.approx([2.5, 2.5, 2.05])
    assert info[0]["pga_g"] == pytest.approx(1.0 / rockjax.G_STANDARD)
    lines = res.report(label="col").splitlines()
    assert lines[0] == ("record        a: units g (file header), dt 0.01 s, 101 points, 1 s, "
                        "PGA 0.102 g, run to 2.5 s")
    assert lines[3] == ("grid          0.005 s (record steps 0.005, 0.01, 0.02 s, resampled "
                        "exactly); each run to its record's end + tail 2 s, at most t1 = 2.5 s")
    assert lines[4] == ("model         rigid_body model, impacts at landings (Eqs 2-3), r 0.9, "
                        "rk4 (4 substeps)")
    assert lines[5:8] == [
        "sweep         9 runs: 1 structure(s) x 3 record(s) x 3 scale(s)",
        "time          2 s (4.5 runs/s, compilation included)",
        "status        completed 3, overturned 1, max_impacts 3, solver_failure 2"]
    assert lines[8] == ("overturned    1 of the 4 runs that completed or overturned (25.0%); 5 "
                        "failed runs left out (max_impacts 3, solver_failure 2)")
    assert lines[10:14] == ["     scale     col", "         1   0.000", "         2   0.500",
                            "         3       -"]
    assert lines[15:] == ["     scale     col", "         1       1", "         2       1",
                          "         3       3"]
    assert "2 processes" in report_sweeps([res, res], ["p", "q"], wall_time=1.0, processes=2)
