"""Measured (or synthetic) free-vibration decay traces: a container and a CSV reader.

A decay trace is the top displacement ``u`` [m] of a structure released from an initial
displacement, sampled at times ``t`` [s], optionally with the uplift of the lifted corner
[m]. On disk it is a CSV file::

    # any number of leading comment lines starting with '#'
    t,u,uplift
    0.000,0.1000,0.0506
    0.005,0.0999,0.0506
    ...

The header is ``t,u`` or ``t,u,uplift``; values are in SI units (s, m, m). Whitespace
around values and blank lines are ignored. The reader refuses, with a ``ValueError`` that
names the file and the line: a missing or wrong header, a row with the wrong number of
values, a value that is not a number or is NaN/inf, a time that does not strictly increase,
fewer than 10 samples, and a gap in time (a step more than 10 times the median step) --
split such a trace into pieces or resample it before fitting.

The package also ships three SYNTHETIC traces made with rockjax by
``data/make_synthetic_traces.py`` (see :func:`synthetic_trace_path` and
:func:`synthetic_truth`); they are simulations with known parameters, not measurements.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import pathlib

import numpy as np

__all__ = [
    "DecayTrace",
    "MAX_GAP_RATIO",
    "MIN_SAMPLES",
    "read_trace",
    "SYNTHETIC_TRACES",
    "synthetic_trace_path",
    "synthetic_truth",
]

MIN_SAMPLES = 10
"""Fewest samples a trace may have."""

MAX_GAP_RATIO = 10.0
"""A time step larger than this multiple of the median step is a gap, and is refused."""

SYNTHETIC_TRACES = ("synthetic_decay_clean", "synthetic_decay_noisy", "synthetic_decay_exact")
"""Names of the synthetic traces shipped in ``rockjax._data`` (files ``<name>.csv/.json``)."""

_HEADERS = (("t", "u"), ("t", "u", "uplift"))
_EXPECTED_HEADER = "'t,u' or 't,u,uplift' (SI units: s, m, m)"


def _as_vector(name: str, x) -> np.ndarray:
    """A read-only float64 1-D copy of `x`; ValueError naming the field otherwise."""
    try:
        a = np.array(x, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as e:
        raise ValueError(f"DecayTrace.{name}: cannot convert to float64 array ({e})") from None
    if a.ndim != 1:
        raise ValueError(f"DecayTrace.{name}: must be 1-D, got shape {a.shape}")
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        i = int(bad[0])
        raise ValueError(
            f"DecayTrace.{name}: {bad.size} non-finite value(s), first at index {i} ({a[i]})"
        )
    a.flags.writeable = False
    return a


def _first_gap(t: np.ndarray) -> tuple[int, float, float] | None:
    """(index i of the sample after the gap, step t[i] - t[i-1], median step) or None."""
    dt = np.diff(t)
    med = float(np.median(dt))
    big = np.flatnonzero(dt > MAX_GAP_RATIO * med)
    if big.size == 0:
        return None
    i = int(big[0]) + 1
    return i, float(dt[i - 1]), med


@dataclasses.dataclass(frozen=True, eq=False)
class DecayTrace:
    """A free-vibration decay trace: top displacement (and optionally uplift) against time.

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times [s]: finite, strictly increasing, at least 10 samples, and without
        gaps (no step larger than 10 times the median step). Need not start at 0.
    u : array_like, shape (n,)
        Top displacement of the structure [m], finite.
    uplift : array_like, shape (n,), optional
        Uplift of the lifted corner [m], finite; ``None`` (default) if not measured.
    source : str, optional
        Where the trace came from (e.g. the file path), for messages.

    Attributes
    ----------
    t, u, uplift : numpy.ndarray
        Read-only float64 copies of the inputs (``uplift`` may be ``None``).
    source : str

    Raises
    ------
    ValueError
        Naming the field (``t``, ``u``, ``uplift`` or ``source``) that is invalid.

    Notes
    -----
    Instances are immutable and compare by identity (``eq=False``), since equality of
    arrays has no single truth value.
    """

    t: np.ndarray
    u: np.ndarray
    uplift: np.ndarray | None = None
    source: str = ""

    def __post_init__(self):
        if not isinstance(self.source, str):
            raise ValueError(f"DecayTrace.source: must be a str, got {type(self.source).__name__}")
        t = _as_vector("t", self.t)
        if t.size < MIN_SAMPLES:
            raise ValueError(f"DecayTrace.t: {t.size} sample(s), at least {MIN_SAMPLES} are needed")
        steps = np.diff(t)
        bad = np.flatnonzero(steps <= 0)
        if bad.size:
            i = int(bad[0]) + 1
            raise ValueError(
                f"DecayTrace.t: must be strictly increasing, but t[{i}] = {t[i]} s "
                f"<= t[{i - 1}] = {t[i - 1]} s"
            )
        gap = _first_gap(t)
        if gap is not None:
            i, step, med = gap
            raise ValueError(
                f"DecayTrace.t: gap in time of {step:g} s at index {i} (more than "
                f"{MAX_GAP_RATIO:g} x the median step {med:g} s); split the trace or resample"
            )
        u = _as_vector("u", self.u)
        if u.shape != t.shape:
            raise ValueError(f"DecayTrace.u: has {u.size} samples but t has {t.size}")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "u", u)
        if self.uplift is not None:
            up = _as_vector("uplift", self.uplift)
            if up.shape != t.shape:
                raise ValueError(f"DecayTrace.uplift: has {up.size} samples but t has {t.size}")
            object.__setattr__(self, "uplift", up)

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.size)

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]`` [s]."""
        return float(self.t[-1] - self.t[0])

    @property
    def has_uplift(self) -> bool:
        """Whether an uplift channel is present."""
        return self.uplift is not None

    def __repr__(self) -> str:
        up = "with uplift" if self.has_uplift else "no uplift"
        src = f", source={self.source!r}" if self.source else ""
        return (
            f"DecayTrace(n={self.n}, t=[{self.t[0]:g} .. {self.t[-1]:g}] s, "
            f"peak |u|={float(np.max(np.abs(self.u))):.4g} m, {up}{src})"
        )


def _open_text(path):
    """Open `path` (str, os.PathLike or an importlib.resources Traversable) for reading."""
    if isinstance(path, (str, os.PathLike)):
        p = pathlib.Path(path)
        if not p.is_file():
            if p.exists():
                raise ValueError(f"{p}: not a regular file")
            raise FileNotFoundError(f"decay trace file not found: {p}")
        return open(p, encoding="utf-8-sig", newline=None)
    if hasattr(path, "open") and hasattr(path, "is_file"):  # importlib.resources Traversable
        if not path.is_file():
            raise FileNotFoundError(f"decay trace file not found: {path}")
        return path.open("r", encoding="utf-8-sig")
    raise TypeError(f"read_trace: expected a path, got {type(path).__name__}")


def read_trace(path) -> DecayTrace:
    """Read a free-vibration decay trace from a CSV file.

    Parameters
    ----------
    path : str, os.PathLike or importlib.resources.abc.Traversable
        The CSV file. Layout: optional leading comment lines starting with ``#``, then the
        header ``t,u`` or ``t,u,uplift``, then one row per sample with time [s], top
        displacement [m] and, if in the header, uplift [m]. Whitespace around values and
        blank lines are ignored.

    Returns
    -------
    DecayTrace
        With ``source`` set to ``str(path)``; ``uplift`` is ``None`` for a ``t,u`` file.

    Raises
    ------
    FileNotFoundError
        If `path` does not exist (the message names it).
    ValueError
        Naming the file and the line number, for: an empty file or a missing/wrong header,
        a row with the wrong number of values, a value that is not a number, a NaN or
        infinite value, a time that goes backwards or repeats, fewer than 10 samples, or a
        gap in time (a step over 10 times the median step; split the trace or resample).

    Examples
    --------
    >>> from identification import read_trace, synthetic_trace_path
    >>> tr = read_trace(synthetic_trace_path("synthetic_decay_clean"))
    >>> tr.n, tr.duration
    (1601, 8.0)
    """
    name = str(path)
    with _open_text(path) as f:
        lines = f.read().splitlines()
    header_line, cols = _read_header(name, lines)
    rows, linenos = _read_rows(name, lines, header_line, cols)
    if len(rows) < MIN_SAMPLES:
        last = linenos[-1] if linenos else header_line + 1
        raise _line_error(
            name, last,
            f"only {len(rows)} sample(s) after the header (line {header_line + 1}); "
            f"at least {MIN_SAMPLES} are needed",
        )
    data = np.asarray(rows, dtype=np.float64)
    t = data[:, 0]
    gap = _first_gap(t)
    if gap is not None:
        k, step, med = gap
        raise _line_error(
            name, linenos[k],
            f"gap in time of {step:g} s at line {linenos[k]} (from t = {t[k - 1]:g} s to "
            f"{t[k]:g} s, more than {MAX_GAP_RATIO:g} x the median step {med:g} s); "
            "split the trace or resample",
        )
    uplift = data[:, 2] if len(cols) == 3 else None
    return DecayTrace(t=t, u=data[:, 1], uplift=uplift, source=name)


def _line_error(name: str, lineno: int, msg: str) -> ValueError:
    """The ValueError for line `lineno` (1-based) of the file `name`."""
    return ValueError(f"{name}, line {lineno}: {msg}")


def _read_header(name: str, lines: list[str]) -> tuple[int, tuple[str, ...]]:
    """(index of the header line, its column names): the first line that is neither blank
    nor a comment, which must be one of `_HEADERS`."""
    header_line = None
    for i, raw in enumerate(lines):
        s = raw.strip()
        if s and not s.startswith("#"):
            header_line = i
            break
    if header_line is None:
        what = "empty file" if not any(x.strip() for x in lines) else "only comment lines"
        raise _line_error(name, max(len(lines), 1),
                          f"{what}; expected a header line {_EXPECTED_HEADER}")
    cols = tuple(c.strip().lower() for c in lines[header_line].split(","))
    if cols not in _HEADERS:
        raise _line_error(
            name, header_line + 1,
            f"expected header {_EXPECTED_HEADER}, got {lines[header_line].strip()!r}",
        )
    return header_line, cols


def _read_rows(name: str, lines: list[str], header_line: int, cols: tuple[str, ...]):
    """(the rows of values after the header, their 1-based line numbers); blank lines are
    skipped, and time must strictly increase."""
    rows: list[tuple[float, ...]] = []
    linenos: list[int] = []
    for i in range(header_line + 1, len(lines)):
        lineno = i + 1
        s = lines[i].strip()
        if not s:
            continue
        vals = _parse_row(name, lineno, s, cols)
        if rows:
            _check_time_step(name, lineno, vals[0], rows[-1][0], linenos[-1])
        rows.append(tuple(vals))
        linenos.append(lineno)
    return rows, linenos


def _parse_row(name: str, lineno: int, s: str, cols: tuple[str, ...]) -> list[float]:
    """The finite values of the (stripped, non-blank) row `s`, one per column."""
    fields = [x.strip() for x in s.split(",")]
    if len(fields) != len(cols):
        raise _line_error(
            name, lineno,
            f"expected {len(cols)} values ({','.join(cols)}), got {len(fields)}: {s!r}",
        )
    vals = []
    for col, x in zip(cols, fields, strict=True):
        try:
            v = float(x)
        except ValueError:
            raise _line_error(name, lineno, f"column {col!r}: {x!r} is not a number") from None
        if not math.isfinite(v):
            raise _line_error(name, lineno, f"column {col!r}: value {x!r} is not finite")
        vals.append(v)
    return vals


def _check_time_step(name: str, lineno: int, t: float, t_prev: float, prev_lineno: int):
    """ValueError unless the time `t` of line `lineno` exceeds the previous sample's."""
    if t == t_prev:
        raise _line_error(
            name, lineno,
            f"time {t!r} s repeats the previous sample (line {prev_lineno}); "
            "time must be strictly increasing",
        )
    if t < t_prev:
        raise _line_error(
            name, lineno,
            f"time goes backwards: {t!r} s after {t_prev!r} s "
            f"(line {prev_lineno}); time must be strictly increasing",
        )


def synthetic_trace_path(name: str):
    """The packaged CSV file of a SYNTHETIC decay trace.

    Parameters
    ----------
    name : str
        One of :data:`SYNTHETIC_TRACES`: ``"synthetic_decay_clean"``,
        ``"synthetic_decay_noisy"`` or ``"synthetic_decay_exact"`` (without ``.csv``).

    Returns
    -------
    pathlib.Path or importlib.resources.abc.Traversable
        The file ``<name>.csv`` of ``rockjax._data`` (the repository's ``data/`` folder);
        pass it to :func:`read_trace`.

    Raises
    ------
    ValueError
        If `name` is not a shipped synthetic trace.
    """
    return _packaged(name, ".csv")


def synthetic_truth(name: str) -> dict:
    """The true parameters and settings of a SYNTHETIC decay trace (its JSON sidecar).

    Parameters
    ----------
    name : str
        One of :data:`SYNTHETIC_TRACES`.

    Returns
    -------
    dict
        Keys ``synthetic`` (True), ``description``, ``model``, ``k_f`` [N/m], ``r`` [-],
        ``u0`` [m], ``t0`` [s], ``noise_std_u`` [m], ``noise_std_uplift`` [m], ``seed``,
        ``rate_hz`` [Hz], ``duration_s`` [s], ``structure`` (the other Table 1 fields, SI
        units), ``generator`` and ``rockjax_version``.
    """
    with _packaged(name, ".json").open("r", encoding="utf-8") as f:
        return json.load(f)


def _packaged(name: str, suffix: str):
    if name not in SYNTHETIC_TRACES:
        raise ValueError(
            f"unknown synthetic trace {name!r}; expected one of {', '.join(SYNTHETIC_TRACES)}"
        )
    import rockjax  # lazy: reading a trace file needs no JAX

    res = rockjax.datasets.packaged_data_path(name + suffix)
    if not res.is_file():
        raise FileNotFoundError(
            f"synthetic trace file {name + suffix} not found (expected at {res}); "
            "run `python data/make_synthetic_traces.py`"
        )
    return res
