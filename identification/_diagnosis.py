r"""What residuals that are not noise look like: the cause the lack-of-fit check names.

When the lack-of-fit check fires (`identification._lack`), the residuals $e$ (model less
trace, kept samples, time order) are split into the parts that explain them, each checked
in turn; the first that holds more than `SHARE` of their mean square names the cause:

1. **offset**: their mean $\bar e$, $\bar e^2 / \overline{e^2}$ > `SHARE`: a sensor zero
   that the fit does not model (the trace reads $-\bar e$ too high); fit it with
   `offset=True`.
2. **drift**: a straight line $a + b\,(t - \bar t)$, its slope part
   $b^2\,\overline{(t-\bar t)^2} / \overline{e^2}$ > `SHARE` / 2 and the line's share
   > `SHARE`: a drifting sensor ($-b$ m/s); fit it with `drift=True`.
3. **periodic**: after the line, the periodogram's highest peak (at $f$ > 0, with its two
   neighbours on each side) holds more than `SHARE` of what is left, and its amplitude is
   steady over the trace (the sine fitted to each quarter at $f$ varies by less than a
   factor `STEADY`): an oscillation at $f$ Hz that the structure's decaying motion does not
   make: mains hum (50 or 60 Hz, or a multiple), a vibration, aliasing. A decaying peak
   (the bounce of a body the model lacks) is not this: it falls to the next.
4. **model**: anything else: the model cannot follow the trace (or the fit stopped in a
   local minimum).

A second release in the trace and a clipped (saturated) trace are found before the fit,
in the trace itself (`identification._anomalies`): `fit_decay` refuses them, naming the
release time or the clipping level and samples.
"""

from __future__ import annotations

import math

import numpy as np

SHARE = 0.5
"""The share of the residuals' mean square that a part must hold to name the cause."""
STEADY = 2.0
"""A periodic part is steady when its amplitude over each quarter of the trace varies by
less than this factor."""
MAINS = (50.0, 60.0)


def _sine_amplitude(t, e, f):
    c = np.column_stack([np.cos(2 * np.pi * f * t), np.sin(2 * np.pi * f * t),
                         np.ones_like(t)])
    coef = np.linalg.lstsq(c, e, rcond=None)[0]
    return float(math.hypot(coef[0], coef[1]))


def _periodic(t: np.ndarray, e: np.ndarray):
    """(frequency [Hz], amplitude [m], share of the mean square, steady) of the highest
    periodogram peak of `e` (uniformly sampled at times `t`), or None."""
    n = e.size
    if n < 16:
        return None
    dt = float(np.median(np.diff(t)))
    spec = np.abs(np.fft.rfft(e * np.hanning(n))) ** 2
    spec[0] = 0.0
    k = int(np.argmax(spec[1:])) + 1
    band = spec[max(1, k - 2): k + 3].sum()
    share = float(band / max(spec.sum(), 1e-300))
    # the peak's frequency, refined by a parabola through the log power
    f = k / (n * dt)
    if 1 <= k < spec.size - 1 and min(spec[k - 1], spec[k + 1]) > 0:
        a, b, c = np.log(spec[k - 1: k + 2])
        den = a - 2 * b + c
        if den < 0:
            f += 0.5 * (a - c) / den / (n * dt)
    amp = _sine_amplitude(t, e, f)
    quarters = [_sine_amplitude(tq, eq, f) for tq, eq in
                zip(np.array_split(t, 4), np.array_split(e, 4)) if tq.size * dt * f >= 2]
    steady = len(quarters) == 4 and max(quarters) < STEADY * max(min(quarters), 1e-300)
    return f, amp, share, steady


def _mains(f: float) -> str:
    for m in MAINS:
        h = f / m
        if round(h) >= 1 and abs(h - round(h)) < 0.02:
            which = "" if round(h) == 1 else f" (harmonic {round(h)})"
            return f"mains hum at {m:g} Hz{which}, "
    return ""


def diagnose(e: np.ndarray, t: np.ndarray, model: str, fitted=()) -> dict:
    """The cause of residuals `e` [m] (model - trace) at times `t` [s] that are not noise:
    a dict with `cause` ("offset", "drift", "periodic" or "model"), `message` (in words,
    with the remedy) and the figures of that cause (`offset_m`, `drift_m_per_s`,
    `frequency_hz`, `amplitude_m`; `share`: of the residuals' mean square)."""
    e, t = np.asarray(e, float), np.asarray(t, float)
    ms = float(np.mean(e**2)) if e.size else 0.0
    if ms <= 0:
        return {"cause": "model", "share": 0.0, "message": f"the {model} model"}
    mean = float(np.mean(e))
    if mean**2 / ms > SHARE:
        off = -mean  # the trace reads this much above the model
        how = ("the offset is fitted already: it is not constant (a drift? fit it with "
               "drift=True)" if "offset" in fitted else "fit it with offset=True")
        return {"cause": "offset", "offset_m": off, "share": mean**2 / ms,
                "message": f"a constant offset of the sensor: the trace reads "
                           f"{1e3 * off:+.3g} mm from the model throughout; {how}"}
    tc = t - t.mean()
    var_t = float(np.mean(tc**2))
    slope = float(np.mean(tc * (e - mean)) / var_t) if var_t > 0 else 0.0
    line_share = (mean**2 + slope**2 * var_t) / ms
    if slope**2 * var_t / ms > SHARE / 2 and line_share > SHARE:
        drift = -slope
        how = ("the drift is fitted already: it is not linear" if "drift" in fitted
               else "fit it with drift=True")
        return {"cause": "drift", "drift_m_per_s": drift, "offset_m": -mean,
                "share": line_share,
                "message": f"a drift of the sensor: the trace moves away from the model at "
                           f"{1e3 * drift:+.3g} mm/s; {how}"}
    rest = e - mean - slope * tc
    per = _periodic(t, rest)
    if per is not None:
        f, amp, share, steady = per
        if share > SHARE and steady:
            return {"cause": "periodic", "frequency_hz": f, "amplitude_m": amp,
                    "share": share,
                    "message": f"a periodic component at {f:.4g} Hz of steady amplitude "
                               f"{1e3 * amp:.3g} mm ({_mains(f)}a vibration of the "
                               "set-up, or aliasing: not the structure's decaying "
                               f"motion); filter it out (a notch at {f:.4g} Hz) and fit "
                               "again"}
    return {"cause": "model", "share": 1.0, "message": f"the {model} model"}
