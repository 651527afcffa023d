"""Fidelity as a distribution (issue 27, item 3): `rockjax.compare_models` and its pieces.

The KS distance is checked against scipy's two-sample test; the comparison of a model with
itself must find no difference at all, and two different models a difference."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from scipy import stats

import rockjax
from rockjax._compare import _quantile


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ks_distance_matches_scipy(seed):
    rng = np.random.default_rng(seed)
    a, b = rng.normal(size=44), rng.normal(0.4, 1.3, size=30)
    d, p = rockjax.ks_distance(a, b)
    ref = stats.ks_2samp(a, b, method="asymp")
    assert d == pytest.approx(ref.statistic, abs=1e-12)
    # Kolmogorov's limit distribution (scipy's kstwobign); scipy's own "asymp" p-value uses
    # the finite-n distribution of D, smaller: the limit is the conservative one
    en = a.size * b.size / (a.size + b.size)
    assert p == pytest.approx(stats.kstwobign.sf(np.sqrt(en) * d), rel=1e-9)
    assert p >= ref.pvalue


def test_ks_distance_with_overturned_and_failed_runs():
    # overturned runs (+inf) lie above every finite peak; failed runs (NaN) are left out
    a = np.array([0.01, 0.02, np.inf, np.inf, np.nan])
    b = np.array([0.01, 0.02, 0.03, np.inf])
    d, _ = rockjax.ks_distance(a, b)
    # F_a jumps to 1/2 at 0.02 and stays there until inf; F_b reaches 3/4 at 0.03
    assert d == pytest.approx(0.25)
    assert rockjax.ks_distance(a, a)[0] == 0.0
    assert np.isnan(rockjax.ks_distance([np.nan], b)[0])


def test_quantiles_keep_overturned_runs_on_top():
    x = np.array([0.1, 0.2, 0.3, np.inf, np.nan])
    q = _quantile(x, (0.25, 0.5, 1.0))
    assert q[0] == 0.1 and q[1] == 0.2 and np.isposinf(q[2])


def test_bad_arguments_name_the_parameter():
    s = rockjax.mcmanus_column()
    with pytest.raises(rockjax.ParameterError, match="models"):
        rockjax.compare_models(s, [], [1.0], ["rigid_body"])
    with pytest.raises(rockjax.ParameterError, match="unique"):
        rockjax.compare_models(s, [], [1.0], ["rigid_body", "rigid_body"])
    with pytest.raises(rockjax.ParameterError, match="quantiles"):
        rockjax.compare_models(s, [], [1.0], ["rigid_body", "housner"], quantiles=(1.5,))
    with pytest.raises(rockjax.ParameterError, match="limit"):
        rockjax.compare_models(s, [], [1.0], ["rigid_body", "housner"], limits=("tilt",))


@pytest.mark.slow  # two sweeps of 3 records x 6 scales with their compiles (~30 s)
def test_compare_a_model_with_itself_and_with_another(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    recs = [rockjax.datasets.synthetic_ground_motion(duration=8.0, seed=k) for k in range(3)]
    s = rockjax.mcmanus_column()
    scales = np.geomspace(0.5, 6.0, 6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        c = rockjax.compare_models(s, recs, scales, {"rb": "rigid_body", "rb again": "rigid_body",
                                                     "housner": "housner"},
                                   limits=("overturned", "rotation=0.01"), n_bootstrap=20,
                                   progress=False)
    assert c.reference == "rb" and c.limits == ("overturned", "rotation >= 0.01 rad")
    assert c.peak_theta["rb"].shape == (3, 6) and c.quantiles["rb"].shape == (3, 6)
    # the same model: the same peaks, no KS distance, the same fragility
    np.testing.assert_array_equal(c.peak_theta["rb again"], c.peak_theta["rb"])
    assert np.all(c.ks["rb again"] == 0.0) and np.all(np.isnan(c.ks["rb"]))
    rows = {(r["model"], r["limit"]): r for r in c.rows()}
    for lim in c.limits:
        if rows[("rb", lim)]["fit"] is None:
            assert rows[("rb again", lim)]["median_ratio"] == pytest.approx(1.0)
            assert rows[("rb again", lim)]["beta_diff"] == pytest.approx(0.0)
    # the peaks grow with the scale (medians, non-decreasing over a geometric ladder)
    med = c.quantiles["rb"][1]
    assert np.all(np.diff(med[np.isfinite(med)]) >= -1e-12)
    # Housner's rigid block is another model: some distance at some scale
    assert np.nanmax(c.ks["housner"]) > 0
    text = c.report()
    assert "rb again" in text and "KS max" in text
    json.dumps(c.to_dict())
    fig = c.plot()
    assert len(fig.axes) == 2
