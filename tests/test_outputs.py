"""Outputs users expect (issue 13, item 6): batched `Response` accessors, the time of the
peak and the residual displacement, `--version`, no progress bar when stderr is not a
terminal, plots that stop at overturning, CSV headers with units, `simulate` on a `Record`,
and checks that come before the run."""

from __future__ import annotations

import json
from importlib.metadata import version

import numpy as np
import pytest
from conftest import run_cli

import rockjax
from rockjax import _plotting, datasets
from rockjax.cli import main

T1 = 6.0


@pytest.fixture(scope="session")
def motion():
    """A 6-s synthetic motion (the package's deterministic generator, seed 3)."""
    return datasets.synthetic_ground_motion(duration=T1, dt=0.01, pga=3.0, seed=3)


@pytest.fixture(scope="session")
def batch(column, motion):
    """Three members of one diffrax batch: weak, moderate, overturning."""
    gm = rockjax.GroundMotion.from_record(motion)
    return rockjax.simulate_batch(column, gm, T1, scale=np.array([0.3, 1.0, 4.0]),
                                  method="diffrax")


@pytest.fixture(scope="session")
def singles(column, motion):
    return [rockjax.simulate(column, rockjax.GroundMotion.from_record(motion, scale=k), T1)
            for k in (0.3, 1.0, 4.0)]


def test_batched_accessors_match_single_runs(batch, singles):
    assert batch.batch_shape == (3,)
    names = batch.status_name
    assert names.shape == (3,) and list(names) == [r.status_name for r in singles]
    assert names[2] == "overturned"  # the case exercises a failure status
    assert list(batch.message) == [r.message for r in singles]
    for got, want in zip(batch.impacts, singles):
        np.testing.assert_allclose(got, want.impacts, atol=1e-6)  # vmapped steps differ
    summaries = batch.summary()
    assert isinstance(summaries, list) and len(summaries) == 3
    for got, want in zip(summaries, (r.summary() for r in singles)):
        assert got["status"] == want["status"] and got["n_impacts"] == want["n_impacts"]
        assert got["peak_u"] == pytest.approx(want["peak_u"], rel=1e-6)
        assert got["t_peak"] == pytest.approx(want["t_peak"], abs=1e-6)
    json.dumps(summaries)  # plain Python all the way down
    assert batch.member(1).status_name == singles[1].status_name
    with pytest.raises(ValueError, match="not batched"):
        singles[0].member(0)


def test_t_peak_and_residual_against_a_dense_grid(column, motion, singles):
    """t_peak (Hermite-refined on the record's grid) against the same run on a 20x finer
    output grid; residual_u is u at the end."""
    res = singles[1]
    dense = rockjax.simulate(column, rockjax.GroundMotion.from_record(motion), T1,
                             ts=np.linspace(0.0, T1, 20 * 600 + 1))
    i = int(np.argmax(np.abs(np.asarray(dense.u))))
    sm = res.summary()
    assert sm["status"] == "completed" and sm["n_impacts"] > 5
    assert sm["t_peak"] == pytest.approx(float(dense.ts[i]), abs=5e-4)
    assert sm["t_peak"] != pytest.approx(float(res.ts[int(np.argmax(np.abs(res.u)))]), abs=1e-6)
    assert sm["residual_u"] == float(res.u[-1]) and sm["t_end"] == pytest.approx(T1)
    over = singles[2].summary()
    assert over["residual_u"] is None and over["t_peak"] == over["t_overturn"]


def test_simulate_takes_a_record(column, motion, singles):
    res = rockjax.simulate(column, motion, T1)
    assert float(res.peak_u) == float(singles[1].peak_u)


def test_version():
    p = run_cli("--version")
    assert p.returncode == 0
    assert p.stdout.strip().startswith(f"rockjax {rockjax.__version__} (jax {version('jax')}")


def test_no_progress_bar_when_stderr_is_not_a_terminal(column, motion, capfd):
    gm = rockjax.GroundMotion.from_record(motion)
    out = rockjax.simulate_batch(column, gm, 1.0, scale=np.linspace(0.5, 1.0, 8),
                                 chunk_size=2, summary_only=True)
    assert out.peak_u.shape == (8,)
    err = capfd.readouterr().err
    assert "\r" not in err and "batch" not in err


def test_plot_stops_at_overturning(column, singles):
    res = singles[2]
    t_ot = float(res.t_overturn)
    assert 0.0 < t_ot < T1
    fig = _plotting.plot_response(column, res)
    ax_u = fig.axes[0]
    data = [ln for ln in ax_u.get_lines() if ln.get_label() == "_child0" or
            len(ln.get_xdata()) > 10]
    assert data and all(np.max(ln.get_xdata()) <= t_ot for ln in data)
    assert any(f"overturned at {t_ot:.3g} s" == ln.get_label() for ln in ax_u.get_lines())


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_simulate_cli_states_what_it_read(tmp_path, capsys, motion):
    path = tmp_path / "m.txt"
    np.savetxt(path, np.column_stack([motion.time, motion.accel / rockjax.G_STANDARD]),
               header="time [s], accel [g]")
    csv = tmp_path / "out.csv"
    assert main(["simulate", "--record", str(path), "--scale", "0.5", "--t1", "2",
                 "--impact", "after_uplift", "--out", str(csv), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    exc = out["excitation"]
    assert out["model"] == "simplified" and out["impact"] == "after_uplift"
    assert exc["units_in_file"] == "g" and exc["dt_s"] == pytest.approx(0.01)
    assert exc["n_points"] == motion.npts and exc["scale"] == 0.5
    assert exc["pga_g"] == pytest.approx(motion.pga / rockjax.G_STANDARD, rel=1e-6)
    assert exc["duration_s"] == pytest.approx(T1)
    assert csv.read_text().splitlines()[0] == "t_s,u_m,v_m_s,theta_rad,uplift_m"
    assert main(["simulate", "--record", str(path), "--t1", "2"]) == 0
    text = capsys.readouterr().out
    assert "m.txt: units g" in text and "simplified model, impact rule paper" in text


def test_checks_come_before_the_run(tmp_path, capsys, monkeypatch):
    def boom(*a, **k):
        raise AssertionError("the run started before the checks")

    monkeypatch.setattr(rockjax, "simulate", boom)
    assert main(["simulate", "--u0", "0.1", "--out", str(tmp_path / "no" / "x.csv")]) == 2
    assert "--out: directory not found" in capsys.readouterr().err
    assert main(["simulate", "--u0", "100"]) == 2
    err = capsys.readouterr().err
    assert "--u0 100 m is beyond u_overturn = 0.375 m" in err and "metres" in err
    assert main(["pushover", "--out", str(tmp_path / "no" / "p.csv")]) == 2


def test_pushover_csv_header_has_units(tmp_path):
    csv = tmp_path / "p.csv"
    assert main(["pushover", "--points", "5", "--out", str(csv), "--json"]) == 0
    assert csv.read_text().splitlines()[0] == (
        "u_m,simplified_N,exact_N,numerical_N,theta_rad,uplift_m"
    )
