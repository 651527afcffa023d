"""What tests/test_literature.py and benchmarks/literature.py share: the literature's
closed forms (Housner's linearised rectangular-pulse threshold, the critical double
impulse of Nabeshima et al. 2016), the blocks they are checked on, and the double-impulse
runs. Units: SI."""

from __future__ import annotations

import math

import numpy as np

import rockjax
from rockjax import GroundMotion, simulate

#: the rectangular pulses' p t1 (Housner 1963)
PT1 = np.array([0.5, 1.0, 2.0])


def linearised_threshold(pt1):
    """Housner's linearised rectangular-pulse threshold a/(g tan alpha)."""
    return 1.0 / (1.0 - np.exp(-np.asarray(pt1)))


def point_mass_block(alpha, h=1.0, m=1000.0, k_f=1e10):
    """A block whose mass sits at its centroid (height h [m], slenderness alpha): for it
    the `housner` SDOF (inertia m about the top mass) linearises to Housner's equation
    theta'' = p^2 (theta - alpha + a/g) with p^2 = g/R = W R / I_O."""
    return rockjax.RockingStructure(m_e=m / 2, m_b=m / 2, H_e=h, H_b=h, B=h * math.tan(alpha),
                                    I_eg=0.0, I_bg=0.0, k_f=k_f)


def uniform_block(h, k_f=1e10, ratio=0.15, m1=1000.0):
    """A uniform block 2b x 2h [m] (b = ratio h) of mass m1 h^3 [kg] (a solid block of
    depth proportional to its size: 1,000 kg at h = 1 m), as two equal halves at its
    centroid."""
    b = ratio * h
    m = m1 * h**3
    inertia = 0.5 * m * (b * b + h * h) / 3.0
    return rockjax.RockingStructure(m_e=m / 2, m_b=m / 2, H_e=h, H_b=h, B=b, I_eg=inertia,
                                    I_bg=inertia, k_f=k_f)


def critical_double_impulse(s):
    """Nabeshima, Taniguchi, Kojima & Takewaki (2016): the velocity amplitude V [m/s] of
    the double impulse (ground velocity +V at t = 0, back to 0 just after the block's
    first impact, the critical timing) that just overturns Housner's block.

    Angular momentum about the pivot: an impulse V at theta = 0 gives the block
    theta' = M V R cos(alpha) / I_O; the impact scales theta' by eta = sqrt(r); the second
    impulse, just after the impact, adds M V R cos(alpha) / I_O again. Energy after it:
    I_O ((1 + eta) M V R cos(alpha) / I_O)^2 / 2 = W R (1 - cos(alpha)) to reach the
    top. So V = sqrt(2 W R (1 - cos alpha) I_O) / ((1 + eta) M R cos alpha); for a
    uniform rectangular block (I_O = 4 M R^2 / 3) V = sqrt(8 g R (1 - cos alpha) / 3) /
    ((1 + eta) cos alpha)."""
    M, W, R, a, I = (float(x) for x in (s.mass, s.W, s.R_c, s.alpha_c, s.I_O))
    eta = math.sqrt(float(s.restitution))
    return math.sqrt(2 * W * R * (1 - math.cos(a)) * I) / ((1 + eta) * M * R * math.cos(a))


def double_impulse(V, t2, *, eps=2e-3, dt=5e-4, T=2.5):
    """Ground acceleration [m/s²] of the impulses +V at t = 0 and -V from t2 [s], each a
    rectangle of about eps [s] sampled at dt [s] (impulses exact: the sample ramps
    counted), zero elsewhere; t2 None: the first impulse alone."""
    n = int(round(T / dt)) + 1
    acc = np.zeros(n)
    k = int(round(eps / dt))
    acc[:k] = V / ((k - 0.5) * dt)  # from t = 0 at full value, one ramp down
    if t2 is not None:
        j = int(math.ceil(t2 / dt))
        acc[j:j + k] = -V / (k * dt)  # a ramp up and a ramp down
    return GroundMotion(dt=dt, accel=acc)


def double_impulse_run(s, V, *, eps=2e-3, dt=5e-4, T=2.5, model="rigid_body"):
    """(status of the double impulse, first impact time [s]): the second impulse starts
    at the first sample after the block's first impact under the first impulse alone."""
    ts = np.array([0.0, T])
    one = simulate(s, double_impulse(V, None, eps=eps, dt=dt, T=T), T, ts=ts, model=model)
    t_imp = float(np.asarray(one.impact_times)[0])
    assert one.status_name == "completed" and np.isfinite(t_imp)
    two = simulate(s, double_impulse(V, t_imp, eps=eps, dt=dt, T=T), T, ts=ts, model=model)
    return two.status_name, t_imp
