"""Readers for ground-motion acceleration records (pure NumPy).

Five layouts are supported, plain or gzip-compressed, with values separated by blanks,
tabs, commas or ``;`` and written with decimal points or decimal commas
(``rockjax/_textfile.py``):

- **PEER AT2** (``format="at2"``): four header lines, the fourth holding the number of
  points and the time step, e.g. ``NPTS=  4000, DT= .01000 SEC`` (old PEER/PEA header),
  ``NPTS =   7500 , DT =   .020 SEC ,`` (NGA-West2 header) or ``4000  0.0100  NPTS, DT``
  (2005 NGA header). The accelerations follow, any number per line, in units of g unless
  the header says otherwise.
- **ESM** and **K-NET/KiK-net** ASCII (``format="esm"``, ``"knet"``): the database
  formats, read by ``rockjax/_record_formats.py`` (step, units and scale from the header).
- **Two columns** (``format="two_column"``): time and acceleration, optionally preceded
  by text header lines. The time is in s unless its column title says otherwise (``t_ms``,
  ``Time[s]``); its step must be uniform, to within ``time_tolerance`` (a jittering clock
  is resampled, with a :class:`ResampledWarning`).
- **One column** (``format="one_column"``): one acceleration per line, optionally preceded
  by text header lines; the time step must be given with ``dt=``.

Formats recognised but not read (COSMOS, binaries, workbooks) are named as unsupported.

Units: g, m/s2, cm/s2, gal, mm/s2 or in/s2, in any spelling of the unit table
(:data:`rockjax.UNITS`: ``m/s^2``, ``cm/sec/sec``, ``Gal``, ...). A file that states its
units (AT2 ``UNITS OF G``, ``in units of cm/sec/sec``, a column title ``Accel[gal]`` or
``accel_cm/s2``, ESM's ``UNITS:``; K-NET is in gal) is read in those units; ``units=`` may
repeat them (in any spelling of the same size) but never contradict them (a
ParameterError names both). ``Record.units_source`` says where the units came from. A PGA
above 5 g is refused as implausible (``check_plausible=False`` reads it).

Every record is returned as a :class:`Record` in SI units (m/s²). The first sample is
taken to be at ``t = 0`` of the simulation: a two-column record whose time column starts at
``t0 != 0`` is shifted so that its first sample is at ``t = 0`` (``t0`` is discarded).
"""

from __future__ import annotations

import dataclasses
import fractions
import math
import os
import re
import warnings
from pathlib import Path

import numpy as np

from . import _record_formats, _textfile, _units
from ._errors import ParameterError, Placeholder
from ._units import G_STANDARD

__all__ = ["G_STANDARD", "Record", "ResampledWarning", "common_time_step", "read_record"]

_FORMATS = ("at2", "two_column", "one_column", "esm", "knet")
#: the default tolerance on a jittering time column, as a fraction of the time step
TIME_TOLERANCE = 1e-3
#: a PGA above this many g is refused unless check_plausible=False
MAX_PLAUSIBLE_PGA_G = 5.0
_ACCEL = "acceleration"
#: the units of acceleration a record may be in (canonical names of the unit table)
RECORD_UNITS = _units.names(_ACCEL)

_NUM = r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eEdD][+-]?\d+)?"
_NUM_RE = re.compile(_NUM)
_NONFINITE_RE = re.compile(r"[+-]?(?:nan|inf(?:inity)?)", re.IGNORECASE)
_SPLIT_RE = re.compile(r"[\s,]+")
_NPTS_DT_RE = re.compile(rf"NPTS\s*[=:]?\s*(\d+)\s*[,;]?\s*DT\s*[=:]?\s*({_NUM})", re.IGNORECASE)
_NPTS_DT_OLD_RE = re.compile(rf"^\s*(\d+)\s*[,;]?\s+({_NUM})\s+NPTS\s*,\s*DT", re.IGNORECASE)
# "UNITS OF G", "units are (g)", "in units of cm/sec/sec", "Units: m/s^2"
_UNITS_PHRASE_RE = re.compile(
    r"\bUNITS(?:\s+(?:OF|ARE|IN)\b|\s*[:=])\s*[:=]?\s*[(\[]?\s*([A-Za-z][A-Za-z0-9/^*]*)",
    re.IGNORECASE,
)
# "Accel[g]", "Acceleration (m/s^2)", "a [cm/s2]"
_UNITS_BRACKET_RE = re.compile(r"[(\[]\s*([A-Za-z][A-Za-z0-9/^*]*)\s*[)\]]")
# "t_ms", "time_s", "Time[s]", "t (ms)": the unit of a time column's title
_TIME_TITLE_RE = re.compile(
    r"(?<![A-Za-z0-9_])(?:t|time|zeit|tiempo|tempo)\s*(?:_([A-Za-zµμ]+)\b|[\[(]\s*([A-Za-zµμ]+)"
    r"\s*[\])])", re.IGNORECASE)


@dataclasses.dataclass(frozen=True, eq=False)
class Record:
    """A uniformly sampled ground-acceleration record in SI units.

    The first sample is at t = 0 and sample i is at t = i dt. Instances compare and hash
    by identity (`accel` is an array).

    **Arguments:**

    - `dt` [s]: the uniform sample step, finite and > 0.
    - `accel` [m/s²]: the ground acceleration, a read-only float64 1-D array, finite, of
      length >= 2.
    - `source`: the file path (or a description) of where the record came from.
    - `description`: the header text of the file, if any (`""` otherwise).
    - `units_in_file`: the units of the values in the file, a canonical name of the unit
      table (`"g"`, `"m/s2"`, `"cm/s2"`, `"gal"`, `"mm/s2"`, `"in/s2"`); `accel` is
      always m/s².
    - `units_source`: where `units_in_file` came from: `"file header"` (the file states
      them; a `units=` given as well agreed), `"given"` (the file states none, `units=`
      was given), `"AT2 default"` (an AT2 header that states none: PEER's g), or `""` for
      a record built from arrays.
    """

    dt: float
    accel: np.ndarray
    source: str = ""
    description: str = ""
    units_in_file: str = "m/s2"
    units_source: str = ""

    def __post_init__(self) -> None:
        try:
            dt = float(self.dt)
        except (TypeError, ValueError):
            raise ParameterError(f"Record: dt must be a number [s], got {self.dt!r}",
                                 param="dt") from None
        if not (math.isfinite(dt) and dt > 0.0):
            raise ParameterError(f"Record: dt must be finite and > 0 [s], got {self.dt!r}",
                                 param="dt")
        try:
            accel = np.array(self.accel, dtype=np.float64, copy=True)
        except (TypeError, ValueError) as e:
            raise ParameterError(f"Record: accel must be an array of numbers ({e})",
                                 param="accel") from None
        if accel.ndim != 1:
            raise ParameterError(f"Record: accel must be 1-D, got shape {accel.shape}",
                                 param="accel")
        if accel.size < 2:
            raise ParameterError(f"Record: accel needs at least 2 samples, got {accel.size}",
                                 param="accel")
        if not np.all(np.isfinite(accel)):
            raise ParameterError("Record: accel contains NaN or inf values", param="accel")
        if self.units_in_file not in RECORD_UNITS:
            raise ParameterError(
                f"Record: units_in_file must be one of {', '.join(RECORD_UNITS)}, got "
                f"{self.units_in_file!r}", param="units_in_file")
        accel.setflags(write=False)
        object.__setattr__(self, "dt", dt)
        object.__setattr__(self, "accel", accel)
        object.__setattr__(self, "source", str(self.source))
        object.__setattr__(self, "description", str(self.description))
        object.__setattr__(self, "units_source", str(self.units_source))

    @property
    def npts(self) -> int:
        """Number of samples."""
        return int(self.accel.size)

    @property
    def time(self) -> np.ndarray:
        """Sample times ``i * dt`` [s], starting at 0."""
        return np.arange(self.accel.size, dtype=np.float64) * self.dt

    @property
    def pga(self) -> float:
        """Peak ground acceleration ``max |accel|`` [m/s²]."""
        return float(np.max(np.abs(self.accel)))

    def __repr__(self) -> str:
        return (
            f"Record(dt={self.dt!r}, npts={self.npts}, pga={self.pga:.4g} m/s2, "
            f"source={self.source!r}, units_in_file={self.units_in_file!r}, "
            f"units_source={self.units_source!r})"
        )


def _normalize_units(units: str) -> str:
    try:
        return _units.normalize(units, _ACCEL)
    except _units.UnitError as e:
        raise ParameterError(f"unknown units={units!r}; {e}", param="units") from None


def _classify_unit_token(token: str, phrase: bool) -> str | None:
    """The canonical unit of acceleration of a unit token found in a header, 'unsupported'
    for a unit that a record cannot be in (cm or mm: a displacement record; in
    a 'UNITS OF ...' phrase also any x/y, such as the CM/SEC of a velocity record), or None
    for a token to ignore (a unit of time such as the [s] of 'Time[s]', or no unit)."""
    key = token.strip().rstrip("/*^")
    kind = _units.kind_of(key)
    if kind == _ACCEL:
        return _units.normalize(key, _ACCEL)
    if kind == "length" and _units.normalize(key, "length") in ("cm", "mm"):
        return "unsupported"  # not m or in: "Depth (m)", "units are in g" say nothing
    if kind is None and phrase and "/" in key:
        return "unsupported"
    return None


def _units_from_header(header: str, source: str) -> tuple[str, str] | None:
    """(units, the header text that states them) or None when the header states nothing
    recognizable; ``("both", ...)`` when it states units of different sizes (g and m/s2).

    Raises ValueError when the header states units that a record cannot be in (e.g. cm,
    or the cm/sec of a velocity record).
    """
    header = header.replace("²", "^2")
    found: list[tuple[str, str, str]] = []
    for m in _UNITS_PHRASE_RE.finditer(header):
        token = m.group(1)
        kind = _classify_unit_token(token, phrase=True)
        if kind is not None:
            found.append((kind, token, m.group(0).strip()))
    for m in _UNITS_BRACKET_RE.finditer(header):
        token = m.group(1)
        kind = _classify_unit_token(token, phrase=False)
        if kind is not None:
            start = m.start()  # quote the column title too: "Accel[g]", not "[g]"
            while start > 0 and (header[start - 1].isalnum() or header[start - 1] in "_."):
                start -= 1
            found.append((kind, token, header[start : m.end()].strip()))
    for tok in re.split(r"[\s,;]+", header):  # "accel_cm/s2", "acc_gal", "a_g"
        if "[" in tok or "(" in tok:
            continue
        _, unit = _units.split_token(tok)
        kind = None if unit is None else _classify_unit_token(unit, phrase=False)
        if kind is not None:
            found.append((kind, unit, tok))
    if not found:
        return None
    bad = [tok for kind, tok, _ in found if kind == "unsupported"]
    if bad:
        raise ValueError(
            f"{source}: the header states units {bad[0]!r}, which are not a unit of "
            f"acceleration; records must be in {', '.join(RECORD_UNITS)} (convert the "
            "values, or build a Record from arrays)"
        )
    sizes = {_units.factor(kind, _ACCEL) for kind, _, _ in found}
    if len(sizes) > 1:
        named = sorted({kind for kind, _, _ in found})
        return "both", ", ".join(repr(text) for _, _, text in found), named
    return found[0][0], repr(found[0][2])


def _resolve_units(
    stated: tuple | None, given: str | None, source: str, default: str | None
) -> tuple[str, str]:
    """(units, where they came from) from what the file states and what was given: a file
    that states its units wins, and units given as well must agree with them (the same
    size: gal and cm/s2 agree)."""
    if stated is not None and stated[0] == "both":
        if given is None:
            named = stated[2]
            raise ParameterError(
                f"{source}: the header states conflicting units {named} ({stated[1]})",
                param="units", choices=tuple(named),
            )
        return given, "given"
    if stated is not None:
        units, text = stated
        if given is not None and _units.factor(given, _ACCEL) != _units.factor(units, _ACCEL):
            raise ParameterError(
                f"{source}: the file states units {units} ({text} in its header) but "
                f"{given} was given", param="units", omit=True, choices=(units,),
            )
        return units, "file header"
    if given is not None:
        return given, "given"
    if default is not None:
        return default, "AT2 default"
    raise ParameterError(
        f"{source}: the units of the acceleration are not stated in the file",
        param="units", choices=("g", "m/s2"),
    )


def _time_unit_from_header(header: str, source: str) -> str:
    """The unit of the time column that the header's column titles state (``t_ms``,
    ``time_s``, ``Time[s]``): a canonical unit of time, ``"s"`` when none is stated."""
    for m in _TIME_TITLE_RE.finditer(header):
        unit = m.group(1) or m.group(2)
        if _units.kind_of(unit) == "time":
            return _units.normalize(unit, "time")
    return "s"


def _tokens(line: str) -> list[str]:
    return [tok for tok in _SPLIT_RE.split(line.strip()) if tok]


def _parse_tokens(tokens: list[str]) -> list[float] | None:
    """Parse all tokens as floats (NaN/inf included); None if any token is not a number."""
    out = []
    for tok in tokens:
        if _NUM_RE.fullmatch(tok):
            out.append(float(tok.replace("d", "e").replace("D", "e")))
        elif _NONFINITE_RE.fullmatch(tok):
            out.append(float(tok))
        else:
            return None
    return out


def _check_finite(values: list[float], source: str, lineno: int, line: str) -> None:
    if not all(math.isfinite(v) for v in values):
        raise ValueError(
            f"{source}, line {lineno}: non-finite value (NaN or inf) in {line.strip()!r}"
        )


def _non_numeric(source: str, lineno: int, line: str) -> ValueError:
    text = line.strip()
    if len(text) > 80:
        text = text[:77] + "..."
    return ValueError(f"{source}, line {lineno}: non-numeric data in data section: {text!r}")


def _check_dt_arg(dt_arg: float | None, dt_file: float, source: str) -> None:
    if dt_arg is not None and abs(dt_arg - dt_file) > 1e-6 * dt_file + 1e-12:
        raise ParameterError(
            f"{source}: a time step of {dt_arg!r} s was given but the file has a time step "
            f"of {dt_file!r} s", param="dt", omit=True,
        )


def _match_npts_dt(line: str) -> tuple[int, float] | None:
    m = _NPTS_DT_RE.search(line) or _NPTS_DT_OLD_RE.search(line)
    if m is None:
        return None
    return int(m.group(1)), float(m.group(2).replace("d", "e").replace("D", "e"))


def _read_at2(
    lines: list[str], source: str, units: str | None, dt_arg: float | None
) -> tuple[float, np.ndarray, tuple[str, str], str]:
    if len(lines) < 4:
        raise ValueError(
            f"{source}: a PEER AT2 file needs 4 header lines, found only {len(lines)} lines"
        )
    npts_dt = _match_npts_dt(lines[3])
    if npts_dt is None:
        raise ParameterError(
            f"{source}, line 4: expected the PEER AT2 header 'NPTS= ..., DT= ... SEC', "
            f"got {lines[3].strip()!r} (a file named .AT2 is read as PEER AT2)",
            param="format", choices=_FORMATS[1:],
        )
    npts, dt = npts_dt
    if not (math.isfinite(dt) and dt > 0.0):
        raise ValueError(f"{source}, line 4: DT must be > 0 [s], got DT={dt!r}")
    _check_dt_arg(dt_arg, dt, source)
    units_and_source = _resolve_units(
        _units_from_header("\n".join(lines[:3]), source), units, source, "g"
    )
    values: list[float] = []
    for lineno, line in enumerate(lines[4:], start=5):
        toks = _tokens(line)
        if not toks:
            continue
        vals = _parse_tokens(toks)
        if vals is None:
            raise _non_numeric(source, lineno, line)
        _check_finite(vals, source, lineno, line)
        values.extend(vals)
    if len(values) != npts:
        raise ValueError(
            f"{source}: the header says NPTS={npts} but {len(values)} values were found "
            "in the data section"
        )
    description = "\n".join(line.rstrip() for line in lines[:4])
    return dt, np.asarray(values, dtype=np.float64), units_and_source, description


def _read_columns(
    lines: list[str], source: str, ncols: int
) -> tuple[np.ndarray, list[int], list[str]]:
    """Read leading text header lines, then rows of exactly `ncols` numbers."""
    header: list[str] = []
    rows: list[list[float]] = []
    linenos: list[int] = []
    for lineno, line in enumerate(lines, start=1):
        toks = _tokens(line)
        if not toks:
            continue
        vals = _parse_tokens(toks)
        if not rows and vals is None:
            header.append(line.rstrip())
            continue
        if vals is None:
            raise _non_numeric(source, lineno, line)
        if len(vals) != ncols:
            what = "2 columns (time, acceleration)" if ncols == 2 else "1 column (acceleration)"
            raise ValueError(
                f"{source}, line {lineno}: expected {what}, found {len(vals)} values "
                f"in {line.strip()[:80]!r}"
            )
        _check_finite(vals, source, lineno, line)
        rows.append(vals)
        linenos.append(lineno)
    if not rows:
        raise ValueError(f"{source}: no numeric data found (empty file or header only)")
    return np.asarray(rows, dtype=np.float64).reshape(-1, ncols), linenos, header


class ResampledWarning(UserWarning):
    """`read_record` put a record whose time column jitters (within `time_tolerance`) on a
    uniform grid; the message gives the largest deviation and the step."""


def _regular(t: np.ndarray, accel: np.ndarray, linenos: list[int], source: str,
             tolerance: float) -> tuple[float, np.ndarray]:
    """(dt, accel on a uniform grid from t[0]) of a two-column record: a time column
    uniform to 1e-6 of its step is taken as it is; one that jitters by up to `tolerance`
    x the step is resampled (linear interpolation) with a `ResampledWarning`; beyond that a
    ParameterError names the line, the deviation and the tolerance."""
    d = np.diff(t)
    bad = np.flatnonzero(d <= 0.0)
    if bad.size:
        i = int(bad[0])
        raise ValueError(
            f"{source}, line {linenos[i + 1]}: time is not strictly increasing "
            f"(t={float(t[i + 1])!r} s after t={float(t[i])!r} s)"
        )
    dt_med = float(np.median(d))
    if not np.any(np.abs(d - dt_med) > 1e-6 * dt_med + 1e-9):
        return float((t[-1] - t[0]) / (t.size - 1)), accel
    index = np.arange(t.size, dtype=np.float64)
    slope, intercept = np.polyfit(index, t, 1)  # the clock's step and start, fitted
    dev = np.abs(t - (intercept + slope * index)) / slope
    i = int(np.argmax(dev))
    worst = float(dev[i])
    if worst > tolerance:
        off = np.flatnonzero(np.abs(d - dt_med) > 2.0 * tolerance * dt_med)
        k = int(off[0]) if off.size else max(i - 1, 0)
        raise ParameterError(
            f"{source}, line {linenos[k + 1]}: non-uniform time step: step "
            f"{float(d[k]):.10g} s from t={float(t[k]):.10g} s differs from the median step "
            f"{dt_med:.10g} s; the time column is {worst:.3g} of a step off a uniform clock "
            f"(at line {linenos[i]}), more than the tolerance time_tolerance={tolerance:g} "
            "(a jitter within it is resampled)",
            param="time_tolerance", choices=(float(f"{worst * 1.01:.2g}"),))
    # the shortest decimal step that stays within half the tolerance over the record
    dt = next(c for c in (float(f"{slope:.{k}g}") for k in range(1, 18))
              if abs(c - slope) * (t.size - 1) <= 0.5 * tolerance * slope)
    grid = t[0] + dt * index  # the same number of samples; np.interp holds the last value
    warnings.warn(
        f"{source}: the time column jitters by up to {worst:.3g} of its step (tolerance "
        f"{tolerance:g}); resampled onto a uniform step of {dt:g} s by linear interpolation",
        ResampledWarning, stacklevel=4)
    return dt, np.interp(grid, t, accel)


_READS = "PEER AT2, ESM, K-NET/KiK-net, two columns (t, a) or one column (a)"


def _detect_format(lines: list[str], path: Path, source: str) -> str:
    if path.suffix.lower() == ".at2":
        return "at2"
    if len(lines) >= 4 and _match_npts_dt(lines[3]) is not None:
        return "at2"
    if _record_formats.is_knet(lines):
        return "knet"
    if _record_formats.is_esm(lines):
        return "esm"
    named = _record_formats.unsupported_format(lines)
    if named is not None:
        raise ValueError(f"{source}: unsupported format: {named}; rockjax reads {_READS}")
    for lineno, line in enumerate(lines, start=1):
        toks = _tokens(line)
        if not toks:
            continue
        vals = _parse_tokens(toks)
        if vals is None:
            continue
        if len(vals) == 2:
            return "two_column"
        if len(vals) == 1:
            return "one_column"
        raise ParameterError(
            f"{source}, line {lineno}: cannot detect the file format from {len(vals)} "
            f"values per line: unsupported format (rockjax reads {_READS})",
            param="format", choices=_FORMATS[:3],
        )
    raise ValueError(f"{source}: no numeric data found (empty file or header only)")


def _file_lines(source: str) -> tuple[list[str], str]:
    """(the lines of a record file, gzip and ';' / decimal commas undone; a note on what
    was undone, "" for a plain text file)."""
    text, compressed = _textfile.read_text(source)
    if not text.strip():
        raise ValueError(f"{source}: file is empty (no data)")
    lines, dialect = _textfile.normalize_rows(text.splitlines(), " ")
    notes = (["gzip"] if compressed else []) + ([dialect.note] if dialect.note else [])
    return lines, ", ".join(notes)


def record_format(path: str | os.PathLike[str]) -> str:
    """The layout of a record file as `read_record` detects it: ``"at2"``,
    ``"two_column"``, ``"one_column"``, ``"esm"`` or ``"knet"`` (ValueError or OSError as
    `read_record`)."""
    source = os.fspath(path)
    return _detect_format(_file_lines(source)[0], Path(source), source)


def _check_args(units, dt, format, time_tolerance):
    """The arguments of `read_record`, checked and normalized."""
    if units is not None:
        units = _normalize_units(units)
    if dt is not None:
        try:
            dt = float(dt)
        except (TypeError, ValueError):
            raise ParameterError(f"dt must be a number of seconds, got {dt!r}",
                                 param="dt") from None
        if not (math.isfinite(dt) and dt > 0.0):
            raise ParameterError(f"dt must be finite and > 0 [s], got {dt!r}", param="dt")
    if format is not None:
        fmt = str(format).strip().lower().replace("-", "_")
        if fmt not in _FORMATS:
            raise ParameterError(
                f"unknown format={format!r}; expected one of {', '.join(map(repr, _FORMATS))}",
                param="format")
        format = fmt
    tol = float(time_tolerance)
    if not (math.isfinite(tol) and 0.0 <= tol < 0.5):
        raise ParameterError(f"time_tolerance must be in [0, 0.5) (a fraction of the time "
                             f"step), got {time_tolerance!r}", param="time_tolerance")
    return units, dt, format, tol


def _read_database(format, lines, source, units, dt):
    """(dt, values, (units, where from), description) of an ESM or K-NET file."""
    reader = _record_formats.read_esm if format == "esm" else _record_formats.read_knet
    dt_file, values, stated, description = reader(lines, source)
    _check_dt_arg(dt, dt_file, source)
    try:
        unit = _units.normalize(stated, _ACCEL)
    except _units.UnitError:
        raise ValueError(f"{source}: the {format.upper()} header states units {stated!r}, "
                         "which are not a unit of acceleration") from None
    resolved = _resolve_units((unit, repr(f"UNITS: {stated}")), units, source, None)
    return dt_file, values, resolved, description


def _read_table(format, lines, source, units, dt, tolerance):
    """(dt, values, (units, where from), description) of a one- or two-column file."""
    ncols = 2 if format == "two_column" else 1
    if ncols == 1 and dt is None:
        raise ParameterError(f"{source}: a one-column file has no time information",
                             param="dt", choices=(Placeholder("time step in s"),))
    data, linenos, header = _read_columns(lines, source, ncols)
    accel = data[:, -1]
    if accel.size < 2:
        raise ValueError(f"{source}: a record needs at least 2 samples, found {accel.size}")
    description = "\n".join(header).strip()
    if ncols == 2:
        t = _units.to_si(data[:, 0], _time_unit_from_header(description, source), "time")
        dt_file, accel = _regular(t, accel, linenos, source, tolerance)
        _check_dt_arg(dt, dt_file, source)
    else:
        dt_file = float(dt)  # type: ignore[arg-type]
    resolved = _resolve_units(_units_from_header(description, source), units, source, None)
    return dt_file, accel, resolved, description


def _check_pga(accel: np.ndarray, units: str, units_source: str, source: str) -> None:
    """ParameterError when the PGA exceeds MAX_PLAUSIBLE_PGA_G, with the units' hint."""
    pga_g = float(np.max(np.abs(accel))) / G_STANDARD
    if pga_g <= MAX_PLAUSIBLE_PGA_G:
        return
    peak = pga_g * G_STANDARD / _units.factor(units, _ACCEL)
    other = [u for u in ("g", "m/s2", "cm/s2", "mm/s2")
             if 0.001 <= peak * _units.factor(u, _ACCEL) / G_STANDARD <= 2.0 and u != units]
    hint = ("; read in other units the PGA would be " + ", ".join(
        f"{peak * _units.factor(u, _ACCEL) / G_STANDARD:.3g} g ({u})" for u in other)
            if other else "")
    raise ParameterError(
        f"{source}: PGA {pga_g:.3g} g is implausible for a ground motion (more than "
        f"{MAX_PLAUSIBLE_PGA_G:g} g): the values peak at {peak:.4g}, read as {units} "
        f"({units_source}){hint}; check the units, or read it as it is",
        param="check_plausible", choices=(False,))


def read_record(
    path: str | os.PathLike[str],
    *,
    units: str | None = None,
    dt: float | None = None,
    format: str | None = None,
    time_tolerance: float = TIME_TOLERANCE,
    check_plausible: bool = True,
) -> Record:
    """Read a ground-acceleration record from a text file (plain or gzip-compressed).

    **Arguments:**

    - `path`: the file: plain text or gzip-compressed (any name; recognised by its first
      bytes). Values may be separated by blanks, tabs, commas or `;`, and use decimal
      commas (`0,01;-0,5`).
    - `units`: the units of the acceleration values in the file: `"g"`, `"m/s2"`,
      `"cm/s2"`, `"gal"`, `"mm/s2"` or `"in/s2"`, in any spelling of the unit table
      `rockjax.UNITS` (`"m/s^2"`, `"mps2"`, `"cm/sec/sec"`, `"Gal"`). A file that states
      its units (`UNITS OF G` in an AT2 header, `Accel[g]` or `accel_cm/s2` in a column
      title, `UNITS: cm/s^2` in an ESM header; K-NET is in gal) is read in those units,
      and `units` must then agree with them (the same size: `"gal"` and `"cm/s2"` agree):
      a contradiction is a `ParameterError` naming both. When the file states nothing,
      `units` is used; an AT2 file without it is in g (PEER's convention); a one- or
      two-column file without it is a `ValueError` asking for `units=`.
      `Record.units_source` says which rule applied.
    - `dt` [s]: the time step, > 0. Required for one-column files; for the other layouts
      the step comes from the file, and a `dt` passed as well must agree with it.
    - `format`: the layout, `"at2"`, `"two_column"`, `"one_column"`, `"esm"` or
      `"knet"`; detected when omitted (an `.AT2` suffix or an `NPTS=..., DT=...` fourth
      line means AT2; `Origin Time` first, K-NET; `SAMPLING_INTERVAL_S:` and `NDATA:` in
      the header, ESM; otherwise the number of values on the first numeric line). A format
      recognised but not read (COSMOS, binary SAC or miniSEED, Excel workbooks, ...) is a
      `ValueError` saying "unsupported format" and naming it.
    - `time_tolerance`: a two-column file's time column (in s, or as its title says:
      `t_ms`, `Time[s]`) must have a uniform step. One whose steps differ from their
      median by at most `time_tolerance` x the step (default 1e-3; a clock's jitter) is
      resampled onto a uniform step by linear interpolation, with a `ResampledWarning`;
      beyond it, a `ParameterError` states the deviation and the tolerance.
    - `check_plausible`: refuse a PGA above 5 g (a `ParameterError` that gives the PGA the
      values would have in other units); default True. False reads such a record as it
      is.

    **Returns:** a `Record`: `accel` in m/s² (values in g are multiplied by `G_STANDARD`
    = 9.80665 m/s², values in cm/s2 or gal by 0.01, and so on: `rockjax.UNITS`), first
    sample at t = 0. A two-column record whose time starts at t0 != 0 is shifted to start
    at 0, and its `dt` is (t[-1] - t[0]) / (n - 1).

    **Raises:** `FileNotFoundError` if `path` does not exist; `ValueError` (or its
    subclass `rockjax.ParameterError`, naming the argument) for unknown `units` or
    `format`, `units` that contradict the file's header, a missing or non-positive `dt`,
    an implausible PGA, an unsupported format, and malformed files: no data, non-numeric
    text or NaN/inf in the data section (the message names the line), an NPTS (NDATA)
    count that does not match the values found, a time column that is not strictly
    increasing or not uniform within `time_tolerance`, or fewer than 2 samples. Messages
    name the file.
    """
    source = os.fspath(path)
    p = Path(source)
    units, dt, format, tolerance = _check_args(units, dt, format, time_tolerance)
    if not p.exists():
        raise FileNotFoundError(f"ground-motion record not found: {source}")
    if p.is_dir():
        raise IsADirectoryError(f"ground-motion record path is a directory: {source}")
    lines, note = _file_lines(source)
    if format is None:
        format = _detect_format(lines, p, source)
    if format == "at2":
        dt_file, accel, (units, units_source), description = _read_at2(lines, source, units, dt)
    elif format in ("esm", "knet"):
        dt_file, accel, (units, units_source), description = _read_database(
            format, lines, source, units, dt)
    else:
        dt_file, accel, (units, units_source), description = _read_table(
            format, lines, source, units, dt, tolerance)
    if accel.size < 2:
        raise ValueError(f"{source}: a record needs at least 2 samples, found {accel.size}")
    accel = accel * _units.factor(units, _ACCEL)
    if check_plausible:
        _check_pga(accel, units, units_source, source)
    if note:
        description = f"{description}\n(read from: {note})".strip()
    return Record(dt=dt_file, accel=accel, source=source, description=description,
                  units_in_file=units, units_source=units_source)


#: a common step more than this many times finer than the finest record is refused
MAX_GRID_REFINEMENT = 10


def _as_fraction(dt: float) -> fractions.Fraction | None:
    """`dt` [s] as a ratio of integers (denominator up to 10**6), or None when no such
    ratio is within 1e-9 of it."""
    frac = fractions.Fraction(dt).limit_denominator(10**6)
    return frac if frac > 0 and abs(float(frac) - dt) <= 1e-9 * dt else None


def common_time_step(dts, *, names=None, max_refinement: int = MAX_GRID_REFINEMENT) -> float:
    """The largest time step [s] that divides every step in `dts` [s] a whole number of
    times: the grid on which records of different steps are resampled exactly.

    The steps are read as ratios of integers (0.005 = 1/200, 0.01 = 1/100, 0.02 = 1/50 give
    0.005), so float steps such as 0.019999999999999997 count as 0.02. When one of `dts` is
    the common step, that float is returned unchanged.

    Raises ValueError, naming the steps (and the records' `names` when given), when a step
    is not positive and finite, is not a ratio of integers with a denominator up to 10**6,
    or when the common step would be more than `max_refinement` times finer than the
    finest record (0.01 s and 0.0073 s need a 0.0001 s grid, 73 times finer).
    """
    dts = [float(d) for d in dts]
    labels = list(names) if names is not None else [None] * len(dts)
    if not dts:
        raise ValueError("common_time_step needs at least one time step")

    def said(i):
        return f"{labels[i]} dt = {dts[i]:g} s" if labels[i] is not None else f"{dts[i]:g} s"

    fracs = []
    for i, d in enumerate(dts):
        if not (math.isfinite(d) and d > 0):
            raise ValueError(f"time steps must be positive and finite, got {said(i)}")
        frac = _as_fraction(d)
        if frac is None:
            raise ValueError(
                f"the time step {said(i)} is not a ratio of integers (denominator up to "
                "10**6); resample the record to a step such as 0.005, 0.01 or 0.02 s"
            )
        fracs.append(frac)
    num = math.gcd(*(f.numerator for f in fracs))
    den = math.lcm(*(f.denominator for f in fracs))
    common = fractions.Fraction(num, den)
    finest = min(dts)
    if finest / float(common) > max_refinement * (1 + 1e-9):
        detail = ", ".join(said(i) for i in range(len(dts)))
        raise ValueError(
            f"the records' time steps ({detail}) have no common step coarser than "
            f"{float(common):g} s, {finest / float(common):.4g} times finer than the finest "
            f"record (at most {max_refinement} is allowed); resample the records to a "
            "common step first"
        )
    for d, f in zip(dts, fracs):
        if f == common:
            return d
    return float(common)


def on_grid(accel: np.ndarray, m: int) -> np.ndarray:
    """Samples `accel` (1-D) linearly interpolated onto a grid `m` times finer: the
    original samples are kept (every `m`-th point), so the piecewise-linear forcing is
    unchanged."""
    accel = np.asarray(accel, dtype=np.float64)
    if m == 1:
        return accel
    x = np.arange((accel.size - 1) * m + 1) / m
    return np.interp(x, np.arange(accel.size, dtype=np.float64), accel)
