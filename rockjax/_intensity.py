r"""Intensity measures of a ground-motion record: PGA, PGV, PGD and Sa(T, ζ).

The record's acceleration is piecewise linear between its samples (as `GroundMotion`
defines it), and every measure here integrates that function exactly:

- PGA [m/s²]: max |a|;
- PGV [m/s] and PGD [m]: max |v| and max |d| of the exact integrals of the piecewise-linear
  acceleration, $v_{k+1} = v_k + \Delta t\,(a_k + a_{k+1})/2$ and
  $d_{k+1} = d_k + \Delta t\,v_k + \Delta t^2 (2a_k + a_{k+1})/6$, after a baseline
  correction (`baseline="end"`, the default: a constant is taken off the acceleration so
  that the ground ends at rest, $v(t_{end}) = 0$; `baseline=None`: as recorded);
- Sa(T, ζ) [m/s²]: the pseudo-spectral acceleration $\omega^2 \max_t |x(t)|$ of the linear
  oscillator $\ddot x + 2\zeta\omega\dot x + \omega^2 x = -a(t)$, $\omega = 2\pi/T$, from
  rest, by the exact recurrence for a piecewise-linear input (the matrix exponential of the
  oscillator augmented with the input and its slope), vectorised over periods. The peak is
  taken over the samples.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from ._errors import ParameterError
from ._excitation import GroundMotion
from ._records import Record


def _series(record, dt):
    """(acceleration [m/s²] as float64 numpy, dt [s]) of a Record, a GroundMotion of one
    record (its scale applied) or an array and dt."""
    if isinstance(record, Record):
        return np.asarray(record.accel, float), float(record.dt)
    if isinstance(record, GroundMotion):
        if np.ndim(record.accel) != 1 or np.ndim(record.dt) or np.ndim(record.scale):
            raise ParameterError("record: a GroundMotion of one record (1-D accel, scalar dt and "
                                 "scale)", param="record")
        return np.asarray(record.accel, float) * float(record.scale), float(record.dt)
    a = np.asarray(record, float)
    if a.ndim != 1 or a.size < 2:
        raise ParameterError(f"record must be a Record or a 1-D array of >= 2 samples, got "
                             f"shape {a.shape}", param="record")
    if dt is None or not np.isfinite(dt) or dt <= 0:
        raise ParameterError(f"dt must be a positive number of seconds with an array, got {dt!r}",
                             param="dt")
    if not np.all(np.isfinite(a)):
        raise ParameterError("record: the acceleration has non-finite samples", param="record")
    return a, float(dt)


def integrate_record(record, dt=None, *, baseline="end"):
    """(t [s], a [m/s²], v [m/s], d [m]) of a record, integrated exactly (module docs)."""
    a, dt = _series(record, dt)
    if baseline not in ("end", None):
        raise ParameterError(f"baseline must be 'end' or None, got {baseline!r}", param="baseline")
    t = np.arange(a.size) * dt
    if baseline == "end":
        v_end = dt * (np.sum(a) - 0.5 * (a[0] + a[-1]))
        a = a - v_end / t[-1]
    v = np.concatenate([[0.0], np.cumsum(dt * (a[:-1] + a[1:]) / 2)])
    inc = dt * v[:-1] + dt**2 * (2 * a[:-1] + a[1:]) / 6
    d = np.concatenate([[0.0], np.cumsum(inc)])
    return t, a, v, d


def pga(record, dt=None) -> float:
    """Peak ground acceleration [m/s²]."""
    a, _ = _series(record, dt)
    return float(np.max(np.abs(a)))


def pgv(record, dt=None, *, baseline="end") -> float:
    """Peak ground velocity [m/s] (module docs: exact integral, baseline correction)."""
    return float(np.max(np.abs(integrate_record(record, dt, baseline=baseline)[2])))


def pgd(record, dt=None, *, baseline="end") -> float:
    """Peak ground displacement [m] (module docs: exact integral, baseline correction)."""
    return float(np.max(np.abs(integrate_record(record, dt, baseline=baseline)[3])))


def _propagator(omega, zeta, dt):
    """exp(M dt) of the oscillator augmented with the input f and its slope s."""
    z = jnp.zeros_like(omega)
    M = jnp.array([[z, z + 1, z, z], [-omega**2, -2 * zeta * omega, z - 1, z],
                   [z, z, z, z + 1], [z, z, z, z]])
    return jax.scipy.linalg.expm(M * dt)


@jax.jit
def _peaks(a, dt, omegas, zeta):
    def one(omega):
        E = _propagator(omega, zeta, dt)

        def step(carry, ak):
            y, peak = carry
            a0, a1 = ak
            y = E[:2, :2] @ y + E[:2, 2] * a0 + E[:2, 3] * (a1 - a0) / dt
            return (y, jnp.maximum(peak, jnp.abs(y[0]))), None

        init = (jnp.zeros(2, a.dtype), jnp.zeros((), a.dtype))
        (_, peak), _ = jax.lax.scan(step, init, (a[:-1], a[1:]))
        return peak

    return jax.vmap(one)(omegas)


def spectral_acceleration(record, periods, zeta=0.05, dt=None):
    """Pseudo-spectral acceleration Sa(T, ζ) = ω² max|x| [m/s²] at each period T [s]
    (module docs), an array of the shape of `periods`."""
    a, dt = _series(record, dt)
    T = np.asarray(periods, float)
    if T.size == 0 or not np.all(np.isfinite(T)) or np.any(T <= 0):
        raise ParameterError(f"periods must be positive numbers of seconds, got {periods!r}",
                             param="periods")
    if not (np.isfinite(zeta) and 0 <= zeta < 1):
        raise ParameterError(f"zeta must lie in [0, 1), got {zeta!r}", param="zeta")
    omegas = 2 * np.pi / T.ravel()
    peaks = _peaks(jnp.asarray(a), jnp.asarray(dt), jnp.asarray(omegas), jnp.asarray(zeta))
    return (omegas**2 * np.asarray(peaks)).reshape(T.shape)
