"""Housner's rigid rocking block as a reference, shared by `tests/test_twospring.py` and
`benchmarks/housner_2dof.py`: a uniform block on very stiff springs, and the rigid
block's zero-crossing times and amplitudes (exact, by energy quadrature). SI units."""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import quad

import rockjax


def uniform_block(k_f, b=0.15, h=1.0, m=1000.0):
    """A uniform block 2b x 2h [m] of mass m [kg], split into two equal halves at the
    centroid, on springs k_f [N/m]."""
    inertia = 0.5 * m * (b * b + h * h) / 3.0
    return rockjax.RockingStructure(m_e=m / 2, m_b=m / 2, H_e=h, H_b=h, B=b, I_eg=inertia,
                                    I_bg=inertia, k_f=k_f)


def housner_block(s, th0, n):
    """Housner's rigid block released at rest from th0 [rad]: the times [s] of its first n
    zero crossings (exact quarter periods by energy quadrature) and its amplitudes [rad]
    after each impact, from the energy balance cos(a - th_k+1) - cos(a) = r (cos(a - th_k)
    - cos(a)) (Eq. 2: the kinetic energy at an impact falls by r)."""
    W, R, a, I, r = (float(x) for x in (s.W, s.R_c, s.alpha_c, s.I_O, s.restitution))

    def quarter(amp):
        def rate(th):
            return math.sqrt(2 * W * R * (math.cos(a - amp) - math.cos(a - th)) / I)
        # th = amp - x^2 removes the integrable singularity at the turning point
        return quad(lambda x: 2 * x / rate(amp - x * x), 0.0, math.sqrt(amp), limit=200)[0]

    times, amps, t, amp = [], [th0], quarter(th0), th0
    for _ in range(n):
        times.append(t)
        amp = a - math.acos(math.cos(a) + r * (math.cos(a - amp) - math.cos(a)))
        amps.append(amp)
        t += 2 * quarter(amp)
    return np.asarray(times), np.asarray(amps)
