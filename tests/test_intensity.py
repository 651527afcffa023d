"""Intensity measures (`rockjax._intensity`): PGA, PGV, PGD against a pulse whose integrals
are known, Sa(T, zeta) against the closed-form response of a linear oscillator to a
harmonic input, and the errors that name the parameter."""

import numpy as np
import pytest

from rockjax import integrate_record, pga, pgd, pgv, spectral_acceleration


def pulse(D=0.2, Tp=1.5, dt=1e-3):
    """A ground displacement pulse d = D (1 - cos(W t)) / 2 over one period Tp, W = 2 pi / Tp:
    v = D W sin(W t) / 2, a = D W^2 cos(W t) / 2; at rest at both ends."""
    W = 2 * np.pi / Tp
    t = np.arange(int(round(Tp / dt)) + 1) * dt
    return t, D * W**2 * np.cos(W * t) / 2, W


def test_peaks_of_a_pulse():
    D, Tp, dt = 0.2, 1.5, 1e-3
    t, a, W = pulse(D, Tp, dt)
    assert pga(a, dt) == pytest.approx(D * W**2 / 2, rel=1e-12)
    for baseline in ("end", None):
        # the piecewise-linear interpolant of a cosine: O(dt^2) from the exact integrals
        assert pgv(a, dt, baseline=baseline) == pytest.approx(D * W / 2, rel=1e-5)
        assert pgd(a, dt, baseline=baseline) == pytest.approx(D, rel=1e-5)


def test_baseline_correction_removes_a_constant_offset():
    t, a, _ = pulse()
    dt = t[1]
    drift = integrate_record(a + 0.05, dt, baseline=None)
    fixed = integrate_record(a + 0.05, dt)
    assert abs(drift[2][-1]) > 0.05  # an offset of 0.05 m/s^2 for 1.5 s
    assert abs(fixed[2][-1]) < 1e-12
    assert pgd(a + 0.05, dt) == pytest.approx(pgd(a, dt), rel=1e-9)


def exact_sa(A, Wi, T, zeta, t_end):
    """omega^2 max|x| of x'' + 2 zeta omega x' + omega^2 x = -A sin(Wi t) from rest, on a
    fine grid: particular plus homogeneous solution in closed form."""
    w = 2 * np.pi / T
    wd = w * np.sqrt(1 - zeta**2)
    M = np.array([[w**2 - Wi**2, -2 * zeta * w * Wi], [2 * zeta * w * Wi, w**2 - Wi**2]])
    C, Dc = np.linalg.solve(M, [-A, 0.0])
    E = -Dc
    F = (zeta * w * E - C * Wi) / wd
    t = np.linspace(0, t_end, 400_001)
    x = (C * np.sin(Wi * t) + Dc * np.cos(Wi * t)
         + np.exp(-zeta * w * t) * (E * np.cos(wd * t) + F * np.sin(wd * t)))
    return w**2 * np.max(np.abs(x))


@pytest.mark.parametrize("zeta", [0.0, 0.05, 0.2])
def test_sa_matches_the_closed_form_for_a_harmonic_input(zeta):
    A, Ti, t_end, dt = 2.0, 0.8, 6.0, 0.8 / 800
    Wi = 2 * np.pi / Ti
    a = A * np.sin(Wi * np.arange(int(round(t_end / dt)) + 1) * dt)
    periods = np.array([0.3, 0.78, 1.0, 2.5])  # (exact resonance, 0.8, is singular at zeta 0)
    sa = spectral_acceleration(a, periods, zeta=zeta, dt=dt)
    ref = np.array([exact_sa(A, Wi, T, zeta, t_end) for T in periods])
    np.testing.assert_allclose(sa, ref, rtol=2e-4)


def test_sa_limits():
    t, a, _ = pulse()
    dt = t[1]
    # a very stiff oscillator follows the ground: Sa -> PGA
    assert spectral_acceleration(a, [1e-3], dt=dt)[0] == pytest.approx(pga(a, dt), rel=1e-3)
    assert spectral_acceleration(a, [[0.5, 1.0]], dt=dt).shape == (1, 2)


@pytest.mark.parametrize("call, message", [
    (lambda: pga(np.ones(5)), "dt must be a positive"),
    (lambda: pga(np.ones((2, 3)), 0.01), "1-D array"),
    (lambda: pga(np.array([0.0, np.nan]), 0.01), "non-finite"),
    (lambda: pgv(np.ones(5), 0.01, baseline="poly"), "baseline must be"),
    (lambda: spectral_acceleration(np.ones(5), [0.0], dt=0.01), "periods must be"),
    (lambda: spectral_acceleration(np.ones(5), [1.0], zeta=1.0, dt=0.01), "zeta must"),
])
def test_bad_input_names_the_parameter(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_records_and_ground_motions():
    import rockjax

    rec = rockjax.datasets.synthetic_ground_motion(duration=5.0, dt=0.01, pga=2.0, seed=1)
    assert rockjax.pga(rec) == pytest.approx(2.0, rel=1e-9)
    gm = rockjax.GroundMotion.from_record(rec, scale=1.5)
    assert rockjax.pga(gm) == pytest.approx(3.0, rel=1e-9)
    assert rockjax.pgv(gm) == pytest.approx(1.5 * rockjax.pgv(rec), rel=1e-9)
    np.testing.assert_allclose(rockjax.spectral_acceleration(gm, [0.5, 1.0]),
                               1.5 * rockjax.spectral_acceleration(rec, [0.5, 1.0]), rtol=1e-9)
