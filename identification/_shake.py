r"""Shake-table runs: a table (base) motion and the structure's measured response.

A shake-table run is the evidence of Eq. 1 driven by the table: the model is
`rockjax.simulate` of the structure under the `rockjax.GroundMotion` of the table record
(its acceleration $\ddot u_g$, in m/s²), and the response channels (top displacement u
*relative to the table*, rotation theta, uplift) are compared with the model's own
observation of each, as for a decay trace (`identification._residuals.TraceModel`, the
same compiled residuals with the record as arrays).

**Two clocks.** The table record is a `rockjax.Record`: its first sample is model time 0.
The response is a `DecayTrace` on its own clock (its own start, rate and length). The
model time of a response sample at time $t$ (response clock) is $t - t_0$, where
$t_0$ is the time on the response clock at which the table record starts. As read,
$t_0$ is `ShakeTableRun.table_start` (the table's first time stamp, on the same time base as
the response: 0 s for a one-file run whose time starts at 0); the fit adjusts it by the
clock offset $\tau = t_0 - t_{0,\text{read}}$ between the channels (a data logger's
filter delay, two loggers started apart): the fit's `t0`, reported as `clock_offset`.

**What is read and reported** (`ShakeTableRun.notes`, never dropped silently):

- a response sampled at another rate than the table: the model is sampled at the
  response's own times, the record interpolated linearly between its samples (as
  `GroundMotion` does);
- a response that starts before the table record: those samples are the structure at
  rest (its initial state) until the table starts;
- a response that ends after the table record: the ground motion is zero after the
  record's last sample (the structure rocks freely, `GroundMotion`'s definition);
- a response channel that saturates (a plateau exactly at its extreme,
  `identification._anomalies.find_clipping`): refused with a `TraceError` naming the
  channel, its level and where (the sensor reads its limit whatever the structure does).
"""

from __future__ import annotations

import dataclasses
import math
import pathlib
import re

import numpy as np

import rockjax

from . import _anomalies
from ._trace import DecayTrace, read_trace, TraceError

_U = rockjax.UNITS
TABLE_ACCEL_NAMES = ("ag", "a_g", "ug_ddot", "table_acc", "table_accel", "table_a",
                     "table_acceleration", "base_acc", "base_accel", "acc", "accel",
                     "acceleration")
"""Column names of a table acceleration in a one-file run (case-insensitive; with a unit
suffix such as `ag_g`, `table_acc [cm/s2]`, `ag_gal`; without one, m/s²)."""
TABLE_DISP_NAMES = ("ug", "u_g", "table_disp", "table_u", "table_displacement", "base_disp",
                    "table_d")
"""Column names of a table displacement in a one-file run (`table_disp_mm`, `ug [cm]`;
without a unit, m). It is differentiated twice (central differences) into the table
acceleration."""
RESPONSE_NAMES = {"u": ("u", "disp", "displacement"), "theta": ("theta", "rotation", "rot",
                                                                  "tilt"),
                  "uplift": ("uplift",)}


@dataclasses.dataclass(frozen=True, eq=False)
class ShakeTableRun:
    """One shake-table run: the table record and the response, each on its own clock.

    - `table`: a `rockjax.Record` (m/s², first sample at model time 0).
    - `response`: a `DecayTrace` of the response channels (SI; u relative to the table).
    - `table_start` [s]: the time of the table's first sample on the response's clock, as
      read (the start of the fit's t0).
    - `table_kind`: `"acceleration"` or `"displacement"` (what the file held);
      `table_units`: its unit in the file; `table_column`: its column (or file).
    - `source`: where it came from; `notes`: what was read and how it is handled
      (different rates, a response longer than the record, ...); `description`: the
      leading `#` comment lines of the (response) file, such as a SYNTHETIC label.
    """

    table: rockjax.Record
    response: DecayTrace
    table_start: float = 0.0
    table_kind: str = "acceleration"
    table_units: str = "m/s2"
    table_column: str = ""
    source: str = ""
    notes: tuple = ()
    description: str = ""  # the leading '#' comment lines of the response file

    def __post_init__(self):
        if not isinstance(self.table, rockjax.Record):
            raise ValueError("ShakeTableRun.table must be a rockjax.Record, got "
                             f"{type(self.table).__name__}")
        if not isinstance(self.response, DecayTrace):
            raise ValueError("ShakeTableRun.response must be an identification.DecayTrace, "
                             f"got {type(self.response).__name__}")
        ts = float(self.table_start)
        if not math.isfinite(ts):
            raise ValueError(f"ShakeTableRun.table_start must be finite, got {ts}")
        object.__setattr__(self, "table_start", ts)
        if not self.notes:
            object.__setattr__(self, "notes", tuple(clock_notes(self)))

    @property
    def start_difference(self) -> float:
        """The response's first time stamp less the table's, as read [s]."""
        return float(self.response.t[0]) - self.table_start

    @property
    def table_end(self) -> float:
        """The time of the table's last sample on the response's clock, as read [s]."""
        return self.table_start + self.table.dt * (self.table.npts - 1)

    def info(self) -> dict:
        """What was read, JSON-ready: the table (kind, unit, column, dt, points, PGA), the
        response (`DecayTrace.info`), the clocks and the notes."""
        return {
            "source": self.source,
            "table": {"kind": self.table_kind, "units_in_file": self.table_units,
                      "column": self.table_column, "source": self.table.source,
                      "dt_s": self.table.dt, "n_points": self.table.npts,
                      "pga_m_per_s2": self.table.pga, "start_s": self.table_start,
                      "end_s": self.table_end},
            "response": self.response.info(),
            "start_difference_s": self.start_difference,
            "notes": list(self.notes),
        }

    def report(self) -> list:
        """What was read, as lines of text (what `rockjax fit-table` prints)."""
        tab = (f"table: {self.table_kind} ({self.table_column or self.table.source}) in "
               f"{self.table_units}, dt {self.table.dt:.6g} s, {self.table.npts} points, "
               f"t = {self.table_start:.6g} .. {self.table_end:.6g} s, PGA "
               f"{self.table.pga:.4g} m/s2")
        return [tab, *self.response.report(), *(f"note: {n}" for n in self.notes)]

    def write_csv(self, path, *, table_path=None, digits: int = 10):
        """Write the run as one CSV (`t`, the table acceleration in its unit, the response
        channels in their units), or, with `table_path`, the response to `path` and the
        table record to `table_path` (two columns `t_s`, `accel[<unit>]`), each on its own
        clock. Returns the path(s) written."""
        tr = self.response
        chans = tr.channels
        unit_of = {c: tr.units.get(c, "rad" if c == "theta" else "m") for c in chans}
        kind = {"u": "length", "uplift": "length", "theta": "angle"}
        cols = {c: np.asarray(getattr(tr, c)) / _U.factor(unit_of[c], kind[c]) for c in chans}
        tu = self.table_units if self.table_units in _U.names("acceleration") else "m/s2"
        acc = np.asarray(self.table.accel) / _U.factor(tu, "acceleration")
        fmt = f"%.{digits}g"
        head = [f"# {line}" for line in (self.source or "shake-table run").splitlines()]
        if table_path is None:
            t = np.asarray(tr.t)
            if not (np.isclose(self.table.dt, tr.dt, rtol=1e-9)
                    and abs(self.table_start - float(t[0])) < 1e-9
                    and self.table.npts >= t.size):
                raise ValueError("write_csv: one file needs the table and the response on "
                                 "one clock and rate; give table_path= to write two files")
            data = [t, acc[:t.size]] + [cols[c] for c in chans]
            names = ["t", f"ag_{tu}"] + [f"{c}_{unit_of[c]}" for c in chans]
            _write(path, head, names, data, fmt)
            return pathlib.Path(path)
        _write(path, head, ["t"] + [f"{c}_{unit_of[c]}" for c in chans],
               [np.asarray(tr.t)] + [cols[c] for c in chans], fmt)
        _write(table_path, head, ["t_s", f"accel[{tu}]"],
               [self.table_start + self.table.time, acc], fmt)
        return pathlib.Path(path), pathlib.Path(table_path)


def _write(path, head, names, data, fmt):
    rows = np.column_stack(data)
    with open(path, "w") as f:
        for h in head:
            f.write(h + "\n")
        f.write(",".join(names) + "\n")
        for row in rows:
            f.write(",".join(fmt % x for x in row) + "\n")


def clock_notes(run: ShakeTableRun) -> list:
    """How the two clocks are handled, in words (the notes of a run)."""
    tr, tab = run.response, run.table
    out = []
    if not math.isclose(tr.dt, tab.dt, rel_tol=1e-6):
        out.append(f"the response is sampled every {tr.dt:.6g} s, the table every "
                   f"{tab.dt:.6g} s: the model is sampled at the response's own times (the "
                   "table record interpolated linearly)")
    if float(tr.t[0]) < run.table_start - 1e-12:
        out.append(f"the response starts {run.table_start - float(tr.t[0]):.6g} s before the "
                   "table record: the structure is at rest (its initial state) until the "
                   "table starts")
    elif float(tr.t[0]) > run.table_start + 1e-12:
        out.append(f"the response starts {float(tr.t[0]) - run.table_start:.6g} s after the "
                   "table record (as read)")
    if float(tr.t[-1]) > run.table_end + 1e-12:
        out.append(f"the response ends {float(tr.t[-1]) - run.table_end:.6g} s after the "
                   f"table record (t = {run.table_end:.6g} s): the ground motion is zero "
                   "after the record's last sample (free rocking)")
    return out


# ------------------------------------------------------------------------- reading


def _header(path) -> tuple[list, int, list]:
    text, _ = rockjax.datasets.read_text(path)
    lines, _ = rockjax.datasets.normalize_rows(text.splitlines(), ",")
    for i, raw in enumerate(lines):
        s = raw.strip()
        if s and not s.startswith("#"):
            return lines, i, [c.strip() for c in s.split(",")]
    raise ValueError(f"{path}: no header line (expected t, a table column such as ag_g or "
                     "table_disp_mm, and response columns u, theta, uplift)")


def _classify(cell: str):
    """('accel' | 'disp' | response channel | 't' | None, unit or None) of a header cell."""
    low = cell.strip().lower()
    for kind, names, kinds in (("accel", TABLE_ACCEL_NAMES, ("acceleration",)),
                               ("disp", TABLE_DISP_NAMES, ("length",))):
        base, unit = _U.split_token(low, kinds)
        if base in names:
            return kind, unit
    base, unit = _U.split_token(low, ("time", "length", "angle"))
    if base in ("t", "time"):
        return "t", unit
    for ch, names in RESPONSE_NAMES.items():
        if base in names:
            return ch, unit
    return None, None


def _comments(path) -> str:
    """The leading '#' comment lines of a text file, without the '#'."""
    try:
        text, _ = rockjax.datasets.read_text(path)
    except (OSError, ValueError, TypeError):
        return ""
    out = []
    for line in text.splitlines():
        s = line.strip()
        if not s:
            continue
        if not s.startswith("#"):
            break
        out.append(s.lstrip("#").strip())
    return "\n".join(out)


def _read_one(path, units, check_plausible) -> ShakeTableRun:
    """A one-file run: t, a table column, response columns."""
    name = str(path)
    if not pathlib.Path(name).is_file():
        raise FileNotFoundError(f"shake-table file not found: {name}")
    lines, hl, cells = _header(path)
    kinds = [_classify(c) for c in cells]
    table = [(i, k, u) for i, (k, u) in enumerate(kinds) if k in ("accel", "disp")]
    if len(table) != 1:
        what = "no table column" if not table else "two table columns"
        raise ValueError(
            f"{name}, line {hl + 1}: {what} in the header {','.join(cells)!r}: a one-file "
            "shake-table run has one table column, its acceleration (ag, table_acc, with a "
            "unit: ag_g, ag_cm/s2, ag [gal]) or its displacement (ug, table_disp, with a "
            "unit: table_disp_mm)")
    ti, tkind, tunit = table[0]
    resp = {k: cells[i] for i, (k, _) in enumerate(kinds) if k in RESPONSE_NAMES or k == "t"}
    if "t" not in resp or len(resp) < 2:
        raise ValueError(f"{name}, line {hl + 1}: the header {','.join(cells)!r} needs a time "
                         "column t and at least one response column (u, theta, uplift)")
    units = dict(units or {})
    given = units.pop("table", None)
    if tunit is None and given is None:
        tunit = "m/s2" if tkind == "accel" else "m"
        origin = "assumed SI"
    elif tunit is None:
        tunit, origin = given, "units argument"
    else:
        origin = "header"
    kind = "acceleration" if tkind == "accel" else "length"
    tunit = _U.normalize(tunit, kind, what="units['table']")
    trace = read_trace(path, columns=resp, units=units or None,
                       check_plausible=check_plausible)
    values = []
    for raw in lines[hl + 1:]:
        s = raw.strip()
        if not s or s.startswith("#"):
            continue
        x = s.split(",")[ti].strip()
        try:
            values.append(float(x))
        except ValueError:
            raise ValueError(f"{name}: table column {cells[ti]!r}: {x!r} is not a "
                             "number") from None
    a = np.asarray(values, float)
    if a.size != trace.n or not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: table column {cells[ti]!r}: {a.size} finite values for "
                         f"{trace.n} samples")
    t = np.asarray(trace.t)
    dt = float((t[-1] - t[0]) / (t.size - 1))
    dev = float(np.max(np.abs(t - (t[0] + dt * np.arange(t.size))))) / dt
    if dev > 1e-3:
        raise ValueError(f"{name}: the time column is not uniform (a sample lies {dev:.3g} "
                         "of a step off a uniform clock): a one-file run's table record "
                         "needs a uniform step; resample it")
    a = a * _U.factor(tunit, kind)
    notes = []
    if tkind == "disp":
        a = np.gradient(np.gradient(a, dt), dt)
        notes.append(f"the table motion is a displacement ({cells[ti]!r} in {tunit}): its "
                     "acceleration is its second derivative by central differences (noise in "
                     "it is amplified by 1/dt^2; give the table's acceleration if recorded)")
    rec = rockjax.Record(dt=dt, accel=a, source=f"{name} [{cells[ti]}]",
                         units_in_file=tunit if tkind == "accel" else "m/s2",
                         units_source=origin)
    run = ShakeTableRun(table=rec, response=trace, table_start=float(t[0]),
                        table_kind="acceleration" if tkind == "accel" else "displacement",
                        table_units=tunit, table_column=cells[ti], source=name,
                        description=_comments(path))
    return dataclasses.replace(run, notes=tuple(notes) + tuple(clock_notes(run)))


_TIME_TITLE = re.compile(r"(?<![a-z0-9_])(?:t|time)\s*(?:_([a-zµμ]+)\b|[\[(]\s*([a-zµμ]+)\s*[\])])",
                         re.IGNORECASE)


def _table_start_of(path) -> float | None:
    """The first time stamp [s] of a two-column record file (a first data line of two
    numbers; its unit from a time title such as `t_ms` or `Time[s]`, else s), None for
    other layouts (AT2, one column, the databases' formats)."""
    try:
        text, _ = rockjax.datasets.read_text(path)
    except (OSError, ValueError, TypeError):
        return None
    header = []
    for line in text.splitlines():
        cells = [c for c in re.split(r"[\s,;]+", line.strip()) if c]
        if not cells:
            continue
        try:
            values = [float(c.replace("D", "E").replace("d", "e")) for c in cells]
        except ValueError:
            header.append(line)
            if len(header) > 50:
                return None
            continue
        if len(values) != 2 or any("NPTS" in h.upper() for h in header):
            return None
        m = _TIME_TITLE.search("\n".join(header))
        unit = (m.group(1) or m.group(2)) if m else "s"
        try:
            return float(_U.to_si(np.asarray([values[0]]), unit, "time")[0])
        except (ValueError, KeyError):
            return values[0]
    return None


def read_shake_table(path=None, *, table=None, response=None, units=None,
                     table_units=None, table_start=None, check_plausible: bool = True
                     ) -> ShakeTableRun:
    """Read a shake-table run: one file with every channel, or a table record and a
    response trace on their own clocks.

    **One file** (`read_shake_table(path)`): a CSV with a header of the time `t`, one
    table column (its acceleration `ag`, `table_acc`, ... with a unit: `ag_g`,
    `ag_cm/s2`, `ag [gal]`; or its displacement `ug`, `table_disp`, ...: `table_disp_mm`,
    differentiated twice) and the response columns as `read_trace` reads them (`u`,
    `theta`, `uplift`, with units: `u_mm`, `theta_deg`); a column without a unit is SI,
    or as `units` says (`{"u": "mm", "table": "g"}`). The table's first sample is at the
    file's first time.

    **Two files** (`read_shake_table(table=..., response=...)`): `table` a record file
    read with `rockjax.read_record` (AT2, two columns `t, a`, ...; `table_units` as its
    `units=`) or a `rockjax.Record`; `response` a trace file read with `read_trace`
    (`units` as its `units=`) or a `DecayTrace`. `table_start` [s]: the time of the
    table's first sample on the response's clock; default: the first time stamp of a
    two-column table file (both files on one time base), else the response's first time
    (the two started together, a note says so). The fit adjusts it (the clock offset).

    **Returns** a `ShakeTableRun` (SI). Its `notes` say how different rates, starts and
    lengths are handled; a saturated response channel is refused (`TraceError`).
    """
    if path is not None:
        if table is not None or response is not None:
            raise ValueError("read_shake_table: give one file (path) or table= and "
                             "response=, not both")
        run = _read_one(path, units, check_plausible)
        check_saturation(run.response)
        return run
    if table is None or response is None:
        raise ValueError("read_shake_table: give one file with every channel, or both "
                         "table= (a record file or rockjax.Record) and response= (a trace "
                         "file or DecayTrace)")
    notes = []
    if isinstance(table, rockjax.Record):
        rec, start_read = table, None
        if table_units is not None:
            raise ValueError("table_units: the table is a Record already (in m/s2)")
    else:
        rec = rockjax.read_record(table, units=table_units, check_plausible=check_plausible)
        start_read = _table_start_of(table)
    tr = response if isinstance(response, DecayTrace) else read_trace(
        response, units=units, check_plausible=check_plausible)
    if table_start is None:
        if start_read is None:
            table_start = float(tr.t[0])
            notes.append(f"the table record has no time stamps: its first sample is taken at "
                         f"the response's first time, t = {table_start:.6g} s (pass "
                         "table_start= if it is known); the fit adjusts it (clock_offset)")
        else:
            table_start = start_read
    src = f"table {rec.source or 'Record'}; response {tr.source or 'DecayTrace'}"
    run = ShakeTableRun(table=rec, response=tr, table_start=float(table_start),
                        table_kind="acceleration", table_units=rec.units_in_file,
                        table_column=rec.source, source=src,
                        description="" if isinstance(response, DecayTrace)
                        else _comments(response))
    run = dataclasses.replace(run, notes=tuple(notes) + tuple(clock_notes(run)))
    check_saturation(run.response)
    return run


def _noise(x: np.ndarray) -> float:
    """A robust noise std from second differences (a smooth signal's are ~0):
    1.4826 MAD / sqrt(6)."""
    d2 = np.diff(np.asarray(x, float), 2)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0))


def check_saturation(trace: DecayTrace):
    """TraceError when a response channel is clipped (a plateau of
    `_anomalies.MIN_RUN` or more samples exactly at its extreme that is not at its
    start; the uplift's upper extreme only)."""
    t = np.asarray(trace.t)
    for ch in trace.channels:
        x = np.asarray(getattr(trace, ch))
        found = _anomalies.find_clipping(t, x, 0.0,
                                         ("upper",) if ch == "uplift" else ("upper", "lower"))
        found = [c for c in found if any(a > 0 for a, _ in c["plateaus"])]
        if not found:
            continue
        c = found[0]
        unit = "rad" if ch == "theta" else "m"
        spans = ", ".join(f"{a:.4g}-{b:.4g} s" for a, b in c["times"][:4])
        raise TraceError(
            f"{trace.source or 'the response'}: the {ch} channel saturates (clipped): "
            f"{c['n_samples']} samples in {len(c['plateaus'])} plateau(s) exactly at its "
            f"{c['side']} extreme {c['level']:.6g} {unit}, t = {spans}: the sensor reads its "
            "limit whatever the structure does there. Not fitted: cut the run before the "
            f"first plateau, or drop the {ch} channel (read it with columns= without it)")


# ----------------------------------------------------------------------- synthetic


def synthetic_shake_table(structure=None, record=None, scale: float = 1.0, *,
                          model="simplified", truth: dict | None = None,
                          noise: float = 0.3e-3, clock_offset: float = 0.015,
                          channels=("u", "theta"), channel_units=None,
                          duration: float | None = None, dt: float | None = None,
                          offsets: dict | None = None, seed: int = 0) -> ShakeTableRun:
    """A SYNTHETIC shake-table run (clearly labelled so in its `source`): `record` (a
    `rockjax.Record`) times `scale` drives the
    structure (`model`, `truth`: k_f, r, c_f), the response channels (`channels` of u,
    theta, uplift) sampled every `dt` (default the record's) for `duration` s (default the
    record's) on a clock that lags the table's by `clock_offset` [s] (the fit's t0 is
    then `clock_offset`, its start 0), with Gaussian noise of std `noise` [m] on u and the
    uplift and `noise / H_e` [rad] on theta, and sensor zeros `offsets` ({"u": ...}).
    `channel_units` ({"u": "mm"}) are the units the channels are written in
    (`ShakeTableRun.write_csv`); the arrays are SI.

    For example (benchmarks/shake_table.py, tests/test_shake_table.py):
    `synthetic_shake_table(rockjax.mcmanus_column(), record, 1.5, model="rigid_body",
    truth={"k_f": 715e3, "r": 0.8}, channel_units={"u": "mm"}, seed=3)`.
    """
    s = rockjax.mcmanus_column() if structure is None else structure
    if not isinstance(record, rockjax.Record):
        raise ValueError("synthetic_shake_table: record must be a rockjax.Record (read one "
                         "with rockjax.read_record), got " + type(record).__name__)
    rec = record
    truth = dict(truth or {})
    s = s.replace(k_f=float(truth.get("k_f", float(s.k_f))))
    r = float(truth.get("r", float(s.restitution)))
    m = model
    if "c_f" in truth:
        m = rockjax.TwoSpring2DOF(damping=float(truth["c_f"])) if model in (
            "two_spring_2dof",) else model
        if not isinstance(m, str):
            import equinox as eqx

            m = eqx.tree_at(lambda x: x.damping, m, float(truth["c_f"]))
    step = rec.dt if dt is None else float(dt)
    dur = rec.dt * (rec.npts - 1) if duration is None else float(duration)
    t = np.arange(0.0, dur + 0.5 * step, step)
    ts = np.maximum(t - clock_offset, 1e-12 * np.arange(t.size))
    res = rockjax.simulate(s, rockjax.GroundMotion.from_record(rec, scale=scale),
                           float(ts[-1]), ts=ts, r=r, model=m, fidelity_warning=False)
    if int(res.status) != rockjax.STATUS["completed"]:
        raise ValueError(f"synthetic_shake_table: the run did not complete (status "
                         f"{int(res.status)}: overturned?); lower scale")
    rng = np.random.default_rng(seed)
    offs = dict(offsets or {})
    sig = {"u": noise, "uplift": noise, "theta": noise / float(s.H_e)}
    data = {c: np.asarray(getattr(res, c)) + offs.get(c, 0.0)
            + sig[c] * rng.standard_normal(t.size) for c in channels}
    cu = {"u": "m", "uplift": "m", "theta": "rad", **(channel_units or {})}
    label = (f"SYNTHETIC shake-table run (rockjax simulation, not a measurement): "
             f"{pathlib.Path(rec.source).name or 'record'} x {scale:g}, model {model}, "
             f"noise {noise:g} m, clock offset {clock_offset:g} s, seed {seed}")
    tr = DecayTrace(t=t, source=label, units={"t": "s", **{c: cu[c] for c in channels}},
                    **data)
    keep = min(rec.npts, int(math.ceil(dur / rec.dt)) + 2)  # the record under the run
    rec_s = rockjax.Record(dt=rec.dt, accel=np.asarray(rec.accel)[:keep] * scale,
                           source=f"{rec.source} x {scale:g}", units_in_file="m/s2",
                           units_source="given")
    return ShakeTableRun(table=rec_s, response=tr, table_start=0.0, table_kind="acceleration",
                         table_units="m/s2", table_column="ag", source=label,
                         description=label)
