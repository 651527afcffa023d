"""Every model × every integrator on one corpus of ordinary and adversarial inputs.

The corpus (`benchmarks/matrix.py`, imported here so that the test and the table in
`docs/matrix.md` run the same cases) is made by the project: leading zeros (0 to 1000
samples), trailing zeros, a record that ends mid-rock, a body at rest at u = 0 under zero
forcing, a constant offset, releases at rest, at u_crit and at u_overturn. The fast
integrators must agree with the event-restart diffrax integrator on the status, the
impact count and the peak within their stated tolerance. The same check runs on the real
records IELC180 (with leading zeros) and ChiChi.dat (2 s of zeros) where the shared folder
is available.
"""

from __future__ import annotations

import importlib.util
import pathlib

import numpy as np
import pytest

import rockjax

_spec = importlib.util.spec_from_file_location(
    "matrix", pathlib.Path(__file__).parents[1] / "benchmarks" / "matrix.py")
matrix = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(matrix)

CASES = [*matrix.records(), *matrix.releases(rockjax.mcmanus_column())]


@pytest.fixture(scope="module")
def results():
    res, _ = matrix.matrix()
    return res


@pytest.mark.parametrize("method", ["rk4", "dopri5"])
@pytest.mark.parametrize("model", matrix.MODELS)
def test_integrators_agree(results, model, method):
    bad = []
    for case in CASES:
        same_status, same_n, rel = matrix.agreement(results, model, method, case)
        if not (same_status and same_n and rel <= matrix.PEAK_RTOL[method]):
            bad.append(f"{case}: diffrax {results[model, 'diffrax'][case]}, "
                       f"{method} {results[model, method][case]} (rel {rel:.1e})")
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("model", matrix.MODELS)
def test_corpus_physics(results, model):
    """Integrator-independent expectations on the corpus (every integrator's cells)."""
    for method in matrix.METHODS:
        cells = results[model, method]
        # a body at rest at u = 0 under zero forcing stays there: no phantom impacts
        assert cells["zero forcing, at rest"] == (0.0, 0, "completed")
        assert cells["release at rest"] == (0.0, 0, "completed")
        assert cells["release at u_overturn"][2] == "overturned"
        # leading zeros delay the response and change nothing else; the runs share one
        # end time, so more zeros leave less time after the motion, and no more impacts
        # (with no zero in front the record starts on a jump from rest: another forcing)
        ref = cells["leading zeros 1"]
        counts = [ref[1]]
        for n in (10, 100, 1000):
            peak, n_imp, status = cells[f"leading zeros {n}"]
            assert status == ref[2]
            assert peak == pytest.approx(ref[0], rel=1e-7)
            counts.append(n_imp)
        assert counts == sorted(counts, reverse=True) and counts[-1] > 0


def _records_with_leading_zeros(rec, zeros):
    """One GroundMotion holding the record with each number of zeros in front."""
    acc = np.asarray(rec.accel)
    n = len(acc) + max(zeros)
    rows = [np.concatenate([np.zeros(k), acc, np.zeros(n - k - len(acc))]) for k in zeros]
    return rockjax.GroundMotion(dt=rec.dt, accel=np.stack(rows)), n * rec.dt


def test_real_records_with_leading_zeros(ground_motions_dir):
    """IELC180 with 0 to 1000 zeros in front, and ChiChi.dat (2 s of zeros at its start):
    the three integrators agree (default model, `simulate`'s default tolerance) on status,
    impact count and peak."""
    s = rockjax.mcmanus_column()
    el = rockjax.read_record(ground_motions_dir / "IELC180.AT2", units="g")
    cc = rockjax.read_record(ground_motions_dir / "ChiChi.dat", units="g")
    for rec, zeros in ((el, (0, 1, 10, 100, 1000)), (cc, (0,))):
        gm, t1 = _records_with_leading_zeros(rec, zeros)
        runs = {m: rockjax.simulate_batch(s, gm, t1, method=m, summary_only=True,
                                          rtol=1e-10, atol=1e-12, progress=False)
                for m in matrix.METHODS}
        ref = runs["diffrax"]
        assert np.all(ref.n_impacts > 0) and set(ref.status_names) == {"completed"}
        for m in ("rk4", "dopri5"):
            assert runs[m].status_names == ref.status_names
            np.testing.assert_array_equal(runs[m].n_impacts, ref.n_impacts)
            np.testing.assert_allclose(runs[m].peak_u, ref.peak_u, rtol=matrix.PEAK_RTOL[m])
