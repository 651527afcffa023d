"""The fast path (method "rk4" / "dopri5") and simulate_batch: accuracy against the scipy
reference, convergence order, batch == single run, chunking, sharding, gradients, errors,
and batches over records of different time steps and lengths.

The ground motions are synthetic (`rockjax.datasets.synthetic_ground_motion`): the file
runs without the shared records. One test reads the real records (mixed time steps)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from test_records import synthetic
from test_reference_scipy import reference_simulate

import rockjax
from rockjax import FreeVibration, GroundMotion, simulate, simulate_batch

T_EQ = 10.0  # length of the synthetic record of these tests [s]


def _fields(s):
    return {k: float(v) for k, v in s.to_dict().items()}


@pytest.fixture(scope="module")
def record():
    """A synthetic 10-s record at 0.01 s with El Centro's PGA (3.07 m/s²): the Table 1
    column rocks at x0.3-1.4 and overturns at x2.0 (seed 1 was chosen for that)."""
    rec = synthetic(seed=1, dt=0.01, duration=T_EQ, pga=3.07)
    return rec.dt, np.asarray(rec.accel)


@pytest.fixture(scope="module")
def gm(record):
    dt, accel = record
    return GroundMotion(dt=dt, accel=accel)


@pytest.fixture(scope="module")
def eq_reference(column, record):
    dt, accel = record
    return reference_simulate(_fields(column), T_EQ, dt=dt, accel=accel)


@pytest.fixture(scope="module")
def free_reference(column):
    return reference_simulate(_fields(column), 4.0, u0=0.10)


# ----------------------------------------------------------------------------- accuracy


def test_rk4_free_vibration_matches_scipy(column, free_reference):
    res = simulate(column, FreeVibration(0.10), 4.0, method="rk4")  # dt = 1 ms
    ref = free_reference
    assert res.status_name == "completed"
    assert int(res.n_impacts) == ref.n_impacts
    np.testing.assert_allclose(res.impacts, ref.impacts, atol=1e-9)
    assert float(np.max(np.abs(np.asarray(res.u) - ref.u_at(np.asarray(res.ts))))) < 1e-9


def test_dopri5_free_vibration_matches_scipy(column, free_reference):
    res = simulate(column, FreeVibration(0.10), 4.0, method="dopri5", rtol=1e-10, atol=1e-12)
    ref = free_reference
    assert int(res.n_impacts) == ref.n_impacts
    np.testing.assert_allclose(res.impacts, ref.impacts, atol=1e-9)
    assert float(np.max(np.abs(np.asarray(res.u) - ref.u_at(np.asarray(res.ts))))) < 1e-9


@pytest.mark.parametrize("substeps, tol", [(1, 1e-4), (2, 1e-5)])
def test_rk4_record_peak_and_impacts(column, gm, eq_reference, substeps, tol):
    res = simulate(column, gm, T_EQ, method="rk4", substeps=substeps)
    ref = eq_reference
    assert int(res.n_impacts) == ref.n_impacts
    assert abs(float(res.peak_u) / ref.peak_u - 1) < tol
    np.testing.assert_allclose(res.impacts, ref.impacts, atol=1e-4 / substeps**2)


def test_rk4_converges_at_fourth_order(column, gm, eq_reference):
    """Events located inside the step keep RK4's order although k(u) has kinks and jumps
    (stepping over them blindly would give first or second order)."""
    ref_u = eq_reference.u_at(np.arange(int(round(T_EQ / 0.01)) + 1) * 0.01)
    errs = []
    for n in (2, 4, 8):
        res = simulate(column, gm, T_EQ, method="rk4", substeps=n)
        errs.append(float(np.max(np.abs(np.asarray(res.u) - ref_u))))
    rates = np.log2(np.asarray(errs[:-1]) / np.asarray(errs[1:]))
    assert np.all(rates > 3.3), (errs, rates)


def test_dopri5_record_at_tolerance(column, gm, eq_reference):
    res = simulate(column, gm, T_EQ, method="dopri5", rtol=1e-10, atol=1e-12)
    assert int(res.n_impacts) == eq_reference.n_impacts
    assert abs(float(res.peak_u) / eq_reference.peak_u - 1) < 1e-8


def test_overturning_and_rest(column, gm):
    big = simulate(column, GroundMotion(dt=gm.dt, accel=gm.accel, scale=2.0), T_EQ, method="rk4",
                   substeps=2)
    ref = simulate(column, GroundMotion(dt=gm.dt, accel=gm.accel, scale=2.0), T_EQ)
    assert big.status_name == ref.status_name == "overturned"
    assert float(big.t_overturn) == pytest.approx(float(ref.t_overturn), abs=1e-4)
    assert np.all(np.isfinite(np.asarray(big.u)))
    assert float(big.peak_u) == pytest.approx(float(column.u_overturn), rel=1e-12)
    # r = 0: the first impact stops a free vibration for good
    dead = simulate(column, FreeVibration(0.10), 2.0, r=0.0, method="rk4")
    assert int(dead.n_impacts) == 1 and dead.status_name == "completed"
    after = np.asarray(dead.ts) > float(dead.impacts[0]) + 1e-3
    assert np.all(np.asarray(dead.u)[after] == 0.0)
    # a release beyond u_overturn is an immediate overturned status, not an error
    gone = simulate(column, FreeVibration(1.01 * float(column.u_overturn)), 1.0, method="rk4")
    assert gone.status_name == "overturned" and float(gone.t_overturn) == 0.0


def test_max_impacts_status(column):
    res = simulate(column, FreeVibration(0.10), 4.0, method="rk4", max_impacts=5)
    assert res.status_name == "max_impacts" and int(res.n_impacts) == 5


@pytest.mark.parametrize("model", ["exact", "smooth", "housner"])
def test_other_models_match_diffrax(column, model):
    ref = simulate(column, FreeVibration(0.10), 2.0, model=model)
    res = simulate(column, FreeVibration(0.10), 2.0, model=model, method="rk4")
    assert int(res.n_impacts) == int(ref.n_impacts)
    assert float(jnp.max(jnp.abs(res.u - ref.u))) < 1e-7
    np.testing.assert_allclose(res.impacts, ref.impacts, atol=1e-7)


def test_float32_runs_and_stays_close(column, gm):
    s32 = column.astype(jnp.float32)
    gm32 = GroundMotion(dt=jnp.float32(gm.dt), accel=jnp.asarray(gm.accel, jnp.float32))
    r32 = simulate(s32, gm32, T_EQ, method="rk4", substeps=2)
    r64 = simulate(column, gm, T_EQ, method="rk4", substeps=2)
    assert r32.u.dtype == jnp.float32 and r32.peak_u.dtype == jnp.float32
    assert np.all(np.isfinite(np.asarray(r32.u)))
    assert int(r32.n_impacts) == int(r64.n_impacts)
    assert abs(float(r32.peak_u) / float(r64.peak_u) - 1) < 1e-4


# ----------------------------------------------------------------------------- batches


@pytest.fixture(scope="module")
def scales():
    return np.array([0.3, 0.8, 1.0, 1.4, 2.0])


@pytest.fixture(scope="module")
def batch_full(column, gm, scales):
    return simulate_batch(column, gm, T_EQ, scale=scales, substeps=2)


def test_batch_equals_single_runs(column, gm, scales, batch_full):
    b = batch_full
    assert b.u.shape == (len(scales), int(round(T_EQ / 0.01)) + 1)
    for i, sc in enumerate(scales):
        one = simulate(column, GroundMotion(dt=gm.dt, accel=gm.accel, scale=sc), T_EQ,
                       method="rk4", substeps=2)
        assert int(b.status[i]) == int(one.status)
        assert int(b.n_impacts[i]) == int(one.n_impacts)
        # The same arithmetic, vectorised differently: rounding differences only, but the
        # impacts amplify them over a 10 s record (most near overturning, scale 1.4). The
        # free-vibration batches below agree to 1e-12.
        np.testing.assert_allclose(b.peak_u[i], one.peak_u, rtol=1e-5)
        np.testing.assert_allclose(b.u[i], one.u, atol=1e-6)
        n = int(b.n_impacts[i])
        np.testing.assert_allclose(np.asarray(b.impact_times[i])[:n], one.impacts, atol=1e-5)


def test_summary_only_equals_full(column, gm, scales, batch_full):
    s = simulate_batch(column, gm, T_EQ, scale=scales, substeps=2, summary_only=True)
    assert isinstance(s, rockjax.Summary) and len(s) == len(scales)
    for name in ("peak_u", "peak_uplift", "n_impacts", "status", "t_overturn"):
        np.testing.assert_array_equal(getattr(s, name), getattr(batch_full, name))
    d = s.to_dict()
    assert list(d["status"]) == s.status_names
    assert s.status_names[-1] == "overturned" and s.status_names[0] == "completed"


def test_diffrax_batch_equals_simulate(column, gm):
    sc = np.array([0.5, 1.2])
    b = simulate_batch(column, gm, 4.0, scale=sc, method="diffrax", summary_only=True,
                       rtol=1e-10, atol=1e-12)
    for i, x in enumerate(sc):
        one = simulate(column, GroundMotion(dt=gm.dt, accel=gm.accel, scale=x), 4.0)
        np.testing.assert_allclose(b.peak_u[i], one.peak_u, rtol=1e-9)
        assert int(b.n_impacts[i]) == int(one.n_impacts)


def test_chunks_padding_and_progress(column, gm, capsys):
    sc = np.linspace(0.2, 1.2, 7)
    whole = simulate_batch(column, gm, 3.0, scale=sc, summary_only=True)
    parts = simulate_batch(column, gm, 3.0, scale=sc, summary_only=True, chunk_size=3,
                           progress=True)
    for name in ("peak_u", "n_impacts", "status"):
        np.testing.assert_array_equal(getattr(whole, name), getattr(parts, name))
    err = capsys.readouterr().err
    assert "rk4 batch" in err and "/7" in err


def test_batched_structures_records_and_initial_states(column, gm):
    k_f = np.array([3e5, 5.5e5, 1e6])
    b = simulate_batch(column.replace(k_f=k_f), FreeVibration(0.1), 2.0, r=np.array([0.6, 0.7,
                                                                                     0.8]))
    for i in range(3):
        one = simulate(column.replace(k_f=k_f[i]), FreeVibration(0.1), 2.0, r=0.6 + 0.1 * i,
                       method="rk4", dt=2.0 / 4000, ts=np.asarray(b.ts))
        np.testing.assert_allclose(b.u[i], one.u, atol=1e-12)
        assert int(b.n_impacts[i]) == int(one.n_impacts)
    # two records of one dt, picked per run
    acc = np.stack([np.asarray(gm.accel), -np.asarray(gm.accel)])
    two = GroundMotion(dt=gm.dt, accel=acc)
    out = simulate_batch(column, two, 4.0, record=np.array([0, 1, 0]), scale=np.array([1, 1, 2.0]),
                         summary_only=True)
    mirror = simulate_batch(column, GroundMotion(dt=gm.dt, accel=gm.accel), 4.0,
                            scale=np.array([1.0, -1.0, 2.0]), summary_only=True)
    np.testing.assert_allclose(out.peak_u, mirror.peak_u, rtol=1e-12)
    # u0 batched on a free vibration
    fv = simulate_batch(column, FreeVibration(0.0), 1.0, u0=np.array([0.02, 0.05]),
                        summary_only=True)
    np.testing.assert_allclose(fv.peak_u, [0.02, 0.05], rtol=1e-12)


def test_execution_object_equals_the_keyword_form(column, gm):
    """`execution=rockjax.Execution(...)` and the earlier keywords run the same batch; the
    initial state batched on the excitation equals `u0=`; both forms at once are refused
    naming the keyword (issue 23: simulate_batch in at most 12 parameters)."""
    sc = np.linspace(0.2, 1.2, 5)
    new = simulate_batch(column, gm, 3.0, scale=sc, summary_only=True,
                         execution=rockjax.Execution(chunk_size=2, progress=False))
    old = simulate_batch(column, gm, 3.0, scale=sc, summary_only=True, chunk_size=2,
                         progress=False)
    for name in ("peak_u", "n_impacts", "status"):
        np.testing.assert_array_equal(getattr(new, name), getattr(old, name))
    u0 = np.array([0.02, 0.05, 0.08])
    on_exc = simulate_batch(column, FreeVibration(u0=u0), 1.0, summary_only=True)
    as_kw = simulate_batch(column, FreeVibration(0.0), 1.0, u0=u0, summary_only=True)
    np.testing.assert_array_equal(on_exc.peak_u, as_kw.peak_u)
    with pytest.raises(rockjax.ParameterError, match="chunk_size= and execution=") as e:
        simulate_batch(column, gm, 3.0, chunk_size=2, execution=rockjax.Execution())
    assert e.value.param == "chunk_size"
    for bad, param in ((dict(chunk_size=0), "chunk_size"), (dict(devices=1.5), "devices"),
                       (dict(record_steps="mine"), "record_steps")):
        with pytest.raises(rockjax.ParameterError) as e:
            rockjax.Execution(**bad)
        assert e.value.param == param


def test_record_table_is_the_ground_motion_of_each_member(gm):
    """`RecordTable`, the one excitation form of a batch: a member's ground acceleration
    is its record's (times its scale), zero after its own last sample even where the table
    is padded; its first direction is opposite to its first non-zero sample."""
    from rockjax._excitation import as_table

    n = np.asarray(gm.accel).size
    one = as_table(gm, jnp.float64, n_min=n + 50)  # padded by 50 zero samples
    t = np.linspace(-0.1, float(gm.duration) + 0.3, 997)
    np.testing.assert_allclose(jax.vmap(one.ground_acceleration)(t),
                               jax.vmap(gm.ground_acceleration)(t), atol=1e-12)
    # two records of different lengths in one table: the shorter one ends at its end
    short = np.asarray(gm.accel)[:300] + 1.0  # non-zero up to its last sample
    table = np.zeros((2, n))
    table[0], table[1, :300] = np.asarray(gm.accel), short
    rt = rockjax.RecordTable(table=jnp.asarray(table), lengths=jnp.array([n, 300]),
                             dt=jnp.asarray(gm.dt), record=jnp.asarray(1), scale=jnp.asarray(-2.0),
                             u0=jnp.zeros(()), v0=jnp.zeros(()))
    end = float(gm.dt) * 299
    assert float(rt.ground_acceleration(end)) == pytest.approx(-2.0 * short[-1])
    assert float(rt.ground_acceleration(end + 0.5 * float(gm.dt))) == 0.0
    assert float(rt.first_direction()) == 1.0  # -sign(-2 * (a0 + 1)) with a0 + 1 > 0
    rows = eqx_set(rt, record=jnp.array([0, 1, 1]), scale=jnp.array([1.0, 1.0, -1.0]))
    d = np.asarray(rows.first_direction())
    first0 = np.asarray(gm.accel)[np.argmax(np.asarray(gm.accel) != 0)]
    np.testing.assert_array_equal(d, [-np.sign(first0), -1.0, 1.0])


def eqx_set(module, **fields):
    import equinox as eqx

    return eqx.tree_at(lambda m: [getattr(m, k) for k in fields], module, list(fields.values()))


def test_grad_through_a_batch_names_the_input(column):
    """`jax.grad` through `simulate_batch` gives a clear error naming the traced input
    (before: a raw TracerArrayConversionError), pointing at `simulate`."""
    def peak(k_f):
        out = simulate_batch(column.replace(k_f=k_f), FreeVibration(0.05), 1.0,
                             summary_only=True)
        return out.peak_u.sum()

    with pytest.raises(rockjax.ParameterError, match="differentiate rockjax.simulate") as e:
        jax.grad(peak)(column.k_f)
    assert e.value.param == "structure"
    with pytest.raises(rockjax.ParameterError) as e:
        jax.grad(lambda a: simulate_batch(column, FreeVibration(0.05), 1.0, scale=a,
                                          summary_only=True).peak_u.sum())(1.0)
    assert e.value.param == "scale"


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(scale=np.ones(3), r=np.full(4, 0.5)), "same length"),
        (dict(r=1.5), "r must lie in"),
        (dict(r=np.array([0.5, -0.1])), "r must lie in"),
        (dict(method="euler"), "method must be"),
        (dict(impact="sometimes"), "impact must be"),
        (dict(substeps=0), "substeps"),
        (dict(record=np.array([0, 3])), "record must hold"),
        (dict(dt=0.001), "dt applies to a free vibration"),
        (dict(ts=np.array([0.0, 1.0]), summary_only=True), "ts applies"),
        (dict(ts=np.array([1.0, 0.5])), "strictly increasing"),
        (dict(scale=np.ones((2, 2))), "scale must be a scalar or a 1-D"),
        (dict(u0=np.array([0.0, np.nan])), "u0 must be finite"),
        (dict(chunk_size=0), "chunk_size"),
        (dict(devices=99), "devices must be"),
    ],
)
def test_bad_input_names_the_parameter(column, gm, kwargs, match):
    with pytest.raises(ValueError, match=match):
        simulate_batch(column, gm, 2.0, **kwargs)


@pytest.mark.parametrize("t1", [0.0, -1.0, np.inf, np.nan])
def test_bad_t1(column, gm, t1):
    with pytest.raises(ValueError, match="t1 must be"):
        simulate_batch(column, gm, t1)


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_sharded_over_four_devices_equals_one(tmp_path, gm):
    """The batch split over 4 host devices (shard_map) gives the same results as 1 device."""
    np.save(tmp_path / "acc.npy", np.asarray(gm.accel))
    code = f"""
import json, numpy as np, jax, rockjax
gm = rockjax.GroundMotion(dt={float(gm.dt)!r}, accel=np.load({str(tmp_path / 'acc.npy')!r}))
s = rockjax.mcmanus_column()
sc = np.linspace(0.2, 2.0, 10)  # 10 runs over 4 devices: the chunk is padded to 12
a = rockjax.simulate_batch(s, gm, 6.0, scale=sc, summary_only=True)
b = rockjax.simulate_batch(s, gm, 6.0, scale=sc, summary_only=True, devices=1)
u0 = np.linspace(0.01, 0.2, 10)
fa = rockjax.simulate_batch(s, rockjax.FreeVibration(0.0), 3.0, u0=u0)
fb = rockjax.simulate_batch(s, rockjax.FreeVibration(0.0), 3.0, u0=u0, devices=1)
print(json.dumps(dict(n=len(jax.local_devices()), a=np.asarray(a.peak_u).tolist(),
     b=np.asarray(b.peak_u).tolist(), sa=np.asarray(a.status).tolist(),
     sb=np.asarray(b.status).tolist(), du=float(np.max(np.abs(fa.u - fb.u))),
     na=np.asarray(fa.n_impacts).tolist(), nb=np.asarray(fb.n_impacts).tolist())))
"""
    env = dict(os.environ, XLA_FLAGS="--xla_force_host_platform_device_count=4")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         timeout=600)
    assert out.returncode == 0, out.stderr
    d = json.loads(out.stdout.strip().splitlines()[-1])
    assert d["n"] == 4
    # free vibration: equal to rounding (vector widths differ between the two splits)
    assert d["na"] == d["nb"] and d["du"] < 1e-9
    # the record: rounding differences (vector widths differ) grow through the impacts
    assert d["sa"] == d["sb"] and 1 in d["sa"]
    np.testing.assert_allclose(d["a"], d["b"], rtol=1e-5)


# ----------------------------------------------------------------------------- gradients


def _fd5(f, x, h):
    return (-f(x + 2 * h) + 8 * f(x + h) - 8 * f(x - h) + f(x - 2 * h)) / (12 * h)


@pytest.mark.slow  # compile-bound (~21 s); test_gradients checks rk4 gradients by default
def test_rk4_gradients_match_finite_differences(column):
    """jacrev == jacfwd == 5-point central differences (float64), through impacts."""
    scale = jnp.asarray([5.5e5, 0.8, 0.1])  # k_f [N/m], r, u0 [m]
    h = jnp.asarray([50.0, 1e-5, 1e-6])

    def outputs(p):
        res = simulate(column.replace(k_f=p[0]), FreeVibration(p[2]), 1.5, r=p[1],
                       method="rk4", dt=2e-3)
        return jnp.stack([jnp.sum(res.u**2), res.peak_u, res.impact_times[2]])

    rev = jax.jacrev(outputs)(scale)
    fwd = jax.jacfwd(outputs)(scale)
    np.testing.assert_allclose(rev, fwd, rtol=1e-9, atol=1e-14)
    for j in range(3):
        e = jnp.zeros(3).at[j].set(1.0)
        fd = _fd5(lambda x: outputs(scale + x * e), 0.0, h[j])
        np.testing.assert_allclose(rev[:, j], fd, rtol=2e-6, atol=1e-12)


@pytest.mark.slow  # moved out of the default suite (issue 23): compile-bound; CI runs it
def test_dopri5_forward_gradient(column):
    def third_impact(k_f):
        res = simulate(column.replace(k_f=k_f), FreeVibration(0.1), 1.5, method="dopri5",
                       rtol=1e-10, atol=1e-12)
        return res.impact_times[2]

    g = jax.jacfwd(third_impact)(jnp.asarray(5.5e5))
    fd = _fd5(third_impact, jnp.asarray(5.5e5), 50.0)
    np.testing.assert_allclose(g, fd, rtol=1e-5)


@pytest.mark.slow  # moved out of the default suite (issue 23): compile-bound; CI runs it
def test_rk4_record_scale_gradient(column, gm):
    def peak(sc):
        res = simulate(column, GroundMotion(dt=gm.dt, accel=gm.accel[:401], scale=sc), 4.0,
                       method="rk4")
        return res.peak_u

    g = jax.grad(peak)(jnp.asarray(1.0))
    np.testing.assert_allclose(g, jax.jacfwd(peak)(jnp.asarray(1.0)), rtol=1e-6)
    # below h ~ 1e-5 the difference quotient meets the rounding of the event locations
    fd = _fd5(peak, jnp.asarray(1.0), 1e-4)
    np.testing.assert_allclose(g, fd, rtol=1e-4)


def test_rigid_block_rests_until_the_uplift_threshold(column, gm):
    """housner under a ground motion: at rest while |a_g| <= k(0+)/M, then rocking; the
    three integrators agree (without the rest rule Eq. 1 chatters at u = 0 from rest)."""
    A = float(rockjax.restoring_force(column, 1e-12, "housner") / column.mass)
    peak_g = float(np.max(np.abs(np.asarray(gm.accel))))
    quiet = GroundMotion(dt=gm.dt, accel=gm.accel, scale=0.9 * A / peak_g)
    for method in ("diffrax", "rk4"):
        res = simulate(column, quiet, T_EQ, model="housner", method=method)
        assert res.status_name == "completed" and int(res.n_impacts) == 0
        assert float(res.peak_u) == 0.0 and np.all(np.asarray(res.u) == 0.0)
    strong = GroundMotion(dt=gm.dt, accel=gm.accel, scale=2.0)
    runs = [simulate(column, strong, T_EQ, model="housner", method=m)
            for m in ("diffrax", "rk4", "dopri5")]
    for res in runs:
        assert res.status_name == "completed" and 0 < int(res.n_impacts) < 1024
        assert 0.05 < float(res.peak_u) < float(column.u_overturn)
    np.testing.assert_allclose([float(r.peak_u) for r in runs], float(runs[0].peak_u),
                               rtol=1e-6)
    # it starts to move exactly when |a_g| first exceeds the threshold
    a = 2.0 * np.asarray(gm.accel)
    t_first = float(np.asarray(gm.dt)) * np.argmax(np.abs(a) > A)
    moving = np.asarray(runs[0].ts)[np.argmax(np.abs(np.asarray(runs[0].u)) > 0)]
    assert t_first - 0.011 < moving <= t_first + 0.011


# ---------------------------------------------------------------- the 2-DOF body batched


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_two_spring_2dof_batch_equals_single_runs_and_diffrax(column):
    """The 2-DOF body on the stepper: a batch equals its single runs, and dopri5 agrees
    with the event-restart diffrax integrator (free rocking from two releases)."""
    u0 = np.array([0.06, -0.1])
    model = rockjax.TwoSpring2DOF(contact="continuous", damping=500.0)
    batch = rockjax.simulate_batch(column, FreeVibration(0.0), 1.0, u0=u0, model=model,
                                   method="dopri5", rtol=1e-9, atol=1e-11, progress=False)
    for i, x in enumerate(u0):
        one = simulate(column, FreeVibration(x), 1.0, model=model, method="dopri5",
                       rtol=1e-9, atol=1e-11, ts=np.asarray(batch.ts))
        np.testing.assert_allclose(batch.u[i], one.u, rtol=1e-9, atol=1e-12)
        ref = simulate(column, FreeVibration(x), 1.0, model=model, ts=one.ts)
        assert float(one.peak_u) == pytest.approx(float(ref.peak_u), rel=1e-6)
        np.testing.assert_allclose(one.u, ref.u, atol=2e-6 * abs(x))
        np.testing.assert_allclose(one.uplift, ref.uplift, atol=2e-6 * abs(x))


@pytest.mark.slow  # about 45 s, mostly compiling jacfwd of the 2-DOF Lagrange flow
def test_two_spring_2dof_stepper_gradient(column):
    """d(peak)/d(k_f) of the 2-DOF body through lift-off and landing on the rk4 stepper:
    jacfwd against 5-point central differences (float64, fixed steps)."""

    def peak(k_f):
        res = simulate(column.replace(k_f=k_f), FreeVibration(0.02), 0.25,
                       model=rockjax.TwoSpring2DOF(contact="continuous"), method="rk4",
                       dt=5e-4)
        return jnp.sum(res.u**2)

    g = jax.jacfwd(peak)(jnp.asarray(5.5e5))
    fd = _fd5(peak, jnp.asarray(5.5e5), 50.0)
    np.testing.assert_allclose(g, fd, rtol=1e-6)


# ------------------------------------------- records of different time steps and lengths

TAIL = 1.5  # free vibration after each record's end in these tests [s]


@pytest.fixture(scope="module")
def mixed():
    """Three synthetic records at 0.005, 0.01 and 0.02 s, 3, 5 and 2.5 s long."""
    return [synthetic(seed=11, dt=0.005, duration=3.0, pga=3.0),
            synthetic(seed=12, dt=0.01, duration=5.0, pga=3.5),
            synthetic(seed=13, dt=0.02, duration=2.5, pga=4.0)]


@pytest.fixture(scope="module")
def mixed_batch(column, mixed):
    """Every record at two scales in one batch, each to its end + TAIL."""
    return simulate_batch(column, mixed, tail=TAIL, record=np.array([0, 1, 2, 0, 1, 2]),
                          scale=np.array([1.0, 1.0, 1.0, 3.0, 3.0, 3.0]), summary_only=True,
                          progress=False)


@pytest.mark.slow  # moved out of the default suite (issue 23): compile-bound; CI runs it
def test_mixed_time_steps_equal_single_runs(column, mixed, mixed_batch):
    """One batch over records of 0.005, 0.01 and 0.02 s (resampled exactly onto 0.005 s):
    each member equals `rockjax.simulate` of its record to its own end + tail (before,
    the batch refused records of different time steps)."""
    out = mixed_batch
    ends = [r.dt * (r.npts - 1) + TAIL for r in mixed]
    np.testing.assert_allclose(out.t_end, ends * 2, rtol=1e-12)
    for k in range(6):
        rec, sc = mixed[k % 3], [1.0, 3.0][k // 3]
        one = simulate(column, GroundMotion.from_record(rec, scale=sc), ends[k % 3],
                       rtol=1e-10, atol=1e-12)
        assert out.status_names[k] == one.status_name
        assert int(out.n_impacts[k]) == int(one.n_impacts)
        np.testing.assert_allclose(out.peak_u[k], one.peak_u, rtol=2e-6)
        np.testing.assert_allclose(out.peak_uplift[k], one.peak_uplift, rtol=2e-5, atol=1e-12)
    assert "overturned" in out.status_names and "completed" in out.status_names


def test_ended_member_takes_nothing_from_the_padding(column, mixed):
    """The short record's member stops at its end + tail although the batch runs on to the
    long record's end: no impacts, peaks or max_impacts status from the padding. Zero
    padding to the longest record (what `rockjax sweep` did) counts the free rocking after
    the short record as impacts and hits max_impacts."""
    short, long_ = mixed[2], mixed[1]
    end = short.dt * (short.npts - 1) + TAIL
    alone = simulate_batch(column, [short], tail=TAIL, summary_only=True, progress=False)
    assert float(alone.t_end[0]) == pytest.approx(end)
    n = int(alone.n_impacts[0])
    both = simulate_batch(column, [short, long_], tail=TAIL, max_impacts=n + 1,
                          summary_only=True, progress=False)
    assert both.status_names[0] == "completed" and int(both.n_impacts[0]) == n
    # the same run on the finer common grid of the pair (0.01 s, not 0.02 s)
    np.testing.assert_allclose(both.peak_u[0], alone.peak_u[0], rtol=1e-5)
    assert float(both.t_end[1]) > float(both.t_end[0]) + 1.0
    padded = np.zeros(long_.npts * 2)
    padded[: short.npts] = short.accel
    old = simulate_batch(column, GroundMotion(dt=short.dt, accel=padded),
                         float(both.t_end[1]), max_impacts=n + 1, summary_only=True)
    assert old.status_names == ["max_impacts"]  # the phantom impacts of the padding
    # the full history holds the member's state after its end
    full = simulate_batch(column, [short, long_], tail=TAIL, progress=False)
    after = np.asarray(full.ts) >= end
    u0 = np.asarray(full.u)[0]
    assert np.all(u0[after] == u0[after][0]) and np.any(np.diff(np.asarray(full.u)[1][after]))


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes); CI runs it
def test_mixed_records_on_every_method(column, mixed):
    """GroundMotions in the sequence (their own scale folded in), a t1 cap, and the
    dopri5 and diffrax methods agree with rk4."""
    gms = [GroundMotion.from_record(mixed[0], scale=2.0), mixed[2]]
    t1 = 4.2  # caps the first record's end (3 s + 1.5 s), not the second's (2.5 s + 1.5 s)
    runs = {m: simulate_batch(column, gms, t1, tail=TAIL, scale=0.5, method=m,
                              summary_only=True, progress=False)
            for m in ("rk4", "dopri5", "diffrax")}
    np.testing.assert_allclose(runs["rk4"].t_end, [4.2, 4.0], rtol=1e-12)
    for k, rec in enumerate([mixed[0], mixed[2]]):
        one = simulate(column, GroundMotion.from_record(rec, scale=[1.0, 0.5][k]),
                       [4.2, 4.0][k], rtol=1e-10, atol=1e-12)
        for out in runs.values():
            np.testing.assert_array_equal(out.t_end, runs["rk4"].t_end)
            assert int(out.n_impacts[k]) == int(one.n_impacts)
            np.testing.assert_allclose(out.peak_u[k], one.peak_u, rtol=1e-5)


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_real_records_of_three_time_steps(column, ground_motions_dir):
    """The shared records at 0.005, 0.01 and 0.02 s in one batch, each to its own end +
    tail, equal single runs of `rockjax.simulate` (the real-record check of this file)."""
    names = ["RSN753_LOMAP_CLS000.AT2", "IELC180.AT2", "elCentro.AT2"]
    recs = [rockjax.read_record(ground_motions_dir / n) for n in names]
    out = simulate_batch(column, recs, tail=TAIL, summary_only=True, progress=False)
    assert [r.dt for r in recs] == [0.005, 0.01, 0.02]
    for k, rec in enumerate(recs):
        end = rec.dt * (rec.npts - 1) + TAIL
        assert float(out.t_end[k]) == pytest.approx(end)
        one = simulate(column, GroundMotion.from_record(rec), end, method="dopri5",
                       rtol=1e-10, atol=1e-12)
        assert out.status_names[k] == one.status_name
        assert int(out.n_impacts[k]) == int(one.n_impacts)
        np.testing.assert_allclose(out.peak_u[k], one.peak_u, rtol=1e-5)


@pytest.mark.parametrize(
    "excitation, kwargs, match",
    [
        ("mixed", dict(tail=-1.0), "tail must be a finite number of seconds >= 0"),
        ("mixed", dict(tail=np.ones(2)), "tail must be a finite number"),
        ("gm", dict(tail=1.0), "tail applies to a sequence of records"),
        ("gm", dict(), "t1 must be given"),
        ([], dict(), "the sequence of records is empty"),
        (["x"], dict(), "item 0 is a str"),
        ("u0", dict(), "has u0 or v0; pass u0=, v0="),
        ("2d", dict(), "must hold one record"),
        ("odd-dt", dict(), "no common step coarser than 0.0001 s"),
        ("mixed", dict(record=np.array([0, 3])), "record must hold integer indices into the 3"),
        ("mixed", dict(dt=0.01), "dt applies to a free vibration"),
        ("mixed", dict(t1=-1.0), "t1 must be a positive"),
    ],
)
def test_sequence_errors(column, mixed, excitation, kwargs, match):
    a = np.zeros(11)
    cases = {
        "mixed": mixed,
        "gm": GroundMotion(dt=0.01, accel=a),
        "u0": [GroundMotion(dt=0.01, accel=a, u0=0.01)],
        "2d": [GroundMotion(dt=0.01, accel=np.zeros((2, 11)))],
        "odd-dt": [rockjax.Record(dt=0.01, accel=a), rockjax.Record(dt=0.0073, accel=a)],
    }
    exc = cases.get(excitation, excitation) if isinstance(excitation, str) else excitation
    with pytest.raises(ValueError, match=match):
        simulate_batch(column, exc, **kwargs)


@pytest.mark.parametrize("n", [1, 31, 32, 33, 300, 4096, 20_000])
def test_first_members_is_nonzero(n):
    """The compacted stepper's index of the members with an event (`first_members`) is
    `jnp.nonzero(mask, size=width, fill_value=n)[0]`: every density, a mask shorter or
    longer than the width, lengths off the 32-bit words, and a chunk past the size where
    the word ranks switch from a product to a cumulative sum."""
    from rockjax.integrators._stepper import first_members

    rng = np.random.default_rng(n)
    for p in (0.0, 0.016, 0.3, 1.0):
        mask = jnp.asarray(rng.random(n) < p)
        for width in (1, 8, 128):
            np.testing.assert_array_equal(first_members(mask, width),
                                          jnp.nonzero(mask, size=width, fill_value=n)[0])


@pytest.mark.parametrize("model, rtol", [("simplified", 1e-12), ("rigid_body", 1e-8)])
def test_compacted_batch_equals_small_chunks(column, gm, model, rtol):
    """A chunk of 300 members (compacted: one whole-batch trial step, the members with an
    event in a gathered sub-batch that continues from it, the bursts of a scale sweep in
    several rounds) gives the results of the same members in chunks of 100 (below
    `COMPACT_MIN`: every piece for the whole chunk), to rounding: the whole-batch trial
    step and the one a small chunk integrates may differ in the last bit (XLA fuses them
    differently), which the rigid body's rocking near overturning amplifies to 7e-10 of
    the peak (measured; exactly equal for simplified)."""
    sc = np.linspace(0.2, 4.0, 300)  # rocking, lift-off bursts, overturning
    kw = dict(scale=sc, summary_only=True, model=model, devices=1, progress=False,
              fidelity_warning=False)
    big = simulate_batch(column, gm, T_EQ, chunk_size=300, **kw)
    small = simulate_batch(column, gm, T_EQ, chunk_size=100, **kw)
    assert len(set(np.asarray(big.status).tolist())) >= 2  # completed and overturned
    np.testing.assert_array_equal(big.status, small.status)
    np.testing.assert_array_equal(big.n_impacts, small.n_impacts)
    np.testing.assert_allclose(big.peak_u, small.peak_u, rtol=rtol)
    np.testing.assert_allclose(big.t_overturn, small.t_overturn, rtol=rtol)


def test_event_rounds_is_the_function_benchmarks_event_cost_replaces():
    """`benchmarks/event_cost.py` times the compacted step without its events by replacing
    `_stepper._event_rounds` with a function that returns its fifth argument (the state)
    and counts the members with events from its last (`hard`): a renamed, reordered or
    inlined function would leave the benchmark timing something else."""
    import inspect
    import pathlib

    from rockjax.integrators import _stepper

    params = list(inspect.signature(_stepper._event_rounds).parameters)
    assert params[4] == "st" and params[-1] == "hard", params
    assert "return _event_rounds(" in inspect.getsource(_stepper._compacted)
    bench = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "event_cost.py"
    src = bench.read_text()
    assert "_stepper._event_rounds = lambda *args: args[4]" in src
    assert "hard = args[-1]" in src


def test_piece_peak_skips_the_turn_only_where_it_cannot_raise_the_peak():
    """The compacted step computes a step's interior turn (`piece_peak` with the running
    peak as `floor`) only when a member's Bernstein hull exceeds its running peak: the
    running peak it gives is that of the exact turn, bit for bit, and the skip is taken
    when no hull reaches the peak."""
    from rockjax.integrators._hermite import hermite, piece_peak

    rng = np.random.default_rng(7)  # steps far coarser than the stepper's: the worst case
    n = 4000
    u0, u1 = rng.normal(size=n), rng.normal(size=n)
    v0, v1 = rng.normal(scale=5.0, size=n), rng.normal(scale=5.0, size=n)
    h = np.full(n, 0.1)
    peak = jax.jit(piece_peak)  # both compiled (eager and compiled round differently)
    exact = np.asarray(peak(u0, v0, u1, v1, h))
    # the premise: the interpolant lies within its control points' hull (dense sampling)
    s = np.linspace(0.0, 1.0, 2001)[:, None]
    curve, _ = hermite(u0, v0 * h, u1, v1 * h, s)
    hull = np.max(np.abs([u0, u0 + v0 * h / 3, u1 - v1 * h / 3, u1]), axis=0)
    assert np.all(np.max(np.abs(curve), axis=0) <= hull * (1 + 1e-15))
    turn = v0 * v1 < 0
    assert 0.3 < turn.mean() < 0.7
    for floor in (np.zeros(n), 0.5 * hull, hull * (1 - 1e-9), hull, 2 * hull,
                  rng.uniform(0.0, 2.0, n) * hull):
        skipped = np.asarray(peak(u0, v0, u1, v1, h, jnp.asarray(floor)))
        np.testing.assert_array_equal(np.maximum(floor, skipped), np.maximum(floor, exact))
    # no hull above its floor: the ends only (the turn was skipped)
    ends = np.maximum(np.abs(u0), np.abs(u1))
    np.testing.assert_array_equal(peak(u0, v0, u1, v1, h, jnp.asarray(hull * (1 + 1e-12))), ends)
    assert np.any(exact > ends)


def test_compacted_batch_with_leading_zeros_equals_small_chunks(column, record):
    """Half the members on a record that starts with 1 s of zeros: they rest at u = 0
    exactly, their first condition exactly 0 at both ends of each step, where the compacted
    step decides from the conditions at the step's start too (`_compacted`'s `exact`),
    while the other half rock on the record without them, with events in the same steps.
    The same results as chunks below `COMPACT_MIN`, to rounding (as above: bit for bit on
    JAX 0.10; 1.3e-13 of one member's peak measured on JAX 0.12)."""
    dt, accel = record
    recs = [rockjax.Record(dt=dt, accel=np.concatenate([np.zeros(int(round(1.0 / dt))),
                                                        accel])),
            rockjax.Record(dt=dt, accel=accel)]
    kw = dict(scale=np.linspace(0.2, 4.0, 300), record=np.arange(300) % 2,
              summary_only=True, devices=1, progress=False, fidelity_warning=False)
    big = simulate_batch(column, recs, T_EQ + 1.0, chunk_size=300, **kw)
    small = simulate_batch(column, recs, T_EQ + 1.0, chunk_size=100, **kw)
    assert len(set(np.asarray(big.status).tolist())) >= 2  # completed and overturned
    np.testing.assert_array_equal(big.status, small.status)
    np.testing.assert_array_equal(big.n_impacts, small.n_impacts)
    np.testing.assert_allclose(big.peak_u, small.peak_u, rtol=1e-12)
    np.testing.assert_allclose(big.t_overturn, small.t_overturn, rtol=1e-12)
