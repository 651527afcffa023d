"""fit_decay on the synthetic decay traces: recovery, uncertainty, mismatch, identifiability."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import identification
import rockjax
from identification import fit_decay, read_trace, synthetic_trace_path, synthetic_truth


def _load(name):
    return read_trace(synthetic_trace_path(name)), synthetic_truth(name)


@pytest.fixture(scope="module")
def clean_fit():
    trace, truth = _load("synthetic_decay_clean")
    s = rockjax.mcmanus_column()
    fit = fit_decay(trace, s, ("k_f", "r"), initial={"k_f": 2 * truth["k_f"]}, starts=2,
                    progress=False)
    return fit, truth


@pytest.fixture(scope="module")
def noisy_fit():
    trace, truth = _load("synthetic_decay_noisy")
    s = rockjax.mcmanus_column()  # k_f = 550 kN/m, r(Eq 3) = 0.735: away from the truth
    fit = fit_decay(trace, s, ("k_f", "r", "u0"),
                    initial={"k_f": 2 * truth["k_f"], "r": float(s.restitution)}, starts=2,
                    progress=False)
    return fit, truth


def test_noise_free_recovery(clean_fit):
    fit, truth = clean_fit
    assert fit.converged
    for p in ("k_f", "r"):
        rel = abs(fit.values[p] / truth[p] - 1)
        assert rel < 1e-3, (p, fit.values[p], truth[p], rel)  # acceptance: 0.1 %
    assert fit.rms < 1e-6


def test_noisy_recovery_and_coverage(noisy_fit):
    fit, truth = noisy_fit
    assert fit.converged
    assert abs(fit.values["k_f"] / truth["k_f"] - 1) < 0.02  # acceptance: 2 %
    assert abs(fit.values["r"] / truth["r"] - 1) < 0.01  # acceptance: 1 %
    for p in ("k_f", "r", "u0"):
        z = (fit.values[p] - truth[p]) / fit.stderr[p]
        assert abs(z) < 3.0, (p, fit.values[p], truth[p], fit.stderr[p], z)
    # the displacement noise is estimated (true std 5e-4 m)
    assert fit.sigma == pytest.approx(truth["noise_std_u"], rel=0.1)
    c = fit.correlation
    np.testing.assert_allclose(np.diag(c), 1.0, rtol=1e-12)
    assert np.all(np.abs(c) <= 1.0 + 1e-12)


def test_fit_result_summary_and_response(noisy_fit):
    fit, _ = noisy_fit
    s = fit.summary()
    assert set(s["values"]) == {"k_f", "r", "u0"} and set(s["stderr"]) == set(s["values"])
    assert {"loss", "converged", "correlation", "identifiability"} <= set(s)
    assert fit.response.u.shape == (1601,) and fit.response.status_name == "completed"
    assert fit.loss_history.ndim == 1 and fit.loss_history.size >= 4
    assert "corr_k_f_r" in fit.identifiability


def test_model_mismatch_bias_is_reported():
    # a trace generated with the exact model, fitted with the simplified one
    trace, truth = _load("synthetic_decay_exact")
    fit = fit_decay(trace, rockjax.mcmanus_column(), ("k_f", "r"),
                    initial={"k_f": truth["k_f"], "r": truth["r"]}, starts=1, progress=False)
    bias = {p: fit.values[p] / truth[p] - 1 for p in ("k_f", "r")}
    print("model-mismatch bias (exact -> simplified):", bias, "rms", fit.rms)
    assert all(np.isfinite(v) for v in bias.values())
    assert abs(bias["r"]) < 0.05 and abs(bias["k_f"]) < 0.5


def test_short_trace_warns_not_crashes():
    # 0.25 s: released and falling, no impact yet: r cannot be identified
    trace, _ = _load("synthetic_decay_clean")
    n = 50
    short = identification.DecayTrace(trace.t[:n], trace.u[:n], trace.uplift[:n])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fit = fit_decay(short, rockjax.mcmanus_column(), ("k_f", "r"), starts=1, max_iter=8,
                        horizons=(1.0,), progress=False)
    msgs = [str(w.message) for w in caught if issubclass(w.category,
                                                          identification.IdentifiabilityWarning)]
    assert any("does not pin r down" in m for m in msgs), msgs
    assert fit.warnings and np.all(np.isfinite(list(fit.values.values())))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(params=("k_f", "banana")), "params"),
        (dict(params=()), "params"),
        (dict(starts=0), "starts"),
        (dict(initial={"r": 1.5}), "initial r"),
        (dict(initial={"k_f": 10.0}), "stability limit"),
        (dict(initial={"zeta": 1.0}), "unknown"),
    ],
)
def test_bad_arguments(kwargs, match):
    trace, _ = _load("synthetic_decay_clean")
    with pytest.raises(ValueError, match=match):
        fit_decay(trace, rockjax.mcmanus_column(), **kwargs)
