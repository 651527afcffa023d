"""Shake-table runs (issue 25, item 1): reading one file and two files, the errors and
stated handling of bad input, and the fit of k_f, r and the clock offset on a short
SYNTHETIC run (the decay fit's machinery with the table record as the excitation)."""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest
from conftest import shared_ground_motions, synthetic_motion

import identification
import rockjax
from rockjax.cli import main

TRUTH = {"k_f": 715e3, "r": 0.8}
CLOCK = 0.015


def _record():
    """2.5 s of the generated test record (from its 3rd s: x1.8 rocks the column)."""
    rec = synthetic_motion()
    return rockjax.Record(dt=rec.dt, accel=np.asarray(rec.accel)[300:551],
                          source="synthetic ground motion (seed 20), 3-5.5 s")


@pytest.fixture(scope="session")
def run():
    """A SYNTHETIC run: u (written in mm) and theta, 0.3 mm noise, 15 ms clock offset."""
    return identification.synthetic_shake_table(
        rockjax.mcmanus_column(), _record(), 1.8, model="simplified", truth=TRUTH,
        noise=0.3e-3, clock_offset=CLOCK, channels=("u", "theta"),
        channel_units={"u": "mm"}, seed=3)


@pytest.fixture(scope="session")
def fit(run):
    # k_f and r correlate strongly on 2.5 s of record (rho ~ 0.96: an identifiability
    # warning, which the values' accuracy below makes harmless here)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", identification.IdentifiabilityWarning)
        return identification.fit_shake_table(run, rockjax.mcmanus_column(),
                                              model="simplified")


def test_synthetic_run_is_labelled_and_rocks(run):
    assert "SYNTHETIC" in run.source and "SYNTHETIC" in run.response.source
    s = rockjax.mcmanus_column()
    assert np.max(np.abs(run.response.u)) > 2 * float(s.u_crit)  # it rocks
    assert run.response.units["u"] == "mm"


def test_fit_recovers_k_f_r_and_the_clock_offset(fit):
    assert fit.converged
    assert isinstance(fit, identification.FitResult)
    for p in ("k_f", "r"):
        assert abs(fit.values[p] / TRUTH[p] - 1) < 0.05, (p, fit.values[p])
        assert abs(fit.values[p] - TRUTH[p]) < 4 * fit.stderr[p]
    assert abs(fit.clock_offset - CLOCK) < 2e-3
    assert abs(fit.clock_offset - CLOCK) < 4 * fit.clock_offset_stderr
    assert set(fit.noise) == {"u", "theta"}
    assert 0.2e-3 < fit.noise["u"] < 0.4e-3
    assert not fit.lack_of_fit["fires"]
    text = fit.report()
    assert "clock offset" in text and "noise" in text
    summary = json.loads(json.dumps(fit.summary()))
    assert summary["kind"] == "shake table" and "clock_offset" in summary


@pytest.mark.slow  # compiles the residuals and Jacobian outside the fit's vmap (~20 s)
def test_posterior_problem_of_a_shake_table_fit(fit):
    import jax

    # the decay fit's likelihood (noise integrated out) and default priors
    assert fit.posterior_problem().priors["k_f"].kind == "lognormal"
    pp = fit.posterior_problem({p: "flat()" for p in fit.names})
    assert pp.source == "shake table" and pp.names == fit.names
    assert pp.chains_together  # a table record: the adaptive solver, chains vectorised
    z0 = np.asarray(pp.z0)
    ld = float(pp.log_density(z0))
    assert math.isfinite(ld)
    g = np.asarray(jax.grad(pp.log_density)(jax.numpy.asarray(z0)))
    for i in (0, 1):  # k_f, r: the gradient agrees with a float64 finite difference, to
        # the 2 % that the adaptive simulations' step choices leave (they make log L rough
        # on the scale of 1e-4 of its curvature)
        e = np.zeros_like(z0)
        e[i] = 1e-5
        fd = (float(pp.log_density(z0 + e)) - float(pp.log_density(z0 - e))) / (2 * e[i])
        assert abs(g[i] - fd) < 2e-2 * max(1.0, abs(fd)), (i, g[i], fd)
    sd = np.sqrt(np.diag(pp.cov0))
    # the optimum is (near) the maximum with flat priors: the gradient is small there
    # against the curvature (one Laplace standard deviation moves log L by ~1/2)
    assert np.all(np.abs(g * sd) < 0.5)


def _write_one(tmp_path, run):
    path = tmp_path / "run.csv"
    run.write_csv(path)
    return path


def test_read_one_file_round_trip(tmp_path, run):
    path = _write_one(tmp_path, run)
    head = path.read_text().splitlines()[1]
    assert head == "t,ag_m/s2,u_mm,theta_rad"
    back = identification.read_shake_table(path)
    assert back.response.units["u"] == "mm" and back.response.units_from["u"] == "header"
    np.testing.assert_allclose(back.response.u, run.response.u, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(back.table.accel, run.table.accel[:back.table.npts],
                               rtol=1e-8, atol=1e-9)
    assert back.table_start == 0.0 and back.table_kind == "acceleration"
    assert "SYNTHETIC" in back.description  # the label travels in the file's comment


def test_read_one_file_table_in_g_and_displacement(tmp_path):
    t = np.arange(0, 2.0, 0.01)
    ug = 0.01 * np.sin(2 * np.pi * 2 * t)  # m
    u = 0.02 * np.sin(2 * np.pi * 2 * t + 0.3)
    rows = "\n".join(f"{a:.6f},{b * 1e3:.9f},{c * 1e3:.9f}" for a, b, c in zip(t, ug, u))
    p = tmp_path / "disp.csv"
    p.write_text("t,table_disp_mm,u_mm\n" + rows + "\n")
    run = identification.read_shake_table(p)
    assert run.table_kind == "displacement" and run.table_units == "mm"
    expect = -(2 * np.pi * 2) ** 2 * ug
    np.testing.assert_allclose(run.table.accel[2:-2], expect[2:-2], rtol=0, atol=0.01)
    assert any("second derivative" in n for n in run.notes)
    g = tmp_path / "g.csv"
    g.write_text("t,ag_g,u_mm\n" + "\n".join(
        f"{a:.6f},{0.1 * math.sin(a):.9f},{c * 1e3:.9f}" for a, c in zip(t, u)) + "\n")
    run = identification.read_shake_table(g)
    np.testing.assert_allclose(run.table.accel, 0.1 * 9.80665 * np.sin(t), atol=1e-7)


def test_read_two_files_different_rates_units_and_clocks(tmp_path, run):
    # the response every 5 ms in mm, its clock starting 0.2 s before the table's; the
    # table a two-column file in cm/s2 every 10 ms starting at t = 0.2 s
    resp, tab = tmp_path / "resp.csv", tmp_path / "table.txt"
    t = np.arange(0.0, 2.0, 0.005)
    resp.write_text("t,u_mm\n" + "\n".join(f"{a:.4f},{5 * math.sin(3 * a):.6f}"
                                           for a in t) + "\n")
    tt = 0.2 + np.arange(0, 150) * 0.01
    tab.write_text("Time[s] Accel[cm/s2]\n" + "\n".join(f"{a:.3f} {10 * math.cos(a):.6f}"
                                                        for a in tt) + "\n")
    run2 = identification.read_shake_table(table=tab, response=resp)
    assert run2.table_start == pytest.approx(0.2)
    assert run2.start_difference == pytest.approx(-0.2)
    assert run2.table.dt == pytest.approx(0.01) and run2.response.dt == pytest.approx(0.005)
    np.testing.assert_allclose(run2.table.accel[:3], 0.1 * np.cos(tt[:3]), atol=1e-9)
    notes = " ".join(run2.notes)
    assert "sampled every 0.005 s" in notes  # different rates: reported
    assert "before the table record" in notes  # response starts earlier: at rest
    assert "ends" in notes and "zero after the record" in notes  # longer: free rocking
    # a Record and a DecayTrace as they are; without time stamps: assumed, reported
    run3 = identification.read_shake_table(table=run.table, response=run.response)
    assert run3.table_start == float(run.response.t[0])
    assert any("no time stamps" in n for n in run3.notes)


def test_saturated_response_channel_is_refused(run):
    u = np.array(run.response.u)
    cap = 0.6 * float(np.max(u))
    clipped = identification.DecayTrace(t=run.response.t, u=np.minimum(u, cap),
                                        source="clipped")
    with pytest.raises(identification.TraceError, match="u channel saturates"):
        identification.read_shake_table(table=run.table, response=clipped, table_start=0.0)


def test_bad_input_errors(tmp_path):
    p = tmp_path / "x.csv"
    p.write_text("t,u\n" + "\n".join(f"{i * 0.01},{i}" for i in range(20)) + "\n")
    with pytest.raises(ValueError, match="no table column"):
        identification.read_shake_table(p)
    with pytest.raises(ValueError, match="table= .* and response="):
        identification.read_shake_table(table=p)
    with pytest.raises(ValueError, match="ShakeTableRun"):
        identification.fit_shake_table("run.csv")


def test_cli_fit_table_json(tmp_path, run, capsys):
    path = _write_one(tmp_path, run)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", identification.IdentifiabilityWarning)
        assert main(["fit-table", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["kind"] == "shake table"
    assert abs(out["values"]["k_f"] / TRUTH["k_f"] - 1) < 0.05
    assert abs(out["clock_offset"] - CLOCK) < 2e-3
    assert out["runs"][0]["response"]["units_in_file"]["u"] == "mm"


def test_cli_fit_table_errors_name_the_flag(tmp_path, capsys):
    assert main(["fit-table", "a.csv", "b.csv", "--table", "t.txt"]) == 2
    assert "--table:" in capsys.readouterr().err
    assert main(["fit-table", "a.csv", "--table-units", "g"]) == 2
    assert "--table-units" in capsys.readouterr().err
    assert main(["fit-table", "a.csv", "--draws-out", "d.csv"]) == 2
    assert "--draws-out needs --posterior" in capsys.readouterr().err


@pytest.mark.slow  # a fit, then a (short) posterior with its compiles: about a minute
@pytest.mark.timeout(1800)
def test_cli_fit_table_posterior(tmp_path, run, capsys):
    path = _write_one(tmp_path, run)
    draws = tmp_path / "draws.csv"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", identification.IdentifiabilityWarning)
        warnings.simplefilter("ignore", identification.PosteriorWarning)  # 2 x 40 draws
        assert main(["fit-table", str(path), "--json", "--posterior", "--chains", "2",
                     "--draws", "40", "--warmup", "40", "--draws-out", str(draws)]) == 0
    out = json.loads(capsys.readouterr().out)
    post = out["posterior"]
    assert set(post["parameters"]) == set(out["values"])
    assert post["settings"]["chains"] == 2 and post["draws_out"] == str(draws)
    k = post["parameters"]["k_f"]
    assert k["q05"] < out["values"]["k_f"] < k["q95"]
    lines = draws.read_text().splitlines()
    assert lines[0].startswith("# units:") and "k_f" in lines[1]
    assert len(lines) == 2 + 2 * 40


@pytest.mark.slow
def test_joint_fit_of_two_runs_shares_k_f_and_r():
    s = rockjax.mcmanus_column()
    runs = [identification.synthetic_shake_table(s, _record(), sc, truth=TRUTH, seed=k,
                                                 channels=("u",))
            for k, sc in ((1, 1.2), (2, 1.5))]
    fit = identification.fit_shake_table(runs, s)
    assert isinstance(fit, identification.JointFitResult)
    for p in ("k_f", "r"):
        assert abs(fit.values[p] / TRUTH[p] - 1) < 0.05
    for d in fit.per_trace:
        assert abs(d["values"]["t0"] - CLOCK) < 3e-3


@pytest.mark.slow
def test_rigid_body_fit_on_a_shared_record():
    rec = rockjax.read_record(shared_ground_motions() / "IELC180.AT2")
    rec = rockjax.Record(dt=rec.dt, accel=rec.accel[:400], source=rec.source)
    s = rockjax.mcmanus_column()
    run = identification.synthetic_shake_table(s, rec, 1.5, model="rigid_body", truth=TRUTH,
                                               seed=5)
    fit = identification.fit_shake_table(run, s, model="rigid_body")
    for p in ("k_f", "r"):
        assert abs(fit.values[p] / TRUTH[p] - 1) < 0.05
