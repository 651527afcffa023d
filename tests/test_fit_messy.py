"""Messy decay traces (issue 24): a sensor offset or drift, mains hum, a clipped sensor, two
releases in one file. Each is found and named, fitted where it can be, or refused.

All the traces are SYNTHETIC (`identification.synthetic_trace`, or the shipped
`synthetic_decay_noisy` with an offset added): the truth is known.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

import identification
import rockjax
from identification import DecayTrace, fit_decay, LackOfFitWarning, TraceError
from identification._diagnosis import diagnose
from identification._lack import BIAS_Z_MAX, lack_of_fit

NAME = "synthetic_decay_noisy"


@pytest.fixture(scope="module")
def noisy():
    trace = identification.read_trace(identification.synthetic_trace_path(NAME))
    return trace, identification.synthetic_truth(NAME)


def _shifted(trace, offset):
    """The trace with `offset` [m] added to its displacement (its uplift as it is)."""
    return DecayTrace(trace.t, np.asarray(trace.u) + offset, trace.uplift,
                      source=f"offset {offset}")


def _fit(trace, **kw):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fit = fit_decay(trace, rockjax.mcmanus_column(), progress=False, **kw)
    return fit, caught


@pytest.fixture(scope="module")
def offset_fits(noisy):
    """The shipped noisy trace with offsets 0, +4 mm and -8 mm on its displacement, each
    fitted with the defaults (the offsets fitted: the trace pins them): one compiled fit,
    the one of tests/test_fit.py's `noisy_fit` (read back from the compile cache)."""
    trace, _ = noisy
    return {off: _fit(_shifted(trace, off)) for off in (0.0, 4e-3, -8e-3)}


# ----------------------------------------------------------------------------- offsets


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes); CI runs it
def test_offset_is_fitted_by_default_and_recovered(noisy, offset_fits):
    _, truth = noisy
    base = offset_fits[0.0][0]
    for off, (fit, caught) in offset_fits.items():
        assert fit.names[-2:] == ("offset", "offset_uplift") and fit.converged
        assert abs(fit.values["offset_uplift"]) < 3 * fit.stderr["offset_uplift"]
        assert abs(fit.values["offset"] - off) < 3 * fit.stderr["offset"]
        assert fit.stderr["offset"] < 1e-4  # 0.1 mm
        for p in ("k_f", "r"):
            assert abs(fit.values[p] / truth[p] - 1) < 0.01
            assert abs(fit.values[p] - truth[p]) < 3 * fit.stderr[p]
            # the offset is a nuisance: the rest of the fit does not see it
            assert fit.values[p] == pytest.approx(base.values[p], rel=1e-5)
        assert not fit.lack_of_fit["fires"] and fit.diagnosis is None
        assert not [w for w in caught if issubclass(w.category, LackOfFitWarning)]
        # the fitted response is what the sensor reads: the trace less the noise
        e = np.asarray(fit.response.u) - np.asarray(_shifted(noisy[0], off).u)
        assert abs(np.mean(e)) < 1e-5 and np.std(e) < 1.2 * truth["noise_std_u"]
    assert identification.UNITS["offset"] == "m" and identification.UNITS["drift"] == "m/s"


def test_an_unfitted_offset_is_flagged_by_the_sign_test():
    """Residuals of one sign: the runs test sees 1 run where 1 is expected (z = 0), the
    sign and mean tests fire; the diagnosis names the offset."""
    e = np.random.default_rng(0).normal(0.0, 5e-4, 801) - 4e-3  # model - trace
    st = lack_of_fit(e, float(np.sqrt(np.mean(e**2))), 0.1, "simplified", ["rigid_body"],
                     t=np.arange(801) / 100)
    assert st["runs_z"] == 0.0 and not st["correlated"]
    assert st["biased"] and st["fires"] and abs(st["sign_z"]) > 5 * BIAS_Z_MAX
    assert st["diagnosis"]["cause"] == "offset"
    assert st["diagnosis"]["offset_m"] == pytest.approx(4e-3, abs=1e-4)
    assert "constant offset of the sensor" in st["message"] and "offset=True" in st["message"]
    assert "cannot represent this trace" not in st["message"]


@pytest.mark.slow  # a compile of its own (40 s); the statistics are tested above
def test_an_unfitted_offset_in_a_fit_is_named(noisy):
    """offset=False on the +4 mm trace (k_f held at the truth, to keep the fit short): the
    lack-of-fit check fires, and names the offset, not the model."""
    trace, truth = noisy
    fit, caught = _fit(_shifted(trace, 4e-3), params=("r", "u0", "t0"), offset=False,
                       initial={"k_f": truth["k_f"]})
    assert "offset" not in fit.names
    assert fit.lack_of_fit["fires"] and fit.lack_of_fit["biased"]
    assert fit.diagnosis["cause"] == "offset"
    assert fit.diagnosis["offset_m"] == pytest.approx(4e-3, rel=0.2)
    msgs = [str(w.message) for w in caught if issubclass(w.category, LackOfFitWarning)]
    assert len(msgs) == 1 and "constant offset of the sensor" in msgs[0]
    summary = json.loads(json.dumps(fit.summary()))
    assert summary["diagnosis"]["cause"] == "offset"


def test_offset_keyword_checks():
    t = np.arange(61) / 200.0  # 0.3 s: the first half swing only
    trace = DecayTrace(t, 0.1 * np.cos(np.pi * t / 0.6))
    pb = identification._problem.setup(trace, rockjax.mcmanus_column(), None,
                                       identification._problem.Settings())
    assert "offset" not in pb.params and "cannot pin it" in pb.notes[-1]
    pb = identification._problem.setup(trace, rockjax.mcmanus_column(), None,
                                       identification._problem.Settings(offset=True,
                                                                        drift=True))
    assert pb.params[-2:] == ("offset", "drift")
    with pytest.raises(ValueError, match="offset=False contradicts"):
        fit_decay(trace, params=("k_f", "offset"), offset=False)
    with pytest.raises(ValueError, match="offset must be None"):
        fit_decay(trace, offset="yes")


# ---------------------------------------------------------------- diagnosis (no fits)


def _diag(e, t):
    return diagnose(e, t, "simplified")


def test_diagnosis_names_hum_drift_and_model():
    rng = np.random.default_rng(1)
    t = np.arange(3001) / 1000.0  # 3 s at 1 kHz
    n = rng.normal(0.0, 5e-4, t.size)
    hum = _diag(n - 2e-3 * np.sin(2 * np.pi * 50.0 * t), t)
    assert hum["cause"] == "periodic" and hum["frequency_hz"] == pytest.approx(50.0, abs=0.05)
    assert hum["amplitude_m"] == pytest.approx(2e-3, rel=0.05)
    assert "mains hum at 50 Hz" in hum["message"] and "notch" in hum["message"]
    h60 = _diag(n + 1e-3 * np.sin(2 * np.pi * 120.0 * t), t)
    assert h60["cause"] == "periodic" and "harmonic 2" in h60["message"]
    drift = _diag(n + 2e-3 * (t - 1.0), t)  # model - trace grows: the trace drifts down
    assert drift["cause"] == "drift" and drift["drift_m_per_s"] == pytest.approx(-2e-3, rel=0.05)
    # a decaying oscillation (a bounce the model lacks) is not hum: the model is blamed
    bounce = _diag(n + 3e-3 * np.exp(-2 * t) * np.sin(2 * np.pi * 12.0 * t), t)
    assert bounce["cause"] == "model"
    smooth = _diag(n + 1e-3 * np.sin(2 * np.pi * 1.3 * t), t)
    assert smooth["cause"] == "model"


# ------------------------------------------------------------------ clipping, releases


def test_a_clipped_trace_is_refused_naming_the_level_and_samples():
    trace, _ = identification.synthetic_trace(u0=0.08, clip=0.05, duration=2.0,
                                              rate_hz=100.0, seed=3)
    with pytest.raises(TraceError, match=r"clipped \(the sensor saturated\) at \+50 mm") as e:
        fit_decay(trace, rockjax.mcmanus_column())
    msg = str(e.value)
    assert "-50 mm (lower)" in msg and "samples 0.." in msg and "plateau" in msg
    # a noise-free hold (exactly constant) and single spikes at the extremes are not
    # clipping
    from identification._anomalies import find_clipping

    t = np.arange(300) / 100.0
    u = np.where(t < 0.5, 0.1, 0.1 * np.cos(3 * (t - 0.5)) * np.exp(-(t - 0.5)))
    assert find_clipping(t, u, sigma=0.0) == []
    spiked = u + np.random.default_rng(0).normal(0, 5e-4, t.size)
    spiked[[100, 200]] = [0.5, -0.5]
    assert find_clipping(t, spiked, sigma=5e-4) == []


@pytest.fixture(scope="module")
def two_releases():
    return identification.synthetic_trace(duration=8.0, rate_hz=100.0, r=0.7,
                                          second=(5.0, 0.09), seed=4)


def test_a_second_release_is_refused_naming_both_segments(two_releases):
    trace, _ = two_releases
    with pytest.raises(TraceError, match=r"holds 2 releases .* again at t = 5\.0\d* s") as e:
        fit_decay(trace, rockjax.mcmanus_column())
    assert "segment 1: t = 0-4.79 s" in str(e.value) and "split_releases" in str(e.value)
    segs = identification.split_releases(trace)
    # segment 2 starts where the structure was set to 0.09 m (0.2 s before its release)
    assert len(segs) == 2 and segs[1].t[0] == pytest.approx(4.8, abs=0.015)
    assert segs[0].t[-1] < segs[1].t[0]
    rel = identification.detect_release(segs[1])
    assert rel.held and rel.time == pytest.approx(5.0, abs=0.02)
    assert rel.level == pytest.approx(0.09, abs=2e-3)
    # a trace of one release is its own only segment
    one, _ = identification.synthetic_trace(duration=4.0, rate_hz=100.0, r=0.7, seed=4)
    assert identification.split_releases(one) == [one]


# -------------------------------------------------------------------------------- slow


@pytest.mark.slow
def test_hum_in_a_fit_is_reported_at_its_frequency():
    trace, _ = identification.synthetic_trace(duration=3.0, rate_hz=1000.0,
                                              hum=(2e-3, 50.0), seed=5)
    fit, caught = _fit(trace)
    assert fit.lack_of_fit["fires"] and fit.diagnosis["cause"] == "periodic"
    assert fit.diagnosis["frequency_hz"] == pytest.approx(50.0, abs=0.1)
    assert any("mains hum at 50 Hz" in str(w.message) for w in caught)


@pytest.mark.slow
def test_drift_is_fitted_when_asked():
    trace, _ = identification.synthetic_trace(duration=8.0, rate_hz=100.0, drift=1e-3,
                                              seed=6)
    fit, _ = _fit(trace, drift=True)
    assert fit.values["drift"] == pytest.approx(1e-3, abs=3 * fit.stderr["drift"])
    assert abs(fit.values["k_f"] / 800e3 - 1) < 0.02 and not fit.lack_of_fit["fires"]


@pytest.mark.slow
def test_the_two_segments_fitted_jointly(two_releases):
    segs = identification.split_releases(two_releases[0])
    joint = fit_decay(segs, rockjax.mcmanus_column(), progress=False)
    assert abs(joint.values["k_f"] / 800e3 - 1) < 0.02
    assert abs(joint.values["r"] / 0.7 - 1) < 0.01


# --------------------------------------------------------------------- convergence


@pytest.mark.slow  # compile-bound (~15 s): a fit of its own shape
def test_an_unconverged_fit_warns():
    """max_iter = 4 stops every horizon after one chunk: converged False, and a
    ConvergenceWarning (in `warnings` too). The shipped clean trace with the defaults: the
    compiled fit of tests/test_fit.py's `clean_fit`."""
    trace = identification.read_trace(
        identification.synthetic_trace_path("synthetic_decay_clean"))
    fit, caught = _fit(trace, max_iter=4)
    assert not fit.converged
    conv = [str(w.message) for w in caught if w.category is identification.ConvergenceWarning]
    assert len(conv) == 1 and conv[0] in fit.warnings
    assert "did not converge" in conv[0] and "raise max_iter" in conv[0]


@pytest.mark.slow
def test_an_unconverged_adam_fit_warns(noisy):
    optax = pytest.importorskip("optax")
    fit, caught = _fit(noisy[0], optimizer=optax.adam(1e-2), max_iter=8)
    assert not fit.converged
    assert any(w.category is identification.ConvergenceWarning for w in caught)
