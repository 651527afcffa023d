"""Gradients of the identification loss and of a ground-motion run: reverse mode
(`jax.grad`) against forward mode (`jax.jacfwd`) and float64 central differences.

The loss is that of `benchmarks/gradients.py`: the sum of squared residuals of u against
the noisy synthetic decay trace (here its first 2 s, to keep the tests short), in
(k_f, r, u0), on the rk4 stepper and on the default method (diffrax). The record test
differentiates the peak |u| of a short ground motion with respect to single samples of the
record, which is what `notebooks/07_sensitivity.ipynb` does over all of El Centro.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import identification
import rockjax

T1 = 2.0  # s of the trace


def _fd5(f, x, h):
    """5-point central difference of f at x, step h."""
    return (-f(x + 2 * h) + 8 * f(x + h) - 8 * f(x - h) + f(x - 2 * h)) / (12 * h)


@pytest.fixture(scope="module")
def trace():
    tr = identification.read_trace(
        identification.synthetic_trace_path("synthetic_decay_noisy"))
    t = np.asarray(tr.t - tr.t[0])
    keep = t <= T1 + 1e-9
    return jnp.asarray(t[keep]), jnp.asarray(np.asarray(tr.u)[keep])


def _loss(column, trace, **kw):
    t, u_meas = trace
    dt = float(np.median(np.diff(np.asarray(t))))
    kw = dict(method="rk4", dt=dt) if kw.get("method") == "rk4" else kw

    def loss(p):
        k_f, r, u0 = p
        res = rockjax.simulate(column.replace(k_f=k_f), rockjax.FreeVibration(u0), T1,
                               ts=t, r=r, **kw)
        return jnp.sum((res.u - u_meas) ** 2)

    return loss


P0 = jnp.asarray([8.0e5, 0.85, 0.1])  # k_f [N/m], r, u0 [m]
H = np.asarray([80.0, 1e-5, 1e-6])  # central-difference steps


@pytest.mark.parametrize("method", ["rk4", pytest.param("diffrax", marks=pytest.mark.slow)])
def test_loss_gradient(column, trace, method):
    """grad == jacfwd (to rounding) == central differences (to ~1e-6)."""
    loss = _loss(column, trace, method=method)
    val, g = jax.jit(jax.value_and_grad(loss))(P0)
    fwd_loss = loss if method == "rk4" else _loss(column, trace, adjoint="forward")
    jf = jax.jit(jax.jacfwd(fwd_loss))(P0)
    np.testing.assert_allclose(g, jf, rtol=1e-9)
    f = jax.jit(loss)
    for j in range(3):
        e = jnp.zeros(3).at[j].set(1.0)
        fd = float(_fd5(lambda x: f(P0 + x * e), 0.0, H[j]))
        # diffrax: the gradient is that of the discrete solution with its step sizes
        # frozen; a difference quotient also moves the adaptive steps (at rtol 1e-10)
        rtol = 1e-6 if method == "rk4" else 1e-5
        floor = 50 * np.finfo(float).eps * abs(float(val)) / H[j]
        assert abs(float(g[j]) - fd) <= rtol * abs(fd) + floor, (j, float(g[j]), fd)


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes); CI runs it
def test_record_sample_gradient(column):
    """d peak|u| / d a_g(t_i) by one reverse pass, against central differences at a few
    samples (rk4, a short synthetic record)."""
    rec = rockjax.datasets.synthetic_ground_motion(duration=3.0, dt=0.01, pga=3.0, seed=3)
    gm = rockjax.GroundMotion.from_record(rec)  # dt concrete: built outside the trace
    accel = jnp.asarray(gm.accel)

    def peak(a):
        res = rockjax.simulate(column, eqx.tree_at(lambda g: g.accel, gm, a), 3.0,
                               method="rk4", fidelity_warning=False)
        return res.peak_u

    f = jax.jit(peak)
    g = np.asarray(jax.jit(jax.grad(peak))(accel))
    assert np.all(np.isfinite(g)) and np.any(g != 0)
    # samples after the peak do not move it
    res = rockjax.simulate(column, gm, 3.0, method="rk4", fidelity_warning=False)
    i_peak = int(np.argmax(np.abs(np.asarray(res.u))))
    assert np.all(g[i_peak + 2:] == 0)
    big = np.argsort(-np.abs(g))[:3]
    for i in [*big, i_peak // 2]:
        e = jnp.zeros_like(accel).at[i].set(1.0)
        fd = float(_fd5(lambda x: f(accel + x * e), 0.0, 1e-4))
        assert abs(g[i] - fd) <= 1e-5 * np.max(np.abs(g)), (i, g[i], fd)
