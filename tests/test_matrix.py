"""Every model × every integrator on one corpus of ordinary and adversarial inputs.

The corpus (tests/helpers/matrix.py, which `benchmarks/matrix.py` imports too so that the
test and the table in `docs/matrix.md` run the same cases) is made by the project: leading
zeros (0 to 1000 samples), trailing zeros, a record that ends mid-rock, a body at rest at
u = 0 under zero forcing, a constant offset, releases at rest, at u_crit and at u_overturn.
The fast
integrators must agree with the event-restart diffrax integrator on the status, the
impact count and the peak within their stated tolerance. The same check runs on long
records with quiet starts, generated like IELC180 (with leading zeros) and ChiChi.dat (2 s
of zeros); `python benchmarks/matrix.py --real DIR` runs it on the real records.
"""

from __future__ import annotations

import numpy as np
import pytest
from helpers import matrix

import rockjax

CASES = [*matrix.records(), *matrix.releases(rockjax.mcmanus_column())]


#: the columns of the default suite; dopri5's runs in the slow set (the suite in 8 minutes,
#: issue 26; CI runs it)
FAST = ("diffrax", "rk4")
SLOW = pytest.mark.slow


@pytest.fixture(scope="module")
def fast_results():
    res, _ = matrix.matrix(methods=FAST)
    return res


@pytest.fixture(scope="module")
def all_results(fast_results):
    res, _ = matrix.matrix(methods=("dopri5",))
    return {**fast_results, **res}


def _results(request, method):
    return request.getfixturevalue("fast_results" if method in FAST else "all_results")


@pytest.mark.parametrize("method", ["rk4", pytest.param("dopri5", marks=SLOW)])
@pytest.mark.parametrize("model", matrix.MODELS)
def test_integrators_agree(request, model, method):
    results = _results(request, method)
    bad = []
    for case in CASES:
        same_status, same_n, rel = matrix.agreement(results, model, method, case)
        if not (same_status and same_n and rel <= matrix.PEAK_RTOL[method]):
            bad.append(f"{case}: diffrax {results[model, 'diffrax'][case]}, "
                       f"{method} {results[model, method][case]} (rel {rel:.1e})")
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("method", [*FAST, pytest.param("dopri5", marks=SLOW)])
@pytest.mark.parametrize("model", matrix.MODELS)
def test_corpus_physics(request, model, method):
    """Integrator-independent expectations on the corpus (every integrator's cells)."""
    cells = _results(request, method)[model, method]
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


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_long_records_with_quiet_starts():
    """`matrix.quiet_starts()`: a 40 s record with 0 to 1000 zeros in front, and one that
    starts with 2 s of zeros (generated like IELC180 and ChiChi.dat; `benchmarks/matrix.py
    --real DIR` runs the real ones): the three integrators agree (default model, tight
    tolerances) on status, impact count and peak, and the zeros only delay the response."""
    s = rockjax.mcmanus_column()
    runs = matrix.quiet_starts()
    rows = [np.concatenate([np.zeros(n), acc]) for _, _, acc, n in runs]
    n = max(len(r) for r in rows)
    table = np.stack([np.concatenate([r, np.zeros(n - len(r))]) for r in rows])
    gm = rockjax.GroundMotion(dt=matrix.DT, accel=table)
    out = {m: rockjax.simulate_batch(s, gm, (n - 1) * matrix.DT, method=m, summary_only=True,
                                     rtol=1e-10, atol=1e-12, progress=False)
           for m in matrix.METHODS}
    ref = out["diffrax"]
    assert np.all(ref.n_impacts > 100) and set(ref.status_names) == {"completed"}
    for m in ("rk4", "dopri5"):
        assert out[m].status_names == ref.status_names
        np.testing.assert_array_equal(out[m].n_impacts, ref.n_impacts)
        np.testing.assert_allclose(out[m].peak_u, ref.peak_u, rtol=matrix.PEAK_RTOL[m])
    # the generated record starts at rest (a_0 = 0): zeros in front are a pure delay
    delayed = ref.peak_u[:len(matrix.QUIET_START_ZEROS)]
    np.testing.assert_allclose(delayed, delayed[0], rtol=1e-7)
