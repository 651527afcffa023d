"""The fidelity warning: the paper's SDOF under a ground motion that lifts the structure off
by more than 3 u_crit warns (`rockjax.FidelityWarning`), naming rigid_body; it can be
silenced, and it stays quiet where the SDOF is fit for the scene."""

from __future__ import annotations

import json
import warnings

import jax
import numpy as np
import pytest
from conftest import run_cli

import rockjax
from rockjax import _fidelity


@pytest.fixture(scope="module")
def short_motion(synthetic_record):
    """The first 10 s of the tests' synthetic record (El Centro's PGA)."""
    n = 1001
    return rockjax.GroundMotion(dt=synthetic_record.dt, accel=synthetic_record.accel[:n])


def _run(column, exc, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = rockjax.simulate(column, exc, 10.0, method="rk4", **kw)
    return res, [w for w in caught if issubclass(w.category, rockjax.FidelityWarning)]


def test_sdof_under_strong_motion_warns(column, short_motion):
    res, caught = _run(column, short_motion)
    assert float(res.peak_u) > _fidelity.LIFT_OFF_LIMIT * float(column.u_crit)
    assert len(caught) == 1
    msg = str(caught[0].message)
    assert "'simplified'" in msg and 'model="rigid_body"' in msg and "fidelity_warning=False" in msg
    assert f"{float(res.peak_u) / float(column.u_crit):.0f} u_crit" in msg


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_warning_is_silenced_and_quiet_where_the_sdof_fits(column, short_motion):
    _, caught = _run(column, short_motion, fidelity_warning=False)
    assert caught == []
    # a weak motion that lifts the column off by less than 3 u_crit
    weak = rockjax.GroundMotion(dt=short_motion.dt, accel=short_motion.accel, scale=0.15)
    res, caught = _run(column, weak)
    assert float(res.peak_u) < _fidelity.LIFT_OFF_LIMIT * float(column.u_crit) and caught == []
    # a free vibration (the paper's own Fig. 9 scene) and the body models never warn
    _, caught = _run(column, rockjax.FreeVibration(0.10))
    assert caught == []
    _, caught = _run(column, short_motion, model="two_spring_2dof")
    assert caught == []


@pytest.mark.slow  # moved out of the default suite (issue 23): compile-bound; CI runs it
def test_no_warning_inside_transformations(column, short_motion):
    """Inside jit or grad the peak is a tracer: nothing to look at, no error."""
    def peak(k_f):
        return rockjax.simulate(column.replace(k_f=k_f), short_motion, 10.0,
                                method="rk4").peak_u

    with warnings.catch_warnings():
        warnings.simplefilter("error", rockjax.FidelityWarning)
        g = jax.grad(peak)(column.k_f)
    assert np.isfinite(float(g))


def test_batch_warns_once_with_a_count(column, short_motion):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = rockjax.simulate_batch(column, short_motion, 10.0, scale=[0.15, 1.0, 1.2],
                                     summary_only=True)
    caught = [w for w in caught if issubclass(w.category, rockjax.FidelityWarning)]
    n_over = int(np.sum(np.asarray(out.peak_u) > 3 * float(column.u_crit)))
    assert len(caught) == 1 and f"in {n_over} of 3 runs" in str(caught[0].message)


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_cli_warns_in_its_own_syntax(tmp_path, synthetic_record):
    """5 s of the synthetic record at x1.5 (the SDOF peaks at 5.4 u_crit): short, for two
    subprocess runs."""
    path = tmp_path / "motion.csv"
    n = 501
    np.savetxt(path, np.column_stack([np.arange(n) * synthetic_record.dt,
                                      1.5 * synthetic_record.accel[:n]]),
               delimiter=",", header="t_s,accel_m_s2", comments="")
    p = run_cli("simulate", "--record", str(path), "--units", "m/s2", "--json")
    assert p.returncode == 0, p.stderr
    assert "warning: the paper's SDOF model ('simplified')" in p.stderr
    assert "--model rigid_body" in p.stderr and "--no-fidelity-warning" in p.stderr
    out = json.loads(p.stdout)
    assert "--model rigid_body" in out["fidelity_warning"]
    p = run_cli("simulate", "--record", str(path), "--units", "m/s2", "--json",
                "--no-fidelity-warning")
    assert p.returncode == 0 and "warning" not in p.stderr
    assert json.loads(p.stdout)["fidelity_warning"] is None
