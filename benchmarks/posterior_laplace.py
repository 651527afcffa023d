"""Issue 25: where the Laplace approximation does not hold. A short, weakly informative
SYNTHETIC decay trace (2 s at 200 Hz, 1 mm noise, McManus column at k_f 800 kN/m, r 0.85),
fitted from the Table 1 start: the log-likelihood along k_f (the other parameters at the
fit's values) is scanned for its local maxima, the posterior is sampled from the default
start, and, when the scan finds a second maximum, with two chains started in each: what
R-hat and the loud flag say.

    python benchmarks/posterior_laplace.py [--duration 2] [--noise 1e-3] [--draws 300]

Writes benchmarks/posterior_laplace.md and benchmarks/posterior_laplace.png.
"""

from __future__ import annotations

import argparse
import json
import os
import pathlib
import time
import warnings

import jax
import jax.numpy as jnp
import numpy as np

import identification
import rockjax
from identification._residuals import _checks_as_nan

HERE = pathlib.Path(__file__).resolve().parent


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--duration", type=float, default=2.0)
    ap.add_argument("--rate", type=float, default=200.0)
    ap.add_argument("--noise", type=float, default=1e-3)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--draws", type=int, default=300)
    ap.add_argument("--warmup", type=int, default=200)
    ap.add_argument("--out", default=str(HERE / "posterior_laplace"))
    a = ap.parse_args()
    trace, truth = identification.synthetic_trace(duration=a.duration, rate_hz=a.rate,
                                                  noise=a.noise, seed=a.seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = identification.fit_decay(trace, rockjax.mcmanus_column())
    pb = fit.posterior_problem()
    ik = pb.names.index("k_f")
    z0 = np.asarray(pb.z0)
    grid = z0[ik] + np.linspace(-3.0, 3.0, 61)
    zs = np.repeat(z0[None], grid.size, 0)
    zs[:, ik] = grid
    with _checks_as_nan():
        ll = np.asarray(jax.jit(jax.vmap(pb.log_density))(jnp.asarray(zs)))
        kf = np.asarray(jax.vmap(lambda z: pb.to_physical(z)["k_f"])(jnp.asarray(zs)))
    peaks = [i for i in range(1, grid.size - 1) if ll[i] > ll[i - 1] and ll[i] > ll[i + 1]]
    rows = {"truth": {k: truth[k] for k in ("k_f", "r")}, "fit": fit.values,
            "stderr": fit.stderr, "scan_k_f": kf.tolist(), "scan_log_density": ll.tolist(),
            "peaks_k_f": [float(kf[i]) for i in peaks], "load_start": os.getloadavg()[0]}
    print(json.dumps({k: rows[k] for k in ("fit", "stderr", "peaks_k_f")}), flush=True)
    t = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", identification.PosteriorWarning)
        post = identification.sample_posterior(fit, chains=4, draws=a.draws, warmup=a.warmup,
                                               seed=0, progress=False)
    rows["default"] = {"s": time.perf_counter() - t, "ok": post.ok,
                       "problems": list(post.problems), "warned": bool(caught),
                       "summary": post.summary()["parameters"]}
    print(post.report(), flush=True)
    import matplotlib

    matplotlib.use("Agg")
    post.plot().savefig(a.out + ".png", dpi=120)
    if len(peaks) >= 2:
        best = max(peaks, key=lambda i: ll[i])
        other = max((i for i in peaks if i != best), key=lambda i: ll[i])
        init = np.repeat(z0[None], 4, 0)
        init[2:, ik] = grid[other]
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", identification.PosteriorWarning)
            p2 = identification.sample_posterior(fit, chains=4, draws=a.draws,
                                                 warmup=a.warmup, seed=1, init=init,
                                                 progress=False)
        rows["two_modes"] = {"init_k_f": [float(kf[best]), float(kf[other])], "ok": p2.ok,
                             "problems": list(p2.problems), "warned": bool(caught),
                             "chain_means_k_f": p2.chains_draws["k_f"].mean(1).tolist(),
                             "rhat": p2.rhat}
        print(p2.report(), flush=True)
    pathlib.Path(a.out + ".json").write_text(json.dumps(rows, indent=1, default=float))
    s = rows["default"]["summary"]
    lines = ["# Where the Laplace approximation does not hold (issue 25)", "",
             f"`python benchmarks/posterior_laplace.py --duration {a.duration:g} --noise "
             f"{a.noise:g} --draws {a.draws}`: a SYNTHETIC {a.duration:g}-s decay at "
             f"{a.rate:g} Hz, {1e3 * a.noise:g} mm noise (truth k_f {truth['k_f']:.4g} N/m, "
             f"r {truth['r']}), 4 chains x {a.draws} draws (warmup {a.warmup}).", "",
             "| | Laplace value | Laplace 90 % | posterior median | posterior 90 % |",
             "|---|---|---|---|---|"]
    for p in ("k_f", "r"):
        v, se = fit.values[p], fit.stderr[p]
        lines.append(f"| {p} | {v:.4g} | [{v - 1.645 * se:.4g}, {v + 1.645 * se:.4g}] | "
                     f"{s[p]['q50']:.4g} | [{s[p]['q05']:.4g}, {s[p]['q95']:.4g}] |")
    lines += ["", f"Default start: ok {post.ok}; " + ("; ".join(post.problems) or "R-hat max "
              f"{max(post.rhat.values()):.4f}"),
              "Log density along k_f (others at the fit): local maxima at k_f = "
              + ", ".join(f"{k:.4g}" for k in rows["peaks_k_f"]) + " N/m."]
    if "two_modes" in rows:
        tm = rows["two_modes"]
        lines.append(f"Two chains started at each of k_f = {tm['init_k_f'][0]:.4g} and "
                     f"{tm['init_k_f'][1]:.4g} N/m: chain means of k_f "
                     + ", ".join(f"{m:.4g}" for m in tm["chain_means_k_f"])
                     + f"; R-hat k_f {tm['rhat']['k_f']:.3g}; ok {tm['ok']}; "
                     f"PosteriorWarning raised: {tm['warned']}.")
    lines.append("\nFigure: benchmarks/posterior_laplace.png (trace plots, k_f-r draws with "
                 "the Laplace ellipses).")
    pathlib.Path(a.out + ".md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
