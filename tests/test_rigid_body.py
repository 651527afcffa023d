"""model="rigid_body": the body's own one-DOF rocking equation on two springs.

Checked against an independent scipy integration of the same piecewise equations (written
here in numpy, docs/rigid_body.md), its energy, its linearised frequency, Housner's rigid
block in the limit k_f -> oo (the uplift threshold g tan(alpha) and the exact overturning
pulse), every integrator and the batch, and finite differences (float64)."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import rockjax
from rockjax import FreeVibration, GroundMotion, simulate, simulate_batch
from rockjax.models import linearised_frequency
from rockjax.models._rigidbody import RigidBodyMode

N_TS = 3001  # output times of the free vibrations (one compile for all of them)


def _zero_crossings(ts, u):
    ts, u = np.asarray(ts), np.asarray(u)
    i = np.nonzero(np.sign(u[:-1]) * np.sign(u[1:]) < 0)[0]
    return ts[i] - u[i] * (ts[i + 1] - ts[i]) / (u[i + 1] - u[i])


def _impacts(res):
    t = np.asarray(res.impact_times)
    return t[np.isfinite(t)]


# ------------------------------------------------- an independent reference (numpy, scipy)
class Body:
    """The piecewise equations of docs/rigid_body.md from the structure's fields alone."""

    def __init__(self, s):
        f = {k: float(v) for k, v in s.to_dict().items()}
        self.__dict__.update(f)
        m_e, m_b, H_e, H_b, B = f["m_e"], f["m_b"], f["H_e"], f["H_b"], f["B"]
        self.M = m_e + m_b
        self.W = self.M * f["g"]
        self.Hc = (m_e * H_e + m_b * H_b) / self.M
        self.Rc, self.ac = math.hypot(B, self.Hc), math.atan2(B, self.Hc)
        self.Ic = f["I_eg"] + f["I_bg"] + m_e * H_e**2 + m_b * H_b**2
        self.Ip = f["I_eg"] + f["I_bg"] + m_e * (B**2 + H_e**2) + m_b * (B**2 + H_b**2)
        self.d0 = self.W / (2 * f["k_f"])
        self.tu = math.asin(self.d0 / B)

    def acc(self, th, w, lifted, sg, ag):
        if not lifted:
            k = 2 * self.k_f * self.B**2 * math.cos(th) - self.W * self.Hc
            return -(k * math.sin(th) + ag * self.M * self.Hc * math.cos(th)) / self.Ic
        ph = self.ac - abs(th)
        moment = sg * self.W * self.Rc * math.sin(ph) + ag * self.M * self.Rc * math.cos(ph)
        return -moment / self.Ip

    def u(self, th, lifted):
        """Top-mass displacement: the base centre held, then the corner (B cos th_u, .)."""
        if not lifted:
            return self.H_e * np.sin(th)
        a, B = np.abs(th), self.B
        return np.sign(th) * (B * math.cos(self.tu) - B * np.cos(a) + self.H_e * np.sin(a))

    def dudth(self, th, lifted):
        a = np.abs(th)
        return self.B * np.sin(a) + self.H_e * np.cos(a) if lifted else self.H_e * np.cos(th)

    def energy(self, th, w, lifted):
        """T + V [J] with V of gravity and the springs (base plane at the spring tops)."""
        if not lifted:
            return (0.5 * self.Ic * w**2 + self.W * (self.Hc * np.cos(th) - self.d0)
                    + 0.5 * self.k_f * ((self.d0 + self.B * np.sin(th)) ** 2
                                        + (self.d0 - self.B * np.sin(th)) ** 2))
        gravity = self.W * (self.Rc * np.cos(self.ac - np.abs(th)) - 2 * self.d0)
        return 0.5 * self.Ip * w**2 + gravity + 2 * self.k_f * self.d0**2


def reference(s, th0, t_end, ts, r, record=None):
    """scipy (DOP853, rtol 1e-11) from rest at th0; the record (dt, accel) linearly
    interpolated, integrated sample interval by sample interval (its kinks on the ends).
    Returns (u on ts, impact times, overturned)."""
    b = Body(s)
    if record is None:
        cuts, ag = np.array([0.0, t_end]), (lambda t: 0.0)
    else:
        dt, acc = record
        tr = dt * np.arange(len(acc))
        cuts = np.unique(np.concatenate([tr[tr < t_end], [t_end]]))
        ag = lambda t: float(np.interp(t, tr, acc, right=0.0))  # noqa: E731
    y, lifted, sg = np.array([th0, 0.0]), abs(th0) > b.tu, 1.0 if th0 >= 0 else -1.0
    u, impacts = np.full(len(ts), np.nan), []
    for lo, hi in zip(cuts[:-1], cuts[1:]):
        t = lo
        while t < hi:
            def contact(tt, yy, lifted=lifted, sg=sg):
                return sg * yy[0] - b.tu if lifted else b.tu - abs(yy[0])

            def over(tt, yy):
                return b.ac - abs(yy[0])

            contact.terminal = over.terminal = True
            contact.direction = over.direction = -1
            sol = solve_ivp(lambda tt, yy: [yy[1], b.acc(yy[0], yy[1], lifted, sg, ag(tt))],
                            (t, hi), y, method="DOP853", rtol=1e-11, atol=1e-14,
                            events=[contact, over], dense_output=True)
            t_stop = sol.t[-1]
            sel = (ts >= t) & (ts <= t_stop)
            u[sel] = b.u(sol.sol(ts[sel])[0], lifted)
            y = sol.y[:, -1].copy()
            if sol.status == 1 and len(sol.t_events[1]):
                return u, np.asarray(impacts), True
            if sol.status == 1:  # lift-off or landing
                if lifted:
                    impacts.append(t_stop)
                    y = np.array([sg * b.tu, math.sqrt(r * b.Ip / b.Ic) * y[1]])
                else:
                    sg = 1.0 if y[0] > 0 else -1.0
                    y = np.array([sg * b.tu, math.sqrt(b.Ic / b.Ip) * y[1]])
                lifted = not lifted
            t = t_stop
    return u, np.asarray(impacts), False


# ------------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def half_overturn(column):
    """Free rocking from 0.5 u_overturn for 3 s (r from Eq. 3): diffrax and the reference."""
    model = rockjax.RigidBody()
    u0 = 0.5 * float(model.u_overturn(column))
    ts = np.linspace(0.0, 3.0, N_TS)
    res = simulate(column, FreeVibration(u0), 3.0, ts=ts, model="rigid_body")
    th0 = float(rockjax.theta_from_u(column, u0))
    ref = reference(column, th0, 3.0, ts, float(column.restitution))
    return u0, res, ref


def _sine(dt=0.002, cycles=2, f=2.0, amp=4.0):
    """Two cycles of a 2 Hz sine of 4 m/s² (0.41 g; lift-off near 3.4 m/s²), then zero:
    501 samples, like the 5 s record of `quake` (one compilation for both)."""
    t = dt * np.arange(int(round(cycles / f / dt)) + 1)
    return dt, amp * np.sin(2 * np.pi * f * t)


# ------------------------------------------------------------------------------ the tests
def test_registered():
    assert rockjax.MODELS["rigid_body"] is rockjax.RigidBody
    assert isinstance(rockjax.get_model("rigid_body"), rockjax.RigidBody)
    # the SDOF impact rule does not apply: refused naming it (issue 24; it was silently
    # ignored, and the sweep plot then said "impact rule after_uplift" for landings)
    for name in ("rigid_body", "two_spring_2dof"):
        with pytest.raises(rockjax.ParameterError, match="applies to the SDOF") as e:
            rockjax.get_model(name, impact="after_uplift")
        assert e.value.param == "impact"
    assert isinstance(rockjax.get_model("rigid_body", impact="paper"), rockjax.RigidBody)
    with pytest.raises(ValueError, match="model must be one of.*'rigid_body'"):
        rockjax.get_model("rigid")


def test_moment_continuous_at_lift_off(column):
    """Both branches give W B cos(th_u) - W H_c sin(th_u) at th_u (a_g = 0)."""
    from rockjax.models._rigidbody import angular_acceleration, centre_inertia

    b = Body(column)
    expect = b.W * (b.B * math.cos(b.tu) - b.Hc * math.sin(b.tu))
    one = jnp.ones(())
    pre = -float(angular_acceleration(column, b.tu, 0.0, one, False, 0.0) * centre_inertia(column))
    post = -float(angular_acceleration(column, b.tu, 0.0, one, True, 0.0) * column.I_O)
    assert pre == pytest.approx(expect, rel=1e-12) and post == pytest.approx(expect, rel=1e-12)
    assert b.Ic == pytest.approx(float(centre_inertia(column)), rel=1e-14)
    assert b.Ip == pytest.approx(float(column.I_O), rel=1e-14)


def test_static_limit_is_the_pushover(column):
    """At rest the model's restoring moment, divided by du/dtheta, is the lateral force at
    m_e of `rockjax.pushover` (Eqs 13 and 18, the same kinematics), on both branches."""
    from rockjax.models._rigidbody import angular_acceleration, centre_inertia, lever

    u = np.array([-0.2, -0.003, 0.001, 0.0054, 0.006, 0.05, 0.2, 0.35])
    th = rockjax.theta_from_u(column, u)
    lifted = jnp.abs(th) > Body(column).tu
    sign = jnp.sign(th)
    inertia = jnp.where(lifted, column.I_O, centre_inertia(column))
    moment = -angular_acceleration(column, th, 0.0 * th, sign, lifted, 0.0) * inertia
    P = moment / lever(column, th, sign, lifted)
    np.testing.assert_allclose(P, rockjax.pushover(column, u).P, rtol=1e-12)


def test_pre_uplift_frequency_is_the_linearised_one(column):
    """Small free vibration (0.3 u_crit): the period of the centre phase is
    2 pi / linearised_frequency (the 2-DOF body's rocking mode), no lift-off, no impact."""
    ts = np.linspace(0.0, 1.0, N_TS)
    res = simulate(column, FreeVibration(0.3 * float(column.u_crit)), 1.0, ts=ts,
                   model="rigid_body")
    assert res.status_name == "completed" and int(res.n_impacts) == 0
    assert float(np.max(res.uplift)) == 0.0
    period = 2 * np.mean(np.diff(_zero_crossings(ts, res.u)))
    assert 2 * np.pi / period == pytest.approx(float(linearised_frequency(column)), rel=1e-5)


def test_free_rocking_matches_scipy_reference(half_overturn):
    u0, res, (u_ref, imp_ref, over) = half_overturn
    assert res.status_name == "completed" and not over
    assert len(imp_ref) >= 5 and int(res.n_impacts) == len(imp_ref)
    # measured: 3e-11 s and 8e-11 of u0
    np.testing.assert_allclose(_impacts(res), imp_ref, atol=1e-9)
    assert np.max(np.abs(np.asarray(res.u) - u_ref)) <= 1e-8 * u0


def test_forced_rocking_matches_scipy_reference(column):
    """Two cycles of a sine that lifts the column off, then free rocking, to 3 s."""
    dt, acc = _sine()
    ts = np.linspace(0.0, 3.0, N_TS)
    res = simulate(column, GroundMotion(dt=dt, accel=acc), 3.0, ts=ts, model="rigid_body")
    u_ref, imp_ref, over = reference(column, 0.0, 3.0, ts, float(column.restitution), (dt, acc))
    assert res.status_name == "completed" and not over
    assert len(imp_ref) >= 4 and int(res.n_impacts) == len(imp_ref)
    # measured: 5e-11 s and 1.2e-10 of the peak
    np.testing.assert_allclose(_impacts(res), imp_ref, atol=1e-9)
    peak = float(np.max(np.abs(u_ref)))
    assert peak > 3 * float(column.u_crit)
    assert np.max(np.abs(np.asarray(res.u) - u_ref)) <= 1e-8 * peak


def test_energy_is_conserved_without_impact_loss(column):
    """r = 1: the pivot switches keep the energy, so T + V (written here) is constant
    through lift-offs and landings."""
    b = Body(column)
    u0 = 0.5 * float(rockjax.RigidBody().u_overturn(column))
    ts = np.linspace(0.0, 3.0, N_TS)
    res = simulate(column, FreeVibration(u0), 3.0, ts=ts, model="rigid_body", r=1.0)
    assert int(res.n_impacts) >= 2  # r = 1: long swings
    th = np.asarray(res.theta)
    lifted = np.abs(th) > b.tu
    w = np.asarray(res.v) / np.where(lifted, b.dudth(th, True), b.dudth(th, False))
    E = np.where(lifted, b.energy(th, w, True), b.energy(th, w, False))
    E_rest = b.energy(0.0, 0.0, False)
    assert np.max(np.abs(E - E[0])) <= 1e-9 * (E[0] - E_rest)  # measured 2e-11


def test_outputs_follow_the_kinematics(column, half_overturn):
    """u, uplift are u_from_theta, uplift_from_theta of theta; the peaks agree with them."""
    u0, res, _ = half_overturn
    th = res.theta
    np.testing.assert_allclose(res.u, rockjax.u_from_theta(column, th), rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.uplift, rockjax.uplift_from_theta(column, th), atol=1e-12)
    assert float(res.peak_u) == pytest.approx(u0, rel=1e-12)
    assert float(res.peak_uplift) == pytest.approx(float(rockjax.uplift(column, u0)), rel=1e-12)
    # the overturning displacement is u_from_theta(alpha_c)
    u_ot = rockjax.RigidBody().u_overturn(column)
    assert float(u_ot) == pytest.approx(float(rockjax.u_from_theta(column, column.alpha_c)),
                                        rel=1e-14)


def test_peak_coordinate_is_theta(column):
    """The batched stepper tracks the peak |theta| of the rigid body (no sine or cosine at
    the step ends) and reports `u_of_peak` of it: |u| of the observed state in both modes,
    increasing in |theta|, and u_overturn exactly at alpha_c (the limit it clips at)."""
    m = rockjax.RigidBody()
    ac = float(column.alpha_c)
    tu = float(rockjax.theta_from_u(column, column.u_crit))
    th = np.concatenate([np.linspace(-ac, ac, 401), [tu, -tu, 0.0]])
    for lifted in (False, True):
        keep = (np.abs(th) > tu) if lifted else (np.abs(th) <= tu)
        for t in th[keep]:
            y = jnp.array([t, 0.3])
            mode = RigidBodyMode(sign=jnp.sign(t) if t else 1.0,
                                 lifted=jnp.asarray(lifted),
                                 settled=jnp.asarray(False))
            q, dq = m.peak_coordinate(column, y, mode)
            assert float(q) == t and float(dq) == 0.3
            u = float(m.observe(column, y, mode).u)
            assert float(m.u_of_peak(column, abs(float(q)))) == pytest.approx(abs(u),
                                                                             rel=1e-14, abs=1e-18)
    grid = np.linspace(0.0, ac, 2001)
    assert np.all(np.diff(np.asarray(m.u_of_peak(column, grid))) > 0)
    assert float(m.peak_limit(column)) == ac
    assert float(m.u_of_peak(column, ac)) == float(m.u_overturn(column))


def test_free_vibration_settles_on_the_springs(column):
    """Free rocking decays by r per landing; once too weak to lift off (SETTLE) it vibrates
    on both springs for good, amplitude u_crit: completed, no impacts after that."""
    ts = np.linspace(0.0, 20.0, N_TS)
    res = simulate(column, FreeVibration(0.1), 20.0, ts=ts, model="rigid_body")
    assert res.status_name == "completed"
    n = int(res.n_impacts)
    assert 10 < n < 100 and _impacts(res)[-1] < 15.0
    tail = np.abs(np.asarray(res.u)[ts > 16.0])
    uc = float(column.u_crit)
    assert tail.max() == pytest.approx(uc, rel=1e-3) and tail.max() <= uc * (1 + 1e-6)
    assert float(np.max(np.asarray(res.uplift)[ts > 16.0])) <= 1e-12
    # released at rest at exactly u_crit it starts settled: no grazing lift-off, no impact
    for u0 in (uc, -uc):
        res = simulate(column, FreeVibration(u0), 20.0, ts=ts, model="rigid_body")
        assert res.status_name == "completed" and int(res.n_impacts) == 0
        assert float(np.max(np.abs(res.u))) == pytest.approx(uc, rel=1e-9)


# --------------------------------------------------------- every integrator, the batch
@pytest.fixture(scope="module")
def quake():
    """5 s of the tests' synthetic motion (tests/conftest.py), scale 1.5."""
    rec = rockjax.datasets.synthetic_ground_motion(duration=5.0, dt=0.01, pga=3.068, seed=20)
    return GroundMotion.from_record(rec, scale=1.5)


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_every_integrator_and_the_batch_agree(column, quake):
    runs = {m: simulate(column, quake, 5.0, model="rigid_body", method=m)
            for m in ("rk4", "dopri5")}
    runs["diffrax"] = simulate(column, quake, 5.0, ts=np.linspace(0.0, 5.0, N_TS),
                               model="rigid_body")
    ref = runs["diffrax"]
    assert ref.status_name == "completed" and int(ref.n_impacts) >= 5
    assert float(ref.peak_u) > 2 * float(column.u_crit)
    for m, res in runs.items():
        assert res.status_name == ref.status_name, m
        assert int(res.n_impacts) == int(ref.n_impacts), m
        # measured: peaks within 6e-8 (rk4) and 2e-9 (dopri5), impacts within 1e-7 s
        assert float(res.peak_u) == pytest.approx(float(ref.peak_u), rel=1e-6), m
        np.testing.assert_allclose(_impacts(res), _impacts(ref), atol=1e-6)
    scales = np.array([1.5, 0.5, 3.0])
    batch = simulate_batch(column, quake, 5.0, scale=scales, model="rigid_body",
                           progress=False)
    np.testing.assert_allclose(batch.u[0], runs["rk4"].u, rtol=0, atol=1e-12)
    assert int(batch.n_impacts[0]) == int(runs["rk4"].n_impacts)
    assert float(batch.peak_u[0]) == pytest.approx(float(runs["rk4"].peak_u), rel=1e-12)


# -------------------------------------------------------------------------- gradients
def _fd5(f, x, h):
    return (-f(x + 2 * h) + 8 * f(x + h) - 8 * f(x - h) + f(x - 2 * h)) / (12 * h)


def _sine_peak(column, method, adjoint="reverse"):
    """peak |u| [m] under the sine, to 3 s, as a function of (k_f, r)."""
    dt, acc = _sine()
    gm = GroundMotion(dt=dt, accel=acc)

    def peak(p):
        res = simulate(column.replace(k_f=p[0]), gm, 3.0, ts=np.linspace(0.0, 3.0, N_TS),
                       model="rigid_body", r=p[1], method=method, adjoint=adjoint)
        return res.peak_u

    return peak


def _check_derivatives(peak, g, p0):
    """g = d(peak)/d(k_f, r) against 5-point central differences of `peak`."""
    for j, h in ((0, 50.0), (1, 1e-4)):
        fd = _fd5(lambda x: peak(p0.at[j].set(x)), p0[j], h)
        assert float(g[j]) == pytest.approx(float(fd), rel=1e-6), (j, g, fd)
    assert float(g[0]) != 0.0 and float(g[1]) != 0.0


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_forward_derivatives_match_finite_differences(column):
    """d(peak |u|)/d(k_f, r) through lift-offs and landings under the sine (diffrax,
    forward mode: `jax.jacfwd`)."""
    p0 = jnp.asarray([5.5e5, float(column.restitution)])
    g = jax.jacfwd(_sine_peak(column, "diffrax", adjoint="forward"))(p0)
    # differences of the default adjoint (the compilation of the scipy comparison)
    _check_derivatives(_sine_peak(column, "diffrax"), g, p0)


@pytest.mark.slow  # about 30 s each, compiling reverse mode through the event loop
@pytest.mark.parametrize("method", ["diffrax", "rk4"])
def test_gradients_match_finite_differences(column, method):
    """`jax.grad` (reverse mode) of the same peak, on diffrax and on the rk4 stepper."""
    peak = _sine_peak(column, method)
    p0 = jnp.asarray([5.5e5, float(column.restitution)])
    _check_derivatives(peak, jax.grad(peak)(p0), p0)


# ------------------------------------------------------- the rigid limit: Housner's block
def uniform_block(k_f, b=0.15, h=1.0, m=1000.0):
    """A uniform block 2b x 2h of mass m [kg] as two equal halves at its centroid:
    H_c = h, I_G = m (b^2 + h^2) / 3."""
    inertia = 0.5 * m * (b * b + h * h) / 3.0
    return rockjax.RockingStructure(m_e=m / 2, m_b=m / 2, H_e=h, H_b=h, B=b, I_eg=inertia,
                                    I_bg=inertia, k_f=k_f)


def test_uplift_threshold_tends_to_g_tan_alpha():
    """A constant ground acceleration, ramped in over 0.5 s: 0.99 g tan(alpha) leaves the
    stiff-spring block on both springs, 1.01 g tan(alpha) rocks it over."""
    s = uniform_block(1e10)
    b = Body(s)
    a_up = b.g * (b.B / b.Hc - math.tan(b.tu))  # the static lift-off threshold
    assert a_up == pytest.approx(b.g * math.tan(b.ac), rel=1e-4)
    n = _pulse_samples(s, 2.0)[0] + 2  # the pulses' record length: one compilation
    dt = 4.0 / (n - 1)
    ramp = np.minimum(np.arange(n) * dt / 0.5, 1.0) * b.g * math.tan(b.ac)
    below, above = (simulate(s, GroundMotion(dt=dt, accel=ramp, scale=f), t1,
                             ts=np.array([0.0, t1]), model="rigid_body")
                    for f, t1 in ((0.99, 0.8), (1.01, 4.0)))
    assert below.status_name == "completed" and int(below.n_impacts) == 0
    # quasi-static: 0.99 theta_u, no lift-off
    assert float(below.peak_u) < float(s.u_crit) and float(below.peak_uplift) == 0.0
    assert float(below.peak_u) > 0.98 * float(s.u_crit)
    assert above.status_name == "overturned" and float(above.t_overturn) < 4.0
    assert float(above.u[-1]) < 0  # a_g > 0 (ground to +x) throws the block to -x


PULSE_DT = 1e-4  # [s] the sample step of the rectangular pulses


def housner_pulse_threshold(s, n, dt=PULSE_DT):
    """The exact smallest amplitude [m/s²] of the sampled pulse (n samples of a, then 0:
    a for t <= (n-1) dt, falling linearly to 0 at n dt) that overturns Housner's rigid
    block: its nonlinear equation integrated by scipy over the pulse, then the energy
    criterion 1/2 I_P th'^2 >= W R_c (1 - cos(alpha - th)). Bisection on the amplitude."""
    b = Body(s)

    def overturns(a):
        def f(t, y):
            ag = a if t <= (n - 1) * dt else a * (n * dt - t) / dt
            ph = b.ac - y[0]
            return [y[1], (-b.W * b.Rc * math.sin(ph) + ag * b.M * b.Rc * math.cos(ph)) / b.Ip]

        y = [0.0, 0.0]
        for lo, hi in (((0.0, (n - 1) * dt)), ((n - 1) * dt, n * dt)):
            y = solve_ivp(f, (lo, hi), y, method="DOP853", rtol=1e-12, atol=1e-14).y[:, -1]
        th, w = y
        return w > 0 and 0.5 * b.Ip * w * w >= b.W * b.Rc * (1 - math.cos(b.ac - th))

    lo, hi = b.g * math.tan(b.ac), 10 * b.g * math.tan(b.ac)
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if overturns(mid) else (mid, hi)
    return hi


def _pulse_runs(s, cases, n_max, t1=6.0):
    """(overturned, n_impacts) of the rigid_body model for pulses [(n, amplitude)], each a
    record of n_max + 1 samples (one compilation)."""
    out = []
    for n, a in cases:
        acc = np.where(np.arange(n_max + 1) < n, 1.0, 0.0)
        res = simulate(s, GroundMotion(dt=PULSE_DT, accel=acc, scale=a), t1,
                       ts=np.array([0.0, t1]), model="rigid_body")
        assert res.status_name in ("overturned", "completed")
        out.append((res.status_name == "overturned", int(res.n_impacts)))
    return out


def _pulse_samples(s, pt1):
    p = math.sqrt(float(s.W * s.R_c / s.I_O))
    return int(round(pt1 / p / PULSE_DT)), p


def _model_threshold(s, n, n_max, a_ref, rel=1e-4):
    """The model's smallest overturning amplitude of the pulse, by bisection from
    a_ref +- 2 % down to `rel`."""
    lo, hi = 0.98 * a_ref, 1.02 * a_ref
    assert [o for o, _ in _pulse_runs(s, [(n, lo), (n, hi)], n_max)] == [False, True]
    while hi - lo > rel * a_ref:
        mid = 0.5 * (lo + hi)
        if _pulse_runs(s, [(n, mid)], n_max)[0][0]:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def test_rectangular_pulse_overturning_matches_housner():
    """The smallest overturning rectangular pulse, p t1 = 0.5, 1, 2: at k_f = 1e10 N/m
    within 1 % of Housner's exact value (measured -0.29, -0.37, -0.44 %), at 1e12 N/m
    within 0.1 % (-0.037 % at p t1 = 1: the difference falls as k_f^-1/2, the time spent
    on both springs); docs/rigid_body.md has the table."""
    s10, s12 = uniform_block(1e10), uniform_block(1e12)
    n_max = _pulse_samples(s10, 2.0)[0] + 1  # every record n_max + 1 samples
    g_tan = float(s10.g) * 0.15
    for pt1 in (0.5, 1.0, 2.0):
        n, p = _pulse_samples(s10, pt1)
        a_ref = housner_pulse_threshold(s10, n)
        # Housner's linearised closed form for slender blocks, a / (g tan a) = 1/(1 - e^-p t1)
        lin = 1 / (1 - math.exp(-p * (n - 0.5) * PULSE_DT))
        assert a_ref / g_tan == pytest.approx(lin, rel=1.5e-3)
        a_10 = _model_threshold(s10, n, n_max, a_ref)
        assert -1e-2 < a_10 / a_ref - 1 < 0, pt1
        if pt1 == 1.0:
            runs = _pulse_runs(s12, [(n, 0.999 * a_ref), (n, 1.001 * a_ref)], n_max)
            assert [o for o, _ in runs] == [False, True]
            assert runs[0][1] >= 1  # it fell back and rocked


def test_restoring_force_by_name_is_the_pushover(column):
    u = jnp.linspace(-0.3, 0.3, 7)
    np.testing.assert_allclose(rockjax.restoring_force(column, u, "rigid_body"),
                               rockjax.pushover(column, u).P)


def test_polynomial_sincos_is_sin_and_cos():
    """The flow's sin and cos (polynomials, vectorised under the batched stepper) agree
    with the library's to rounding over every rotation before overturning
    (|theta| <= pi/2), and closely beyond, where a step's stages may reach (|theta| <= 2);
    the derivative of one is the other."""
    from rockjax.models._rigidbody import sincos

    x = jnp.linspace(-math.pi / 2, math.pi / 2, 20001)
    s, c = sincos(x)
    np.testing.assert_allclose(s, jnp.sin(x), rtol=0, atol=4e-16)
    np.testing.assert_allclose(c, jnp.cos(x), rtol=0, atol=4e-16)
    far = jnp.linspace(-2.0, 2.0, 2001)
    np.testing.assert_allclose(sincos(far)[0], jnp.sin(far), rtol=0, atol=1e-12)
    np.testing.assert_allclose(sincos(far)[1], jnp.cos(far), rtol=0, atol=1e-12)
    assert float(jax.grad(lambda t: sincos(t)[0])(0.3)) == pytest.approx(math.cos(0.3),
                                                                        abs=1e-15)


def _economised(taylor, degree, half_width_sq):
    """Coefficients in t of the polynomial `taylor` (exact rationals in t) economised by
    Chebyshev on t in [0, half_width_sq]: written in Chebyshev polynomials of
    z = 2t/half_width_sq - 1, truncated at `degree`, and written back in t (all exact)."""
    from fractions import Fraction as F
    from math import comb

    T = half_width_sq
    n = len(taylor)
    pz = [F(0)] * n  # in z: t = T(1 + z)/2
    for k, ak in enumerate(taylor):
        for j in range(k + 1):
            pz[j] += ak * (T / 2) ** k * comb(k, j)
    ch = [F(0)] * n  # z^k = 2^(1-k) sum_j C(k, j) T_(k-2j), the T_0 term halved
    for k, c in enumerate(pz):
        for j in range(k // 2 + 1):
            w = F(comb(k, j), 2 ** (k - 1)) if k else F(1)
            ch[k - 2 * j] += c * (w / 2 if k and k == 2 * j else w)
    cheb = [[F(1)], [F(0), F(1)]]
    while len(cheb) <= degree:
        nxt = [F(0)] + [2 * c for c in cheb[-1]]
        for i, c in enumerate(cheb[-2]):
            nxt[i] -= c
        cheb.append(nxt)
    mz = [F(0)] * (degree + 1)
    for d in range(degree + 1):
        for i, c in enumerate(cheb[d]):
            mz[i] += ch[d] * c
    mt = [F(0)] * (degree + 1)  # z = 2t/T - 1
    for k, c in enumerate(mz):
        for j in range(k + 1):
            mt[j] += c * comb(k, j) * (2 / T) ** j * (-1) ** (k - j)
    return [float(c) for c in mt]


def test_sincos_coefficients_are_the_economised_taylor_series():
    """`_SIN`, `_COS` are re-derived here from their Taylor series (30 terms, exact
    rationals) economised by Chebyshev on |x| <= pi/2 at degree 8 in x²."""
    from fractions import Fraction as F
    from math import factorial

    from rockjax.models._rigidbody import _COS, _SIN

    half_pi_sq = (F(31415926535897932384626433832795028841971, 10**40) / 2) ** 2
    sin_t = [F((-1) ** k, factorial(2 * k + 1)) for k in range(30)]
    cos_t = [F((-1) ** k, factorial(2 * k)) for k in range(30)]
    assert _economised(sin_t, 8, half_pi_sq) == list(_SIN)
    assert _economised(cos_t, 8, half_pi_sq) == list(_COS)
