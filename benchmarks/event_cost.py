"""Where the batched stepper's time goes (issue 26): the step every member pays for, and the
events, measured apart.

The yardstick (`benchmarks/run.py --only yardstick`) times `simulate_batch` whole. This
splits it, on the same inputs (10,000 El Centro runs, IELC180, scales 0.25-1.5, 40 s,
`simplified`, summaries, default settings), each mode in a fresh process beside the floor
(`benchmarks/floor.py`, timed in the same process, so that the modes compare through their
ratio to it on a shared machine):

- `default`: `simulate_batch` as users run it;
- `no-events`: the same with `rockjax.integrators._stepper._event_rounds` replaced by a
  function that returns the state as it is: the members with an event in a step keep their
  state at its start (their results are wrong; **timing only**). What is left is what
  every member pays in every step: the trial step of the whole batch, its conditions, the
  peak, the tally;
- `count`: the same as `default` with the members that have an event counted in each step
  (a host callback; not timed): how many event member-steps there are, how they cluster,
  and how many sub-batch rounds they take.

    python benchmarks/event_cost.py [--record PATH] [--runs 10000] [--repeats 5]

Prints a table and writes benchmarks/event_cost.json and event_cost.md.
"""

from __future__ import annotations

import argparse
import json
import pathlib
import subprocess
import sys
import time

import numpy as np
from _shared import shared_folder

HERE = pathlib.Path(__file__).resolve().parent
T1 = 40.0


def _record(path):
    return path or str(shared_folder() / "IELC180.AT2")


def child(mode, record, n, repeats):
    """One mode in this process: the floor and `simulate_batch`, interleaved, best of
    `repeats`; `count` mode: the event counts instead of times."""
    import warnings

    import jax
    import jax.numpy as jnp

    import rockjax
    from rockjax.integrators import _stepper

    rockjax.configure()
    import floor

    counts = []
    if mode == "no-events":
        _stepper._event_rounds = lambda *args: args[4]  # the state as it is: timing only
    elif mode == "count":
        original = _stepper._event_rounds

        def counted(*args):
            hard = args[-1]
            jax.debug.callback(lambda h, a, w: counts.append((int(h), int(a), int(w))),
                               jnp.sum(hard), jnp.sum(~args[4].tally.done),
                               _stepper._compact_width(hard.shape[0]))
            return original(*args)

        _stepper._event_rounds = counted
    s = rockjax.mcmanus_column()
    gm = rockjax.GroundMotion.from_file(record, units="g")
    scales = np.linspace(0.25, 1.5, n)
    steps = floor.member_steps(T1, float(gm.dt), 4, n)
    n_dev = len(jax.local_devices())
    if n < _stepper.COMPACT_MIN * n_dev:  # smaller batches have no event rounds to split off
        sys.exit(f"--runs {n}: at least {_stepper.COMPACT_MIN * n_dev} on {n_dev} devices "
                 f"(the compacted step starts at {_stepper.COMPACT_MIN} runs per device)")
    f_inp = floor.floor_inputs(s, gm, T1)

    def batch():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", rockjax.FidelityWarning)
            out = rockjax.simulate_batch(s, gm, T1, scale=scales, summary_only=True,
                                         model="simplified", progress=False)
        return jax.block_until_ready(out)

    if mode == "count":
        out = batch()
        c = np.array(counts)
        hard, width = c[:, 0], c[:, 2]
        rounds = np.ceil(hard / width)
        return dict(mode=mode, n=n, devices=n_dev, member_steps=steps,
                    event_member_steps=int(hard.sum()), step_calls=int(len(c)),
                    width=sorted({int(w) for w in width}),
                    event_fraction=float(hard.sum() / steps),
                    steps_without_events=float(np.mean(hard == 0)),
                    rounds=int(rounds.sum()),
                    rounds_in_steps_of_several=int(rounds[rounds > 1].sum()),
                    hard_percentiles={str(q): float(np.percentile(hard, q))
                                      for q in (50, 90, 99, 100)},
                    impacts=int(np.asarray(out.n_impacts).sum()))
    variants = {"floor": lambda: floor.simulate_floor(**f_inp, scales=scales, devices=n_dev),
                mode: batch}
    best = {k: np.inf for k in variants}
    for fn in variants.values():
        fn()
    for _ in range(repeats):
        for k, fn in variants.items():
            t0 = time.perf_counter()
            fn()
            best[k] = min(best[k], time.perf_counter() - t0)
    return dict(mode=mode, n=n, devices=n_dev, member_steps=steps,
                ns_per_member_step={k: v / steps * 1e9 for k, v in best.items()})


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--record", help="IELC180.AT2 (default: $ROCKJAX_SHARED_DATA's)")
    ap.add_argument("--runs", type=int, default=10_000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    record = _record(args.record)
    if args.child:
        print(json.dumps(child(args.child, record, args.runs, args.repeats)))
        return 0
    res = {}
    for mode in ("default", "no-events", "count"):
        print(f"{mode} ...", flush=True)
        out = subprocess.run([sys.executable, __file__, "--child", mode, "--record", record,
                              "--runs", str(args.runs), "--repeats", str(args.repeats)],
                             capture_output=True, text=True)
        if out.returncode:
            sys.exit(f"{mode}: {out.stderr.strip().splitlines()[-1]}")
        res[mode] = json.loads(out.stdout.strip().splitlines()[-1])
    d, e, c = res["default"], res["no-events"], res["count"]
    fd, fe = d["ns_per_member_step"]["floor"], e["ns_per_member_step"]["floor"]
    td, te = d["ns_per_member_step"]["default"], e["ns_per_member_step"]["no-events"]
    summary = dict(
        date=time.strftime("%Y-%m-%d %H:%M"), runs=args.runs, repeats=args.repeats,
        devices=d["devices"], floor_ns=[fd, fe], default_ns=td, no_events_ns=te,
        default_over_floor=td / fd, no_events_over_floor=te / fe,
        events_ns=td - te * fd / fe,  # the events' share, in the default process's units
        events_ns_per_event_member_step=(td - te * fd / fe) * c["member_steps"]
        / c["event_member_steps"],
        counts=c)
    (HERE / "event_cost.json").write_text(json.dumps(summary, indent=1) + "\n")
    md = markdown(summary)
    (HERE / "event_cost.md").write_text(md)
    print(md)
    return 0


def markdown(s):
    c = s["counts"]
    hp = c["hard_percentiles"]
    return "\n".join([
        "# Where the batched stepper's time goes",
        "",
        f"{s['runs']:,} El Centro runs (IELC180, scales 0.25-1.5, 40 s, `simplified`, "
        f"summaries, default settings), {s['devices']} devices; each mode in its own "
        f"process beside the floor (`benchmarks/floor.py`, (N,) arrays), best of "
        f"{s['repeats']}. Measured {s['date']} by `python benchmarks/event_cost.py`.",
        "",
        "| | ns per member-step | / floor in the same process |",
        "|---|---|---|",
        f"| `simulate_batch`, default | {s['default_ns']:.2f} | {s['default_over_floor']:.2f} |",
        f"| the same without its event rounds (timing only: wrong results) | "
        f"{s['no_events_ns']:.2f} | {s['no_events_over_floor']:.2f} |",
        f"| the floor (no events, no peaks between grid points) | "
        f"{s['floor_ns'][0]:.2f} / {s['floor_ns'][1]:.2f} | 1 |",
        "",
        f"The events' share: **{s['events_ns']:.2f} ns per member-step** "
        f"({s['events_ns'] / s['default_ns']:.0%} of the default's time), "
        f"**{s['events_ns_per_event_member_step']:.0f} ns per member-step that carries an "
        f"event**. {c['event_member_steps']:,} of the {c['member_steps']:,} member-steps "
        f"carry one ({c['event_fraction']:.2%}; {c['impacts']:,} impacts in all). They "
        f"cluster: {c['steps_without_events']:.0%} of the steps (per device and chunk) have "
        f"none, the median step {hp['50']:.0f} members with one, the 90th percentile "
        f"{hp['90']:.0f}, the 99th {hp['99']:.0f}, the largest {hp['100']:.0f} (sub-batch "
        f"width {', '.join(map(str, c['width']))}); {c['rounds']:,} sub-batch rounds over "
        f"{c['step_calls']:,} steps, {c['rounds_in_steps_of_several']:,} of them in steps "
        "that take several (the members still in the linear range cross u = 0 together: "
        "their responses are proportional to the scale).",
        "",
    ])


if __name__ == "__main__":
    sys.exit(main())
