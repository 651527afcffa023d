"""The peak resident memory of each test worker, and the tests where it grows most.

Run the suite with a memory log, then read it:

    ROCKJAX_MEMLOG=/tmp/mem.log python -m pytest        # the README's test command
    python benchmarks/worker_memory.py /tmp/mem.log

Each worker appends "worker nodeid peak-RSS-kB" after every test (tests/conftest.py), so
the jumps of the running maximum name the tests that raise a worker's peak.
"""

from __future__ import annotations

import argparse
import collections


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("log", help="the file ROCKJAX_MEMLOG pointed at")
    ap.add_argument("--top", type=int, default=15, help="how many jumps to list")
    args = ap.parse_args(argv)
    rows = collections.defaultdict(list)
    with open(args.log) as f:
        for line in f:
            worker, rest = line.rstrip("\n").split(" ", 1)  # test ids may hold blanks
            nodeid, rss = rest.rsplit(" ", 1)
            rows[worker].append((nodeid, int(rss)))
    jumps = []
    for worker, seq in sorted(rows.items()):
        peak = max(r for _, r in seq)
        print(f"{worker}: peak RSS {peak / 1024**2:.2f} GB over {len(seq)} tests")
        prev = 0
        for nodeid, rss in seq:
            if rss > prev:
                jumps.append((rss - prev, worker, nodeid, rss))
                prev = rss
    print(f"\nlargest steps of a worker's peak (top {args.top}):")
    for d, worker, nodeid, rss in sorted(jumps, reverse=True)[: args.top]:
        print(f"  +{d / 1024:7.0f} MB -> {rss / 1024**2:5.2f} GB  {worker}  {nodeid}")


if __name__ == "__main__":
    main()
