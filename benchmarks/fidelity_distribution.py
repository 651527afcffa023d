"""Fidelity as a distribution (issue 27, item 3): the models of the ladder against the 2-DOF
body over a suite of records, as fragility curves and distributions of the peak rotation.

    python benchmarks/fidelity_distribution.py [--suite p695-far-field] [--records DIR]
        [--scales 0.25:4:12] [--structures column,block] [--bootstrap 200] [--out PREFIX]

For each structure (the Table 1 column, `rockjax.mcmanus_column()`; a slender uniform block,
2b x 2h = 0.3 m x 2 m, 1,000 kg, alpha = 0.149 rad, k_f = 2e8 N/m per spring: the rigid
limit within about 1 %) every record of the suite runs at every scale with each model
(`rockjax.compare_models`, default settings of `rockjax.sweep`): the reference, the 2-DOF
body with impact landings (`rockjax.TwoSpring2DOF()`), then `rigid_body`, the paper's SDOF
(`simplified`), `housner`, and the 2-DOF body with continuous contact and compression-only
dashpots of 5 % of critical (the spread that a choice of contact model alone makes).

Per model and limit state (overturning; an uplift of 1 % of the body's height): the
fragility median (IM: the scale on the suite's records) and beta with 90 % intervals
(records resampled), the median ratio and the beta difference to the reference, and the
largest two-sample Kolmogorov-Smirnov distance of the peak-rotation distributions over the
scales. Writes PREFIX.md, PREFIX.json and PREFIX.png (default benchmarks/fidelity_distribution).
"""

from __future__ import annotations

import argparse
import json
import math
import pathlib
import platform
import sys
import time

import jax
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import rockjax  # noqa: E402

rockjax.configure()

HERE = pathlib.Path(__file__).resolve().parent


def slender_block(b=0.15, h=1.0, m=1000.0, k_f=2e8):
    """A uniform block 2b x 2h of mass m [kg] as two equal halves at its centroid
    (H = h, I_G = m (b^2 + h^2) / 3), on springs of k_f [N/m] each."""
    inertia = 0.5 * m * (b * b + h * h) / 3.0
    return rockjax.RockingStructure(m_e=m / 2, m_b=m / 2, H_e=h, H_b=h, B=b, I_eg=inertia,
                                    I_bg=inertia, k_f=k_f)


def structures():
    """key -> (structure, title, default scales LO:HI:N): the scales span each one's
    fragility (the block overturns at about a third of the column's scale)."""
    return {"column": (rockjax.mcmanus_column(), "Table 1 column (McManus & Wen)",
                       "0.3:5:12"),
            "block": (slender_block(), "slender uniform block 0.3 m x 2 m, 1,000 kg",
                      "0.05:1.5:12")}


def models(s):
    c_f = 2 * 0.05 * float(np.sqrt(float(s.k_f) * float(s.mass) / 2))
    return {"2-DOF impact (ref.)": rockjax.TwoSpring2DOF(),
            "rigid_body": "rigid_body",
            "simplified": "simplified",
            "housner": "housner",
            "2-DOF continuous, 5 % dashpots": rockjax.TwoSpring2DOF(damping=c_f,
                                                                     contact="continuous")}


def parse_scales(text):
    lo, hi, n = text.split(":")
    return np.geomspace(float(lo), float(hi), int(n))


def load(args):
    if args.records:
        sys.path.insert(0, str(HERE))
        from fidelity import read_records

        recs, notes = read_records(args.records)
        return recs, [r.source or f"record {i}" for i, r in enumerate(recs)], \
            f"the records of {args.records}", notes
    suite = rockjax.datasets.load_suite(args.suite, normalized=args.normalized)
    labels = list(suite.labels)
    what = f"suite {suite.name}" + (" (P695-normalised)" if args.normalized else "")
    return list(suite.records), labels, what, []


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--suite", default="p695-far-field")
    ap.add_argument("--normalized", action="store_true",
                    help="apply the P695 normalisation factors")
    ap.add_argument("--records", help="a folder of records instead of a suite")
    ap.add_argument("--scales", help="LO:HI:N, geometric, for every structure (default: "
                    "each structure's own, see structures())")
    ap.add_argument("--structures", default="column,block")
    ap.add_argument("--bootstrap", type=int, default=200)
    ap.add_argument("--out", default=str(HERE / "fidelity_distribution"))
    args = ap.parse_args()
    recs, labels, what, notes = load(args)
    out = {"what": what, "notes": notes,
           "machine": f"{platform.machine()}, {jax.device_count()} CPU devices",
           "structures": {}}
    figs = []
    for key in args.structures.split(","):
        s, title, default = structures()[key]
        scales = parse_scales(args.scales or default)
        height = float(s.H_e)
        limits = ("overturned", f"uplift={0.01 * height:.4g}")
        t0 = time.perf_counter()
        cmp = rockjax.compare_models(s, recs, scales, models(s), limits=limits, labels=labels,
                                     n_bootstrap=args.bootstrap, progress=False)
        wall = time.perf_counter() - t0
        print(f"== {title}: {wall:.0f} s", flush=True)
        print(cmp.report(), flush=True)
        d = cmp.to_dict()
        d["title"], d["wall_s"], d["alpha"] = title, wall, float(s.alpha_c)
        d["scales_arg"] = args.scales or default
        d["wall_per_model_s"] = {k: float(v.wall_time) for k, v in cmp.sweeps.items()}
        out["structures"][key] = d
        fig = cmp.plot()
        fig.suptitle(f"{title}: {what}", fontsize=10)
        fig.tight_layout()
        figs.append((key, fig))
    prefix = pathlib.Path(args.out)
    prefix.with_suffix(".json").write_text(json.dumps(out, indent=1))
    for key, fig in figs:
        fig.savefig(f"{prefix}_{key}.png", dpi=120)
        plt.close(fig)
    prefix.with_suffix(".md").write_text(markdown(out, args))


def _f(x, fmt="{:.3g}"):
    return "n/a" if x is None or (isinstance(x, float) and not math.isfinite(x)) else \
        fmt.format(x)


def markdown(out, args):
    cmd = "python benchmarks/fidelity_distribution.py " + " ".join(sys.argv[1:])
    L = ["# Fidelity as a distribution (issue 27)", "",
         f"`{cmd.strip()}`: {out['what']}, "
         f"{args.bootstrap} record resamples for the intervals; measured "
         f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} on the shared 2-core CPU.", ""]
    for key, d in out["structures"].items():
        L += [f"## {d['title']} (alpha = {d['alpha']:.3f} rad)", "",
              f"{len(d['records'])} records x {len(d['scales'])} scales "
              f"({d['scales_arg']}, geometric) per model; wall "
              f"{d['wall_s']:.0f} s in all (per model: "
              + ", ".join(f"{k} {v:.0f} s" for k, v in d["wall_per_model_s"].items()) + ").",
              "", "| model | limit | fragility median (scale) | 90 % interval | ratio to ref. "
              "| beta | 90 % interval | beta - ref. | largest KS distance (at scale) |",
              "|---|---|---|---|---|---|---|---|---|"]
        for r in d["rows"]:
            if r["fit"] is not None:
                L.append(f"| {r['model']} | {r['limit']} | no curve: {r['fit']} |  |  |  |  |"
                         "  |  |")
                continue
            ci, bci = r["median_ci"] or (None, None), r["beta_ci"] or (None, None)
            L.append(f"| {r['model']} | {r['limit']} | {_f(r['median'])} | "
                     f"[{_f(ci[0])}, {_f(ci[1])}] | {_f(r.get('median_ratio'), '{:.3f}')} | "
                     f"{_f(r['beta'], '{:.3f}')} | [{_f(bci[0], '{:.3f}')}, "
                     f"{_f(bci[1], '{:.3f}')}] | {_f(r.get('beta_diff'), '{:+.3f}')} | "
                     f"{_f(r['ks_max'], '{:.3f}')} ({_f(r['ks_scale'])}) |")
        L += ["", f"![{key}](fidelity_distribution_{key}.png)", ""]
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    main()
