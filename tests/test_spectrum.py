"""Pulses and overturning spectra (`rockjax.pulses`, `rockjax.overturning_spectrum`).

Checked against Housner's rigid block written here independently of rockjax: the exact
threshold of a rectangular pulse by energy quadrature (Housner 1963), his linearised closed
form, and the block's nonlinear equation with its impacts integrated by scipy for the sine
and cosine pulses. `rigid_body` at k_f = 1e10 N/m is the rigid limit (within 1 %).
"""

from __future__ import annotations

import json
import math

import jax.numpy as jnp
import numpy as np
import pytest
from scipy.integrate import quad, solve_ivp
from scipy.optimize import brentq

import rockjax
from rockjax.integrators._hermite import hermite, hermite_root

G = 9.80665


def uniform_block(k_f, b=0.15, h=1.0, m=1000.0):
    """A uniform block 2b x 2h [m] of mass m [kg] as two halves at its centroid."""
    inertia = 0.5 * m * (b * b + h * h) / 3.0
    return rockjax.RockingStructure(m_e=m / 2, m_b=m / 2, H_e=h, H_b=h, B=b, I_eg=inertia,
                                    I_bg=inertia, k_f=k_f)


def frequency_parameter(s):
    """p = sqrt(W R / I_O) [rad/s] and g tan(alpha) [m/s²] of a structure."""
    return math.sqrt(float(s.W * s.R_c / s.I_O)), float(s.g * s.B / s.H_c)


# ----------------------------------------------------------- Housner's block, independently
class Block:
    """Housner's rigid block (W R_c, I_O about a corner, slenderness alpha), from a
    structure's fields, with Housner's restitution of angular velocity eta = sqrt(r)."""

    def __init__(self, s):
        self.M = float(s.m_e + s.m_b)
        self.g = float(s.g)
        self.W = self.M * self.g
        self.Hc = float(s.m_e * s.H_e + s.m_b * s.H_b) / self.M
        self.R = math.hypot(float(s.B), self.Hc)
        self.alpha = math.atan2(float(s.B), self.Hc)
        self.I = float(s.I_O)
        self.eta = math.sqrt(float(s.restitution))

    # rectangular pulse: energy quadrature ------------------------------------------------
    def _F(self, a, th):
        """1/2 I th'^2 on the pulse [J]: the work of the pulse and of gravity from rest,
        M a R (sin al - sin(al - th)) - W R (cos(al - th) - cos al), written without
        cancellation: 2 R sin(th/2) [M a cos(al - th/2) - W sin(al - th/2)]."""
        return 2 * self.R * math.sin(th / 2) * self._bracket(a, th)

    def _bracket(self, a, th):
        al = self.alpha
        return self.M * a * math.cos(al - th / 2) - self.W * math.sin(al - th / 2)

    def _time_to(self, a, th):
        """t(theta) = int_0^theta d th / th'(th) [s], with th = phi^2 (no singularity):
        d th / th' = 2 phi d phi / sqrt(2 F / I) = 2 d phi / sqrt(2 (F / phi^2) / I)."""
        def f(phi):
            x = phi * phi
            half = math.sin(x / 2) / x if x > 1e-12 else 0.5  # sin(th/2) / th
            return 2 / math.sqrt(4 * self.R * half * self._bracket(a, x) / self.I)
        return quad(f, 0.0, math.sqrt(th), epsabs=1e-13, epsrel=1e-12, limit=200)[0]

    def overturns_rectangular(self, a, t1):
        """Whether a pulse a [m/s²] for t1 [s] overturns the block: the rotation at t1 by
        the quadrature, then the energy criterion 1/2 I th'^2 >= W R (1 - cos(alpha - th))
        (after the pulse energy is conserved until the block falls back)."""
        if a <= self.g * math.tan(self.alpha):
            return False
        top = 0.999999 * self.alpha
        if self._time_to(a, top) <= t1:
            return True
        th1 = brentq(lambda th: self._time_to(a, th) - t1, 1e-14, top, xtol=1e-15)
        return self._F(a, th1) >= self.W * self.R * (1 - math.cos(self.alpha - th1))

    def rectangular_threshold(self, t1, rel=1e-7):
        lo, hi = self.g * math.tan(self.alpha), 20 * self.g * math.tan(self.alpha)
        while hi / lo - 1 > rel:
            mid = math.sqrt(lo * hi)
            lo, hi = (lo, mid) if self.overturns_rectangular(mid, t1) else (mid, hi)
        return math.sqrt(lo * hi)

    # any pulse: the equation with impacts -----------------------------------------------
    def run(self, ag, t_start, t_end, max_impacts=200):
        """(overturned, impacts): the block from rest under ground acceleration ag(t)
        [m/s²] (positive throws it to -theta), uplifting at t_start [s]."""
        p2 = self.W * self.R / self.I
        al = self.alpha

        def f(t, y):
            sg = 1.0 if y[0] > 0 else -1.0
            return [y[1], -p2 * (sg * math.sin(al - sg * y[0])
                                 + ag(t) / self.g * math.cos(al - sg * y[0]))]

        def cross(t, y):
            return y[0]
        cross.terminal = True

        def over(t, y):
            return abs(y[0]) - al
        over.terminal = True
        sign = -math.copysign(1.0, ag(t_start))
        y, t, n = [sign * 1e-13, 0.0], t_start, 0
        while t < t_end and n <= max_impacts:
            sol = solve_ivp(f, (t, t_end), y, method="DOP853", rtol=1e-11, atol=1e-13,
                            events=[cross, over], max_step=0.01)
            if sol.t_events[1].size:
                return True, n
            if not sol.t_events[0].size:
                return False, n
            t, w = sol.t_events[0][0], sol.y_events[0][0][1]
            n += 1
            y = [math.copysign(1e-13, w), self.eta * w]  # Housner's impact
        return False, n

    def overturns_pulse(self, kind, a, T, t_end):
        """(overturned, impacts) under a one-sine or one-cosine pulse of amplitude a
        [m/s²], period T [s]: at rest until |ag| first exceeds g tan(alpha)."""
        w = 2 * math.pi / T
        shape = math.sin if kind == "one_sine" else math.cos

        def ag(t):
            return a * shape(w * t) if 0 <= t <= T else 0.0
        ts = np.linspace(0, T, 400001)
        above = np.abs(a * np.vectorize(shape)(w * ts)) > self.g * math.tan(self.alpha)
        if not above.any():
            return False, 0
        return self.run(ag, ts[np.argmax(above)], t_end)


# ------------------------------------------------------------------------------- pulses
def test_rectangular_pulse_is_exact():
    g = rockjax.pulses.rectangular(2.5, 0.3, steps=7)
    t = np.array([0.0, 0.1, 0.3 - 1e-12, 0.3, 0.3 + 1e-9, 0.5])
    np.testing.assert_allclose(g.ground_acceleration(jnp.asarray(t)),
                               [2.5, 2.5, 2.5, 2.5, 0.0, 0.0], rtol=0, atol=1e-12)
    # its ground velocity is a t (PGV = a t1 exactly)
    assert float(rockjax.pgv(g, baseline=None)) == pytest.approx(2.5 * 0.3, rel=1e-13)


@pytest.mark.parametrize("kind", ["one_sine", "one_cosine"])
def test_sine_and_cosine_pulses_have_exact_impulses(kind):
    """The linear interpolant's impulse over every sample interval is the pulse's: the
    ground velocity at every sample is exact; the acceleration is within (h w)^2/12."""
    a, T, n = 3.0, 0.8, 32
    g = rockjax.pulses.pulse(kind, a, T, steps=n)
    assert float(g.dt) == pytest.approx(T / n, rel=1e-15)
    acc = np.asarray(g.accel) * a
    vel = np.concatenate([[0.0], np.cumsum(0.5 * (acc[1:] + acc[:-1]) * float(g.dt))])
    t = np.arange(n + 1) * T / n
    w = 2 * np.pi / T
    exact = a / w * ((1 - np.cos(w * t)) if kind == "one_sine" else np.sin(w * t))
    np.testing.assert_allclose(vel, exact, rtol=0, atol=1e-13 * a * T)
    tt = np.linspace(0, T, 1001)
    shape = np.sin(w * tt) if kind == "one_sine" else np.cos(w * tt)
    err = np.max(np.abs(np.asarray(g.ground_acceleration(jnp.asarray(tt))) - a * shape))
    assert err <= a * (w * T / n) ** 2 / 12 * 1.01
    assert float(g.ground_acceleration(jnp.asarray(T + 1e-9))) == 0.0


def test_pulse_defaults_and_bad_input():
    g = rockjax.pulses.one_sine(1.0, 2.0)
    assert g.accel.shape[-1] == 401  # 2 s at most 5 ms per step
    assert rockjax.pulses.one_cosine(1.0, 0.1).accel.shape[-1] == 129  # at least 128 steps
    assert rockjax.pulses.rectangular(1.0, 0.0123).accel.shape[-1] == 4
    for call, name in [(lambda: rockjax.pulses.one_sine(1.0, -1.0), "period"),
                       (lambda: rockjax.pulses.rectangular(1.0, 0.0), "duration"),
                       (lambda: rockjax.pulses.one_sine(float("nan"), 1.0), "amplitude"),
                       (lambda: rockjax.pulses.one_sine(1.0, 1.0, steps=4), "steps"),
                       (lambda: rockjax.pulses.pulse("square", 1.0, 1.0), "kind")]:
        with pytest.raises(ValueError, match=name):
            call()


# ------------------------------------------------------ the stepper after a landing (fix)
def test_hermite_root_of_a_condition_leaving_its_surface():
    """A condition at 0 at the step's start (right after a jump), rising, then falling
    below 0: the root is where it comes back, not the start (which repeated the jump)."""
    a0, m0, a1, m1 = 0.0, 3.0, -1.0, -4.0
    s = float(hermite_root(a0, m0, a1, m1))
    assert s > 0.3
    assert abs(float(hermite(a0, m0, a1, m1, s)[0])) < 1e-12
    roots = np.roots([2 * a0 + m0 - 2 * a1 + m1, -3 * a0 - 2 * m0 + 3 * a1 - m1, m0, a0])
    later = [r.real for r in roots if abs(r.imag) < 1e-12 and 1e-9 < r.real <= 1]
    assert s == pytest.approx(min(later), abs=1e-12)
    # the ordinary bracket a0 > 0 > a1 is unchanged
    assert float(hermite_root(1.0, -1.0, -1.0, -1.0)) == pytest.approx(0.5, abs=1e-12)


@pytest.fixture(scope="module")
def stiff_block():
    return uniform_block(1e10)


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_rk4_rigid_body_crosses_the_springs_after_a_landing(stiff_block):
    """Regression: on stiff springs a landing and the lift-off on the other side share a
    substep; rk4 used to find the landing condition's root at the landing itself, landing
    again and again (hundreds of impacts at one instant) instead of rocking over."""
    s = stiff_block
    p, gta = frequency_parameter(s)
    T = 2 * math.pi / (6.0 * p)
    g = rockjax.pulses.one_sine(5.0 * gta, T)
    ts = np.array([0.0, 4.0])
    rk4 = rockjax.simulate(s, g, 4.0, ts=ts, model="rigid_body", method="rk4")
    dfx = rockjax.simulate(s, g, 4.0, ts=ts, model="rigid_body")
    ref = Block(s).overturns_pulse("one_sine", 5.0 * gta, T, 4.0)
    assert ref == (True, 1)
    for res in (rk4, dfx):
        assert (res.status_name, int(res.n_impacts)) == ("overturned", 1)
    assert float(rk4.t_overturn) == pytest.approx(float(dfx.t_overturn), rel=1e-3)


# -------------------------------------------------------------------- overturning spectra
PT1 = (0.5, 1.0, 2.0)


@pytest.fixture(scope="module")
def rectangular_spectrum(stiff_block):
    p, _ = frequency_parameter(stiff_block)
    return rockjax.overturning_spectrum(stiff_block, "rectangular", np.asarray(PT1) / p)


def test_rectangular_spectrum_matches_housner(stiff_block, rectangular_spectrum):
    """p t1 = 0.5, 1, 2: rigid_body at k_f = 1e10 N/m within 1 % of Housner's exact
    threshold (energy quadrature; measured -0.29, -0.37, -0.43 %, and -0.03 to -0.05 %
    at 1e12 N/m: the time on the springs), which is within 0.2 % of his linearised
    1 / (1 - exp(-p t1)) (+0.10, +0.01, -0.04 %)."""
    sp = rectangular_spectrum
    p, gta = frequency_parameter(stiff_block)
    block = Block(stiff_block)
    assert sp.p == pytest.approx(p) and sp.g_tan_alpha == pytest.approx(gta)
    np.testing.assert_allclose(sp.x, PT1, rtol=1e-12)
    for i, pt1 in enumerate(PT1):
        exact = block.rectangular_threshold(pt1 / p)
        assert exact / gta == pytest.approx(1 / (1 - math.exp(-pt1)), rel=2e-3)
        assert abs(sp.amplitude[i] / exact - 1) < 1e-2, (pt1, sp.amplitude[i] / exact - 1)
        assert sp.mode[i] == "no impact"
        lo, hi = sp.bracket[i]
        assert lo < sp.amplitude[i] < hi and hi / lo - 1 <= 1e-3
    assert sp.n_failed == 0


@pytest.mark.parametrize("kind", ["one_sine", "one_cosine"])
def test_pulse_spectrum_matches_the_rigid_block(stiff_block, kind):
    """omega_p / p = 2 and 6: rigid_body at k_f = 1e10 N/m against Housner's block with
    its impacts (scipy): the block survives 0.99 and 0.9 of the threshold and overturns at
    1.01 of it, in the same mode (after an impact or without)."""
    p, gta = frequency_parameter(stiff_block)
    x = np.array([2.0, 6.0])
    T = 2 * np.pi / (p * x)
    sp = rockjax.overturning_spectrum(stiff_block, kind, T)
    block = Block(stiff_block)
    for i in range(2):
        a, t_end = sp.amplitude[i], T[i] + 20 / p
        over, n = block.overturns_pulse(kind, 1.01 * a, T[i], t_end)
        assert over and (n > 0) == (sp.mode[i] == "after impact"), (kind, x[i], n, sp.mode[i])
        for f in (0.99, 0.9):
            assert not block.overturns_pulse(kind, f * a, T[i], t_end)[0], (kind, x[i], f)
        assert sp.amplitude_no_impact[i] >= sp.amplitude[i] * (1 - 1e-3)


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_spectrum_runs_are_the_single_runs(column):
    """The Table 1 column (flexible springs), one-cosine pulses: the batched runs (each
    period on its own grid) agree with `simulate` of `rockjax.pulses.one_cosine` on the
    same grid: survives at the bracket's low end, overturns at its high end."""
    p, gta = frequency_parameter(column)
    T = np.array([0.3, 1.5])
    sp = rockjax.overturning_spectrum(column, "cosine", T, rtol=1e-2)
    assert sp.kind == "one_cosine" and sp.model == "rigid_body"
    for i in range(2):
        for a, status in zip(sp.bracket[i], ("completed", "overturned")):
            g = rockjax.pulses.one_cosine(a, T[i], max_dt=float(sp.dt[i]))
            assert float(g.dt) == pytest.approx(float(sp.dt[i]), rel=1e-12)
            res = rockjax.simulate(column, g, float(sp.t_end[i]), model="rigid_body",
                                   method="rk4", ts=np.array([0.0, float(sp.t_end[i])]))
            assert res.status_name == status, (T[i], a)
    d = json.loads(json.dumps(sp.to_dict()))
    assert d["kind"] == "one_cosine" and len(d["amplitude_m_s2"]) == 2
    assert d["x_label"] == "omega_p / p"


def test_spectrum_plot(rectangular_spectrum, tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    ax = rectangular_spectrum.plot()
    assert ax.get_xlabel() == "$p\\,t_1$"
    line = ax.get_lines()[0]
    np.testing.assert_allclose(line.get_ydata(), rectangular_spectrum.normalised)
    ax.figure.savefig(tmp_path / "s.png")
    assert (tmp_path / "s.png").stat().st_size > 1000


def test_spectrum_report():
    """`OverturningSpectrum.report` (the text of `rockjax spectrum`): the model line, one
    row per period in increasing order, the runs, and a note where nothing overturned."""
    nan = float("nan")
    sp = rockjax.OverturningSpectrum(
        kind="one_sine", model="simplified", periods=np.array([1.0, 0.5]),
        amplitude=np.array([nan, 3.0]), bracket=np.array([[nan, nan], [2.9, 3.1]]),
        mode=("none", "after impact"), amplitude_no_impact=np.array([nan, 4.0]),
        bracket_no_impact=np.array([[nan, nan], [3.9, 4.1]]), p=2.0, g_tan_alpha=2.5,
        rtol=1e-3, dt=np.array([0.01, 0.005]), t_end=np.array([11.0, 10.5]), n_runs=96,
        n_failed=2, wall_time=1.234, impact="after_uplift", r=0.8)
    lines = sp.report().splitlines()
    assert lines[:2] == [
        "overturning spectrum, one_sine pulse (simplified model, impact rule after_uplift, r 0.8)",
        "p = 2 rad/s, g tan(alpha) = 2.5 m/s2, rtol 0.001"]
    assert lines[2].split() == ["period", "[s]", "wp/p", "a", "[m/s2]", "a/(g", "tan", "a)",
                                "mode", "no", "impact", "[m/s2]"]
    assert lines[3].split() == ["0.5", "6.283", "3", "1.2000", "after", "impact", "4"]
    assert lines[4].split() == ["1", "3.142", "nan", "nan", "none", "nan"]
    assert lines[5:] == ["96 runs in 1.23 s; 2 failed runs (max_impacts, solver_failure) "
                         "counted as survivors", "nan: nothing overturned up to 1000 g tan(alpha)"]


def test_periods_at_inverts_the_abscissa(column):
    """`periods_at` (`rockjax spectrum --ratios`): the periods whose `OverturningSpectrum.x`
    are the ratios given, for each kind of pulse."""
    from rockjax._spectrum import periods_at

    p = rockjax._spectrum.frequency_parameter(column)
    x = np.array([0.5, 2.0, 8.0])
    np.testing.assert_allclose(p * periods_at(column, "rectangular", x), x, rtol=1e-14)
    for kind in ("sine", "one_cosine"):
        np.testing.assert_allclose(2 * np.pi / (p * periods_at(column, kind, x)), x, rtol=1e-14)


def test_spectrum_bad_input(column):
    bad = [
        (dict(kind="square"), "kind"),
        (dict(periods=[]), "periods"),
        (dict(periods=[1.0, -2.0]), "periods"),
        (dict(periods=[[1.0]]), "periods"),
        (dict(rtol=0.5), "rtol"),
        (dict(n_scan=3), "n_scan"),
        (dict(t_free=-1.0), "t_free"),
        (dict(structure=column.replace(k_f=np.array([1e6, 2e6]))), "one structure"),
        (dict(model="no_such_model"), "model"),
    ]
    for change, name in bad:
        kw = dict(structure=column, kind="sine", periods=[1.0])
        kw.update(change)
        with pytest.raises(ValueError, match=name):
            rockjax.overturning_spectrum(kw.pop("structure"), kw.pop("kind"), kw.pop("periods"),
                                         **kw)


# ------------------------------------------------------------------------------------ CLI
def _cli(*args, fail=False):
    from conftest import run_cli

    proc = run_cli("spectrum", *args)
    assert (proc.returncode != 0) == fail, proc.stderr[-2000:]
    return proc.stdout if not fail else proc.stderr


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes); CI runs it
def test_cli_spectrum_json_plot_csv(tmp_path):
    d = json.loads(_cli("--pulse", "rectangular", "--ratios", "1,2", "--plot",
                        str(tmp_path / "s.png"), "--out", str(tmp_path / "s.csv"), "--json"))
    assert d["kind"] == "rectangular" and d["model_info"]["model"] == "rigid_body"
    np.testing.assert_allclose(d["x"], [1.0, 2.0], rtol=1e-9)
    # a longer pulse overturns at a lower amplitude, as Housner's 1 / (1 - e^-p t1)
    assert d["normalised"][0] > d["normalised"][1] > 0.5
    assert (tmp_path / "s.png").stat().st_size > 1000
    rows = np.loadtxt(tmp_path / "s.csv", delimiter=",", skiprows=1)
    np.testing.assert_allclose(rows[:, 2], d["amplitude_m_s2"], rtol=1e-9)
    text = _cli("--pulse", "sine", "--periods", "0.5")
    assert "overturning spectrum, one_sine pulse" in text and "a/(g tan a)" in text
    assert "--pulse" in _cli("--help")


def test_cli_spectrum_errors():
    for args, msg in [(("--pulse", "sine"), "--periods"),
                      (("--pulse", "sine", "--periods", "1,-1"), "--periods"),
                      (("--pulse", "sine", "--ratios", "1", "--rtol", "2"), "--rtol"),
                      (("--pulse", "square", "--periods", "1"), "--pulse")]:
        err = _cli(*args, fail=True)
        assert msg in err, (args, err)


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_simulate_batch_records_on_their_own_steps():
    """`simulate_batch(record_steps="own")` (the spectrum's engine): pulses of unrelated
    sample steps in one batch, each run on its own pulse's grid, give the summaries of the
    same pulse run alone (its grid is the common one then), bit for bit in the status and
    impacts; the mode is refused where it does not apply."""
    s = rockjax.mcmanus_column()
    pulses = [rockjax.pulses.one_sine(1.0, 0.3, steps=30), rockjax.pulses.one_sine(1.0, 0.7,
                                                                                    steps=50)]
    assert pulses[0].dt != pulses[1].dt
    amp = np.array([2.0, 6.0, 2.0, 6.0])
    rec = np.array([0, 0, 1, 1])
    out = rockjax.simulate_batch(s, pulses, record=rec, scale=amp, tail=0.5, model="rigid_body",
                                 summary_only=True, record_steps="own")
    for k in range(4):
        one = rockjax.simulate_batch(s, [pulses[rec[k]]], scale=amp[k], tail=0.5,
                                     model="rigid_body", summary_only=True)
        assert int(out.status[k]) == int(one.status[0])
        assert int(out.n_impacts[k]) == int(one.n_impacts[0])
        np.testing.assert_allclose(out.peak_u[k], one.peak_u[0], rtol=1e-9)
        np.testing.assert_allclose(out.t_end[k], one.t_end[0], rtol=1e-12)
    with pytest.raises(ValueError, match="summaries only"):
        rockjax.simulate_batch(s, pulses, record_steps="own")
    with pytest.raises(ValueError, match="record_steps must be"):
        rockjax.simulate_batch(s, pulses[0], 1.0, record_steps="own", summary_only=True)


def test_runner_of_a_model_without_springs():
    """`housner` has no springs (frequency 0): its pulses are sampled at the pulses' own
    limit, not at a step divided by that zero (a ZeroDivisionError before)."""
    from rockjax import _spectrum, pulses

    runner = _spectrum._runner(rockjax.mcmanus_column(), "housner", "paper", "one_cosine",
                               np.array([0.5, 1.0]), 1.0, 4, None, 8, None)
    assert np.all(runner.dt <= pulses.MAX_DT) and np.all(runner.dt > 0)
