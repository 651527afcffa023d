"""The ShakeBot outcome fit (issue 25, item 2): 135 one-cosine runs of one rock specimen
(DREAMS Lab, `exp270.csv`, MIT licence), fitted with rockjax's own overturning spectra.

    python benchmarks/shakebot.py [--table PATH] [--out benchmarks/shakebot.md]

The table: `--table`, else `identification.shakebot_path()` ($ROCKJAX_SHAKEBOT, the cache,
or a download checked by SHA-256). Prints and writes (Markdown) the fitted alpha, R, beta
with 90 % intervals, the NLL of the physics model, the three-parameter probit and the
constant, their 5-fold cross-validated held-out log loss, the wall time of the fit (the
threshold grid built in it, then the fit alone on the built grid), the grid's interpolation
error against direct `rockjax.overturning_spectrum` calls between its nodes, and the
figure `benchmarks/shakebot.png`.
"""

from __future__ import annotations

import argparse
import math
import os
import pathlib
import time

import numpy as np

import rockjax

rockjax.configure()  # float64 and one CPU device per core, before any computation

import identification  # noqa: E402
from identification._outcome_grid import pulse_x  # noqa: E402

HERE = pathlib.Path(__file__).resolve().parent
G = 9.80665


def interpolation_error(grid, alphas):
    """Relative error of the interpolated a_c/(g tan alpha) against direct spectra at the
    midpoints of the grid's x nodes, at each alpha of `alphas` (one spectrum each)."""
    lnx = np.asarray(grid.nodes[0])
    x = np.exp(0.5 * (lnx[1:] + lnx[:-1]))
    rows = []
    for a in alphas:
        s = identification.uniform_block(a, 1.0)
        p = math.sqrt(3 * G / 4)
        sp = rockjax.overturning_spectrum(s, grid.kind, 2 * np.pi / (p * x),
                                          amplitude_rtol=grid.settings["amplitude_rtol"],
                                          n_scan=grid.settings["n_scan"], progress=False)
        interp = np.exp(np.asarray(grid(np.log(x), a)))
        rows.append((a, x, interp / sp.normalised - 1, sp.mode))
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--table", default=None)
    ap.add_argument("--out", default=str(HERE / "shakebot.md"))
    a = ap.parse_args(argv)
    path = a.table or identification.shakebot_path()
    load0 = os.getloadavg()[0]
    t0, c0 = time.perf_counter(), time.process_time()
    fit = identification.fit_outcomes(path)
    cold, cold_cpu = time.perf_counter() - t0, time.process_time() - c0
    t0 = time.perf_counter()
    fit = identification.fit_outcomes(path)
    warm = time.perf_counter() - t0
    t0 = time.perf_counter()
    cv = fit.cross_validate(k=5, seed=0)
    cv_time = time.perf_counter() - t0
    print(fit.report(cv))
    e = fit.estimates
    p = math.sqrt(3 * G / (4 * e["R"]))
    x_data = np.asarray(pulse_x("one_cosine", p, fit.table.period))
    err = interpolation_error(fit.grid, [e["alpha"], 0.30])

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(1, 2, figsize=(12, 4.6))
    fit.plot(axs[0], axes="pga-ratio")
    fit.plot(axs[1], axes="dimensionless")
    fig.suptitle("ShakeBot exp270 (DREAMS Lab, 135 runs): fitted uniform block, rigid_body",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(HERE / "shakebot.png", dpi=120)

    lines = ["# ShakeBot outcome fit (issue 25, item 2)", "",
             "Command: `python benchmarks/shakebot.py` "
             f"({os.cpu_count()} cores, load average {load0:.1f} at the start, "
             f"{os.getloadavg()[0]:.1f} at the end: the machine was shared).", "",
             f"Data: `{pathlib.Path(path).name}`, {fit.table.describe()}", "",
             "Model: P(topple) = Φ(ln(PGA / A_c(T; α, R)) / β), A_c the lowest one-cosine "
             "amplitude that overturns a uniform block of slenderness α and half-diagonal R "
             "on rockjax's `rigid_body` model, interpolated on a grid of overturning spectra.",
             "", "| parameter | estimate | 90 % interval (Laplace in z) | unit |",
             "|---|---|---|---|"]
    for n in fit.free:
        lo, hi = fit.interval90[n]
        lines.append(f"| {n} | {e[n]:.4g} | {lo:.4g} – {hi:.4g} | "
                     f"{ {'alpha': 'rad', 'R': 'm', 'beta': '-'}[n]} |")
    ll = cv["log_loss"]
    lines += ["", "| model | parameters | NLL (all 135 runs) | 5-fold CV held-out log loss "
              "per run (seed 0) |", "|---|---|---|---|",
              f"| physics (block, rigid_body) | 3 | {fit.nll:.2f} | {ll['physics']:.4f} |",
              f"| probit in (ln PGA, ln PGV/PGA) | 3 | {fit.nll_probit:.2f} | "
              f"{ll['probit']:.4f} |",
              f"| constant | 1 | {fit.nll_constant:.2f} | {ll['constant']:.4f} |", "",
              f"Cross-validation winner: **{cv['winner']}**.", "",
              "Wall time: "
              f"the first fit {cold:.1f} s ({cold_cpu:.1f} s of CPU time over the "
              f"machine's {os.cpu_count()} cores; the threshold grid built in it: "
              f"{fit.grid.n_runs} runs, {fit.grid.build_time:.1f} s; the grid "
              f"{len(fit.grid.nodes[1])} α × {len(fit.grid.nodes[0])} x, amplitude_rtol "
              f"{fit.grid.settings['amplitude_rtol']}), a second fit on the built grid "
              f"{warm:.1f} s, the 5-fold cross-validation {cv_time:.1f} s.", "",
              f"The runs span x = ω_p/p = {x_data.min():.2f} – {x_data.max():.2f} at the "
              "fitted R.", "",
              "Interpolation error of a_c/(g tan α) against direct `overturning_spectrum` "
              "calls at the midpoints between the x nodes (the same rtol):", "",
              "| α | x | interpolated / direct − 1 | mode (direct) |", "|---|---|---|---|"]
    for alpha, x, rel, mode in err:
        for xi, r, m in zip(x, rel, mode):
            lines.append(f"| {alpha:.3f} | {xi:.3f} | {100 * r:+.2f} % | {m} |")
    inside = np.concatenate([rel[(x >= x_data.min()) & (x <= x_data.max())]
                             for _, x, rel, _ in err])
    lines += ["", f"Within the runs' range of x: median |error| "
              f"{100 * np.median(np.abs(inside)):.2f} %, largest "
              f"{100 * np.max(np.abs(inside)):.2f} % (the largest errors sit in the interval "
              "where the overturning mode jumps from 'after impact' to 'no impact').", "",
              "![ShakeBot fit](shakebot.png)", ""]
    pathlib.Path(a.out).write_text("\n".join(lines), encoding="utf-8")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
