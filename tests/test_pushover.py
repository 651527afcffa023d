"""The numerical pushover of the rigid body against the closed forms (paper Fig 8)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

import rockjax
from rockjax import restoring_force, RockingStructure

SQUAT = RockingStructure(
    m_e=2000.0, m_b=800.0, H_e=1.2, H_b=0.15, B=1.0, I_eg=400.0, I_bg=150.0, k_f=2e6
)
SLENDER = RockingStructure(
    m_e=500.0, m_b=100.0, H_e=4.0, H_b=0.1, B=0.3, I_eg=900.0, I_bg=5.0, k_f=5e6
)


@pytest.fixture(scope="module", params=["table1", "squat", "slender"])
def case(request, column):
    s = {"table1": column, "squat": SQUAT, "slender": SLENDER}[request.param]
    u = jnp.linspace(-0.99, 0.99, 801) * s.u_overturn
    return s, u, rockjax.pushover(s, u)


def test_converged(case):
    _, _, res = case
    assert bool(jnp.all(res.converged))


def test_matches_exact_after_uplift(case):
    s, u, res = case
    a = jnp.abs(u)
    mask = (a >= 1.2 * s.u_crit) & (a <= 0.95 * s.u_overturn)
    err = jnp.max(jnp.abs(res.P - restoring_force(s, u, "exact"))[mask]) / s.P_crit
    assert float(err) < 1e-3  # acceptance: 0.1% of P_crit (measured ~1e-15)
    assert float(err) < 1e-10


def test_matches_linear_branch_before_uplift(case):
    s, u, res = case
    mask = jnp.abs(u) < 0.99 * s.u_crit
    err = jnp.max(jnp.abs(res.P - s.K1 * u)[mask]) / s.P_crit
    assert float(err) < 1e-4  # small-angle Eq 13 vs exact statics


def test_simplified_error_is_small(case):
    s, u, res = case
    a = jnp.abs(u)
    mask = (a >= 1.2 * s.u_crit) & (a <= 0.95 * s.u_overturn)
    err = jnp.max(jnp.abs(res.P - restoring_force(s, u))[mask]) / s.P_crit
    assert float(err) < 0.1


def test_statics_consistency(case):
    s, u, res = case
    # vertical force balance, odd P, even uplift, uplift only after lift-off
    np.testing.assert_allclose(res.f_left + res.f_right, float(s.W), rtol=1e-10)
    np.testing.assert_allclose(res.P, -res.P[::-1], atol=1e-9 * float(s.P_crit))
    np.testing.assert_allclose(res.uplift, res.uplift[::-1], atol=1e-14)
    a = jnp.abs(u)
    assert float(jnp.max(res.uplift[a < 0.99 * s.u_crit])) == 0.0
    assert bool(jnp.all(res.uplift[a > 1.01 * s.u_crit] > 0))
    np.testing.assert_allclose(res.uplift, rockjax.uplift(s, u), atol=1e-12)
    np.testing.assert_allclose(res.theta, rockjax.theta_from_u(s, u), atol=1e-12)


def test_overturn_displacement(case):
    s, _, _ = case
    uo = float(rockjax.overturn_displacement(s))
    assert uo == pytest.approx(float(s.u_overturn), rel=1e-3)  # acceptance 0.1%
    # the exact value is smaller by B (1 - cos theta_lift)
    tl = np.arcsin(float(s.delta_0 / s.B))
    assert float(s.u_overturn) - uo == pytest.approx(float(s.B) * (1 - np.cos(tl)), rel=1e-6)
