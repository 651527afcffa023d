"""The release of a decay trace: where its free vibration starts (`detect_release`).

A lab trace often starts before the release: the structure held at its initial
displacement for a while, or a logger clock that does not start at 0. `detect_release`
finds the end of the initial plateau (noise-aware) and refines the release time by fitting
``u0 - c (t - t0)^2`` to the start of the motion. It works on the first channel of the
motion the trace has (`DecayTrace.channels`: u, else the rotation theta, else the uplift):
released from rest, each of them starts as that parabola (the uplift, non-negative, from
its level at the release down towards the landing).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ._trace import DecayTrace, MIN_SAMPLES

__all__ = ["detect_release", "Release", "RELEASE_SIGMAS"]


RELEASE_SIGMAS = 5.0
"""A sample departs from the initial plateau when it lies more than this many noise standard
deviations from the plateau's level, and so do the next two."""
_PERSIST = 3  # consecutive samples beyond the threshold that make a departure
_HOLD_STEPS = 3.0  # a release more than this many steps after the first sample: a hold


@dataclasses.dataclass(frozen=True)
class Release:
    """Where the free vibration of a decay trace starts (see :func:`detect_release`).

    - ``time`` [s]: the release time to use: ``estimate`` when the trace starts with a
      hold (``held``), else the first sample's time.
    - ``estimate`` [s]: the release time fitted to the start of the motion.
    - ``index``: the last sample of the initial plateau, before the signal departs from it.
    - ``level`` [m, or rad for ``channel`` theta]: the channel's value at the release:
      the fitted plateau level when ``held``, else the first sample.
    - ``sigma``: the noise standard deviation of the channel used; ``threshold``: the
      departure threshold (``RELEASE_SIGMAS`` sigma); in the channel's unit.
    - ``held``: the trace starts with a hold (or a clock offset): ``estimate`` lies more
      than 3 sample steps after the first sample.
    - ``channel``: the channel the release was found in (``"u"``, ``"theta"`` or
      ``"uplift"``).
    """

    time: float
    estimate: float
    index: int
    level: float
    sigma: float
    threshold: float
    held: bool
    channel: str = "u"

    def as_dict(self) -> dict:
        """JSON-ready, keys with their units (``level_rad``, ``noise_sigma_rad``,
        ``threshold_rad`` for a release found in the rotation; ``channel`` unless u)."""
        unit = "rad" if self.channel == "theta" else "m"
        out = {"release_time_s": self.time, "estimate_s": self.estimate,
               "plateau_last_index": self.index, f"level_{unit}": self.level,
               f"noise_sigma_{unit}": self.sigma, f"threshold_{unit}": self.threshold,
               "held": self.held}
        return out if self.channel == "u" else {**out, "channel": self.channel}


def detect_release(trace: DecayTrace, *, sigmas: float = RELEASE_SIGMAS,
                   channel: str | None = None) -> Release:
    r"""Find where the free vibration of a decay trace starts (a :class:`Release`).

    Lab traces often start before the release: the structure held at its initial
    displacement (noisy samples about a constant), or a logger clock that does not start
    at 0. The detection, in three steps:

    1. **Noise.** $\sigma$ = 1.4826 MAD of the second differences $/\sqrt6$ (white noise
       of std $\sigma$ gives second differences of std $\sqrt6\,\sigma$; the smooth motion
       adds little at usual rates); when 10 samples or more precede the release found
       with it (a hold), the robust spread (1.4826 MAD) of those, and steps 2-3 again.
    2. **Plateau.** From the first sample up to the last one before the first run of 3
       samples that all lie more than `sigmas` $\sigma$ from the plateau's median (iterated:
       a single spike does not end it).
    3. **Release time.** A structure released at rest starts as
       $u = u_0 - c\,(t - t_0)^2$: that hinge (constant, then parabola) is fitted by least
       squares to the end of the plateau and the start of the motion (up to a departure of
       max(4 threshold, 10 % of $u_0$)), $t_0$ on a grid of 1/20 step, $u_0$ and $c$
       linear. Unlike the last plateau sample, which lags by the time the motion takes to
       exceed the noise, this is not biased late.

    The trace starts with a hold when the release lies more than 3 steps after the first
    sample; otherwise it is taken to start at the release (``time`` = ``t[0]``, ``level`` =
    ``u[0]``).

    `channel`: the channel to find it in (``"u"``, ``"theta"``, ``"uplift"``); default the
    first the trace has (`DecayTrace.channels`).
    """
    channel = trace.channels[0] if channel is None else channel
    if getattr(trace, channel, None) is None:
        raise ValueError(f"detect_release: the trace has no {channel!r} channel (it has "
                         f"{', '.join(trace.channels)})")
    t, u = np.asarray(trace.t), np.asarray(getattr(trace, channel))
    dt = float(np.median(np.diff(t)))
    sigma = _noise_sigma(u)
    k, level, thr = _plateau(u, sigma, sigmas)
    est, fitted_level = _hinge_fit(t, u, k, level, thr)
    plat = u[t < est - dt]  # the hold, if any: its spread is the noise
    if plat.size >= MIN_SAMPLES:
        s_plat = 1.4826 * float(np.median(np.abs(plat - np.median(plat))))
        if s_plat > 0:
            sigma = s_plat
            k, level, thr = _plateau(u, sigma, sigmas)
            est, fitted_level = _hinge_fit(t, u, k, level, thr)
    held = bool(est - t[0] > _HOLD_STEPS * dt)
    return Release(time=est if held else float(t[0]), estimate=est, index=k,
                   level=fitted_level if held else float(u[0]), sigma=sigma,
                   threshold=thr, held=held, channel=channel)


def _noise_sigma(u: np.ndarray) -> float:
    """Noise std from the robust spread of the second differences."""
    d2 = np.diff(u, 2)
    return 1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / math.sqrt(6.0)


def _plateau(u: np.ndarray, sigma: float, sigmas: float) -> tuple[int, float, float]:
    """(last index of the initial plateau, its median, the departure threshold)."""
    n = u.size
    thr = max(sigmas * sigma, 1e-9 * float(np.max(np.abs(u))))
    level = float(np.median(u[: min(5, n)]))
    k = 0
    for _ in range(8):
        out = np.abs(u - level) > thr
        run = np.ones(n - _PERSIST + 1, bool)
        for j in range(_PERSIST):
            run &= out[j : n - _PERSIST + 1 + j]
        starts = np.flatnonzero(run)
        k = max(int(starts[0]) - 1, 0) if starts.size else n - 1
        new = float(np.median(u[: k + 1]))
        if new == level:
            break
        level = new
    return k, level, thr


def _hinge_fit(t: np.ndarray, u: np.ndarray, k: int, level: float,
               thr: float) -> tuple[float, float]:
    """(release time, level) of the least-squares hinge u = L - c max(t - t_r, 0)^2 over
    the end of the plateau and the start of the motion (see `detect_release`)."""
    n = u.size
    reach = max(4.0 * thr, 0.1 * abs(level))
    beyond = np.flatnonzero(np.abs(u[k + 1 :] - level) > reach)
    e = min(k + 1 + (int(beyond[0]) + 1 if beyond.size else n), n)  # window end
    e = max(e, min(k + 4, n))
    w0 = max(0, k + 1 - max(20, 2 * (e - k - 1)))  # some of the plateau, not all of it
    tw, uw = t[w0:e], u[w0:e]
    dt = float(np.median(np.diff(t)))
    lo, hi = float(tw[0]) - 2 * dt, float(t[min(k + 1, n - 1)])
    cand = np.linspace(lo, hi, int(min(4000, max(2, 20 * (hi - lo) / dt))))
    q = np.maximum(tw[None, :] - cand[:, None], 0.0) ** 2  # (candidates, window)
    qc = q - q.mean(axis=1, keepdims=True)
    uc = uw - uw.mean()
    var_q = np.sum(qc**2, axis=1)
    cov = qc @ uc
    ok = var_q > 0
    gain = np.where(ok, cov**2 / np.where(ok, var_q, 1.0), -np.inf)  # RSS reduction
    if not np.any(ok):
        return float(t[k]), level
    i = int(np.argmax(gain))
    c = -cov[i] / var_q[i]
    return float(cand[i]), float(uw.mean() + c * q[i].mean())
