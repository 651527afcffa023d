"""The 2-DOF rigid body on two springs: statics, linear frequency, energy, the rigid-rocking
quadrature, the SDOF comparison and gradients (float64 finite differences)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from helpers.housner import housner_block, uniform_block
from scipy.integrate import quad, solve_ivp

import rockjax
from rockjax import FreeVibration, simulate
from rockjax.models import _twospring as T2


def _zero_crossings(ts, u):
    """Times of sign changes of u, linearly interpolated."""
    ts, u = np.asarray(ts), np.asarray(u)
    i = np.nonzero(np.sign(u[:-1]) * np.sign(u[1:]) < 0)[0]
    return ts[i] - u[i] * (ts[i + 1] - ts[i]) / (u[i + 1] - u[i])


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_static_limit_equals_pushover(column):
    """Virtual work on the 2-DOF potential against rockjax.pushover's force/moment balance."""
    u = jnp.concatenate([jnp.linspace(-0.36, -0.001, 6), jnp.linspace(0.0005, 0.36, 9)])
    P2 = T2.static_pushover(column, u)
    P = rockjax.pushover(column, u).P
    np.testing.assert_allclose(P2, P, rtol=1e-6, atol=1e-6 * float(column.P_crit))
    # as a restoring-force law the model is that pushover
    np.testing.assert_allclose(rockjax.restoring_force(column, u[:3], "two_spring_2dof"), P[:3])


def _linearised_omega(s):
    """Independent linearisation: energies of the body rotating about its base centre on
    both springs, written here in numpy, Hessians by central differences."""
    m_e, m_b, H_e, H_b, B = (float(getattr(s, k)) for k in ("m_e", "m_b", "H_e", "H_b", "B"))
    I = float(s.I_eg + s.I_bg)
    k, g = float(s.k_f), float(s.g)
    W = (m_e + m_b) * g
    y0 = -W / (2 * k)

    def V(y, th):
        yl, yr = y + B * math.sin(th), y - B * math.sin(th)
        grav = g * (m_e * (y + H_e * math.cos(th)) + m_b * (y + H_b * math.cos(th)))
        return grav + 0.5 * k * (yl**2 + yr**2)

    h = 1e-5
    K = np.zeros((2, 2))
    x0 = np.array([y0, 0.0])
    for i in range(2):
        for j in range(2):
            e_i, e_j = np.eye(2)[i] * h, np.eye(2)[j] * h
            K[i, j] = (V(*(x0 + e_i + e_j)) - V(*(x0 + e_i - e_j)) - V(*(x0 - e_i + e_j))
                       + V(*(x0 - e_i - e_j))) / (4 * h * h)
    M = np.array([[m_e + m_b, 0.0], [0.0, I + m_e * H_e**2 + m_b * H_b**2]])
    w2 = np.linalg.eigvals(np.linalg.solve(M, K))
    return np.sqrt(np.sort(w2.real))  # (rocking, vertical)


def test_small_amplitude_frequency_is_the_linearised_one(column):
    omega_rock, omega_vert = _linearised_omega(column)
    assert float(T2.linearised_frequency(column)) == pytest.approx(omega_rock, rel=1e-6)
    model = T2.TwoSpring2DOF(contact="continuous")
    ts = np.linspace(0.0, 0.6, 3001)
    res = simulate(column, FreeVibration(5e-4), 0.6, ts=ts, model=model)  # u_crit = 5.5 mm
    assert res.status_name == "completed" and int(res.n_impacts) == 0
    zc = _zero_crossings(res.ts, res.u)
    period = 2 * np.mean(np.diff(zc))
    assert 2 * np.pi / period == pytest.approx(omega_rock, rel=2e-4)
    # the SDOF pre-uplift frequency sqrt(K1 / (m_e + m_b)) differs by the rotary inertia
    sdof = float(jnp.sqrt(column.K1 / column.mass))
    assert abs(sdof / omega_rock - 1) < 0.05


def test_equations_of_motion_conserve_energy(column):
    """Lagrange's equations (autodiff) integrated by scipy on one contact state conserve
    T + V to the integration tolerance: both springs in contact, no dashpot."""
    s = column
    model = T2.TwoSpring2DOF(contact="continuous")
    q0, _, pivot, _ = T2.static_state(s, jnp.asarray(0.004))  # before lift-off
    acc = jax.jit(lambda q, qd: T2.accelerations(s, model, q, qd, 0.0, True, True, 0.0))

    def f(t, y):
        return np.concatenate([y[2:], np.asarray(acc(jnp.asarray(y[:2]), jnp.asarray(y[2:])))])

    y0 = np.concatenate([np.asarray(q0), [0.0, 0.0]])
    sol = solve_ivp(f, (0.0, 0.5), y0, method="DOP853", rtol=1e-12, atol=1e-15,
                    dense_output=True)
    E = [float(T2.energy(s, jnp.asarray(y[:2]), jnp.asarray(y[2:]), 0.0))
         for y in sol.sol(np.linspace(0, 0.5, 50)).T]
    scale = float(s.W * s.u_crit)
    assert np.max(np.abs(np.asarray(E) - E[0])) / scale < 1e-9
    assert np.min(np.asarray(sol.y[:2])) < 0 and np.max(np.asarray(sol.y[:2])) < 0  # contact


def test_pivot_switch_never_gains_energy(column):
    """The friction impulse of a pivot change is an inelastic projection: kinetic energy
    drops, by a fraction of order (delta_0 / H)^2, and the new constraint holds."""
    s = column
    q = T2.coords(s, jnp.asarray(-1e-3), jnp.asarray(0.01))
    for qd in (jnp.asarray([0.3, -0.2]), jnp.asarray([-0.1, 0.4])):
        for old, new in ((0.0, 1.0), (1.0, 0.0), (0.0, -1.0), (-1.0, 1.0)):
            T_before = float(T2.kinetic(s, q, qd, old))
            qd2 = T2.switch_pivot(s, q, qd, old, new)
            T_after = float(T2.kinetic(s, q, qd2, new))
            assert T_after <= T_before * (1 + 1e-14)
            assert T_before - T_after < 1e-3 * T_before


def _rigid_first_zero_crossing(s, u0):
    """Time for the rigid body released at rest from u0 to return to u = 0, rotating about
    a corner (energy quadrature, Housner): 1/2 I_O th'^2 = W R_c [cos(a - th0) - cos(a - th)]."""
    R_e, a_e = float(s.R_e), float(s.alpha_e)
    R_c, a_c = float(s.R_c), float(s.alpha_c)
    th0 = a_e - math.asin(math.sin(a_e) - u0 / R_e)  # u = R_e [sin a_e - sin(a_e - th)]
    W, I_O = float(s.W), float(s.I_O)

    def rate(th):
        return math.sqrt(2 * W * R_c * (math.cos(a_c - th0) - math.cos(a_c - th)) / I_O)

    # substitute th = th0 - x^2 to remove the integrable singularity at the release
    val, _ = quad(lambda x: 2 * x / rate(th0 - x * x), 0.0, math.sqrt(th0), limit=200)
    return val


@pytest.fixture(scope="module")
def release(column):
    ts = np.linspace(0.0, 0.6, 3001)
    return simulate(column, FreeVibration(0.10), 0.6, ts=ts, model="two_spring_2dof")


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_first_zero_crossing_matches_rigid_rocking(column, release):
    t_rigid = _rigid_first_zero_crossing(column, 0.10)
    t_2dof = _zero_crossings(release.ts, release.u)[0]
    assert abs(t_2dof / t_rigid - 1) < 0.01, (t_2dof, t_rigid)
    # the SDOF models, for the record (their differences are reported in the fidelity study)
    for model, tol in (("exact", 0.01), ("simplified", 0.02)):
        sd = simulate(column, FreeVibration(0.10), 0.6, ts=np.asarray(release.ts), model=model)
        assert abs(_zero_crossings(sd.ts, sd.u)[0] / t_2dof - 1) < tol


def test_release_basics(column, release):
    assert release.status_name == "completed"
    assert int(release.n_impacts) >= 1  # the lifted corner lands
    assert float(release.peak_u) == pytest.approx(0.10, rel=1e-9)
    assert np.all(np.isfinite(np.asarray(release.u)))
    assert float(release.uplift[0]) > 0.03  # the lifted corner at the release


def test_overturning_release_and_push(column):
    ts = np.linspace(0.0, 0.6, 3001)  # the release fixture's shapes: one compilation
    gone = simulate(column, FreeVibration(1.01 * float(column.u_overturn)), 0.6, ts=ts,
                    model="two_spring_2dof")
    assert gone.status_name == "overturned" and float(gone.t_overturn) == 0.0
    push = simulate(column, FreeVibration(0.25, 0.8), 0.6, ts=ts, model="two_spring_2dof")
    assert push.status_name == "overturned" and np.isfinite(float(push.t_overturn))
    assert np.all(np.isfinite(np.asarray(push.u)))


def _fd(f, x, h):
    return (-f(x + 2 * h) + 8 * f(x + h) - 8 * f(x - h) + f(x - 2 * h)) / (12 * h)


@pytest.mark.slow  # moved out of the default suite (issue 23): compile-bound; CI runs it
def test_gradients_match_finite_differences(column):
    """d/dk_f through lift-off and landing (u0 = 20 mm > u_crit), and d/dc_f of the dashpots
    on small oscillations (u0 = 3 mm: no contact change, so the dashpot never pulls and the
    clip at zero force stays inactive); fixed steps, forward mode, 5-point differences."""
    ts = jnp.linspace(0.0, 0.5, 101)

    def out(p, u0):
        model = T2.TwoSpring2DOF(damping=p[1], contact="continuous")
        res = simulate(column.replace(k_f=p[0]), FreeVibration(u0), 0.5, ts=ts, model=model,
                       dt=2e-4, adjoint="forward")
        return jnp.sum(res.u**2)

    p0 = jnp.asarray([5.5e5, 500.0])
    for j, u0, h in ((0, 0.02, 50.0), (1, 0.003, 5.0)):
        g = jax.jacfwd(out)(p0, jnp.asarray(u0))[j]
        fd = _fd(lambda x: out(p0.at[j].set(x), jnp.asarray(u0)), p0[j], h)
        np.testing.assert_allclose(g, fd, rtol=1e-6)


def test_bad_model_settings():
    with pytest.raises(ValueError, match="contact"):
        T2.TwoSpring2DOF(contact="sticky")
    with pytest.raises(ValueError, match="damping"):
        T2.TwoSpring2DOF(damping=-1.0)
    with pytest.raises(ValueError, match="damping"):
        T2.TwoSpring2DOF(damping=float("nan"))


# ------------------------------------------------ the rigid limit: Housner's rocking block
@pytest.fixture(scope="module")
def block_errors():
    """Relative errors of the 2-DOF body (impact contact) against Housner's block released
    from 0.6 alpha, over its first 5 crossings, for k_f = 1e9, 1e10, 1e11 N/m."""
    out = {}
    n, T = 5, 4.6
    ts = np.linspace(0.0, T, 46001)
    for k_f in (1e9, 1e10, 1e11):
        s = uniform_block(k_f)
        th0 = 0.6 * float(s.alpha_c)
        res = simulate(s, FreeVibration(float(rockjax.u_from_theta(s, th0))), T, ts=ts,
                       model="two_spring_2dof")
        th = np.asarray(res.theta)
        zc = _zero_crossings(ts, th)
        impacts = np.asarray(res.impact_times)
        impacts = impacts[np.isfinite(impacts)]
        t_ref, a_ref = housner_block(s, th0, n)
        edges = np.concatenate([[0.0], zc[:n]])
        amps = [np.max(np.abs(th[(ts >= lo) & (ts < hi)])) for lo, hi in zip(edges[:-1], edges[1:])]
        out[k_f] = dict(status=res.status_name, zc=zc, impacts=impacts, t_ref=t_ref,
                        t_err=np.max(np.abs(zc[:n] / t_ref - 1)),
                        a_err=np.max(np.abs(np.asarray(amps) / a_ref[:n] - 1)))
    return out


def test_one_impact_per_crossing_in_the_rigid_limit(block_errors):
    """Issue 14: a corner that hops off its spring and lands again about the same side is a
    plastic impact of that corner alone, not a second rocking impact (Eqs 2-3)."""
    for k_f, e in block_errors.items():
        assert e["status"] == "completed"
        assert len(e["zc"]) == len(e["impacts"]) == 5, (k_f, e["zc"], e["impacts"])
        # each impact is the landing just before its crossing (theta_u ~ 1e-6 rad away)
        np.testing.assert_allclose(e["impacts"], e["zc"], atol=2e-3)


def test_converges_to_housners_block(block_errors):
    """The crossing times and the amplitudes after n impacts tend to the rigid block's
    (r from Eq. 3) as k_f grows; at 1e11 N/m within 0.1 % and 0.3 %."""
    t_err = [block_errors[k]["t_err"] for k in (1e9, 1e10, 1e11)]
    a_err = [block_errors[k]["a_err"] for k in (1e9, 1e10, 1e11)]
    assert t_err[0] > t_err[1] > t_err[2], t_err
    assert a_err[0] > a_err[1] > a_err[2], a_err
    assert t_err[2] < 1e-3 and a_err[2] < 3e-3, (t_err, a_err)


def _damped_block_errors(k_f, zeta=0.05, n=6, T=5.3):
    """(crossing-time error, amplitude error) of the 2-DOF body with compression-only
    dashpots of `zeta` of critical for the vertical mode on both springs, c_f = 2 zeta
    sqrt(k_f m / 2), against Housner's block over n crossings (release from 0.6 alpha)."""
    s = uniform_block(k_f)
    c_f = 2.0 * zeta * math.sqrt(k_f * float(s.mass) / 2.0)
    th0 = 0.6 * float(s.alpha_c)
    ts = np.linspace(0.0, T, int(round(T * 1e4)) + 1)
    res = simulate(s, FreeVibration(float(rockjax.u_from_theta(s, th0))), T, ts=ts,
                   model=T2.TwoSpring2DOF(damping=jnp.asarray(c_f)))
    assert res.status_name == "completed"
    th = np.asarray(res.theta)
    zc = _zero_crossings(ts, th)[:n]
    t_ref, a_ref = housner_block(s, th0, n)
    edges = np.concatenate([[0.0], zc])
    amps = [np.max(np.abs(th[(ts >= lo) & (ts < hi)])) for lo, hi in zip(edges[:-1], edges[1:])]
    return np.max(np.abs(zc / t_ref - 1)), np.max(np.abs(np.asarray(amps) / a_ref[:n] - 1))


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_damped_body_on_housners_block():
    """Issue 27: the undamped body keeps the vertical vibration that each rocking impact
    starts (the landing corner stops on its unloaded spring and must take the weight);
    its velocity, ~g sqrt(m/k_f), meets the next impact with a changing phase, so the
    errors above fall only as k_f^-1/2 and irregularly. With 5 % dashpots it is damped
    between impacts: at k_f = 1e10 N/m, six crossings, crossing times within 5e-4 and
    amplitudes within 2e-3 of Housner's block (measured 3.0e-4 and 7.5e-4)."""
    t_err, a_err = _damped_block_errors(1e10)
    assert t_err < 5e-4 and a_err < 2e-3, (t_err, a_err)


@pytest.mark.slow  # three 5-s runs on stiff springs
def test_damped_body_converges_as_one_over_k_f():
    """With the vibration damped the error is smooth and falls as 1/k_f (measured
    2.9e-3, 3.0e-4, 3.0e-5 in time and 7.2e-3, 7.5e-4, 7.5e-5 in amplitude at 1e9,
    1e10, 1e11 N/m; `benchmarks/housner_2dof.md`)."""
    errs = np.array([_damped_block_errors(k) for k in (1e9, 1e10, 1e11)])
    ratios = errs[:-1] / errs[1:]
    assert np.all((ratios > 7) & (ratios < 13)), errs
    assert errs[2, 0] < 1e-4 and errs[2, 1] < 2e-4, errs


def test_hop_landing_is_a_plastic_impact_of_the_corner_alone(column):
    """`corner_stop`: the landing corner stops, the impulse acts at that corner only (so
    angular momentum about it is conserved), and kinetic energy is lost, not gained."""
    s = column
    q = T2.coords(s, jnp.asarray(1e-4), jnp.asarray(0.02))
    for pivot in (-1.0, 1.0):
        for i, qd in ((0, jnp.asarray([-0.05, 0.3])), (1, jnp.asarray([0.2, -0.04]))):
            qd2 = T2.corner_stop(s, q, qd, pivot, i)
            assert abs(float(qd2[i])) < 1e-15
            M = T2.mass_matrix(s, q, pivot)
            impulse = M @ (qd2 - qd)
            assert abs(float(impulse[1 - i])) < 1e-12 * abs(float(impulse[i]))
            assert float(T2.kinetic(s, q, qd2, pivot)) < float(T2.kinetic(s, q, qd, pivot))


def _lagrange_autodiff(s, model, q, qd, pivot, cl, cr, ag):
    """Lagrange's equations formed by automatic differentiation of the kinetic energy:
    M q'' = Q + dT/dq - (dp/dq) q', p = dT/dq'; the reference for the written-out ones."""
    M = jax.hessian(T2.kinetic, argnums=2)(s, q, jnp.zeros_like(q), pivot)
    dTdq = jax.grad(T2.kinetic, argnums=1)(s, q, qd, pivot)
    _, dp = jax.jvp(lambda qq: jax.grad(T2.kinetic, argnums=2)(s, qq, qd, pivot), (q,), (qd,))
    Q = -jax.grad(T2.gravity_potential, argnums=1)(s, q)
    f = -s.k_f * q - model.damping * qd
    f = jnp.where(model.damping > 0, jnp.maximum(f, 0.0), f)
    Q = Q + jnp.where(jnp.stack([cl, cr]), f, 0.0)
    Q = Q - ag * jax.grad(T2._horizontal_moment, argnums=1)(s, q, pivot, 0.0)
    return jnp.linalg.solve(M, Q + dTdq - dp), M


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_written_out_equations_match_autodiff_lagrange(column):
    """`accelerations` and `mass_matrix` (closed forms, the fast path's) against Lagrange's
    equations from autodiff of the kinetic energy, at random states, pivots, contacts,
    dashpots and ground accelerations."""
    rng = np.random.default_rng(0)
    for _ in range(40):
        q, qd = jnp.asarray(rng.normal(0, 0.05, 2)), jnp.asarray(rng.normal(0, 0.5, 2))
        pivot, ag = float(rng.choice([-1, 0, 1])), float(rng.normal(0, 3))
        model = T2.TwoSpring2DOF(damping=float(rng.choice([0.0, 800.0])))
        cl, cr = bool(rng.integers(2)), bool(rng.integers(2))
        ref, M = _lagrange_autodiff(column, model, q, qd, pivot, cl, cr, ag)
        got = T2.accelerations(column, model, q, qd, pivot, cl, cr, ag)
        np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12 * float(jnp.max(jnp.abs(ref))))
        np.testing.assert_allclose(T2.mass_matrix(column, q, pivot), M, rtol=1e-12)
