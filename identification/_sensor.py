r"""The sensor's own terms in a fit: a zero (offset) per channel and a linear drift.

A displacement transducer rarely reads exactly 0 m at rest: its zero is off by a few mm
(a sensor offset), and some drift slowly. The fit models what the sensor reads,

$$u_{meas}(t) = u(t) + o + d\,(t - t_{ref}) + \text{noise},\qquad
  v_{meas}(t) = v(t) + o_{up} + \text{noise},\qquad
  \theta_{meas}(t) = \theta(t) + o_\theta + \text{noise},$$

with $u$, $v$, $\theta$ the structure's displacement, uplift and rotation (the model),
$o$, $o_{up}$ the zeros of the displacement and uplift channels [m] (`offset`,
`offset_uplift`), $o_\theta$ that of the rotation channel [rad] (`offset_theta`), $d$ the drift
of the displacement channel [m/s] (`drift`) and $t_{ref}$ the release time the fit starts
from. They are nuisance parameters: fitted with the others, with standard errors, and
linear in the residuals (their Jacobian columns are written out, not differentiated
through the simulation: they cost nothing).

**When the offsets are fitted** (`fit_decay(..., offset=None)`, the default): when the
trace can pin the zero, i.e. when it holds at least two cycles of motion after the release
(the restoring force of a rocking structure is odd in u, so the centre of the oscillation
is the zero) or ends at rest (the structure at rest reads the zero). Both hold for any
decay trace of a few seconds; a trace of the first swing only pins neither, and then the
offset is not fitted (a note says so). The test is made on the first channel of the trace
(u, else theta, else the uplift, whose zero is pinned by two landings: the uplift is 0 in
contact); the offset of every channel fitted is fitted then. `offset=True` fits it
anyway, `offset=False` never.
The drift is fitted only when asked (`drift=True`): over a decay trace, a slow drift and
the decay of the envelope are hard to tell apart unless the trace ends at rest.
"""

from __future__ import annotations

import equinox as eqx
import numpy as np

from ._transforms import LINEAR

NUISANCE = LINEAR
"""The nuisance parameters: the zeros of the displacement and uplift channels [m], the
drift of the displacement channel [m/s] and the zero of the rotation channel [rad]."""
UNITS = {"offset": "m", "offset_uplift": "m", "drift": "m/s", "offset_theta": "rad"}
OFFSET_OF = {"u": "offset", "theta": "offset_theta", "uplift": "offset_uplift"}
"""The nuisance parameter of the zero of each channel."""
MIN_CROSSINGS = 4
"""Crossings of the centre line (two cycles) that pin the zero."""


def _crossings(u: np.ndarray, centre: float, band: float) -> int:
    """Crossings of `centre` with hysteresis `band` (noise does not count)."""
    state, n = 0, 0
    for x in u:
        s = 1 if x > centre + band else -1 if x < centre - band else 0
        if s and state and s != state:
            n += 1
        if s:
            state = s
    return n


def at_rest_at_end(u: np.ndarray, sigma: float) -> bool:
    """Whether the trace ends at rest: its last tenth (at least 10 samples) spreads less
    than max(6 sigma, 2 % of the amplitude) peak to peak."""
    n = u.size
    tail = u[-max(10, n // 10):]
    amp = float(np.max(np.abs(u - np.median(tail))))
    return float(np.ptp(tail)) < max(6.0 * sigma, 0.02 * amp)


def offset_pinned(t: np.ndarray, u: np.ndarray, release) -> tuple[bool, str]:
    """(whether the trace pins the zero of its displacement channel (or of the channel
    `u` the release was found in: the rotation, the uplift), why in words)."""
    after = u[t >= release.time]
    if after.size < 10:
        return False, "too few samples after the release"
    if getattr(release, "channel", "u") == "uplift":
        return _uplift_pinned(after, release.sigma)
    tail = after[-max(10, after.size // 4):]
    centre = float(np.median(tail))
    amp = float(np.max(np.abs(after - centre)))
    band = max(5.0 * release.sigma, 0.02 * amp)
    n = _crossings(after, centre, band)
    if n >= MIN_CROSSINGS:
        return True, f"{n // 2} cycles of motion after the release"
    if at_rest_at_end(after, release.sigma):
        return True, "the trace ends at rest"
    return False, (f"{n / 2:g} cycle(s) of motion after the release, and the trace does "
                   "not end at rest")


def _uplift_pinned(up: np.ndarray, sigma: float) -> tuple[bool, str]:
    """The uplift is 0 while both springs are in contact: two landings (crossings of half
    its range downwards), or a trace that ends at rest, pin its zero."""
    lo, amp = float(np.min(up)), float(np.ptp(up))
    band = max(5.0 * sigma, 0.02 * amp)
    n = _crossings(up, lo + 0.5 * amp, band)
    if n >= MIN_CROSSINGS - 1:
        return True, f"{(n + 1) // 2} landings after the release"
    if at_rest_at_end(up, sigma):
        return True, "the trace ends at rest"
    return False, f"{(n + 1) // 2} landing(s) after the release, and the trace does not end at rest"


def choose(params: tuple, offset, drift: bool, fits_uplift, t, u, release):
    """(the nuisance parameters to fit, notes): `offset` None (where the trace pins it),
    True or False; `drift`; those named in `params` are fitted whatever the keywords.
    `fits_uplift`: whether the uplift channel is fitted, or the tuple of the channels
    fitted (``"u"``, ``"theta"``, ``"uplift"``); `u`: the channel the release was found
    in."""
    fitted = (fits_uplift if isinstance(fits_uplift, tuple)
              else ("u", "uplift") if fits_uplift else ("u",))
    if offset not in (None, True, False):
        raise ValueError(f"offset must be None (where the trace pins it), True or False, "
                         f"got {offset!r}")
    if drift not in (True, False):
        raise ValueError(f"drift must be True or False, got {drift!r}")
    named = [p for p in params if p in NUISANCE]
    if offset is False and any(p in named for p in ("offset", "offset_uplift")):
        raise ValueError(f"offset=False contradicts params={params}: leave the offset out "
                         "of one of them")
    if drift is False and "drift" in named:
        drift = True
    absent = [p for p in named if p in OFFSET_OF.values()
              and next(c for c, o in OFFSET_OF.items() if o == p) not in fitted]
    if absent or (drift and "u" not in fitted):
        which = absent[0] if absent else "drift"
        raise ValueError(f"{which} is a parameter of a channel the fit does not have (its "
                         f"channels: {', '.join(fitted)}): leave it out")
    notes = []
    on = offset
    if offset is None:
        on, why = offset_pinned(t, u, release)
        if not on:
            notes.append(f"the sensor offset is not fitted: the trace cannot pin it ({why}); "
                         "pass offset=True to fit it anyway")
    out = list(named)
    if on:
        out += [OFFSET_OF[c] for c in fitted]
    if drift:
        out.append("drift")
    return tuple(p for p in NUISANCE if p in out), notes


def observe(response, values: dict, t, t_ref: float):
    """The response as the sensor reads it: `u` + offset + drift (t - t_ref), `uplift` +
    offset_uplift, `theta` + offset_theta (numpy arrays; `values` holds all of them, 0
    when not fitted)."""
    u = (np.asarray(response.u) + float(values.get("offset", 0.0))
         + float(values.get("drift", 0.0)) * (np.asarray(t) - t_ref))
    up = np.asarray(response.uplift) + float(values.get("offset_uplift", 0.0))
    th = np.asarray(response.theta) + float(values.get("offset_theta", 0.0))
    return eqx.tree_at(lambda r: (r.u, r.uplift, r.theta), response, (u, up, th))
