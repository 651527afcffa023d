"""Does `fit_decay(..., model="auto")` choose the rung of the ladder that made the data?

    python benchmarks/model_auto.py [--quick] [--seeds N] [--rungs NAME ...] [--json FILE]
    python benchmarks/model_auto.py --merge FILE.json ...   # the tables of earlier runs

Each SYNTHETIC decay trace is `identification.synthetic_trace` of one rung of the ladder
(the Table 1 column with k_f = 700 kN/m, released at rest from u0 = 0.1 m at t = 0,
Gaussian noise 0.5 mm on u, no uplift channel, seeds 100, 101, ...):

- `simplified`: the paper's SDOF law, r = 0.80;
- `rigid_body`: the body's one-DOF rotational equation, r = 0.80;
- `2dof_impact`: the 2-DOF body on its springs, Housner's impact at each landing, r = 0.80,
  no dashpots;
- `2dof_continuous`: the 2-DOF body with continuous contact and compression-only dashpots
  at 5 % of critical of the vertical mode, c_f = 0.05 sqrt(2 k_f (m_e + m_b)) = 765 N s/m.

Every trace is fitted with `fit_decay(trace, rockjax.mcmanus_column(), model="auto")`
from the structure's values (k_f = 550 kN/m, r = 0.735 from Eq. 3, c_f at 5 % of critical
there): every rung with its default parameters (and the sensor's offset), ranked by the
lack-of-fit check, then AIC (`identification._auto`). Prints, per trace, the ranking;
then the confusion table (rows: the rung that made the data; columns: the rung chosen)
and the AIC gaps (the runner-up's AIC minus the chosen one's; the true rung's AIC minus
the chosen one's, 0 where it was chosen). Default traces 4 s at 100 Hz; `--quick`: 2 s
at 100 Hz. Wall times include JAX's compiles.
"""

from __future__ import annotations

import argparse
import json
import math
import time
import warnings

import identification
import rockjax
from identification._auto import describe, rank, ranking_table, RUNGS

rockjax.configure()  # float64 and one CPU device per core, before any computation

K_F, R, U0, NOISE, ZETA = 700e3, 0.80, 0.1, 5e-4, 0.05
#: the generating rungs: label -> (model name, contact) of `identification._auto.RUNGS`
TRACES = {"simplified": RUNGS[0], "rigid_body": RUNGS[1], "2dof_impact": RUNGS[2],
          "2dof_continuous": RUNGS[3]}


def dashpot(structure, k_f=K_F, zeta=ZETA):
    """c_f [N s/m] giving the damping ratio `zeta` of the vertical mode: sqrt(2 k_f M)."""
    return zeta * math.sqrt(2.0 * k_f * (float(structure.m_e) + float(structure.m_b)))


def make_trace(label, seed, duration, rate_hz):
    """(trace, truth) of the SYNTHETIC trace of the rung `label`."""
    s = rockjax.mcmanus_column()
    model, contact = TRACES[label]
    if model == "two_spring_2dof":
        model = rockjax.TwoSpring2DOF(damping=dashpot(s) if contact == "continuous" else 0.0,
                                      contact=contact)
    return identification.synthetic_trace(k_f=K_F, r=R, model=model, u0=U0, rate_hz=rate_hz,
                                          duration=duration, noise=NOISE, seed=seed,
                                          structure=s)


def run_one(label, seed, duration, rate_hz):
    trace, _ = make_trace(label, seed, duration, rate_hz)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = identification.fit_decay(trace, rockjax.mcmanus_column(), model="auto",
                                       progress=False)
    return {"truth": describe(*TRACES[label]), "label": label, "seed": seed,
            "duration_s": duration, "rate_hz": rate_hz, "chosen": fit.ranking[0]["model"],
            "k_f": fit.values.get("k_f"), "seconds": time.perf_counter() - t0,
            "ranking": [dict(r) for r in fit.ranking]}


def _aic(row, model):
    return next((r["aic"] for r in row["ranking"] if r["model"] == model and "aic" in r),
                math.nan)


def _load(path):
    """The rows of an earlier --json run (a JSON list, or one JSON object a line), ranked
    again by the current rule (`identification._auto.rank`)."""
    text = open(path).read()
    rows = json.loads(text) if text.lstrip().startswith("[") else [
        json.loads(ln) for ln in text.splitlines() if ln.strip()]
    for r in rows:
        r.setdefault("truth", describe(*TRACES[r["label"]]))
        r["ranking"] = rank([{k: v for k, v in x.items() if k not in ("rank", "delta_aic")}
                             for x in r["ranking"]])
        r["chosen"] = r["ranking"][0]["model"]
        r["k_f"] = r["ranking"][0].get("k_f")
    return rows


def print_tables(rows):
    """The confusion table, then the AIC gaps of each trace."""
    rungs = [describe(*r) for r in RUNGS]
    short = {m: m.replace("two_spring_2dof (contact ", "2dof ").rstrip(")") for m in rungs}
    print("Confusion table (rows: the rung that made the data; columns: the rung chosen):\n")
    print("| made by \\ chosen | " + " | ".join(short[m] for m in rungs) + " |")
    print("|---" * (len(rungs) + 1) + "|")
    for truth in rungs:
        mine = [r for r in rows if r["truth"] == truth]
        if mine:
            counts = [sum(r["chosen"] == m for r in mine) for m in rungs]
            cells = [f"**{c}**" if m == truth else str(c) for c, m in zip(counts, rungs)]
            print(f"| {short[truth]} | " + " | ".join(cells) + " |")
    print("\nAIC gaps (AIC of a rung minus the chosen rung's; lack of fit: which rungs' "
          "residuals are not noise):\n")
    print("| made by | seed | chosen | k_f [kN/m] | runner-up | dAIC runner-up | "
          "dAIC true rung | lack of fit fires for | time [s] |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        ok = [x for x in r["ranking"] if "error" not in x]
        second = ok[1] if len(ok) > 1 else None
        true_gap = _aic(r, r["truth"]) - _aic(r, r["chosen"])
        fires = ", ".join(short[x["model"]] for x in ok if x["lack_of_fit"]) or "none"
        kf = "-" if r["k_f"] is None else f"{r['k_f'] / 1e3:.1f}"
        print(f"| {short[r['truth']]} | {r['seed']} | {short[r['chosen']]}"
              f"{'' if r['chosen'] == r['truth'] else ' (WRONG)'} | {kf} | "
              f"{short[second['model']] if second else '-'} | "
              f"{second['delta_aic'] if second else math.nan:.1f} | {true_gap:.1f} | "
              f"{fires} | {r['seconds']:.0f} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="2 s traces (default 4 s)")
    ap.add_argument("--seeds", type=int, default=1, help="traces per rung (default 1)")
    ap.add_argument("--seed0", type=int, default=100, help="the first seed (default 100)")
    ap.add_argument("--rungs", nargs="+", choices=list(TRACES), default=list(TRACES),
                    help="the rungs that make traces (default all)")
    ap.add_argument("--rate", type=float, default=100.0, help="sampling rate [Hz]")
    ap.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    ap.add_argument("--merge", nargs="+", metavar="FILE",
                    help="print the tables of earlier --json runs (ranked again by the "
                    "current rule) and exit")
    a = ap.parse_args(argv)
    if a.merge:
        rows = [r for f in a.merge for r in _load(f)]
        print_tables(rows)
        return 0
    duration = 2.0 if a.quick else 4.0
    print(f"SYNTHETIC traces: k_f = {K_F / 1e3:g} kN/m, r = {R}, u0 = {U0} m, "
          f"{duration:g} s at {a.rate:g} Hz, noise {NOISE * 1e3:g} mm; fit_decay(model='auto') "
          "from Table 1 (k_f = 550 kN/m, Eq 3 r)\n")
    rows = []
    for label in a.rungs:
        for i in range(a.seeds):
            row = run_one(label, a.seed0 + i, duration, a.rate)
            rows.append(row)
            print(f"## trace made by {row['truth']}, seed {row['seed']} "
                  f"({row['seconds']:.0f} s)\n\n{ranking_table(row['ranking'])}\n", flush=True)
            if a.json:
                with open(a.json, "w") as f:
                    json.dump(rows, f, indent=1)
    print_tables(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
