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
from scipy.integrate import solve_ivp

import rockjax
from rockjax import simulate
from rockjax._spectrum import frequency_parameter

PT1 = np.array([0.5, 1.0, 2.0])


def linearised_threshold(pt1):
    """Housner's linearised rectangular-pulse threshold a/(g tan alpha)."""
    return 1.0 / (1.0 - np.exp(-np.asarray(pt1)))


def point_mass_block(alpha, h=1.0, m=1000.0, k_f=1e10):
    """A block whose mass sits at its centroid (height h [m], slenderness alpha): for it
    the `housner` SDOF (inertia m about the top mass) linearises to Housner's equation
    theta'' = p^2 (theta - alpha + a/g) with p^2 = g/R = W R / I_O."""
    return rockjax.RockingStructure(m_e=m / 2, m_b=m / 2, H_e=h, H_b=h, B=h * math.tan(alpha),
                                    I_eg=0.0, I_bg=0.0, k_f=k_f)


def uniform_block(h, k_f=1e10, ratio=0.15, rho=1000.0):
    """A uniform block 2b x 2h [m] (b = ratio h) of density rho [kg/m^2 per unit depth],
    as two equal halves at its centroid."""
    b = ratio * h
    m = rho * 4 * b * h
    inertia = 0.5 * m * (b * b + h * h) / 3.0
    return rockjax.RockingStructure(m_e=m / 2, m_b=m / 2, H_e=h, H_b=h, B=b, I_eg=inertia,
                                    I_bg=inertia, k_f=k_f)


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
