r"""The 2-DOF body against Housner's exact rigid block as the springs stiffen (issue 27).

A uniform block (half-width 0.15 m, half-height 1.0 m, 1,000 kg, split into two equal
halves at its centroid) on two compression-only springs of stiffness k_f, released at rest
from 0.6 alpha, contact="impact". Reference: Housner's rigid block, its zero-crossing times
by exact energy quadrature and its amplitudes after each impact from the energy balance
with the structure's restitution r (the same reference as `tests/test_twospring.py`).

For each k_f the largest relative errors over the first six crossings of

- the crossing times, and
- the amplitudes (the peak |theta| between crossings),

once without dashpots (`damping=0`, the default) and once with compression-only dashpots
of 5 % of critical for the vertical mode on both springs, c_f = 2 (0.05) sqrt(k_f m / 2).

    python benchmarks/housner_2dof.py            # writes benchmarks/housner_2dof.md

Units: SI (m, s, N, kg).
"""

from __future__ import annotations

import math
import pathlib
import sys
import time

import jax
import numpy as np

jax.config.update("jax_enable_x64", True)

import rockjax  # noqa: E402
from rockjax import FreeVibration, simulate  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))
from helpers.housner import housner_block, uniform_block  # noqa: E402  (shared with the test)

N_CROSSINGS = 6
T_END = 5.3
ZETA = 0.05
K_FS = (1e9, 1e10, 1e11)
M, B, H = 1000.0, 0.15, 1.0


def zero_crossings(ts, u):
    i = np.nonzero(np.sign(u[:-1]) * np.sign(u[1:]) < 0)[0]
    return ts[i] - u[i] * (ts[i + 1] - ts[i]) / (u[i + 1] - u[i])


def errors(k_f, zeta, n=N_CROSSINGS, t_end=T_END):
    """(largest crossing-time error, largest amplitude error, status) over n crossings."""
    s = uniform_block(k_f, B, H, M)
    damping = 2.0 * zeta * math.sqrt(k_f * float(s.mass) / 2.0)
    th0 = 0.6 * float(s.alpha_c)
    ts = np.linspace(0.0, t_end, int(round(t_end * 1e4)) + 1)
    res = simulate(s, FreeVibration(float(rockjax.u_from_theta(s, th0))), t_end, ts=ts,
                   model=rockjax.TwoSpring2DOF(damping=damping))
    th = np.asarray(res.theta)
    zc = zero_crossings(ts, th)[:n]
    t_ref, a_ref = housner_block(s, th0, n)
    edges = np.concatenate([[0.0], zc])
    amps = np.array([np.max(np.abs(th[(ts >= lo) & (ts < hi)]))
                     for lo, hi in zip(edges[:-1], edges[1:])])
    return (float(np.max(np.abs(zc / t_ref - 1))), float(np.max(np.abs(amps / a_ref[:n] - 1))),
            res.status_name)


def main():
    rows = []
    t0 = time.time()
    for k_f in K_FS:
        e0 = errors(k_f, 0.0)
        e1 = errors(k_f, ZETA)
        rows.append((k_f, e0, e1))
        print(f"k_f={k_f:.0e}: no dashpots t {e0[0]:.2e} a {e0[1]:.2e}; "
              f"5% dashpots t {e1[0]:.2e} a {e1[1]:.2e}", flush=True)
    lines = [
        "# The 2-DOF body against Housner's rigid block (issue 27, item 5)",
        "",
        "Uniform block 0.30 m x 2.0 m, 1,000 kg, released at rest from 0.6 alpha, "
        "`contact=\"impact\"`; largest relative errors over the first six zero crossings "
        "against Housner's exact rigid block (energy quadrature, same restitution r).",
        "",
        "Command: `python benchmarks/housner_2dof.py` "
        f"(CPU, {time.time() - t0:.0f} s).",
        "",
        "| k_f [N/m] | crossing times, no dashpots | amplitudes, no dashpots "
        "| crossing times, 5 % dashpots | amplitudes, 5 % dashpots |",
        "|---|---|---|---|---|",
    ]
    for k_f, e0, e1 in rows:
        lines.append(f"| {k_f:.0e} | {e0[0]:.2e} | {e0[1]:.2e} | {e1[0]:.2e} | {e1[1]:.2e} |")
    lines += [
        "",
        "Dashpots: compression-only, c_f = 2 (0.05) sqrt(k_f m / 2), 5 % of critical for the "
        "vertical mode on both springs (`rockjax.TwoSpring2DOF(damping=c_f)`).",
        "",
        "**Why the undamped body converges slowly and irregularly.** At each rocking impact "
        "the landing corner stops at the top of its unloaded spring and must then take the "
        "weight: the body starts a vertical vibration of amplitude about W/k_f at the "
        "vertical frequency sqrt(k_f/m), so of velocity about g sqrt(m/k_f). Without "
        "dashpots nothing damps it, and at the next impact it adds to (or takes from) the "
        "rotation rate that the restitution scales, with a phase that changes from impact "
        "to impact: errors of order sqrt(E_vib/E) ~ k_f^(-1/2) that grow or shrink from one "
        "impact to the next. Any dashpot "
        "damps it between impacts (the vertical period is about a millisecond, the rocking "
        "half-cycles about a second); what remains is the vibration energy lost at each "
        "impact, of order E_vib/E ~ 1/k_f, nearly the same with dashpots five times weaker: the "
        "errors fall tenfold per decade of k_f. The impact law itself (Housner's rate "
        "ratio sqrt(r) at a rocking impact, the corner-alone plastic impact at a hop "
        "landing), the solver tolerances and the event location are not the cause: with "
        "the vibration damped, the error is smooth and proportional to 1/k_f. A rocking-impact "
        "rule from the angular momentum about the landing corner (which counts the "
        "vibration's momentum too) was tried in place of the rate ratio: worse without "
        "dashpots at 1e10 N/m (4.9e-3 in time, 1.3e-2 in amplitude), so not kept.",
        "",
    ]
    out = pathlib.Path(__file__).with_suffix(".md")
    out.write_text("\n".join(lines))
    print(out.read_text())


if __name__ == "__main__":
    main()
