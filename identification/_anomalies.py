"""Traces a decay fit must not take at face value: a clipped sensor, a second release.

Both are found in the trace itself, before the fit (`fit_decay` refuses them with a
`TraceError` that names what was found; `check_trace` is its test):

- **Clipping (saturation).** A sensor at the end of its range reads the same value, to the
  last digit, for as long as the structure stays beyond it. `find_clipping` looks at the
  two extremes of the displacement: a plateau of `MIN_RUN` or more samples exactly at the
  trace's maximum (or minimum) that is not its initial hold, or an initial hold exactly
  constant although the rest of the trace is noisy, is clipping. A fit would read the
  plateau at the start as a hold and each clipped swing as motion (k_f +248 % on a trace
  clipped at +-50 mm): refused, naming the level and the samples. (Not masked: when the
  start is clipped, the release displacement is unknown.)
- **A second release.** A file that holds two tests: the motion dies out (the trace at
  rest), then the structure is displaced and released again. `find_second_release` finds
  the first quiet stretch after the first release (a window of `QUIET_S` over which the
  trace spreads less than max(8 sigma, 3 % of the amplitude)) followed by a departure of
  more than 20 % of the amplitude lasting `PERSIST` samples (spikes do not count).
  Refused, naming the release times and the two segments: fit each
  (`split_releases(trace)` gives them), or both at once (`fit_decay(split_releases(trace),
  structure)`, a joint fit).
"""

from __future__ import annotations

import numpy as np

from ._trace import DecayTrace, TraceError

MIN_RUN = 3
"""Samples exactly at an extreme, in a row, that make a clipped plateau."""
QUIET_S = 0.25
"""The window [s] over which the trace must be at rest between two releases."""
PERSIST = 5
"""Samples in a row beyond 20 % of the amplitude that make a second release."""


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) of the runs of True in `mask`."""
    d = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def find_clipping(t, u, sigma: float, sides=("upper", "lower")) -> list[dict]:
    """The clipped plateaus of `u`, one dict per side (`level` [m], `side`, `plateaus`:
    (first, last) sample indices, `n_samples`, `times` [s] of each plateau); empty if none.
    `sigma`: the noise std of the trace (an exactly constant initial hold in a noisy trace
    is clipping too). `sides`: those to look at (an uplift, 0 in contact, only the upper)."""
    u = np.asarray(u, float)
    t = np.asarray(t, float)
    amp = float(np.max(np.abs(u)))
    tol = 1e-9 * amp
    out = []
    for side, level in (("upper", float(np.max(u))), ("lower", float(np.min(u)))):
        if side not in sides:
            continue
        runs = [(a, b) for a, b in _runs(np.abs(u - level) <= tol) if b - a >= MIN_RUN]
        later = [r for r in runs if r[0] > 0]
        noisy_hold = bool(runs and runs[0][0] == 0 and sigma > 1e-6 * amp)
        if not later and not noisy_hold:
            continue
        out.append({"side": side, "level": level, "plateaus": [(int(a), int(b - 1))
                                                                 for a, b in runs],
                    "n_samples": int(sum(b - a for a, b in runs)),
                    "times": [(float(t[a]), float(t[b - 1])) for a, b in runs]})
    return out


def find_second_release(t, u, release) -> int | None:
    """The index where a second test starts in the trace (the first sample within 10 % of
    the second motion's largest deviation from rest), or None."""
    t, u = np.asarray(t, float), np.asarray(u, float)
    dt = float(np.median(np.diff(t)))
    w = max(10, int(round(QUIET_S / dt)))
    i0 = int(np.searchsorted(t, release.time)) + w
    amp = float(np.max(np.abs(u - np.median(u[-w:]))))
    quiet_thr = max(8.0 * release.sigma, 0.03 * amp)
    n = u.size
    for s in range(i0, n - w, max(1, w // 2)):
        win = u[s:s + w]
        if np.ptp(win) >= quiet_thr:
            continue
        rest = float(np.median(win))
        beyond = (np.abs(u[s + w:] - rest) > 0.2 * amp).astype(int)
        if beyond.size < PERSIST:
            return None
        hits = np.flatnonzero(np.convolve(beyond, np.ones(PERSIST, int), "valid") == PERSIST)
        if not hits.size:
            return None
        j0 = s + w + int(hits[0])
        dev = np.abs(u[j0:] - rest)
        peak = float(np.max(dev))
        return j0 + int(np.flatnonzero(dev >= 0.9 * peak)[0])
    return None


def _segment(trace: DecayTrace, a: int, b: int, k: int) -> DecayTrace:
    cut = {c: np.asarray(getattr(trace, c))[a:b] for c in trace.channels}
    src = f"{trace.source or 'trace'} [release {k}: samples {a}..{b - 1}]"
    return DecayTrace(np.asarray(trace.t)[a:b], source=src, **cut)


def split_releases(trace: DecayTrace) -> list[DecayTrace]:
    """The segments of a trace that holds several releases, one per release (a list of
    one, the trace itself, when it holds one): fit each with `fit_decay`, or all of them
    at once (`fit_decay(split_releases(trace), structure)`, k_f and r shared)."""
    from ._release import detect_release

    out, start = [], 0
    while True:
        seg = _segment(trace, start, trace.n, len(out) + 1) if start else trace
        k = find_second_release(seg.t, getattr(seg, seg.channels[0]), detect_release(seg))
        if k is None:
            out.append(seg)
            return out
        out.append(_segment(trace, start, start + k, len(out) + 1))
        start += k


def check_trace(trace: DecayTrace, release):
    """TraceError if the trace is clipped or holds a second release (module docstring)."""
    ch = getattr(release, "channel", "u")  # the channel the release was found in
    t, u = np.asarray(trace.t, float), np.asarray(getattr(trace, ch), float)
    unit = "mrad" if ch == "theta" else "mm"
    clipped = find_clipping(t, u, release.sigma,
                            ("upper",) if ch == "uplift" else ("upper", "lower"))
    if clipped:
        parts = []
        for c in clipped:
            spans = ", ".join(f"{a:.4g}-{b:.4g} s" for a, b in c["times"][:4])
            more = f" and {len(c['times']) - 4} more" if len(c["times"]) > 4 else ""
            first = ", ".join(f"{a}..{b}" for a, b in c["plateaus"][:4])
            parts.append(f"at {1e3 * c['level']:+.4g} {unit} ({c['side']}): {c['n_samples']} "
                         f"samples in {len(c['plateaus'])} plateau(s), t = {spans}{more} "
                         f"(samples {first})")
        msg = ("the trace is clipped (the sensor saturated) " + "; ".join(parts) + ": the "
               "sensor reads its limit whatever the structure does there, and a fit would "
               "take the plateau for a hold or for motion. Not fitted: record within the "
               "sensor's range, or cut the trace (DecayTrace(t[a:b], u[a:b])) to a stretch "
               "that starts at a release and stays inside it")
        raise TraceError(msg)
    k = find_second_release(t, u, release)
    if k is not None:
        from ._release import detect_release

        segs = split_releases(trace)
        rel = [detect_release(s).time for s in segs]
        spans = "; ".join(f"segment {i + 1}: t = {s.t[0]:.4g}-{s.t[-1]:.4g} s, release at "
                          f"{r:.4g} s" for i, (s, r) in enumerate(zip(segs, rel)))
        msg = (f"the trace holds {len(segs)} releases (the motion dies out, then starts "
               f"again at t = {rel[1]:.4g} s): {spans}. A fit of it would take the second "
               "test for motion of the first. Fit each segment, "
               "identification.split_releases(trace)[i], or both at once, "
               "fit_decay(identification.split_releases(trace), structure) (k_f and r "
               "shared)")
        raise TraceError(msg)
