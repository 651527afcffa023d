"""Property-based tests (hypothesis) over random valid structures and excitations.

Structures are drawn in physical ranges (masses 10 kg - 100 t, heights 0.3 - 20 m,
slenderness B/H_e 0.1 - 0.6, k_f from 1.05x to 100x its stability limit
k_min = W H_c / (2 B^2)), so the extremes of the issue "numerical stability at the
extremes" are in: foundations barely stiff enough to stand (lift-off close to, or even
beyond, u_overturn), very stiff ones (u_crit ~ 1e-3 u_overturn), releases exactly at
u_crit or u_overturn, r = 0 and r = 1.

JAX compiles once per shape and static setting: every array keeps its shape across
examples (fixed batch sizes, output grids and record lengths), so examples only change
values and each test compiles once. Set ROCKJAX_PROPERTY_SCALE (e.g. 10) to draw that many
times more examples.
"""

from __future__ import annotations

import os

import jax
import numpy as np
import pytest
from hypothesis import given, HealthCheck, settings, strategies as st
from test_simulate import energy

import rockjax
from rockjax import FreeVibration, GroundMotion, simulate, simulate_batch

G = 9.81
MAX_IMPACTS = 256  # static: one value for the whole module, so compilations are shared
N_TS = 2001  # output samples of the single runs (fixed shape)
REC_DT, REC_N = 0.01, 401  # ground motions: 4 s records at 100 Hz (fixed shape)
BATCH = 8  # members per simulate_batch call
MODELS = ["simplified", "exact", "smooth", "housner"]
STATUS_CODES = set(rockjax.STATUS.values())


def props(max_examples):
    """Hypothesis settings: no deadline (the first example compiles), a few examples (times
    $ROCKJAX_PROPERTY_SCALE, e.g. 10 for a longer search)."""
    scale = float(os.environ.get("ROCKJAX_PROPERTY_SCALE", "1"))
    return settings(max_examples=max(1, round(scale * max_examples)), deadline=None,
                    print_blob=True, suppress_health_check=[HealthCheck.too_slow])


# ------------------------------------------------------------------------ strategies


def _log_uniform(lo, hi):
    return st.floats(np.log10(lo), np.log10(hi)).map(lambda x: float(10.0**x))


@st.composite
def structure_fields(draw):
    """The fields of a valid structure (SI units), in physical ranges."""
    m_e = draw(_log_uniform(10.0, 1e5))
    m_b = m_e * draw(_log_uniform(0.03, 2.0))
    H_e = draw(_log_uniform(0.3, 20.0))
    H_b = H_e * draw(st.floats(0.01, 0.3))
    B = H_e * draw(st.floats(0.1, 0.6))
    I_eg = m_e * H_e**2 * draw(st.floats(0.0, 0.2))
    I_bg = m_b * B**2 * draw(st.floats(0.0, 0.4))
    k_min = G * (m_e * H_e + m_b * H_b) / (2.0 * B**2)  # W H_c / (2 B^2)
    k_f = k_min * draw(_log_uniform(1.05, 100.0))
    return dict(m_e=m_e, m_b=m_b, H_e=H_e, H_b=H_b, B=B, I_eg=I_eg, I_bg=I_bg, k_f=k_f,
                g=G)


def make_structure(fields):
    return rockjax.mcmanus_column().replace(**fields)


def stack_structures(members, trailing=()):
    """One structure whose fields have shape (n, *trailing), one member per row."""
    fields = {k: np.reshape([m[k] for m in members], (len(members), *trailing))
              for k in members[0]}
    return make_structure(fields)


def time_scale(s):
    r"""$1/p$ [s] with Housner's frequency parameter $p = \sqrt{W R_c / I_O}$."""
    return float(np.sqrt(s.I_O / (s.W * s.R_c)))


def _signed_log_uniform(lo, hi):
    return st.tuples(st.sampled_from([-1.0, 1.0]), _log_uniform(lo, hi)).map(
        lambda x: x[0] * x[1])


def u0_fractions(smallest=1e-9):
    """Release displacements as fractions of u_overturn: anywhere from `smallest` to 1.2
    (beyond 1: released overturned), and the edges exactly (0, +-u_crit, +-u_overturn).
    Far smaller releases (hypothesis likes 1e-200) are below the solver's atol (1e-12 m):
    nothing is resolved there, and below 1e-30 m impacts are not detected at all (the
    1e-30 offset of the event condition)."""
    return st.one_of(
        _signed_log_uniform(smallest, 1.2),
        st.sampled_from([0.0, 1.0, -1.0, 0.999999, "u_crit", "-u_crit"]),
    )


def v0_fractions(smallest=1e-9):
    """Release velocities in units of u_overturn p (p: Housner's frequency parameter)."""
    return st.one_of(st.just(0.0), _signed_log_uniform(smallest, 1.0))


restitution = st.one_of(st.floats(0.0, 1.0), st.sampled_from([0.0, 1.0, 0.999]))


def release(s, frac, v_frac):
    """(u0 [m], v0 [m/s]) from a fraction of u_overturn (or +-u_crit exactly)."""
    if frac == "u_crit":
        u0 = float(s.u_crit)
    elif frac == "-u_crit":
        u0 = -float(s.u_crit)
    else:
        u0 = frac * float(s.u_overturn)
    return u0, v_frac * float(s.u_overturn) / time_scale(s)


@st.composite
def free_vibrations(draw, smallest=1e-9):
    s = make_structure(draw(structure_fields()))
    u0, v0 = release(s, draw(u0_fractions(smallest)), draw(v0_fractions(smallest)))
    return s, FreeVibration(u0, v0), draw(restitution)


@st.composite
def ground_motions(draw):
    """A noisy, decaying sine of random frequency; peak about 0.1x - 10x g B/H_c."""
    s = make_structure(draw(structure_fields()))
    t = np.arange(REC_N) * REC_DT
    amp = G * float(s.B / s.H_c) * draw(_log_uniform(0.1, 10.0))
    f = draw(_log_uniform(0.3, 10.0))
    phase = draw(st.floats(0.0, 2 * np.pi))
    decay = draw(_log_uniform(0.3, 10.0))
    noise_level = draw(st.floats(0.0, 0.5))
    seed = draw(st.integers(0, 2**32 - 1))
    noise = np.random.default_rng(seed).standard_normal(REC_N) * noise_level
    accel = amp * (np.sin(2 * np.pi * f * t + phase) + noise) * np.exp(-t / decay)
    return s, GroundMotion(dt=REC_DT, accel=accel), draw(restitution)


# ------------------------------------------------------------------ restoring force

_force = jax.jit(rockjax.restoring_force, static_argnums=2)
_N_STRUCT = 16
_N_COARSE, _K = 500, 16  # coarse steps per side of u = 0, fine steps per coarse step
_POS = np.linspace(0.0, 1.0, _N_COARSE * _K + 1)[1:]
_X = np.concatenate([-_POS[::-1], [0.0], _POS])  # exactly symmetric (unlike linspace(-1, 1))


def jumps(f, allowed):
    """Coarse grid steps across which `f` jumps: (n, n_coarse) booleans.

    `f`: (n, m) values on rows of uniform fine grids, `_K` fine steps per coarse step;
    `allowed`: (n, n_coarse) coarse steps where a jump is permitted. Continuity is that
    the oscillation shrinks under refinement: on a continuous, piecewise-C1 function no
    single fine step carries more than half the oscillation (max - min) of f over its
    coarse step (about 1/K of it where f is monotonic, at most about 1/4 around an
    extremum), while a jump J carries at least J, so any jump larger than about the
    change of f over one coarse step is flagged.
    """
    blocks = np.lib.stride_tricks.sliding_window_view(f, _K + 1, axis=1)[:, ::_K]
    osc = blocks.max(axis=-1) - blocks.min(axis=-1)
    biggest = np.abs(np.diff(blocks, axis=-1)).max(axis=-1)
    floor = 1e-12 * np.max(np.abs(f), axis=1, keepdims=True)
    return (biggest > 0.5 * osc + floor) & ~allowed


def _force_grid(s, model):
    u = _X * np.asarray(s.u_overturn)  # (n, m), exactly symmetric about 0
    return u, np.asarray(_force(s, jax.numpy.asarray(u), model))


def _coarse(u):
    """(left end, right end) of every coarse step."""
    return u[:, :-1:_K], u[:, _K::_K]


@pytest.mark.parametrize("model", MODELS)
@props(12)
@given(members=st.lists(structure_fields(), min_size=_N_STRUCT, max_size=_N_STRUCT))
def test_restoring_force_odd_and_continuous(members, model):
    s = stack_structures(members, trailing=(1,))
    u, f = _force_grid(s, model)
    assert np.all(np.isfinite(f))
    # odd, exactly, on the symmetric grid; zero at u = 0
    np.testing.assert_array_equal(f, -f[:, ::-1])
    assert np.all(f[:, _N_COARSE * _K] == 0.0)
    # continuous away from u_crit (the P_crit / P_crit2 gap of simplified and exact) and,
    # for the rigid housner law, away from u = 0 (it jumps from -WB/H_e to +WB/H_e)
    lo, hi = _coarse(u)
    h = hi - lo
    allowed = np.zeros(lo.shape, bool)
    if model in ("simplified", "exact"):
        uc = np.asarray(s.u_crit)
        allowed |= (np.abs(lo) < uc + h) & (np.abs(hi) > uc - h)
    if model == "housner":
        allowed |= (lo < h) & (hi > -h)
    found = jumps(f, allowed)
    bad = np.flatnonzero(found.any(axis=1))
    assert bad.size == 0, (model, [members[i] for i in bad[:2]],
                           [lo[i][found[i]][:4] for i in bad[:2]])


@props(12)
@given(members=st.lists(structure_fields(), min_size=_N_STRUCT, max_size=_N_STRUCT))
def test_lift_off_gap_is_bounded(members):
    # Across u_crit simplified jumps from P_crit (Eq. 14) to P_crit2 (Eq. 19) and by no
    # more; smooth does not jump at all. Evaluated at u_crit (1 -+ 1e-10): the branches'
    # slopes move the values by at most L * 2e-10 u_crit.
    s = stack_structures(members)
    uc, uo = np.asarray(s.u_crit), np.asarray(s.u_overturn)
    P1, P2, K1 = np.asarray(s.P_crit), np.asarray(s.P_crit2), np.asarray(s.K1)
    eps = 1e-10
    u = jax.numpy.asarray(np.stack([uc * (1 - eps), uc * (1 + eps)], axis=1))
    s1 = stack_structures(members, trailing=(1,))
    simp = np.asarray(_force(s1, u, "simplified"))
    smooth = np.asarray(_force(s1, u, "smooth"))
    gap = np.abs(P2 - P1)
    slope = K1 + np.abs(P2) / np.abs(uo - uc) + 5 * gap / uc  # bounds |dk/du| near u_crit
    tol = slope * 2 * eps * uc + 1e-12 * (np.abs(P1) + np.abs(P2))
    np.testing.assert_allclose(simp[:, 0], P1, rtol=1e-9)  # K1 u on the linear branch
    assert np.all(np.abs(simp[:, 1] - simp[:, 0]) <= gap + tol)
    assert np.all(np.abs(smooth[:, 1] - smooth[:, 0]) <= tol)


def test_jump_detector_sees_the_lift_off_gap():
    """The continuity check has teeth: with u_crit not excluded it flags the gap there."""
    s = rockjax.mcmanus_column()
    s = s.replace(k_f=1.5 * float(s.W * s.H_c / (2 * s.B**2)))  # a wide gap at lift-off
    s1 = stack_structures([s.to_dict()], trailing=(1,))
    for model in ("simplified", "exact"):
        u, f = _force_grid(s1, model)
        lo, hi = _coarse(u)
        found = jumps(f, np.zeros(lo.shape, bool))[0]
        assert found.sum() == 2, (model, lo[0][found])  # at -u_crit and +u_crit
        a, b = np.abs(lo[0][found]), np.abs(hi[0][found])
        uc = float(s.u_crit)
        assert np.all((np.minimum(a, b) <= uc) & (np.maximum(a, b) >= uc)), model


# ----------------------------------------------------------------------- simulate


def _check_finite(res, max_impacts=MAX_IMPACTS):
    u, v = np.asarray(res.u), np.asarray(res.v)
    bad = np.flatnonzero(~(np.isfinite(u) & np.isfinite(v)))
    assert bad.size == 0, f"non-finite u/v at samples {bad[:5]} of {u.size} ({res.status_name})"
    assert np.isfinite(float(res.peak_u))
    assert int(res.status) in STATUS_CODES
    n = int(res.n_impacts)
    assert 0 <= n <= max_impacts
    imp = res.impacts
    assert np.all(np.isfinite(imp)) and np.all(np.diff(imp) >= 0)


def _free_run(s, exc, r, method, model="simplified"):
    t1 = 20.0 * time_scale(s)
    ts = np.linspace(0.0, t1, N_TS)
    return simulate(s, exc, t1, ts=ts, r=r, method=method, model=model,
                    max_impacts=MAX_IMPACTS), t1


@pytest.mark.parametrize("method", ["diffrax", "rk4"])
@props(25)
@given(case=free_vibrations())
def test_free_vibration_is_finite(case, method):
    s, exc, r = case
    res, _ = _free_run(s, exc, r, method)
    _check_finite(res)
    assert float(res.peak_u) <= float(s.u_overturn) * (1 + 1e-12)


@pytest.mark.parametrize("method", ["diffrax", pytest.param("rk4", marks=pytest.mark.slow)])
@props(50)
@given(case=ground_motions(), n_t1=st.integers(50, REC_N - 1))
def test_ground_motion_is_finite(case, method, n_t1):
    s, gm, r = case
    # t1 on a sample of the record, as a user would run it (to the record's end, say);
    # REC_N output times whatever t1, so that nothing recompiles
    t1 = n_t1 * REC_DT
    res = simulate(s, gm, t1, ts=np.linspace(0.0, t1, REC_N), r=r, method=method,
                   max_impacts=MAX_IMPACTS)
    _check_finite(res)


def test_ground_motion_end_on_a_sample_is_finite():
    """Regression (found by test_ground_motion_is_finite): the diffrax path run to a t1 on
    a sample of the record returned u = v = inf at ts = t1, with status 'completed'
    (diffrax issue #663); outputs at a segment's end now come from its final state."""
    s = rockjax.mcmanus_column()
    t = np.arange(REC_N) * REC_DT
    gm = GroundMotion(dt=REC_DT, accel=3.0 * np.sin(2 * np.pi * 1.5 * t) * np.exp(-t / 2))
    bad = []
    for t1 in (0.92, 1.17, 1.43):  # with k * dt = t1 (some other samples are fine)
        res = simulate(s, gm, t1, ts=np.linspace(0.0, t1, REC_N), max_impacts=MAX_IMPACTS)
        if not np.all(np.isfinite(np.asarray(res.u))):
            bad.append(t1)
    assert not bad, f"non-finite output at ts = t1 for t1 = {bad}"


@pytest.mark.slow
@pytest.mark.parametrize("model", ["exact", "smooth", "housner"])
@pytest.mark.parametrize("method", ["diffrax", "rk4"])
@props(20)
@given(case=free_vibrations())
def test_free_vibration_is_finite_other_models(case, method, model):
    s, exc, r = case
    res, _ = _free_run(s, exc, r, method, model)
    _check_finite(res)


@props(60)
@given(case=free_vibrations(smallest=1e-3))
def test_energy_conserved_between_impacts(case):
    """Simplified model, default method: E = T + V is constant between impacts, and each
    impact keeps the fraction r of it (Eq. 2 at u = 0, where V = 0).

    Relative 1e-7 of the segment's energy (and 1e-6 for the impact ratio) while the motion
    is resolved: it holds at least 1e-4 of the initial energy E0 and its peak |u| is at
    least 1e-4 m = 1e8 atol (the solver's error is absolute, atol = 1e-12 m, so a motion of
    amplitude a has a relative energy error of about N atol / a over N steps). Otherwise
    1e-7 of E0.
    """
    s, exc, r = case
    res, t1 = _free_run(s, exc, r, "diffrax")
    _check_finite(res)
    ts, u = np.asarray(res.ts), np.asarray(res.u)
    E = np.asarray(energy(s, res.u, res.v))
    E0 = float(np.asarray(energy(s, exc.u0, exc.v0)))
    if not E0 > 0:  # released at rest on u = 0: nothing moves
        assert np.all(u == 0.0)
        return
    t_end = min(t1, float(res.t_overturn))
    edges = np.concatenate([[0.0], res.impacts, [t_end]])
    eps = 1e-9 * t1
    seg_E = []  # energy of each segment between impacts, if resolved
    for a, b in zip(edges[:-1], edges[1:]):
        m = (ts > a + eps) & (ts < b - eps)
        if not m.any():
            seg_E.append(None)
            continue
        seg = E[m]
        dev = float(np.max(np.abs(seg - seg[0])))
        assert dev <= 1e-7 * E0, (a, b, dev / E0)
        resolved = seg[0] >= 1e-4 * E0 and np.max(np.abs(u[m])) >= 1e-4
        if resolved:
            assert dev <= 1e-7 * seg[0], (a, b, dev / seg[0])
        seg_E.append(float(seg[0]) if resolved else None)
    for k in range(1, len(seg_E)):  # segment k starts at impact k - 1
        before, after = seg_E[k - 1], seg_E[k]
        if before is not None and after is not None:
            assert after / before == pytest.approx(r, rel=1e-6), k


@props(6)
@given(
    members=st.lists(st.tuples(structure_fields(), u0_fractions(), v0_fractions(),
                               restitution), min_size=BATCH, max_size=BATCH),
    t1=st.floats(1.0, 8.0),
)
def test_batch_summaries_equal_single_runs(members, t1):
    """simulate_batch(summary_only=True) == simulate(method="rk4") member by member."""
    fields = [m[0] for m in members]
    s = stack_structures(fields)
    singles = [make_structure(f) for f in fields]
    u0, v0 = np.array([release(si, m[1], m[2]) for si, m in zip(singles, members)]).T
    r = np.array([m[3] for m in members])
    out = simulate_batch(s, FreeVibration(0.0), t1, u0=u0, v0=v0, r=r, summary_only=True,
                         max_impacts=MAX_IMPACTS)
    for i, si in enumerate(singles):
        one = simulate(si, FreeVibration(u0[i], v0[i]), t1, r=r[i], method="rk4",
                       max_impacts=MAX_IMPACTS)
        assert int(out.status[i]) == int(one.status), i
        assert int(out.n_impacts[i]) == int(one.n_impacts), i
        np.testing.assert_allclose(out.peak_u[i], one.peak_u, rtol=1e-9, atol=0)
        assert float(out.t_overturn[i]) == pytest.approx(float(one.t_overturn), rel=1e-9)
