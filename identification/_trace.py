"""Measured (or synthetic) free-vibration decay traces: a container and a CSV reader.

A decay trace is the motion of a structure released from an initial displacement,
sampled at times ``t`` [s]: any of its top displacement ``u`` [m], its rotation ``theta``
[rad] and the uplift of the lifted corner [m] (at least one). On disk it is a CSV file::

    # any number of leading comment lines starting with '#'
    t,u,uplift
    0.000,0.1000,0.0506
    0.005,0.0999,0.0506
    ...

**Header.** One name per column: time ``t`` or ``time``; displacement ``u``, ``disp`` or
``displacement``; rotation ``theta``, ``rotation``, ``rot`` or ``tilt``; uplift
``uplift``; in any order, case-insensitive; time and at least one of the others. Each name
may carry its unit: ``time_s``, ``t_ms``, ``disp_mm``, ``u [mm]``, ``u (cm)``,
``uplift[mm]``, ``theta_deg``, ``rot [mrad]``. Units of time: s, ms, us, min; of length:
m, cm, mm, um, in; of angle: rad, mrad, deg (the table of
:data:`rockjax.UNITS`, which also lists their other spellings, such as sec). A column
without a unit is taken as SI (s, m, rad). Values are converted to SI, and the trace records
what was read (:meth:`DecayTrace.info`). ``read_trace(path, columns={"t": "Zeit", "u":
"Weg_mm"})`` picks the columns by name instead (others are ignored), and ``units={"u":
"mm"}`` gives units the header does not state.

**Text.** The file may be gzip-compressed, and its values separated by commas, ``;``,
tabs or blanks, with decimal points or decimal commas (``rockjax.datasets.read_text`` and
``normalize_rows``, shared with the record reader).

**Plausibility.** A median time step of 0.1 s or more (a time column in ms under a plain
``t`` title) and a displacement column in mm, cm or um that never reaches 1 mm (metres
under a ``disp_mm`` title) are refused with a hint on the units, unless
``check_plausible=False``; so is a rotation read in rad that exceeds 1 rad (57 deg: a
column in degrees under a plain ``theta`` title). A rotation column (``theta``, or one
with a unit of angle) picked as the displacement (``columns={'u': 'theta'}``) is refused,
and so is a displacement title with a unit of angle (``u_deg``).

**Refused**, with a ``ValueError`` that names the file and the line: a missing or
unrecognised header, a row with the wrong number of values, a value that is not a number
or is infinite, a time that does not strictly increase, fewer than 10 samples, and a gap in
time (a step more than 10 times the median step) -- split such a trace into pieces or
resample it before fitting. A missing value (empty, ``nan``, ``NA``) is refused too, with
the count of such rows; ``drop_nan=True`` drops those rows instead, with a
:class:`DroppedRowsWarning` that says how many.

**Release.** A lab trace often starts before the release: the structure held at its
initial displacement for a while, or a logger clock that does not start at 0.
``identification.detect_release`` (``_release.py``) finds the release (noise-aware).

The package also ships three SYNTHETIC traces made with rockjax by
``data/make_synthetic_traces.py`` (``_synthetic.py``: ``synthetic_trace_path``,
``synthetic_truth``); they are simulations with known parameters, not measurements.
"""

from __future__ import annotations

import dataclasses
import math
import os
import pathlib
import types
import warnings

import numpy as np

import rockjax

__all__ = [
    "CHANNELS",
    "DecayTrace",
    "DroppedRowsWarning",
    "LENGTH_UNITS",
    "MAX_GAP_RATIO",
    "MIN_SAMPLES",
    "read_trace",
    "SYNTHETIC_TRACES",
    "TIME_UNITS",
    "TraceError",
]

MIN_SAMPLES = 10
"""Fewest samples a trace may have."""

MAX_GAP_RATIO = 10.0
"""A time step larger than this multiple of the median step is a gap, and is refused."""

SYNTHETIC_TRACES = ("synthetic_decay_clean", "synthetic_decay_noisy", "synthetic_decay_exact")
"""Names of the synthetic traces shipped in ``rockjax._data`` (files ``<name>.csv/.json``)."""

CHANNELS = ("t", "u", "uplift", "theta")
"""The channels of a trace: time [s], top displacement [m], uplift [m], rotation [rad]
(any of the last three, at least one)."""
MOTION = ("u", "theta", "uplift")
"""The channels of the motion, in the order the fit takes them (`identification.fit_decay`:
the first present is the one whose release is found)."""

_UNITS = rockjax.UNITS  # the one unit table of rockjax (records, traces, command line)


def _spelled(kind: str) -> dict:
    return {name: _UNITS.factor(name, kind) for name, (k, _) in _UNITS.spellings.items()
            if k == kind}


TIME_UNITS = _spelled("time")
"""Units of time a trace file may use (every spelling), and their size in s; from
:data:`rockjax.UNITS`."""

LENGTH_UNITS = _spelled("length")
"""Units of length a trace file may use (every spelling), and their size in m; from
:data:`rockjax.UNITS`."""

_UNITS_OF = {"t": "time", "u": "length", "uplift": "length", "theta": "angle"}  # unit kinds
_SI = {"t": "s", "u": "m", "uplift": "m", "theta": "rad"}
_KIND = {"t": "time", "u": "displacement", "uplift": "uplift", "theta": "rotation"}
_NAMES = {"t": ("t", "time"), "u": ("u", "disp", "displacement"), "uplift": ("uplift",),
          "theta": ("theta", "rotation", "rot", "tilt")}
_MISSING = ("", "nan", "na", "n/a", "null", "none")
_EXPECTED_HEADER = (
    "'t,u' or 't,u,uplift' (s, m, m), or with units such as 'time_s,disp_mm' or "
    "'t [s],u [mm]'; a rotation (rad) or an uplift alone, 't,theta_deg' or 't,uplift'"
)
_UNITS_FROM = ("header", "units argument", "assumed SI", "SI arrays")


class TraceError(ValueError):
    """A trace that cannot be used as given. `param` names the argument that would fix it
    (``"drop_nan"``, ``"columns"``, ``"units"``, ``"structure"``; None: none) and `value`
    a value of it that would. ``str(e)`` is `message` with the advice in Python terms
    (``pass drop_nan=True``); a front end writes the argument in its own terms into
    `advice` (``{}`` marks where) with `advice_for`, as ``rockjax fit`` does (``--drop-nan``)."""

    def __init__(self, message: str, *, param=None, value=None, advice="", python=None):
        self.message, self.param, self.value, self.advice = message, param, value, advice
        super().__init__(message + (advice.format(f"{param}={value!r}") if python is None
                                    else python))

    def advice_for(self, argument: str) -> str:
        """The advice with `argument`, the parameter and its value in a front end's terms."""
        return self.advice.format(argument)


class DroppedRowsWarning(UserWarning):
    """``read_trace(..., drop_nan=True)`` dropped rows with missing values."""


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


def _frozen_map(name: str, value, default: dict):
    """A read-only str -> str mapping over channels (`default` when None)."""
    d = dict(default if value is None else value)
    if not all(k in CHANNELS and isinstance(v, str) for k, v in d.items()):
        raise ValueError(f"DecayTrace.{name}: must map channels {CHANNELS} to str, got {d!r}")
    return types.MappingProxyType(d)


@dataclasses.dataclass(frozen=True, eq=False)
class DecayTrace:
    """A free-vibration decay trace: top displacement, rotation and/or uplift against time.

    Parameters
    ----------
    t : array_like, shape (n,)
        Sample times [s]: finite, strictly increasing, at least 10 samples, and without
        gaps (no step larger than 10 times the median step). Need not start at 0.
    u : array_like, shape (n,), optional
        Top displacement of the structure [m], finite; ``None`` if not measured.
    uplift : array_like, shape (n,), optional
        Uplift of the lifted corner [m], finite; ``None`` (default) if not measured.
    theta : array_like, shape (n,), optional
        Rotation of the body [rad], finite; ``None`` (default) if not measured. At least
        one of `u`, `theta` and `uplift` is required.
    source : str, optional
        Where the trace came from (e.g. the file path), for messages.
    columns, units, units_from : mapping, optional
        What was read, per channel (``"t"``, ``"u"``, ``"uplift"``): the column of the
        file, its unit there (e.g. ``"mm"``; the arrays are in SI units whatever it was),
        and where that unit came from (``"header"``, ``"units argument"``, ``"assumed
        SI"``). Set by :func:`read_trace`; for arrays given directly, SI units.
    dropped_lines : tuple of int, optional
        Lines of the file dropped for missing values (``read_trace(..., drop_nan=True)``).

    Attributes
    ----------
    t, u, uplift, theta : numpy.ndarray
        Read-only float64 copies of the inputs (``u``, ``uplift``, ``theta`` may be
        ``None``).
    source : str
    columns, units, units_from : mappingproxy
    dropped_lines : tuple of int

    Raises
    ------
    ValueError
        Naming the field (``t``, ``u``, ``uplift``, ``theta`` or ``source``) that is
        invalid, or when none of ``u``, ``theta`` and ``uplift`` is given.

    Notes
    -----
    Instances are immutable and compare by identity (``eq=False``), since equality of
    arrays has no single truth value.
    """

    t: np.ndarray
    u: np.ndarray | None = None
    uplift: np.ndarray | None = None
    source: str = ""
    columns: object = None
    units: object = None
    units_from: object = None
    dropped_lines: tuple = ()
    theta: np.ndarray | None = None

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
        if self.u is None and self.theta is None and self.uplift is None:
            raise ValueError("DecayTrace: no channel of the motion: give at least one of u "
                             "[m], theta [rad] and uplift [m]")
        object.__setattr__(self, "t", t)
        for ch in MOTION:
            if getattr(self, ch) is not None:
                x = _as_vector(ch, getattr(self, ch))
                if x.shape != t.shape:
                    raise ValueError(f"DecayTrace.{ch}: has {x.size} samples but t has "
                                     f"{t.size}")
                object.__setattr__(self, ch, x)
        self._set_read_info()

    def _set_read_info(self):
        chans = ("t",) + tuple(c for c in CHANNELS[1:] if getattr(self, c) is not None)
        si = {c: _SI[c] for c in chans}
        object.__setattr__(self, "columns", _frozen_map("columns", self.columns, {}))
        object.__setattr__(self, "units", _frozen_map("units", self.units, si))
        object.__setattr__(self, "units_from", _frozen_map(
            "units_from", self.units_from, dict.fromkeys(chans, "SI arrays")))
        object.__setattr__(self, "dropped_lines", tuple(int(i) for i in self.dropped_lines))

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.size)

    @property
    def duration(self) -> float:
        """``t[-1] - t[0]`` [s]."""
        return float(self.t[-1] - self.t[0])

    @property
    def dt(self) -> float:
        """The median time step [s], to 12 significant digits (0.005, not 0.00499999...)."""
        return float(f"{float(np.median(np.diff(self.t))):.12g}")

    @property
    def amplitude(self) -> float | None:
        """``max |u|`` [m]; None without a displacement channel."""
        return None if self.u is None else float(np.max(np.abs(self.u)))

    @property
    def has_uplift(self) -> bool:
        """Whether an uplift channel is present."""
        return self.uplift is not None

    @property
    def has_theta(self) -> bool:
        """Whether a rotation channel is present."""
        return self.theta is not None

    @property
    def channels(self) -> tuple:
        """The channels of the motion present, in the order of `MOTION` (u, theta,
        uplift)."""
        return tuple(c for c in MOTION if getattr(self, c) is not None)

    def report(self) -> list[str]:
        """What was read, as lines of text (what `rockjax fit` prints): the columns and
        units of each channel, dt, points, duration, amplitude, rows dropped."""
        return trace_lines(self.info())

    def info(self) -> dict:
        """What was read, JSON-ready (SI values; keys carry their units): ``file``,
        ``columns``, ``units_in_file``, ``units_from`` (per channel), ``dt_s``,
        ``n_points``, ``duration_s``, ``t_start_s``, ``t_end_s``, ``max_abs_u_m`` (None
        without u), ``has_uplift``, ``dropped_nan_rows`` and ``dropped_lines``; with a
        rotation channel also ``has_theta`` and ``max_abs_theta_rad``."""
        extra = ({} if self.theta is None else
                 {"has_theta": True, "max_abs_theta_rad": float(np.max(np.abs(self.theta)))})
        return {
            "file": self.source,
            "columns": dict(self.columns),
            "units_in_file": dict(self.units),
            "units_from": dict(self.units_from),
            "dt_s": self.dt,
            "n_points": self.n,
            "duration_s": self.duration,
            "t_start_s": float(self.t[0]),
            "t_end_s": float(self.t[-1]),
            "max_abs_u_m": self.amplitude,
            "has_uplift": self.has_uplift,
            "dropped_nan_rows": len(self.dropped_lines),
            "dropped_lines": list(self.dropped_lines),
            **extra,
        }

    def __repr__(self) -> str:
        up = "with uplift" if self.has_uplift else "no uplift"
        src = f", source={self.source!r}" if self.source else ""
        peak = ("no u" if self.u is None else f"peak |u|={self.amplitude:.4g} m")
        if self.theta is not None:
            peak += f", peak |theta|={float(np.max(np.abs(self.theta))):.4g} rad"
        return (
            f"DecayTrace(n={self.n}, t=[{self.t[0]:g} .. {self.t[-1]:g}] s, "
            f"{peak}, {up}{src})"
        )


def _read_lines(path) -> tuple[list[str], str]:
    """(the lines of the file at `path` (str, os.PathLike or an importlib.resources
    Traversable), gzip and ';' / tab / blank separators and decimal commas undone, so
    that rows are comma-separated with decimal points; a note on what was undone)."""
    if isinstance(path, (str, os.PathLike)):
        p = pathlib.Path(path)
        if not p.is_file():
            if p.exists():
                raise ValueError(f"{p}: not a regular file")
            raise FileNotFoundError(f"decay trace file not found: {p}")
    elif hasattr(path, "read_bytes") and hasattr(path, "is_file"):  # a Traversable
        if not path.is_file():
            raise FileNotFoundError(f"decay trace file not found: {path}")
    else:
        raise TypeError(f"read_trace: expected a path, got {type(path).__name__}")
    text, compressed = rockjax.datasets.read_text(path)
    lines, dialect = rockjax.datasets.normalize_rows(text.splitlines(), ",")
    notes = (["gzip"] if compressed else []) + ([dialect.note] if dialect.note else [])
    return lines, ", ".join(notes)


def read_trace(path, *, columns=None, units=None, drop_nan: bool = False,
               check_plausible: bool = True) -> DecayTrace:
    """Read a free-vibration decay trace from a CSV file.

    Parameters
    ----------
    path : str, os.PathLike or importlib.resources.abc.Traversable
        The CSV file, plain or gzip-compressed (any name). Layout: optional leading
        comment lines starting with ``#``, then the header, then one row per sample.
        Values may be separated by commas, ``;``, tabs or blanks, and use decimal commas
        (``0,01;1,5``). Whitespace around values and blank lines are ignored.
        Header: time ``t``/``time`` and at least one of displacement
        ``u``/``disp``/``displacement``, rotation ``theta``/``rotation``/``rot``/``tilt``
        and ``uplift``, in any order, each with an optional unit (``time_s``, ``t_ms``,
        ``disp_mm``, ``u [mm]``, ``u (cm)``, ``theta_deg``; time: s, ms, us, min; length:
        m, cm, mm, um, in; angle: rad, mrad, deg); without a unit, SI (s, m, rad).
    columns : mapping, optional
        Pick the columns by their header names instead, e.g. ``{"t": "time_s", "u":
        "disp_mm"}`` or ``{"t": "t", "theta": "Winkel_deg"}`` (``"t"`` and at least one
        of ``"u"``, ``"theta"``, ``"uplift"``; case-insensitive). Other columns are
        ignored.
        The unit is still taken from a suffix of the name when it has one.
    units : mapping, optional
        Units of channels whose header names state none, e.g. ``{"u": "mm"}``,
        ``{"theta": "deg"}``. A unit
        that contradicts the header is refused.
    drop_nan : bool
        Drop rows with a missing value (empty, ``nan``, ``NA``) in a used column, with a
        :class:`DroppedRowsWarning` saying how many; default False: refuse them.
    check_plausible : bool
        Refuse, with a hint on the units, a median time step of 0.1 s or more (a time
        column in ms read as s), a displacement stated in mm, cm or um that never
        reaches 1 mm (a column in metres under a ``disp_mm`` title) and a rotation read in
        rad beyond 1 rad (degrees under a plain ``theta`` title); default True. False
        reads such a trace as it is.

    Returns
    -------
    DecayTrace
        In SI units, with ``source`` set to ``str(path)``, and what was read in
        ``columns``, ``units``, ``units_from`` and ``dropped_lines`` (see
        :meth:`DecayTrace.info`); ``u``, ``theta``, ``uplift`` are ``None`` without
        their column.

    Raises
    ------
    FileNotFoundError
        If `path` does not exist (the message names it).
    ValueError
        Naming the file and the line number, for: an empty file or a missing/unrecognised
        header, an unknown unit, a row with the wrong number of values, a value that is not
        a number or is infinite, a missing value (unless `drop_nan`), a time that goes
        backwards or repeats, fewer than 10 samples, or a gap in time (a step over 10 times
        the median step; split the trace or resample). Those with advice that differs
        between Python and the command line are :class:`TraceError`.

    Examples
    --------
    >>> from identification import read_trace, synthetic_trace_path
    >>> tr = read_trace(synthetic_trace_path("synthetic_decay_clean"))
    >>> tr.n, tr.duration, tr.units["u"]
    (1601, 8.0, 'm')
    """
    name = str(path)
    lines, _ = _read_lines(path)
    header_line, layout = _read_header(name, lines, columns, units)
    rows, linenos, dropped = _read_rows(name, lines, header_line, layout, drop_nan)
    if len(rows) < MIN_SAMPLES:
        last = linenos[-1] if linenos else header_line + 1
        raise _line_error(
            name, last,
            f"only {len(rows)} sample(s) after the header (line {header_line + 1}); "
            f"at least {MIN_SAMPLES} are needed",
        )
    data = np.asarray(rows, dtype=np.float64)
    si = {ch: _UNITS.to_si(data[:, k], layout.units[ch], _UNITS_OF[ch])
          for k, ch in enumerate(layout.channels)}
    t = si["t"]
    if check_plausible:
        _check_plausible(name, layout, t, si)
    gap = _first_gap(t)
    if gap is not None:
        k, step, med = gap
        raise _line_error(
            name, linenos[k],
            f"gap in time of {step:g} s at line {linenos[k]} (from t = {t[k - 1]:g} s to "
            f"{t[k]:g} s, more than {MAX_GAP_RATIO:g} x the median step {med:g} s); "
            "split the trace or resample",
        )
    if dropped:
        warnings.warn(f"{name}: dropped {len(dropped)} row(s) with missing (NaN) values "
                      f"(line(s) {_some(dropped)})", DroppedRowsWarning, stacklevel=2)
    return DecayTrace(t=t, u=si.get("u"), uplift=si.get("uplift"), theta=si.get("theta"),
                      source=name, columns=layout.names, units=layout.units,
                      units_from=layout.units_from, dropped_lines=dropped)


#: a median time step of this many seconds or more is implausible for a decay trace
MAX_PLAUSIBLE_DT = 0.1
#: a displacement column in mm, cm or um whose peak stays below this [m] is implausible
MIN_PLAUSIBLE_PEAK = 1e-3
#: a rotation column in rad whose peak exceeds this [rad] (57 deg) is implausible
MAX_PLAUSIBLE_ROTATION = 1.0


def _check_plausible(name: str, layout, t: np.ndarray, si: dict) -> None:
    """TraceError, with a hint on the units, for a time step of seconds, a displacement
    column in mm (cm, um) that never reaches 1 mm, or a rotation in rad beyond 1 rad."""
    off = "; pass {} to read it as it is"
    dt = float(np.median(np.diff(t)))
    if dt >= MAX_PLAUSIBLE_DT:
        col, unit = layout.names["t"], layout.units["t"]
        msg = (f"column {col!r}: a time step of {dt:g} s (read in {unit}, "
               f"{layout.units_from['t']}) is implausible for a decay trace; if the column "
               f"is in milliseconds (a step of {dt * 1e-3:g} s), name it t_ms")
        raise TraceError(f"{name}: {msg}",
                         param="check_plausible", value=False,
                         advice=" or pass --units t=ms" + off,
                         python=" or pass units={'t': 'ms'}" + off.format(
                             "check_plausible=False"))
    if "theta" in si and layout.units["theta"] == "rad":
        peak = float(np.max(np.abs(si["theta"])))
        if peak > MAX_PLAUSIBLE_ROTATION:
            col = layout.names["theta"]
            msg = (f"column {col!r}: a rotation of {peak:.4g} rad (read in rad, "
                   f"{layout.units_from['theta']}) is implausible for a rocking decay (a "
                   f"rocking body overturns long before {MAX_PLAUSIBLE_ROTATION:g} rad); if "
                   f"the column holds degrees ({peak:.4g} deg), name it theta_deg")
            raise TraceError(f"{name}: {msg}", param="check_plausible", value=False,
                             advice=" or pass --units theta=deg" + off,
                             python=" or pass units={'theta': 'deg'}" + off.format(
                                 "check_plausible=False"))
    if "u" not in si:
        return
    u = si["u"]
    unit = layout.units["u"]
    peak = float(np.max(np.abs(u)))
    if unit in ("mm", "cm", "um") and peak < MIN_PLAUSIBLE_PEAK:
        col = layout.names["u"]
        size = _UNITS.factor(unit, "length")
        msg = (f"column {col!r}: the displacement, read in {unit} "
               f"({layout.units_from['u']}), never exceeds {peak / size:.4g} {unit} "
               f"({peak * 1e3:.3g} mm), implausible for a rocking decay; if the column "
               f"holds metres ({peak / size:.4g} m), ")
        fix = "correct its title (such as disp_m)"
        raise TraceError(f"{name}: {msg}{fix}", param="check_plausible", value=False,
                         advice=off, python=off.format("check_plausible=False"))


def _some(items, n: int = 5) -> str:
    """The first `n` of `items`, comma-separated, with '...' when there are more."""
    items = list(items)
    return ", ".join(str(x) for x in items[:n]) + (", ..." if len(items) > n else "")


def _line_error(name: str, lineno: int, msg: str, **advice) -> TraceError:
    """The error for line `lineno` (1-based) of the file `name` (`advice`: `TraceError`'s)."""
    return TraceError(f"{name}, line {lineno}: {msg}", **advice)


@dataclasses.dataclass(frozen=True)
class _Layout:
    """Which columns of the file hold which channel, and in which unit."""

    header: tuple  # the header's cells, stripped
    channels: tuple  # channels present, in CHANNELS order
    index: dict  # channel -> column index
    names: dict  # channel -> column name
    units: dict  # channel -> unit in the file
    units_from: dict  # channel -> "header", "units argument" or "assumed SI"


def _split_unit(cell: str) -> tuple[str, str | None]:
    """(name, unit or None) of a header cell: 'u [mm]', 'u (mm)', 'u[mm]' and 'u_mm' carry
    the unit mm; lower case. An underscore suffix counts only if it is a known unit of time
    or length (`rockjax.UNITS.split_token`)."""
    return _UNITS.split_token(cell.strip().lower(), ("time", "length", "angle"))


_ROTATION_NAMES = ("theta", "rotation", "rot", "tilt")


def _rotation_message(cell: str, ch: str = "u") -> str:
    """Why a rotation column cannot be read as a displacement (channel `ch`), and what to
    do."""
    what = "a displacement" if ch == "u" else "an uplift"
    return (f"column {cell!r} is a rotation, not {what}: read it as the rotation channel "
            f"theta (title it theta, theta_deg or theta_rad, or pick it with "
            f"columns={{'theta': {cell!r}}}); the fit then compares it with the model's "
            "rotation")


def _read_header(name: str, lines: list[str], columns, units) -> tuple[int, _Layout]:
    """(index of the header line, the layout it gives): the header is the first line that
    is neither blank nor a comment."""
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
    raw = lines[header_line].strip()
    cells = tuple(c.strip() for c in raw.split(","))
    where = (name, header_line + 1)
    index = (_auto_columns(where, raw, cells) if columns is None
             else _named_columns(where, cells, columns))
    chans = tuple(c for c in CHANNELS if c in index)
    names = {ch: cells[index[ch]] for ch in chans}
    unit_of, units_from = _channel_units(where, names, units)
    return header_line, _Layout(header=cells, channels=chans, index=index, names=names,
                                units=unit_of, units_from=units_from)


def _auto_columns(where, raw: str, cells: tuple) -> dict:
    """channel -> column index, from the names of the header (every column must be one)."""
    hint = dict(param="columns", value={"t": "NAME", "u": "NAME"},
                advice="; name the columns with {}",
                python="; name the columns with columns={'t': ..., 'u': ...}")
    index: dict = {}
    for i, cell in enumerate(cells):
        base, _ = _split_unit(cell)
        ch = next((c for c, names in _NAMES.items() if base in names), None)
        if ch is None:
            msg = (f"expected header {_EXPECTED_HEADER}, got {raw!r}: column {cell!r} is "
                   "not a time, displacement or uplift column")
            raise _line_error(*where, msg, **hint)
        if ch in index:
            msg = f"two {_KIND[ch]} columns in the header ({cells[index[ch]]!r} and {cell!r})"
            raise _line_error(*where, msg, **hint)
        index[ch] = i
    if "t" not in index:
        msg = f"expected header {_EXPECTED_HEADER}, got {raw!r}: no time column"
        raise _line_error(*where, msg, **hint)
    if not set(MOTION) & set(index):
        msg = (f"expected header {_EXPECTED_HEADER}, got {raw!r}: no displacement, "
               "rotation or uplift column")
        raise _line_error(*where, msg, **hint)
    return index


def _named_columns(where, cells: tuple, columns) -> dict:
    """channel -> column index, from an explicit mapping channel -> column name."""
    if not isinstance(columns, dict) or not all(isinstance(v, str) for v in columns.values()):
        raise ValueError(f"columns must map channels to column names, such as {{'t': "
                         f"'time_s', 'u': 'disp_mm'}}, got {columns!r}")
    bad = sorted(set(columns) - set(CHANNELS))
    if bad or "t" not in columns or not set(MOTION) & set(columns):
        raise ValueError(f"columns must name the columns of 't' and 'u' (or of 't' and "
                         f"'theta' or 'uplift'), got {sorted(columns)}")
    lower = [c.lower() for c in cells]
    index = {}
    for ch, col in columns.items():
        n = lower.count(col.strip().lower())
        if n != 1:
            what = "no column" if n == 0 else f"{n} columns"
            raise _line_error(*where, f"{what} {col!r} in the header (its columns: "
                              f"{', '.join(repr(c) for c in cells)})")
        index[ch] = lower.index(col.strip().lower())
    if len(set(index.values())) < len(index):
        raise ValueError(f"columns maps two channels to one column: {columns!r}")
    return index


def _check_units_arg(units) -> dict:
    """channel -> canonical unit of the `units` argument (UnitError for an unknown one)."""
    if units is None:
        return {}
    if not isinstance(units, dict) or set(units) - set(CHANNELS):
        raise ValueError(f"units must map channels {CHANNELS} to units, such as {{'u': "
                         f"'mm'}}, got {units!r}")
    return {ch: _UNITS.normalize(unit, _UNITS_OF[ch], what=f"units[{ch!r}]")
            for ch, unit in units.items()}


def _channel_units(where, names: dict, units) -> tuple[dict, dict]:
    """(channel -> unit in the file, channel -> where that unit came from)."""
    given = _check_units_arg(units)
    unit_of, units_from = {}, {}
    for ch, cell in names.items():
        _, in_header = _split_unit(cell)
        kind = _UNITS_OF[ch]
        if ch in ("u", "uplift") and (_UNITS.kind_of(in_header or "") == "angle"
                                      or _split_unit(cell)[0] in _ROTATION_NAMES):
            raise _line_error(*where, _rotation_message(cell, ch))
        if in_header is not None:
            try:
                in_header = _UNITS.normalize(in_header, kind)
            except rockjax.UnitError:
                raise _line_error(*where, f"column {cell!r}: {in_header!r} is not a unit of "
                                  f"{kind} (expected one of {', '.join(_UNITS.names(kind))})"
                                  ) from None
        arg = given.get(ch)
        if (in_header is not None and arg is not None
                and _UNITS.factor(in_header, kind) != _UNITS.factor(arg, kind)):
            raise _line_error(*where, f"column {cell!r} is in {in_header}, but the units "
                              f"given say {arg} for {ch!r}")
        if in_header is not None:
            unit_of[ch], units_from[ch] = in_header, "header"
        elif arg is not None:
            unit_of[ch], units_from[ch] = arg, "units argument"
        else:
            unit_of[ch], units_from[ch] = _SI[ch], "assumed SI"
    return unit_of, units_from


def _read_rows(name: str, lines: list[str], header_line: int, layout: _Layout,
               drop_nan: bool):
    """(the rows of values after the header, in file units, their 1-based line numbers,
    the line numbers of rows dropped for a missing value); blank lines are skipped, and
    time must strictly increase."""
    rows: list[list[float]] = []
    linenos: list[int] = []
    missing: list[tuple[int, str, str]] = []  # (line, column, value)
    for i in range(header_line + 1, len(lines)):
        lineno = i + 1
        s = lines[i].strip()
        if not s:
            continue
        vals, gone = _parse_row(name, lineno, s, layout)
        if gone is not None:
            missing.append((lineno, *gone))
            continue
        if rows:
            _check_time_step(name, lineno, vals[0], rows[-1][0], linenos[-1])
        rows.append(vals)
        linenos.append(lineno)
    if missing and not drop_nan:
        lineno, col, x = missing[0]
        msg = (f"column {col!r}: missing value {x!r} (NaN); {len(missing)} row(s) of the "
               f"file have missing values (line(s) {_some(m[0] for m in missing)}); ")
        raise _line_error(name, lineno, msg, param="drop_nan", value=True,
                          advice="pass {} to drop them")
    return rows, linenos, tuple(m[0] for m in missing)


def _parse_row(name: str, lineno: int, s: str, layout: _Layout):
    """(the finite values of the used columns of row `s`, in `layout.channels` order, and
    None), or (None, (column, value)) for a row with a missing value."""
    fields = [x.strip() for x in s.split(",")]
    if len(fields) != len(layout.header):
        raise _line_error(
            name, lineno,
            f"expected {len(layout.header)} values ({','.join(layout.header)}), got "
            f"{len(fields)}: {s!r}",
        )
    vals = []
    gone = None
    for ch in layout.channels:
        col, x = layout.names[ch], fields[layout.index[ch]]
        if x.lower().lstrip("+-") in _MISSING:
            gone = gone or (col, x)
            continue
        try:
            v = float(x)
        except ValueError:
            raise _line_error(name, lineno, f"column {col!r}: {x!r} is not a number") from None
        if not math.isfinite(v):
            raise _line_error(name, lineno, f"column {col!r}: value {x!r} is not finite")
        vals.append(v)
    return (None, gone) if gone is not None else (vals, None)


def _check_time_step(name: str, lineno: int, t: float, t_prev: float, prev_lineno: int):
    """ValueError unless the time `t` of line `lineno` exceeds the previous sample's."""
    if t == t_prev:
        raise _line_error(
            name, lineno,
            f"time {t!r} repeats the previous sample (line {prev_lineno}); "
            "time must be strictly increasing",
        )
    if t < t_prev:
        raise _line_error(
            name, lineno,
            f"time goes backwards: {t!r} after {t_prev!r} "
            f"(line {prev_lineno}); time must be strictly increasing",
        )


def trace_lines(info) -> list[str]:
    """`DecayTrace.info()` as lines of text: the columns and units read, dt, points,
    duration, amplitude, rows dropped."""
    chans = ", ".join(
        f"{ch} = column {info['columns'].get(ch, ch)!r} in {unit} ({info['units_from'][ch]})"
        for ch, unit in info["units_in_file"].items())
    out = [f"{info['file']}: {chans}",
           f"dt {info['dt_s']:.6g} s, {info['n_points']} points, {info['duration_s']:.6g} s "
           f"(t = {info['t_start_s']:.6g} .. {info['t_end_s']:.6g} s), "
           + (f"max |u| {info['max_abs_u_m']:.4g} m" if info["max_abs_u_m"] is not None
              else "no u")]
    if info["dropped_nan_rows"]:
        out.append(f"{info['dropped_nan_rows']} row(s) with missing values dropped (--drop-nan)")
    return out
