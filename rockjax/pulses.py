r"""Pulses as excitations: `rectangular`, `one_sine` and `one_cosine` ground accelerations.

Each returns a `rockjax.GroundMotion` whose samples are the pulse's shape and whose `scale`
is the amplitude [m/s²], so that a batch over amplitudes is `simulate_batch(..., scale=a)`:

- `rectangular(a, t1)`: $\ddot u_g(t) = a$ for $0 \le t \le t_1$ (Housner 1963);
- `one_sine(a, T)`: $\ddot u_g(t) = a \sin(2\pi t/T)$ for $0 \le t \le T$ (Zhang & Makris
  2001, type A: the ground velocity $\frac{aT}{2\pi}(1 - \cos 2\pi t/T)$ is one-signed and
  returns to zero);
- `one_cosine(a, T)`: $\ddot u_g(t) = a \cos(2\pi t/T)$ for $0 \le t \le T$ (type B: the
  velocity $\frac{aT}{2\pi}\sin 2\pi t/T$ makes one full cycle).

The ground acceleration is zero before $t = 0$ and after the pulse. The pulse's ends lie on
its samples (the first and last), and a `GroundMotion` is zero right after its last sample,
so the jumps at the ends (of the rectangular and one-cosine pulses) are exact. Between
samples a `GroundMotion` is linear; a rectangular pulse is therefore exact, and the samples
of the sine and cosine pulses are the pulse's values times
$c = \tan(h\omega_p/2)/(h\omega_p/2)$ ($h$ the sample step, $\omega_p = 2\pi/T$), which
makes the impulse $\int \ddot u_g\,dt$ of every sample interval, and so the ground velocity
at every sample, exact (the trapezoid rule integrates $e^{i\omega t}$ to $\frac{h\omega}{2}
\cot\frac{h\omega}{2}$ times the exact integral over any interval of whole steps). The
acceleration between samples is within $(h\omega_p)^2/12$ of the pulse's, relative to `a`
($2\times10^{-4}$ at the default 128 steps per period).
"""

from __future__ import annotations

import math

import numpy as np

from ._errors import ParameterError
from ._excitation import GroundMotion

__all__ = ["KINDS", "one_cosine", "one_sine", "pulse", "rectangular"]

#: the pulse kinds, with their aliases (the CLI's --pulse names)
KINDS = {"rectangular": "rectangular", "one_sine": "one_sine", "sine": "one_sine",
         "one_cosine": "one_cosine", "cosine": "one_cosine"}
#: the default sample step [s] cap: a record-like grid for the run after the pulse
MAX_DT = 0.005
#: the default number of sample steps over a sine or cosine pulse (at least)
MIN_STEPS = 128


def _positive(name, x):
    try:
        v = float(x)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a positive number, got {x!r}", param=name) from None
    if not (math.isfinite(v) and v > 0):
        raise ParameterError(f"{name} must be a positive finite number, got {x!r}", param=name)
    return v


def _amplitude(amplitude):
    try:
        a = float(amplitude)
    except (TypeError, ValueError):
        raise ParameterError(f"amplitude must be a number [m/s²], got {amplitude!r}",
                             param="amplitude") from None
    if not math.isfinite(a):
        raise ParameterError(f"amplitude must be finite [m/s²], got {amplitude!r}",
                             param="amplitude")
    return a


def _steps(length, steps, kind, max_dt):
    """The number of sample steps over the pulse: `steps`, or enough for `max_dt`."""
    if steps is None:
        least = 1 if kind == "rectangular" else MIN_STEPS
        return max(least, math.ceil(length / _positive("max_dt", max_dt) - 1e-9))
    if isinstance(steps, bool) or not isinstance(steps, (int, np.integer)) or steps < 1:
        raise ParameterError(f"steps must be a positive integer, got {steps!r}", param="steps")
    if kind != "rectangular" and steps < 8:
        raise ParameterError(f"steps must be at least 8 for a {kind} pulse, got {steps}",
                             param="steps")
    return int(steps)


def shape_samples(kind, n):
    r"""The unit shape of a pulse at its n + 1 samples $t_k = k T / n$ (the sine and
    cosine scaled by $c$ for an exact impulse per interval; see the module docstring)."""
    if kind == "rectangular":
        return np.ones(n + 1)
    x = 2.0 * math.pi * np.arange(n + 1) / n
    half = math.pi / n  # h omega_p / 2
    c = math.tan(half) / half
    return c * (np.sin(x) if kind == "one_sine" else np.cos(x))


def pulse(kind, amplitude, length, *, steps=None, max_dt=MAX_DT):
    """A pulse of `kind` ("rectangular", "one_sine"/"sine", "one_cosine"/"cosine") as a
    `GroundMotion`: `amplitude` [m/s²], `length` [s] its duration (rectangular) or period.
    `steps`: sample steps over the pulse (default: enough for a step of at most `max_dt`
    [s], and at least 128 for a sine or cosine)."""
    if kind not in KINDS:
        raise ParameterError(f"kind must be one of {sorted(KINDS)}, got {kind!r}", param="kind")
    kind = KINDS[kind]
    a = _amplitude(amplitude)
    T = _positive("duration" if kind == "rectangular" else "period", length)
    n = _steps(T, steps, kind, max_dt)
    return GroundMotion(dt=T / n, accel=shape_samples(kind, n), scale=a)


def rectangular(amplitude, duration, *, steps=None, max_dt=MAX_DT):
    r"""Housner's rectangular pulse $\ddot u_g = a$ [m/s²] for $0 \le t \le t_1$ =
    `duration` [s], zero after: a `GroundMotion` (exact; `steps` samples steps over it,
    default one per `max_dt` [s])."""
    return pulse("rectangular", amplitude, duration, steps=steps, max_dt=max_dt)


def one_sine(amplitude, period, *, steps=None, max_dt=MAX_DT):
    r"""One full sine $\ddot u_g = a\sin(2\pi t/T)$ [m/s²] for $0 \le t \le T$ = `period`
    [s], zero after (Zhang & Makris 2001, type A): a `GroundMotion` with an exact impulse
    per sample interval (module docstring)."""
    return pulse("one_sine", amplitude, period, steps=steps, max_dt=max_dt)


def one_cosine(amplitude, period, *, steps=None, max_dt=MAX_DT):
    r"""One full cosine $\ddot u_g = a\cos(2\pi t/T)$ [m/s²] for $0 \le t \le T$ =
    `period` [s], zero before and after (Zhang & Makris 2001, type B; it jumps to `a` at
    $t = 0$ and from `a` to zero at $T$): a `GroundMotion` with an exact impulse per sample
    interval (module docstring)."""
    return pulse("one_cosine", amplitude, period, steps=steps, max_dt=max_dt)
