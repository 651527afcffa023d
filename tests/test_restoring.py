"""Closed-form restoring forces: properties, limits and gradients."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import rockjax
from rockjax import restoring_force

MODELS = ["simplified", "exact", "smooth", "housner"]


@pytest.fixture(scope="module")
def grid(column):
    pos = jnp.linspace(0.0, 0.99, 2001)[1:] * column.u_overturn
    return jnp.concatenate([-pos[::-1], jnp.zeros(1), pos])  # exactly symmetric


@pytest.mark.parametrize("model", MODELS)
def test_odd_symmetry(column, grid, model):
    f = np.asarray(restoring_force(column, grid, model))
    np.testing.assert_allclose(f, -f[::-1], rtol=0, atol=1e-12 * float(column.P_crit))
    assert float(restoring_force(column, 0.0, model)) == 0.0


@pytest.mark.parametrize("model", MODELS)
def test_vectorised_shapes(column, model):
    u = jnp.zeros((3, 4, 5)) + 0.01
    assert restoring_force(column, u, model).shape == (3, 4, 5)
    assert restoring_force(column, 0.01, model).shape == ()


def test_simplified_segments_and_slopes(column):
    s = column
    uc, uo = float(s.u_crit), float(s.u_overturn)
    # Linear before lift-off with slope K1 (Eq 13)
    u = jnp.linspace(0.0, 0.99 * uc, 50)
    np.testing.assert_allclose(restoring_force(s, u), float(s.K1) * np.asarray(u), rtol=1e-14)
    # Eq 20 passes through (u_crit, P_crit2) and (u_overturn, 0), slope negative
    assert float(restoring_force(s, uc * (1 + 1e-12))) == pytest.approx(float(s.P_crit2), rel=1e-9)
    assert abs(float(restoring_force(s, uo))) < 1e-9
    assert float(restoring_force(s, 1.01 * uo)) < 0.0  # past overturning the force reverses
    slope = jax.vmap(jax.grad(lambda x: restoring_force(s, x)))
    pre = np.asarray(slope(jnp.linspace(-0.9 * uc, 0.9 * uc, 11)))
    post = np.asarray(slope(jnp.linspace(1.1 * uc, 0.99 * uo, 11)))
    assert np.all(pre > 0) and np.all(post < 0)
    np.testing.assert_allclose(post, -float(s.P_crit2) / (uo - uc), rtol=1e-12)


@pytest.mark.parametrize("model", ["simplified", "exact"])
def test_continuity_at_u_crit_up_to_gap(column, model):
    s = column
    uc = float(s.u_crit)
    below = float(restoring_force(s, uc * (1 - 1e-9), model))
    above = float(restoring_force(s, uc * (1 + 1e-9), model))
    gap = abs(float(s.P_crit - s.P_crit2))
    assert below == pytest.approx(float(s.P_crit), rel=1e-8)
    assert abs(above - below) <= gap * 1.05 + 1e-6
    assert gap / float(s.P_crit) < 2e-3


@pytest.mark.parametrize("model", MODELS)
def test_continuity_elsewhere(column, model):
    # Away from u = 0 (housner) and u_crit (gap), neighbouring values differ by O(h)
    s = column
    u = jnp.linspace(1.5 * s.u_crit, 0.99 * s.u_overturn, 20001)
    f = np.asarray(restoring_force(s, u, model))
    assert np.max(np.abs(np.diff(f))) < 1e-3 * float(s.P_crit)


def test_exact_slopes(column):
    s = column
    slope = jax.vmap(jax.grad(lambda x: restoring_force(s, x, "exact")))
    post = np.asarray(slope(jnp.linspace(1.05 * s.u_crit, 0.99 * s.u_overturn, 50)))
    assert np.all(post < 0)


def test_smooth_is_c1_and_converges(column):
    s = column
    uc = float(s.u_crit)
    u = jnp.linspace(0.5 * uc, 1.5 * uc, 20001)
    fsm = lambda x: restoring_force(s, x, rockjax.Smooth(width=0.2))  # noqa: E731
    d1 = np.asarray(jax.vmap(jax.grad(fsm))(u))
    # C1: the derivative has no jumps on a fine grid (bounded by the curvature)
    assert np.max(np.abs(np.diff(d1))) < 0.01 * float(s.K1)
    # Equal to simplified outside the window
    far = jnp.array([0.1 * uc, 0.5 * uc, 2 * uc, 0.5 * float(s.u_overturn)])
    np.testing.assert_allclose(fsm(far), restoring_force(s, far), rtol=1e-13)
    # Converges to simplified as width -> 0 (pointwise, in the L1 sense across the window)
    errs = []
    for w in (0.2, 0.05, 0.0125):
        f = restoring_force(s, u, rockjax.Smooth(width=w))
        errs.append(float(jnp.mean(jnp.abs(f - restoring_force(s, u)))))
    assert errs[0] > errs[1] > errs[2] and errs[2] < 0.1 * errs[0]


def test_smooth_width_validated():
    with pytest.raises(ValueError, match="width"):
        rockjax.Smooth(width=1.5)
    with pytest.raises(ValueError, match="width"):
        rockjax.Smooth(width=0.0)


def test_unknown_model(column):
    with pytest.raises(ValueError, match="model must be one of"):
        restoring_force(column, 0.1, "banana")


def test_housner_is_rigid_limit(column):
    u = jnp.linspace(0.02, 0.35, 30)
    fh = np.asarray(restoring_force(column, u, "housner"))
    errs = []
    for k in (1e6, 1e8, 1e10):
        fe = np.asarray(restoring_force(column.replace(k_f=k), u, "exact"))
        errs.append(np.max(np.abs(fe - fh)))
    assert errs[0] > errs[1] > errs[2] and errs[2] < 1e-3
    # the rigid force at 0+ is W B / H_e
    s = column
    assert float(restoring_force(s, 1e-12, "housner")) == pytest.approx(
        float(s.W * s.B / s.H_e), rel=1e-9
    )


def test_exact_force_vs_simplified_max_error(column):
    # The simplified line deviates from Eq 18 by ~1.3% of P_crit at most for Table 1
    u = jnp.linspace(1.2 * column.u_crit, 0.95 * column.u_overturn, 2000)
    d = np.max(np.abs(np.asarray(restoring_force(column, u) - restoring_force(column, u, "exact"))))
    assert 0.001 < d / float(column.P_crit) < 0.02


FIELDS = ["k_f", "B", "H_e", "m_e", "m_b"]


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("u", [0.003, 0.05, 0.2, -0.1])
def test_gradients_match_finite_differences(column, model, u):
    def f(params, uu):
        return restoring_force(column.replace(**params), uu, model)

    p0 = {k: getattr(column, k) for k in FIELDS}
    g = jax.grad(f, argnums=(0, 1))(p0, jnp.asarray(u))
    for k in FIELDS:
        h = 1e-6 * float(p0[k])
        fd = (float(f({**p0, k: p0[k] + h}, u)) - float(f({**p0, k: p0[k] - h}, u))) / (2 * h)
        assert float(g[0][k]) == pytest.approx(fd, rel=1e-6, abs=1e-9 * abs(float(f(p0, u))) / h), k
    h = 1e-7
    fd = (float(f(p0, u + h)) - float(f(p0, u - h))) / (2 * h)
    assert float(g[1]) == pytest.approx(fd, rel=1e-6)


def test_theta_mapping_roundtrip(column):
    u = jnp.linspace(-0.37, 0.37, 1001)
    for rigid in (False, True):
        th = rockjax.theta_from_u(column, u, rigid=rigid)
        np.testing.assert_allclose(rockjax.u_from_theta(column, th, rigid=rigid), u, atol=1e-13)
    # before lift-off: Eq 6; uplift zero before lift-off and positive after
    uc = float(column.u_crit)
    assert float(rockjax.theta_from_u(column, 0.5 * uc)) == pytest.approx(
        np.arcsin(0.5 * uc / 1.05), rel=1e-13
    )
    assert float(rockjax.uplift(column, 0.99 * uc)) == 0.0
    assert float(rockjax.uplift(column, 1.5 * uc)) > 0.0
