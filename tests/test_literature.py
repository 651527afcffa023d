"""The rocking literature's benchmarks (issue 27, item 4; `docs/benchmarks_literature.md`).

Each against a value written here independently of rockjax:

- Housner (1963): the smallest rectangular pulse that overturns a slender block,
  $a/(g\\tan\\alpha) = 1/(1 - e^{-p t_1})$ in the linearised limit $\\alpha \\to 0$;
- Nabeshima, Taniguchi, Kojima & Takewaki (2016): the closed-form critical double impulse;
- Dimitrakopoulos & DeJong (2012): geometrically similar blocks' overturning thresholds
  collapse onto one curve in $(\\omega_p/p,\\ a/(g\\tan\\alpha))$.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers.literature import (
    critical_double_impulse,
    double_impulse_run,
    linearised_threshold,
    point_mass_block,
    PT1,
    uniform_block,
)
from scipy.integrate import solve_ivp

import rockjax
from rockjax import simulate
from rockjax._spectrum import frequency_parameter, periods_at


# ------------------------------------------------------- a rigid block released by a jump
def _sdof_reference(s, a, t1, ts):
    """The housner SDOF of a point-mass block (all lengths from its fields) under a
    rectangular pulse a [m/s²] for t1 [s], from rest, by scipy: u(ts) [m] (motion towards
    -u for a > 0: returned as |u|)."""
    g, al = float(s.g), float(s.alpha_c)
    R = float(s.R_c)

    def f(t, y):
        th, w = y
        acc = a if t <= t1 else 0.0
        b = al - th
        return [w, (-g * math.tan(b) + acc - R * math.sin(b) * w * w) / (R * math.cos(b))]

    sol = solve_ivp(f, (0.0, ts[-1]), [0.0, 0.0], t_eval=ts, rtol=1e-12, atol=1e-15,
                    max_step=1e-3)
    return R * (math.sin(al) - np.sin(al - sol.y[0]))


@pytest.mark.parametrize("method", ["diffrax", "rk4"])
def test_rigid_block_is_released_by_a_pulse_that_starts_above_the_threshold(method):
    """Regression: a `housner` block at rest under a ground motion whose first sample
    already exceeds k(0+)/M (a rectangular or one-cosine pulse) stayed at rest for good on
    diffrax (the release events fire when |a_g| reaches the threshold, not when it starts
    above it) and was released one RK4 substep late on rk4 (+0.6 % on the thresholds)."""
    s = point_mass_block(0.01)
    p, gta = frequency_parameter(s), float(s.g * s.B / s.H_c)
    t1 = 0.5 / p
    ts = np.linspace(0.0, 0.6, 7)
    a = 2.6 * gta
    res = simulate(s, rockjax.pulses.rectangular(a, t1), 0.6, ts=ts, model="housner",
                   method=method)
    ref = _sdof_reference(s, a, t1, ts)
    assert np.all(np.asarray(res.u)[1:] < 0)  # thrown towards -u
    np.testing.assert_allclose(-np.asarray(res.u), ref, rtol=1e-6, atol=1e-12)
    # below the threshold it stays at rest
    quiet = simulate(s, rockjax.pulses.rectangular(0.9 * gta, t1), 0.6, ts=ts,
                     model="housner", method=method)
    assert np.all(np.asarray(quiet.u) == 0.0)


# ------------------------------------------------- Housner's linearised rectangular pulse
@pytest.fixture(scope="module")
def rectangular_thresholds():
    """a/(g tan alpha) of the housner model for point-mass blocks, alpha = 0.05 and 0.01,
    at p t1 = 0.5, 1, 2 (amplitude bracket 1e-6)."""
    out = {}
    for alpha in (0.05, 0.01):
        s = point_mass_block(alpha)
        p = frequency_parameter(s)
        sp = rockjax.overturning_spectrum(s, "rectangular", PT1 / p, model="housner",
                                          amplitude_rtol=1e-6)
        out[alpha] = sp
    return out


def test_housner_linearised_rectangular_pulse(rectangular_thresholds):
    """Housner (1963): the smallest rectangular pulse that overturns a slender block is
    a = g tan(alpha) / (1 - exp(-p t1)) (2.5415, 1.5820, 1.1565 at p t1 = 0.5, 1, 2), the
    limit alpha -> 0; the difference falls as alpha^2 (measured -7.4e-4, -5.8e-4, -3.4e-4
    at alpha = 0.05, -2.9e-5, -2.3e-5, -1.4e-5 at 0.01)."""
    lin = linearised_threshold(PT1)
    np.testing.assert_allclose(lin, [2.5415, 1.5820, 1.1565], atol=5e-5)
    err = {}
    for alpha, sp in rectangular_thresholds.items():
        assert sp.n_failed == 0 and sp.mode == ("no impact",) * 3
        np.testing.assert_allclose(sp.x, PT1, rtol=1e-12)
        err[alpha] = sp.normalised / lin - 1
    assert np.all(np.abs(err[0.05]) < 1e-3), err
    assert np.all(np.abs(err[0.01]) < 5e-5), err
    ratio = err[0.05] / err[0.01]
    assert np.all((ratio > 15) & (ratio < 35)), ratio  # (0.05 / 0.01)^2 = 25


# ------------------------------------------------------------ the critical double impulse
@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_closed_form_critical_double_impulse():
    """The uniform block (0.30 x 2.0 m, 1,000 kg, alpha = 0.149) on stiff springs
    (rigid_body, k_f = 1e10 N/m), impulses as 2-ms rectangles: it survives the double
    impulse at 0.99 of the closed form V = 0.27811 m/s and overturns at 1.01 of it
    (rockjax's threshold, by bisection: +0.30 %, `docs/benchmarks_literature.md`)."""
    s = uniform_block(1.0)
    V = critical_double_impulse(s)
    g, R, a = float(s.g), float(s.R_c), float(s.alpha_c)
    eta = 1 - 1.5 * math.sin(a) ** 2  # a uniform block's eta, independently
    assert V == pytest.approx(math.sqrt(8 * g * R * (1 - math.cos(a)) / 3)
                              / ((1 + eta) * math.cos(a)), rel=1e-12)
    assert V == pytest.approx(0.27811, abs=1e-5)
    assert double_impulse_run(s, 0.99 * V)[0] == "completed"
    assert double_impulse_run(s, 1.01 * V)[0] == "overturned"


# ---------------------------------------------------- geometric similarity (collapse)
@pytest.mark.parametrize("kind", ["one_sine",
                                  pytest.param("one_cosine", marks=pytest.mark.slow)])
def test_similar_blocks_collapse_in_the_dimensionless_axes(kind):
    """Dimitrakopoulos & DeJong (2012): blocks of the same slenderness have one overturning
    spectrum in (omega_p / p, a / (g tan alpha)), whatever their size. Uniform blocks
    b/h = 0.15 of h = 0.5 and 2 m (p = 3.81 and 1.91 rad/s), one-sine pulses (one-cosine:
    slow) at omega_p / p = 2 and 6, rigid_body with k_f scaled as h^2 (the mass goes as
    h^3, so the springs, too, are similar: omega_spring / p and delta_0 / B the same):
    thresholds within 2e-3 of each other (the brackets are 1e-3 wide), at pulse periods a
    factor 2 apart."""
    x = np.array([2.0, 6.0])
    spectra = []
    for h in (0.5, 2.0):
        s = uniform_block(h, k_f=1e10 * h**2)
        spectra.append(rockjax.overturning_spectrum(s, kind, periods_at(s, kind, x),
                                                    model="rigid_body"))
    small, large = spectra
    np.testing.assert_allclose(small.x, x, rtol=1e-12)
    np.testing.assert_allclose(large.x, x, rtol=1e-12)
    np.testing.assert_allclose(large.periods / small.periods, 2.0, rtol=1e-12)
    spread = np.abs(large.normalised / small.normalised - 1)
    assert np.all(spread < 2e-3), spread
    assert small.mode == large.mode
