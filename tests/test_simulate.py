"""simulate(): conservation, statuses, Housner limit, gradients through impacts, no recompiles."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import rockjax
from rockjax import FreeVibration, GroundMotion, simulate


def energy(s, u, v):
    """Kinetic + potential energy of Eq. 1 for the simplified k(u), integrated by hand:
    V = K1 a^2 / 2 below u_crit; above, plus the integral of the Eq. 20 line."""
    a = jnp.abs(u)
    uc, uo, K1, P2 = s.u_crit, s.u_overturn, s.K1, s.P_crit2
    lin = 0.5 * K1 * jnp.minimum(a, uc) ** 2
    b = jnp.maximum(a, uc)
    line = P2 / (uc - uo) * 0.5 * ((b - uo) ** 2 - (uc - uo) ** 2)
    return 0.5 * s.mass * v**2 + lin + line


@pytest.fixture(scope="module")
def free_run(column):
    ts = jnp.linspace(0.0, 4.0, 4001)
    return simulate(column, FreeVibration(0.10), 4.0, ts=ts)


def test_free_vibration_basic(free_run, column):
    res = free_run
    assert res.status_name == "completed"
    assert 10 <= int(res.n_impacts) <= 40
    assert float(res.peak_u) == pytest.approx(0.10, rel=1e-12)
    assert np.all(np.isfinite(np.asarray(res.u)))
    imp = res.impacts
    assert np.all(np.diff(imp) > 0) and imp[0] > 0
    # the response decays: peaks between impacts shrink
    assert float(jnp.max(jnp.abs(res.u[res.ts > imp[3]]))) < 0.5 * 0.10
    # uplift and theta follow the kinematic mapping
    np.testing.assert_allclose(res.uplift, rockjax.uplift(column, res.u), atol=1e-15)


def test_report(free_run, column):
    """`Response.report` (the text of `rockjax simulate`): status, peaks, impacts and the
    residual displacement of a run that did not overturn."""
    res, model = free_run, rockjax.get_model("simplified")
    out, theta = res.summary(), res.peak_theta(column, model)
    lines = res.report(column, model).splitlines()
    assert lines == [
        "status        completed",
        f"peak |u|      {out['peak_u']:.6g} m at t = {out['t_peak']:.6g} s",
        f"peak theta    {theta:.6g} rad = {theta / float(column.alpha_c):.4g} alpha_c",
        f"peak uplift   {out['peak_uplift']:.6g} m",
        f"impacts       {out['n_impacts']}",
        f"residual u    {out['residual_u']:.6g} m at t = 4 s"]
    over = simulate(column, FreeVibration(0.99 * float(column.u_overturn), 1.0), 2.0)
    assert over.report(column, model).splitlines()[-1].startswith("t_overturn    ")


def test_to_csv(free_run, tmp_path):
    """`Response.to_csv` (`rockjax simulate --out`): t, u, v, theta, uplift of one run,
    the units in the header; a batch is refused."""
    free_run.to_csv(tmp_path / "h.csv")
    assert (tmp_path / "h.csv").read_text().splitlines()[0] == "t_s,u_m,v_m_s,theta_rad,uplift_m"
    data = np.loadtxt(tmp_path / "h.csv", delimiter=",", skiprows=1)
    assert data.shape == (4001, 5)
    for i, f in enumerate(("ts", "u", "v", "theta", "uplift")):
        np.testing.assert_allclose(data[:, i], np.asarray(getattr(free_run, f)), rtol=1e-9,
                                   atol=1e-15)
    batch = jax.tree_util.tree_map(lambda x: jnp.stack([x, x]), free_run)
    with pytest.raises(TypeError, match="one run"):
        batch.to_csv(tmp_path / "b.csv")


def test_energy_conserved_between_impacts(free_run, column):
    res = free_run
    E = np.asarray(energy(column, res.u, res.v))
    edges = np.concatenate([[0.0], res.impacts, [4.0]])
    ts = np.asarray(res.ts)
    worst = 0.0
    for a, b in zip(edges[:-1], edges[1:]):
        m = (ts > a + 1e-9) & (ts < b - 1e-9)
        if m.sum() > 2:
            seg = E[m]
            worst = max(worst, float(np.max(np.abs(seg - seg[0])) / seg[0]))
    assert worst < 1e-8, worst


def test_energy_lost_at_impacts_is_r(column):
    # just after an impact the kinetic energy is r times the one just before
    ts = jnp.linspace(0.0, 1.0, 2001)
    r = 0.6
    res = simulate(column, FreeVibration(0.10), 1.0, ts=ts, r=r)
    t_imp = res.impacts[0]
    E = np.asarray(energy(column, res.u, res.v))
    before = E[np.asarray(res.ts) < t_imp][-1]
    after = E[np.asarray(res.ts) > t_imp][0]
    assert after / before == pytest.approx(r, rel=1e-5)


def test_r_one_conserves_energy(column):
    ts = jnp.linspace(0.0, 3.0, 1501)
    res = simulate(column, FreeVibration(0.08), 3.0, ts=ts, r=1.0)
    E = np.asarray(energy(column, res.u, res.v))
    assert np.max(np.abs(E - E[0])) / E[0] < 1e-7
    assert int(res.n_impacts) >= 4


def test_r_zero_stops_at_first_impact(column):
    ts = jnp.linspace(0.0, 2.0, 401)
    res = simulate(column, FreeVibration(0.08), 2.0, ts=ts, r=0.0)
    assert int(res.n_impacts) == 1 and res.status_name == "completed"
    after = np.asarray(res.ts) > res.impacts[0]
    assert np.all(np.asarray(res.u)[after] == 0.0) and np.all(np.asarray(res.v)[after] == 0.0)


def test_overturning_release(column):
    res = simulate(column, FreeVibration(float(column.u_overturn) * 1.01), 2.0)
    assert res.status_name == "overturned" and float(res.t_overturn) == 0.0
    assert np.all(np.isfinite(np.asarray(res.u)))
    # pushed outwards near the unstable equilibrium: topples, t_overturn positive
    res = simulate(column, FreeVibration(0.9 * float(column.u_overturn), v0=0.5), 10.0)
    assert res.status_name == "overturned"
    assert 0 < float(res.t_overturn) < 10.0 and np.all(np.isfinite(np.asarray(res.u)))


def test_overturning_by_ground_motion(column):
    # a strong sine pulse overturns the column; the run stops at |u| = u_overturn
    dt = 0.01
    t = np.arange(0.0, 4.0, dt)
    accel = np.where(t < 1.0, 12.0 * np.sin(2 * np.pi * t), 0.0)
    res = simulate(column, GroundMotion(dt=dt, accel=accel), 4.0)
    assert res.status_name == "overturned"
    t_ot = float(res.t_overturn)
    assert 0 < t_ot < 4.0
    i = int(np.searchsorted(np.asarray(res.ts), t_ot))
    assert abs(float(res.u[i])) == pytest.approx(float(column.u_overturn), rel=1e-6)
    assert float(res.peak_u) == pytest.approx(float(column.u_overturn), rel=1e-9)


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_housner_limit_trend(column):
    ts = jnp.linspace(0.0, 1.5, 301)
    href = simulate(column, FreeVibration(0.10), 1.5, ts=ts, model="housner", r=0.8)
    errs = []
    for k in (1e6, 1e8, 1e10):
        res = simulate(column.replace(k_f=k), FreeVibration(0.10), 1.5, ts=ts, model="exact", r=0.8)
        errs.append(float(jnp.max(jnp.abs(res.u - href.u))))
    assert errs[0] > errs[1] > errs[2], errs
    assert errs[2] < 1e-3


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_after_uplift_rule_counts_fewer_impacts(column):
    ts = jnp.linspace(0.0, 4.0, 801)
    paper = simulate(column, FreeVibration(0.10), 4.0, ts=ts)
    phys = simulate(column, FreeVibration(0.10), 4.0, ts=ts, impact="after_uplift")
    assert int(phys.n_impacts) <= int(paper.n_impacts)
    # until the motion is back on the springs only, the two rules agree
    np.testing.assert_allclose(paper.impacts[:3], phys.impacts[:3], rtol=1e-9)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(t1=0.0), "t1"),
        (dict(t1=-1.0), "t1"),
        (dict(r=1.5), "r must lie"),
        (dict(r=-0.1), "r must lie"),
        (dict(ts=[0.0, 0.2, 0.1]), "ts must be strictly increasing"),
        (dict(ts=[0.0, 5.0]), "ts must lie within"),
        (dict(impact="sometimes"), "impact"),
        (dict(model="nope"), "model"),
        (dict(rtol=-1.0), "rtol"),
        (dict(dt=0.0), "dt"),
    ],
)
def test_bad_arguments(column, kwargs, match):
    args = dict(t1=1.0)
    args.update(kwargs)
    t1 = args.pop("t1")
    with pytest.raises(ValueError, match=match):
        simulate(column, FreeVibration(0.05), t1, **args)


def test_bad_excitation(column):
    with pytest.raises(ValueError, match="u0"):
        FreeVibration(float("nan"))
    with pytest.raises(ValueError, match="excitation"):
        simulate(column, 0.1, 1.0)
    with pytest.raises(ValueError, match="dt"):
        GroundMotion(dt=0.0, accel=np.zeros(10))


# ------------------------------------------------------------------ gradients
TS_G = jnp.linspace(0.0, 1.5, 151)


def _loss_fn(column, adjoint):
    def loss(p):
        s = column.replace(k_f=p["k_f"], H_e=p["H_e"], m_e=p["m_e"])
        res = simulate(s, FreeVibration(p["u0"]), 1.5, ts=TS_G, r=p["r"], dt=1e-3,
                       adjoint=adjoint)
        # u(ts) is continuous in time, so sum u(ts)^2 is smooth in the parameters; v(ts)
        # jumps at impacts and is not (a finite-difference check of it would be meaningless).
        return jnp.stack([jnp.sum(res.u**2), res.impact_times[0], res.impact_times[2],
                          res.peak_u])

    return loss


@pytest.fixture(scope="module")
def grad_setup(column):
    p = {"k_f": column.k_f, "H_e": column.H_e, "m_e": column.m_e, "u0": jnp.asarray(0.10),
         "r": jnp.asarray(0.7)}
    rev = jax.jit(jax.jacrev(_loss_fn(column, "reverse")))(p)
    fwd = jax.jit(jax.jacfwd(_loss_fn(column, "forward")))(p)
    f = jax.jit(_loss_fn(column, "forward"))
    return p, rev, fwd, f


@pytest.mark.slow  # moved out of the default suite (issue 23): compile-bound; CI runs it
@pytest.mark.parametrize("name", ["k_f", "H_e", "m_e", "u0", "r"])
def test_gradients_match_finite_differences(grad_setup, name):
    p, rev, fwd, f = grad_setup
    x = p[name]
    h = 3e-4 * abs(float(x))

    def at(d):
        return np.asarray(f({**p, name: x + d}))

    fd = (-at(2 * h) + 8 * at(h) - 8 * at(-h) + at(-2 * h)) / (12 * h)  # 5-point central
    g_rev = np.asarray(rev[name])
    g_fwd = np.asarray(fwd[name])
    np.testing.assert_allclose(g_rev, g_fwd, rtol=1e-10, atol=1e-300)
    # rtol 1e-10, plus the rounding floor of the stencil itself (~ eps |f| / h): it matters
    # where a parameter barely moves an output (e.g. k_f on the first impact time).
    floor = 50 * np.finfo(float).eps * np.abs(at(0.0)) / h
    err = np.abs(g_rev - fd)
    assert np.all(err <= 1e-10 * np.abs(fd) + floor), (name, g_rev, fd, err / np.abs(fd))


@pytest.mark.slow  # moved out of the default suite (issue 23): compile-bound; CI runs it
def test_gradient_ground_motion_scale(column):
    dt = 0.01
    t = np.arange(0.0, 3.0, dt)
    accel = 4.0 * np.sin(2 * np.pi * 1.5 * t) * np.exp(-t)
    gm = GroundMotion(dt=dt, accel=accel)

    def make_loss(adjoint):
        @jax.jit
        def loss(scale):
            res = simulate(column, eqx.tree_at(lambda g: g.scale, gm, scale), 3.0,
                           ts=jnp.linspace(0, 3.0, 301), dt=1e-3, adjoint=adjoint)
            return jnp.sum(res.u**2)

        return loss

    loss = make_loss("forward")
    g = float(jax.jacfwd(loss)(jnp.asarray(1.0)))
    g_rev = float(jax.grad(make_loss("reverse"))(jnp.asarray(1.0)))
    h = 1e-4
    fd = (-loss(1 + 2 * h) + 8 * loss(1 + h) - 8 * loss(1 - h) + loss(1 - 2 * h)) / (12 * h)
    floor = 50 * np.finfo(float).eps * abs(float(loss(1.0))) / h
    assert abs(g - float(fd)) <= 1e-10 * abs(float(fd)) + floor, (g, float(fd))
    assert g_rev == pytest.approx(g, rel=1e-10)
    assert g != 0.0


def test_no_recompile_on_new_values(column):
    ts = jnp.linspace(0.0, 1.0, 101)
    calls = []

    @eqx.filter_jit
    def run(s, u0, r):
        calls.append(1)  # Python side effect: runs once per trace
        return simulate(s, FreeVibration(u0), 1.0, ts=ts, r=r).peak_u

    for k, u0, r in [(5.5e5, 0.1, 0.7), (6e5, 0.05, 0.5), (1e6, 0.12, 0.9)]:
        run(column.replace(k_f=k), jnp.asarray(u0), jnp.asarray(r))
    assert len(calls) == 1
    # and the public entry point itself does not retrace for new values
    before = rockjax.integrators.solve._cached._cache_size()
    for k in (5.6e5, 5.7e5):
        simulate(column.replace(k_f=k), FreeVibration(0.1), 1.0, ts=ts)
    mid = rockjax.integrators.solve._cached._cache_size()
    simulate(column.replace(k_f=5.8e5), FreeVibration(0.09), 1.0, ts=ts, r=0.6)
    assert rockjax.integrators.solve._cached._cache_size() == mid >= before


@pytest.mark.slow  # moved out of the default suite (issue 23): compile-bound; CI runs it
def test_adaptive_gradient_on_a_record_is_sane(column, synthetic_record):
    # Regression: gradients through the adaptive step-size controller once exploded
    # (1e100) on El Centro, when steps clipped to record samples passed their start-time
    # derivative on to every later step size. Any sampled record shows it: here the
    # generated test record (El Centro's step and PGA).
    gm = GroundMotion.from_record(synthetic_record)
    ts = jnp.linspace(0.0, 8.0, 201)

    @jax.jit
    def peak(k):
        return simulate(column.replace(k_f=k), gm, 8.0, ts=ts).peak_u

    g = float(jax.grad(peak)(column.k_f))
    h = 1e-4 * float(column.k_f)
    fd = float(-peak(column.k_f + 2 * h) + 8 * peak(column.k_f + h)
               - 8 * peak(column.k_f - h) + peak(column.k_f - 2 * h)) / (12 * h)
    # adaptive steps: the finite difference itself is good to ~1e-7 here
    assert g == pytest.approx(fd, rel=1e-6)


def test_weak_typed_values_do_not_recompile(column):
    gm = GroundMotion(dt=0.01, accel=np.sin(np.arange(200) * 0.1), scale=1.0)
    before = rockjax.integrators.solve._cached._cache_size()
    simulate(column, gm, 1.0)
    mid = rockjax.integrators.solve._cached._cache_size()
    simulate(column, eqx.tree_at(lambda g: g.scale, gm, jnp.asarray(2.0)), 1.0)
    simulate(column, GroundMotion(dt=0.01, accel=gm.accel, scale=jnp.asarray(0.5)), 1.0)
    assert rockjax.integrators.solve._cached._cache_size() == mid <= before + 1
