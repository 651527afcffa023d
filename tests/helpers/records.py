"""Writers of SYNTHETIC ground-motion records (`rockjax.datasets.synthetic_ground_motion`,
not real earthquakes) in the AT2, two-column and one-column layouts that `read_record`
reads: tests/test_records.py, tests/test_sweep_cli.py, tests/test_batch.py and
tests/test_sweep_distributed.py use them (the last three through test_records' names).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rockjax import datasets, G_STANDARD


def synthetic(seed=0, dt=0.01, duration=4.0, pga=3.0):
    """`datasets.synthetic_ground_motion`: a Record in m/s² (not a real earthquake)."""
    return datasets.synthetic_ground_motion(seed=seed, dt=dt, duration=duration, pga=pga)


def write_at2(path, rec, units_line="ACCELERATION TIME HISTORY IN UNITS OF G.", per_line=5):
    """`rec` as a PEER AT2 file, values in g (`units_line`: the third header line)."""
    vals = np.asarray(rec.accel) / G_STANDARD
    rows = [
        "".join(f"{v:17.9E}" for v in vals[i : i + per_line]) for i in range(0, vals.size, per_line)
    ]
    head = ["SYNTHETIC RECORD (rockjax.datasets.synthetic_ground_motion)", rec.source, units_line,
            f"NPTS=  {vals.size}, DT= {rec.dt:.6f} SEC"]
    Path(path).write_text("\n".join(head + rows) + "\n")
    return Path(path)


def write_two_column(path, rec, header="Time[s] Accel[g]", in_g=True):
    """`rec` as two columns t [s], a (in g or m/s²), after the `header` lines (may be "")."""
    vals = np.asarray(rec.accel) / (G_STANDARD if in_g else 1.0)
    body = "\n".join(f"{i * rec.dt:.6f}\t{v:.10e}" for i, v in enumerate(vals))
    Path(path).write_text((header + "\n" if header else "") + body + "\n")
    return Path(path)


def write_one_column(path, rec, in_g=True):
    """`rec` as one column of accelerations (in g or m/s²), no header."""
    vals = np.asarray(rec.accel) / (G_STANDARD if in_g else 1.0)
    Path(path).write_text("\n".join(f"{v:.10e}" for v in vals) + "\n")
    return Path(path)
