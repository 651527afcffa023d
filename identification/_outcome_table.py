r"""Tables of pass/fail runs: `read_outcomes` -> `OutcomeTable` (issue 25, item 2 and 6).

A run is a pulse (its kind and period, or its PGV/PGA ratio), a commanded amplitude with its
unit, and an outcome: toppled (1) or stood (0). The ShakeBot file of the DREAMS Lab
(`exp270.csv`, columns `Date & Time, PGV/PGA, PGA, Rock Status`) reads with its documented
meaning: one-cosine pulses $a(t) = \mathrm{PGA}\cos(2\pi t/T)$, $T = 2\pi\,\mathrm{PGV/PGA}$,
PGA in g (9.80665 m/s²). The file is never copied into the project: `shakebot_path` finds
a local copy or downloads it, pinned by commit and checked by SHA-256.
"""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import io
import math
import os
import pathlib
import shutil
import tempfile
import urllib.request
import warnings

import numpy as np

from rockjax import datasets

from ._trace import DroppedRowsWarning, TraceError

G = 9.80665
"""Standard gravity [m/s²]: the unit g of the amplitudes (the ShakeBot table's too)."""

TOPPLED = ("y", "yes", "true", "1", "1.0", "toppled", "t", "overturned")
"""Outcome labels read as toppled (1), case-insensitive."""
STOOD = ("n", "no", "false", "0", "0.0", "stood", "f", "survived")
"""Outcome labels read as stood (0), case-insensitive."""

SHAKEBOT_URL = ("https://raw.githubusercontent.com/DREAMS-lab/shakebot_motion/"
                "be66989d806e68b8457a6e3d9882c2ec765c7677/assets/Grapher/exp270.csv")
SHAKEBOT_SHA256 = "a99840ee0e53f6bf227bb9d86b1e24542d7e3da77f94e733a61afd63dc6e9208"
SHAKEBOT_FILENAME = "exp270.csv"
_ENV_SHAKEBOT = "ROCKJAX_SHAKEBOT"
_SHAKEBOT_HEADER = ("date & time", "pgv/pga", "pga", "rock status")

#: PGV/PGA [s] -> the pulse's period [s] (a rectangular pulse: its duration): the peak
#: velocity of a(t) = A cos(wt) over one cycle is A/w, of A sin(wt) over one cycle 2A/w
_RATIO_TO_PERIOD = {"one_cosine": 2 * math.pi, "one_sine": math.pi, "rectangular": 1.0}
_KINDS = {"one_cosine": "one_cosine", "cosine": "one_cosine", "one_sine": "one_sine",
          "sine": "one_sine", "rectangular": "rectangular"}
_AMP_UNITS = {"g": G, "m/s2": 1.0, "m/s^2": 1.0, "m/s²": 1.0}
_PERIOD_COLS = ("period", "period_s", "t_s", "duration", "duration_s")
_RATIO_COLS = ("pgv/pga", "pgv/pga_s", "pgv_pga", "pgv_pga_s")
_AMP_COLS = ("pga", "amplitude", "a")
_OUTCOME_COLS = ("rock status", "outcome", "toppled", "status", "result")
_KIND_COLS = ("pulse", "kind")


class OutcomeError(TraceError):
    """A table of outcomes that cannot be used as given (a `TraceError`: `param` names the
    argument that would fix it, e.g. ``"drop_unknown_labels"``)."""


@dataclasses.dataclass(frozen=True)
class OutcomeTable:
    """Pass/fail runs of one specimen under one kind of pulse (SI units).

    - `kind`: "one_cosine", "one_sine" or "rectangular" (`rockjax.pulses`).
    - `period` [s]: each run's pulse period (a rectangular pulse: its duration).
    - `amplitude` [m/s²]: each run's commanded peak acceleration (zero allowed for a run
      that stood: no motion; the ShakeBot table has one, and `describe()` says so).
    - `toppled`: 1 toppled, 0 stood (int array).
    - `ratio` [s]: PGV/PGA of each run (as read, or computed from the period).
    - `rows`: the line of the file each run came from (1 = the header).
    - `dropped`: ((line, label), ...) rows dropped for an unknown label (only with
      `drop_unknown_labels=True`; reported by `describe()` and a `DroppedRowsWarning`).
    - `source`: the file; `meaning`: how its columns were read, in words.
    """

    kind: str
    period: np.ndarray
    amplitude: np.ndarray
    toppled: np.ndarray
    ratio: np.ndarray
    rows: tuple = ()
    dropped: tuple = ()
    source: str = ""
    meaning: str = ""

    def __post_init__(self):
        n = len(self.toppled)
        for name in ("period", "amplitude", "ratio"):
            a = np.asarray(getattr(self, name), float)
            low = a >= 0 if name == "amplitude" else a > 0
            if a.shape != (n,) or not np.all(np.isfinite(a) & low):
                raise OutcomeError(f"OutcomeTable.{name}: {n} positive finite values "
                                   f"expected, got shape {a.shape}")
            object.__setattr__(self, name, a)
        object.__setattr__(self, "toppled", np.asarray(self.toppled, int))
        if not set(np.unique(self.toppled)) <= {0, 1}:
            raise OutcomeError("OutcomeTable.toppled: only 0 (stood) and 1 (toppled)")
        if np.any((self.amplitude == 0) & (self.toppled == 1)):
            raise OutcomeError("OutcomeTable: a run toppled at zero amplitude")
        _check_two_classes(self.toppled, self.source or "outcomes")

    @classmethod
    def from_arrays(cls, kind, period, amplitude, toppled, *, source="arrays"):
        """A table from arrays: `period` [s], `amplitude` [m/s²], `toppled` (0/1)."""
        kind = _kind(kind)
        period = np.asarray(period, float)
        return cls(kind, period, np.asarray(amplitude, float), np.asarray(toppled, int),
                   period / _RATIO_TO_PERIOD[kind], source=source,
                   meaning=f"{kind} pulses given as arrays (SI)")

    @property
    def n(self) -> int:
        """The number of runs."""
        return len(self.toppled)

    @property
    def pga_g(self) -> np.ndarray:
        """The amplitudes in g (9.80665 m/s²)."""
        return self.amplitude / G

    def subset(self, index) -> OutcomeTable:
        """The runs at `index` (an integer array or a boolean mask), as a new table."""
        idx = np.arange(self.n)[index]
        return dataclasses.replace(self, period=self.period[idx],
                                   amplitude=self.amplitude[idx], toppled=self.toppled[idx],
                                   ratio=self.ratio[idx],
                                   rows=tuple(np.asarray(self.rows)[idx]) if self.rows else ())

    def describe(self) -> str:
        """Where the runs came from, how they were read, and what was dropped."""
        lines = [f"{self.n} runs from {self.source} ({self.meaning}): {int(self.toppled.sum())}"
                 f" toppled, {self.n - int(self.toppled.sum())} stood; PGA "
                 f"{self.pga_g.min():.4g}-{self.pga_g.max():.4g} g, PGV/PGA "
                 f"{self.ratio.min():.4g}-{self.ratio.max():.4g} s"]
        zero = np.flatnonzero(self.amplitude == 0)
        if zero.size:
            at = ", ".join(f"line {self.rows[i]}" if self.rows else f"run {i}" for i in zero)
            lines.append(f"{zero.size} run(s) at zero amplitude ({at}): stood, as every model "
                         "predicts (probability 0 of toppling); kept, they add nothing to "
                         "the physics and probit likelihoods")
        if self.dropped:
            lines.append(f"dropped {len(self.dropped)} row(s) with an unknown label: "
                         + ", ".join(f"line {r} ({v!r})" for r, v in self.dropped))
        return "\n".join(lines)


def _check_two_classes(y, source):
    if len(y) == 0:
        raise OutcomeError(f"{source}: no runs")
    if np.all(y == y[0]):
        what = "toppled" if y[0] == 1 else "stood"
        raise OutcomeError(f"{source}: all {len(y)} runs {what}: a fit cannot locate the "
                           "boundary between toppling and standing without both outcomes")


def _kind(kind):
    k = _KINDS.get(str(kind).strip().lower()) if kind is not None else None
    if k is None:
        raise OutcomeError(f"pulse kind {kind!r}: expected one of {sorted(_KINDS)} (the "
                           "table names none)", param="kind", value="one_cosine",
                           advice="; pass e.g. {}")
    return k


def parse_label(value, *, where="") -> int | None:
    """1 for a toppled label (`TOPPLED`), 0 for a stood one (`STOOD`), None otherwise."""
    s = str(value).strip().lower()
    return 1 if s in TOPPLED else 0 if s in STOOD else None


def _find(header, names, what, *, required=True):
    hits = [i for i, h in enumerate(header) if h in names]
    if len(hits) > 1:
        raise OutcomeError(f"two {what} columns: {[header[i] for i in hits]}", param="columns")
    if not hits and required:
        raise OutcomeError(f"no {what} column (expected one of {', '.join(names)}); the "
                           f"header: {', '.join(header)}", param="columns")
    return hits[0] if hits else None


def _split_unit(name):
    """'pga_g' -> ('pga', 'g'); 'pga' -> ('pga', None); 'pga [m/s2]' -> ('pga', 'm/s2')."""
    s = name.strip().lower().replace("[", " ").replace("]", " ").replace("(", " ").replace(
        ")", " ").split()
    if len(s) == 2 and s[1] in _AMP_UNITS:
        return s[0], s[1]
    for u in _AMP_UNITS:
        if s and s[0].endswith("_" + u):
            return s[0][: -len(u) - 1], u
    return " ".join(s), None


def _number(text, line, column, zero=False):
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and (v > 0 or (zero and v == 0))):
        raise OutcomeError(f"line {line}: column {column!r} holds {text!r}, not a positive "
                           "number")
    return v


def read_outcomes(path, *, kind=None, amplitude_unit=None, drop_unknown_labels=False,
                  columns=None) -> OutcomeTable:
    r"""Read a table of pass/fail runs (CSV, a header row) into an `OutcomeTable`.

    **Columns** (names case-insensitive):

    - the pulse: `period` / `period_s` [s] (a rectangular pulse: `duration`), or `PGV/PGA`
      [s] (converted: one-cosine $T = 2\pi\,$PGV/PGA, one-sine $T = \pi\,$PGV/PGA,
      rectangular $t_1$ = PGV/PGA);
    - the amplitude: `PGA` or `amplitude`, with its unit in the name (`PGA_g`, `PGA [g]`,
      `amplitude_m/s2`) or given by `amplitude_unit` ("g" or "m/s2");
    - the outcome: `Rock Status`, `outcome`, `toppled` or `status`, labels `TOPPLED`
      (Y, y, yes, true, 1, toppled) or `STOOD` (N, n, no, false, 0, stood);
    - optionally `pulse` / `kind`: one pulse kind for every row (else `kind=`).

    The ShakeBot layout (`Date & Time, PGV/PGA, PGA, Rock Status`) is recognised and read
    with its documented meaning (one-cosine pulses, PGA in g); `columns` maps the roles
    "period", "ratio", "amplitude", "outcome" to other column names.

    **Bad input** raises `OutcomeError` (a `TraceError`) naming the line and the value: a
    label that is neither toppled nor stood (a blank, a note), unless
    `drop_unknown_labels=True`, which drops those rows and says so (a
    `DroppedRowsWarning`, and `OutcomeTable.dropped`); a number that is missing or not
    positive; an amplitude without a unit; outcomes all of one class.
    """
    path = pathlib.Path(path)
    text, _ = datasets.read_text(path)
    rows = [r for r in csv.reader(io.StringIO(text)) if any(c.strip() for c in r)
            and not r[0].lstrip().startswith("#")]
    if len(rows) < 2:
        raise OutcomeError(f"{path}: expected a header row and at least one run")
    header = [h.strip().lower() for h in rows[0]]
    shakebot = tuple(header) == _SHAKEBOT_HEADER
    roles = {k: v.strip().lower() for k, v in (columns or {}).items()}
    bad = sorted(set(roles) - {"period", "ratio", "amplitude", "outcome", "kind"})
    if bad:
        raise OutcomeError(f"columns: unknown role(s) {bad} (period, ratio, amplitude, "
                           "outcome, kind)", param="columns")
    base = [_split_unit(h) for h in header]
    names = [b[0] for b in base]

    def col(role, cands, required=True):
        if role in roles:
            if roles[role] not in header:
                raise OutcomeError(f"{path}: no column {roles[role]!r} (columns={{'{role}': "
                                   f"...}}); the header: {', '.join(header)}", param="columns")
            return header.index(roles[role])
        return _find(names, cands, role, required=required)

    i_amp, i_out = col("amplitude", _AMP_COLS), col("outcome", _OUTCOME_COLS)
    i_per = col("period", _PERIOD_COLS, required=False)
    i_rat = col("ratio", _RATIO_COLS, required=i_per is None)
    i_kind = col("kind", _KIND_COLS, required=False)
    unit = base[i_amp][1] or (amplitude_unit and str(amplitude_unit).strip().lower()) or (
        "g" if shakebot else None)
    if unit not in _AMP_UNITS:
        raise OutcomeError(f"{path}: the amplitude column {rows[0][i_amp]!r} has no unit: "
                           "name it PGA_g or PGA_m/s2, or give the unit (g or m/s2)",
                           param="amplitude_unit", value="g", advice="; pass {}")
    kinds = {rows[j][i_kind].strip() for j in range(1, len(rows))} if i_kind is not None else set()
    if len(kinds) > 1:
        raise OutcomeError(f"{path}: column {rows[0][i_kind]!r} names several pulse kinds "
                           f"{sorted(kinds)}: fit one kind at a time")
    kind = _kind(kinds.pop() if kinds else kind if kind is not None else
                 "one_cosine" if shakebot else None)
    per, amp, y, lines, dropped = _read_rows(path, rows, (i_per, i_rat, i_amp, i_out),
                                             kind, unit, drop_unknown_labels)
    if dropped:
        warnings.warn(f"{path}: dropped {len(dropped)} row(s) with an unknown outcome label: "
                      + ", ".join(f"line {r} ({v!r})" for r, v in dropped),
                      DroppedRowsWarning, stacklevel=2)
    pulse = {"one_cosine": "a(t) = PGA cos(2 pi t/T), T = 2 pi PGV/PGA",
             "one_sine": "a(t) = PGA sin(2 pi t/T), T = pi PGV/PGA",
             "rectangular": "a(t) = PGA for t1 = PGV/PGA"}[kind]
    meaning = (f"{kind} pulses, {pulse}, " if i_per is None else f"{kind} pulses, "
               ) + f"amplitude in {unit}"
    _check_two_classes(y, str(path))
    return OutcomeTable(kind, per, amp, y,
                        per / _RATIO_TO_PERIOD[kind], rows=tuple(lines), dropped=tuple(dropped),
                        source=str(path), meaning=meaning + (" (the ShakeBot layout)"
                                                             if shakebot else ""))


def _sha256(path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 16), b""):
            h.update(chunk)
    return h.hexdigest()


def _verified(path, origin):
    path = pathlib.Path(path).expanduser()
    if path.is_dir():
        path = path / SHAKEBOT_FILENAME
    if not path.is_file():
        raise FileNotFoundError(f"ShakeBot table not found at {path} ({origin}); it is "
                                f"available from {SHAKEBOT_URL}")
    if _sha256(path) != SHAKEBOT_SHA256:
        raise ValueError(f"{path}: SHA-256 differs from {SHAKEBOT_SHA256}: not the ShakeBot "
                         f"{SHAKEBOT_FILENAME} of commit be66989 ({origin})")
    return path


def shakebot_path(*, local=None, download=True) -> pathlib.Path:
    """A verified copy of the ShakeBot table `exp270.csv` (DREAMS Lab, MIT licence): 135
    one-cosine runs of one rock specimen, 51 toppled.

    Looked for in order: `local` (the file or its folder), `$ROCKJAX_SHAKEBOT` (the same),
    the cache (`rockjax.datasets.cache_dir() / "exp270.csv"`), then downloaded from
    `SHAKEBOT_URL` (the repository DREAMS-lab/shakebot_motion at a pinned commit) with
    `download=True`. Every copy is checked against `SHAKEBOT_SHA256` (ValueError
    otherwise); FileNotFoundError where none is found and `download=False`.
    """
    if local is not None:
        return _verified(local, "the local= argument")
    if os.environ.get(_ENV_SHAKEBOT):
        return _verified(os.environ[_ENV_SHAKEBOT], f"${_ENV_SHAKEBOT}")
    cached = datasets.cache_dir() / SHAKEBOT_FILENAME
    if cached.is_file():
        return _verified(cached, "the cache; delete it to download it again")
    if not download:
        raise FileNotFoundError(f"ShakeBot table not in the cache ({cached}) and "
                                f"download=False; get it from {SHAKEBOT_URL}")
    cached.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".exp270.", dir=cached.parent)
    os.close(fd)
    try:
        try:
            with urllib.request.urlopen(SHAKEBOT_URL, timeout=30) as r, open(tmp, "wb") as f:
                shutil.copyfileobj(r, f)
        except Exception as e:
            raise RuntimeError(f"could not download {SHAKEBOT_URL}: {e}") from e
        _verified(tmp, f"downloaded from {SHAKEBOT_URL}; deleted")
        os.replace(tmp, cached)
    finally:
        pathlib.Path(tmp).unlink(missing_ok=True)
    return cached


def _read_rows(path, rows, cols, kind, unit, drop_unknown_labels):
    """(period [s], amplitude [m/s²], toppled, lines, dropped) of the rows after the header."""
    i_per, i_rat, i_amp, i_out = cols
    header = rows[0]
    per, amp, y, lines, dropped = [], [], [], [], []
    for j, r in enumerate(rows[1:], start=2):
        if len(r) < len(header):
            raise OutcomeError(f"{path}, line {j}: {len(r)} fields, the header has "
                               f"{len(header)}")
        label = parse_label(r[i_out])
        if label is None:
            if drop_unknown_labels:
                dropped.append((j, r[i_out]))
                continue
            raise OutcomeError(
                f"{path}, line {j}: outcome {r[i_out]!r} in column {rows[0][i_out]!r} is "
                "neither toppled (Y, yes, true, 1, toppled) nor stood (N, no, false, 0, "
                "stood)", param="drop_unknown_labels", value=True,
                advice="; to drop such rows (they are reported), pass {}")
        if i_per is not None:
            per.append(_number(r[i_per], j, rows[0][i_per]))
        else:
            per.append(_RATIO_TO_PERIOD[kind] * _number(r[i_rat], j, rows[0][i_rat]))
        amp.append(_number(r[i_amp], j, rows[0][i_amp], zero=True) * _AMP_UNITS[unit])
        if amp[-1] == 0 and label == 1:
            raise OutcomeError(f"{path}, line {j}: toppled at zero amplitude (column "
                               f"{rows[0][i_amp]!r}): no model can explain it")
        y.append(label)
        lines.append(j)
    return np.asarray(per), np.asarray(amp), np.asarray(y, int), lines, dropped
