"""Cubic Hermite interpolation on a step: values, roots and peaks (the stepper's tools)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np


def hermite(a0, m0, a1, m1, s):
    """Cubic Hermite interpolant on [0, 1] (ends a0, a1; end slopes m0, m1) and d/ds."""
    s2 = s * s
    s3 = s2 * s
    val = (
        (2 * s3 - 3 * s2 + 1) * a0
        + (s3 - 2 * s2 + s) * m0
        + (3 * s2 - 2 * s3) * a1
        + (s3 - s2) * m1
    )
    der = (6 * s2 - 6 * s) * (a0 - a1) + (3 * s2 - 4 * s + 1) * m0 + (3 * s2 - 2 * s) * m1
    return val, der


def _top(a0, m0, a1, m1):
    """The s in [0, 1] of the interpolant's maximum (where its slope falls to 0 from m0 > 0;
    0.5 when there is none)."""
    A = 3 * (2 * (a0 - a1) + m0 + m1)  # H'(s) = A s^2 + Bq s + m0
    Bq = -6 * (a0 - a1) - 4 * m0 - 2 * m1
    disc = Bq * Bq - 4 * A * m0
    pos = disc > 0  # a safe square root: finite derivatives on both sides of jnp.where
    root = jnp.where(pos, jnp.sqrt(jnp.where(pos, disc, 1.0)), 0.0)
    q = -0.5 * (Bq + jnp.where(Bq >= 0, 1.0, -1.0) * root)
    r1 = jnp.where(q != 0, m0 / jnp.where(q != 0, q, 1.0), 2.0)
    r2 = jnp.where(A != 0, q / jnp.where(A != 0, A, 1.0), 2.0)
    r1 = jnp.where((r1 > 0) & (r1 < 1), r1, 2.0)
    r2 = jnp.where((r2 > 0) & (r2 < 1), r2, 2.0)
    s = jnp.minimum(r1, r2)  # the first turn of the slope
    return jnp.where(s < 1, s, 0.5)


def root_bracket(a0, m0, a1, m1, grazing=True):
    """(left end s_l, value there) of the bracket of the interpolant's root. With
    `grazing`, a condition resting on its surface (a0 <= 0) and leaving it to the positive
    side (m0 > 0), as right after a jump, crosses zero later (a1 < 0): its root is
    bracketed from the interpolant's maximum, not from s = 0 (where a root at the start
    would repeat the jump). Without it (the SDOF models) the bracket starts at s = 0."""
    if not grazing:
        return jnp.zeros_like(a0), a0
    grazing = (a0 <= 0) & (m0 > 0)
    s_top = _top(a0, m0, a1, m1)
    g_top, _ = hermite(a0, m0, a1, m1, s_top)
    use = grazing & (g_top > 0)
    return jnp.where(use, s_top, 0.0), jnp.where(use, g_top, a0)


def root_estimate(a0, m0, a1, m1, grazing=True):
    """The linear estimate of the root in [0, 1] from its bracket (for ordering events)."""
    sl, gl = root_bracket(a0, m0, a1, m1, grazing)
    den = gl - a1
    return sl + (1 - sl) * jnp.where(den != 0, gl / jnp.where(den != 0, den, 1.0), 1.0)


def hermite_root(a0, m0, a1, m1, iters=4, grazing=True):
    """The s in [0, 1] where the Hermite interpolant is 0 (a0 >= 0 >= a1 bracket it, or a
    condition leaving its surface at s = 0 comes back: `root_bracket`).

    Safeguarded Newton (bisection when a Newton step leaves the bracket), finishing with two
    plain Newton steps so that the root is converged and carries the implicit-function
    derivative.
    """
    lo, g_lo = root_bracket(a0, m0, a1, m1, grazing)
    den = g_lo - a1
    safe = jnp.where(den != 0, den, 1.0)
    s = jnp.clip(lo + (1 - lo) * jnp.where(den != 0, g_lo / safe, 0.5), 0.0, 1.0)
    hi = jnp.ones_like(s)
    for _ in range(iters):
        g, der = hermite(a0, m0, a1, m1, s)
        above = g * g_lo > 0  # still on the starting side: the root lies beyond s
        lo = jnp.where(above, s, lo)
        hi = jnp.where(above, hi, s)
        ok = der != 0
        sn = s - g / jnp.where(ok, der, 1.0)
        s = jnp.where(ok & (sn > lo) & (sn < hi), sn, 0.5 * (lo + hi))
    for _ in range(2):  # plain Newton: converged, and the implicit-function derivative
        g, der = hermite(a0, m0, a1, m1, s)
        ok = der != 0
        s = jnp.clip(s - jnp.where(ok, g / jnp.where(ok, der, 1.0), 0.0), 0.0, 1.0)
    return s


def piece_peak(u0, v0, u1, v1, h, floor=None):
    """max |u| over a step, from its cubic Hermite interpolant (exact ends, interior turn).

    With `floor` (the running peak, shape of u0), the interior turn is only computed when
    it could exceed it for some member: the interpolant lies within the convex hull of its
    Bernstein control points u0, u0 + m0/3, u1 - m1/3, u1 (m = v h), so where the larger
    |.| of the two inner ones is at most `floor`, |u| stays below max(|u0|, |u1|, floor)
    and the turn cannot raise the running peak past the ends: the peak of the ends is
    returned instead (the same running peak, bit for bit). Few members turn with a chance
    to raise their peak; the turn's Newton iterations (three divisions) run only in the
    steps where one does (`jax.lax.cond`)."""
    m0 = v0 * h
    m1 = v1 * h
    turn = v0 * v1 < 0
    ends = jnp.maximum(jnp.abs(u0), jnp.abs(u1))

    def interior(_):
        den = m0 - m1
        s = jnp.clip(jnp.where(turn, m0 / jnp.where(turn, den, 1.0), 0.5), 0.0, 1.0)
        A = 6 * (u0 - u1) + 3 * m0 + 3 * m1
        Bq = -6 * (u0 - u1) - 4 * m0 - 2 * m1
        for _ in range(2):  # Newton on H'(s) = A s^2 + B s + m0
            d1 = (A * s + Bq) * s + m0
            d2 = 2 * A * s + Bq
            s = jnp.clip(s - d1 / jnp.where(d2 != 0, d2, 1.0), 0.0, 1.0)
        mid, _ = hermite(u0, m0, u1, m1, s)
        return jnp.maximum(ends, jnp.where(turn, jnp.abs(mid), 0.0))

    if floor is None:
        return interior(None)
    hull = jnp.maximum(jnp.abs(u0 + m0 * (1 / 3)), jnp.abs(u1 - m1 * (1 / 3)))
    return jax.lax.cond(jnp.any(turn & (hull > floor)), interior, lambda _: ends, None)


def resample(grid, u, v, ts):
    """Cubic Hermite interpolation of (u, v) from `grid` to `ts` (along the last axis)."""
    i = np.clip(np.searchsorted(grid, ts, side="right") - 1, 0, len(grid) - 2)
    dtype = u.dtype
    h = (grid[i + 1] - grid[i]).astype(dtype)
    s = ((ts - grid[i]) / (grid[i + 1] - grid[i])).astype(dtype)
    uu, du = hermite(u[..., i], v[..., i] * h, u[..., i + 1], v[..., i + 1] * h, s)
    return uu, du / h
