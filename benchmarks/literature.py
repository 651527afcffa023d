r"""The rocking literature's benchmarks, measured (issue 27, item 4): the figures of
`docs/benchmarks_literature.md`.

1. Housner (1963), the linearised rectangular-pulse threshold $1/(1 - e^{-p t_1})$:
   `model="housner"` on point-mass blocks of slenderness alpha = 0.2, 0.05, 0.01
   (`rockjax.overturning_spectrum`, amplitude bracket 1e-6).
2. Nabeshima, Taniguchi, Kojima & Takewaki (2016), the closed-form critical double
   impulse: `model="rigid_body"` on the uniform block (0.30 x 2.0 m, 1,000 kg), the
   impulses as rectangles of eps [s], the second one at the block's first impact;
   bisection on V to 1e-4.
3. Dimitrakopoulos & DeJong (2012), similar blocks collapse in
   $(\omega_p/p,\ a/(g\tan\alpha))$: uniform blocks b/h = 0.15 of h = 0.25 ... 4 m,
   one-sine and one-cosine pulses, `rigid_body` with k_f scaled as h^2 (similar springs)
   and with k_f fixed at 1e10 N/m.

    python benchmarks/literature.py        # about 2 min on 2 CPU cores; writes literature.md

Units: SI.
"""

from __future__ import annotations

import pathlib
import sys
import time

import numpy as np

import rockjax

rockjax.configure(cpu_devices=None)
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "tests"))

from helpers.literature import (  # noqa: E402
    critical_double_impulse,
    double_impulse_run,
    linearised_threshold,
    point_mass_block,
    PT1,
    uniform_block,
)

from rockjax._spectrum import frequency_parameter, periods_at  # noqa: E402


def rectangular():
    lin = linearised_threshold(PT1)
    rows = []
    for alpha in (0.2, 0.05, 0.01):
        s = point_mass_block(alpha)
        sp = rockjax.overturning_spectrum(s, "rectangular", PT1 / frequency_parameter(s),
                                          model="housner", amplitude_rtol=1e-6)
        for pt1, v, ref in zip(PT1, sp.normalised, lin):
            rows.append((alpha, pt1, ref, v, v / ref - 1))
    return rows


def double(k_f, eps, dt, tol=1e-4):
    s = uniform_block(1.0, k_f=k_f)
    V = critical_double_impulse(s)
    lo, hi = 0.95, 1.05
    assert double_impulse_run(s, lo * V, eps=eps, dt=dt)[0] == "completed"
    assert double_impulse_run(s, hi * V, eps=eps, dt=dt)[0] == "overturned"
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if double_impulse_run(s, mid * V, eps=eps, dt=dt)[0] == "overturned":
            hi = mid
        else:
            lo = mid
    return V, 0.5 * (lo + hi) * V


def similarity(kind, x, scaled):
    out = {}
    for h in (0.25, 0.5, 1.0, 2.0, 4.0):
        s = uniform_block(h, k_f=1e10 * h**2 if scaled else 1e10)
        sp = rockjax.overturning_spectrum(s, kind, periods_at(s, kind, x), model="rigid_body")
        out[h] = sp.normalised
    return out


def main():
    t0 = time.time()
    lines = ["### 1. Housner's linearised rectangular pulse", "",
             "| alpha | p t1 | linearised 1/(1 - e^(-p t1)) | rockjax (`housner`) | error |",
             "|---|---|---|---|---|"]
    for alpha, pt1, ref, v, e in rectangular():
        lines.append(f"| {alpha} | {pt1} | {ref:.5f} | {v:.5f} | {e:+.2e} |")
    print("\n".join(lines), flush=True)
    lines += ["", "### 2. The critical double impulse", "",
              "| k_f [N/m] | impulse width eps [ms] | closed form V [m/s] | rockjax "
              "(`rigid_body`) [m/s] | error |", "|---|---|---|---|---|"]
    for k_f, eps, dt in ((1e10, 2e-3, 5e-4), (1e10, 1e-3, 2.5e-4), (1e11, 1e-3, 2.5e-4)):
        V, Vr = double(k_f, eps, dt)
        lines.append(f"| {k_f:.0e} | {eps * 1e3:g} | {V:.5f} | {Vr:.5f} | {Vr / V - 1:+.2e} |")
        print(lines[-1], flush=True)
    x = np.array([2.0, 4.0, 8.0])
    lines += ["", "### 3. Similar blocks (h = 0.25, 0.5, 1, 2, 4 m)", "",
              "| pulse | springs | omega_p/p | a/(g tan alpha), h = 0.25 ... 4 m | "
              "relative spread (max/min - 1) |", "|---|---|---|---|---|"]
    for kind in ("one_sine", "one_cosine"):
        for scaled in (True, False):
            out = similarity(kind, x, scaled)
            vals = np.array(list(out.values()))
            for j, xj in enumerate(x):
                col = vals[:, j]
                lines.append(f"| {kind} | {'k_f ~ h^2' if scaled else 'k_f = 1e10'} | {xj:g} | "
                             + ", ".join(f"{v:.4f}" for v in col)
                             + f" | {col.max() / col.min() - 1:.1e} |")
                print(lines[-1], flush=True)
    lines += ["", f"(`python benchmarks/literature.py`, {time.time() - t0:.0f} s on CPU)", ""]
    text = "\n".join(lines)
    pathlib.Path(__file__).with_suffix(".md").write_text(
        "# The literature's benchmarks, measured\n\n"
        "Written by `python benchmarks/literature.py`; sources, formulas and tolerances in "
        "`docs/benchmarks_literature.md`.\n\n" + text)
    print(text)


if __name__ == "__main__":
    main()
