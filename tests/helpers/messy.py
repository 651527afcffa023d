"""The messy corpus: files of the kinds that labs and record databases produce, each with its
truth (the value rockjax must read, or the error it must raise), for issue 24.

Every case is a `Case` in `CASES`: a file name, the reader (``"record"``:
`rockjax.read_record`, ``"trace"``: `identification.read_trace`, ``"structure"``:
`rockjax.RockingStructure.from_toml`), a writer of the file's bytes, the reader's keyword
arguments, the truth (`Truth`: values, or an error class with its parameter and a pattern
of its message, and a warning where one is due), the class of mess, and the outcome
before issue 24 (measured on the commit before it). Add a row by appending a `Case`
(`tests/test_messy.py` reads every row).

- ``python tests/helpers/messy.py`` (or ``python -m tests.helpers.messy --table``) prints the
  table: case, class, outcome before issue 24, expected, outcome now, pass/FAIL (the rows
  that a fit judges, `FIT_CASES`, take a few minutes; ``--no-fits`` leaves them out);
- ``python tests/helpers/messy.py --write DIR`` writes the files into DIR.

The signals are synthetic (no real record): a zero-mean ground acceleration of 0.3 g peak
at 0.01 s and a decay trace of 80 mm at 0.005 s.
"""

from __future__ import annotations

import dataclasses
import gzip
import math
import pathlib
import re
import sys
import tempfile
import warnings
from collections.abc import Callable

import numpy as np

G = 9.80665
DT = 0.01
#: McManus' Table 1 column in SI (data/mcmanus_column.toml)
MCMANUS = {"m_e": 122.6, "m_b": 44.7, "H_e": 1.050, "H_b": 0.062, "B": 0.285,
           "I_eg": 37.57, "I_bg": 4.33, "k_f": 550.0e3, "g": 9.81}


# ------------------------------------------------------------------------------ signals
def accel_si(n: int = 600) -> np.ndarray:
    """A zero-mean ground acceleration [m/s²], peak 0.3 g, n samples at DT."""
    t = np.arange(n) * DT
    a = np.sin(2 * np.pi * 1.7 * t) * np.sin(np.pi * t / t[-1]) ** 2
    a += 0.3 * np.sin(2 * np.pi * 4.1 * t) * np.sin(np.pi * t / t[-1])
    a -= a.mean()
    return 0.3 * G * a / np.max(np.abs(a))


def decay_si(n: int = 800, dt: float = 0.005) -> tuple[np.ndarray, np.ndarray]:
    """(t [s], u [m]) of a decaying oscillation from 80 mm."""
    t = np.arange(n) * dt
    return t, 0.08 * np.exp(-0.4 * t) * np.cos(2 * np.pi * 1.5 * t)


PGA = float(np.max(np.abs(accel_si())))


def _fmt(x: float) -> str:
    return f"{x:.9g}"


def two_columns(title: str, t_factor: float = 1.0, a_factor: float = 1.0, sep: str = ",",
                comma: bool = False, t=None) -> str:
    """A two-column record: `title` line, time / `t_factor`, accel / `a_factor`."""
    a = accel_si() / a_factor
    t = np.arange(a.size) * DT if t is None else t
    rows = []
    for ti, ai in zip(t / t_factor, a):
        cells = [_fmt(ti), _fmt(ai)]
        if comma:
            cells = [c.replace(".", ",") for c in cells]
        rows.append(sep.join(cells))
    return "\n".join(([title] if title else []) + rows) + "\n"


def trace_csv(title: str, t_factor: float = 1.0, u_factor: float = 1.0, sep: str = ",",
              comma: bool = False) -> str:
    t, u = decay_si()
    rows = []
    for ti, ui in zip(t / t_factor, u / u_factor):
        cells = [_fmt(ti), _fmt(ui)]
        if comma:
            cells = [c.replace(".", ",") for c in cells]
        rows.append(sep.join(cells))
    return "\n".join([title] + rows) + "\n"


def esm(data_type: str = "ACCELERATION", units: str = "cm/s^2") -> str:
    """An ESM ASCII file (the published header layout: KEY: value lines up to USER5)."""
    a = accel_si() / 0.01
    head = {
        "EVENT_NAME": "SYNTHETIC", "EVENT_ID": "XX-00000000-0000", "EVENT_DATE_YYYYMMDD":
        "20000101", "EVENT_TIME_HHMMSS": "000000", "EVENT_LATITUDE_DEGREE": "42.0",
        "EVENT_LONGITUDE_DEGREE": "13.0", "EVENT_DEPTH_KM": "10.0", "HYPOCENTER_REFERENCE":
        "", "MAGNITUDE_W": "6.0", "MAGNITUDE_W_REFERENCE": "", "MAGNITUDE_L": "",
        "MAGNITUDE_L_REFERENCE": "", "FOCAL_MECHANISM": "", "NETWORK": "XX", "STATION_CODE":
        "SYN", "STATION_NAME": "SYNTHETIC", "STATION_LATITUDE_DEGREE": "42.1",
        "STATION_LONGITUDE_DEGREE": "13.1", "STATION_ELEVATION_M": "100", "LOCATION": "00",
        "SENSOR_DEPTH_M": "0", "VS30_M/S": "", "SITE_CLASSIFICATION_EC8": "B",
        "MORPHOLOGIC_CLASSIFICATION": "", "EPICENTRAL_DISTANCE_KM": "10.0",
        "EARTHQUAKE_BACKAZIMUTH_DEGREE": "0", "DATE_TIME_FIRST_SAMPLE_YYYYMMDD_HHMMSS":
        "20000101_000000.000", "DATE_TIME_FIRST_SAMPLE_PRECISION": "milliseconds",
        "SAMPLING_INTERVAL_S": "0.010000", "NDATA": str(a.size), "DURATION_S":
        f"{(a.size - 1) * DT:.6f}", "STREAM": "HNE", "UNITS": units, "INSTRUMENT": "",
        "INSTRUMENT_ANALOG/DIGITAL": "D", "INSTRUMENTAL_FREQUENCY_HZ": "",
        "INSTRUMENTAL_DAMPING": "", "FULL_SCALE_G": "", "N_BIT_DIGITAL_CONVERTER": "",
        "PGA_CM/S^2": f"{np.max(np.abs(a)):.6f}", "TIME_PGA_S": "", "BASELINE_CORRECTION":
        "BASELINE REMOVED", "FILTER_TYPE": "BUTTERWORTH", "FILTER_ORDER": "2",
        "LOW_CUT_FREQUENCY_HZ": "0.05", "HIGH_CUT_FREQUENCY_HZ": "30",
        "LATE/NORMAL_TRIGGERED": "NT", "DATABASE_VERSION": "ESM", "HEADER_FORMAT":
        "DYNA 1.2", "DATA_TYPE": data_type, "PROCESSING": "manual", "DATA_TIMESTAMP_"
        "YYYYMMDD_HHMMSS": "20000101_000000", "DATA_LICENSE": "", "DATA_CITATION": "",
        "DATA_CREATOR": "", "ORIGINAL_DATA_MEDIATOR_CITATION": "", "ORIGINAL_DATA_MEDIATOR":
        "", "ORIGINAL_DATA_CREATOR_CITATION": "", "ORIGINAL_DATA_CREATOR": "", "USER1": "",
        "USER2": "", "USER3": "", "USER4": "", "USER5": "",
    }
    lines = [f"{k}: {v}" for k, v in head.items()]
    return "\n".join(lines + [f"{x:.6E}" for x in a]) + "\n"


KNET_SCALE = (3920.0, 6182761.0)


def knet(direction: str = "E-W") -> str:
    """A K-NET ASCII file (17 header lines, counts 8 per line, scale 3920(gal)/6182761)
    whose counts carry an offset of 1000."""
    gal = accel_si() / 0.01
    counts = np.round(gal * KNET_SCALE[1] / KNET_SCALE[0]).astype(int) + 1000
    peak = np.max(np.abs((counts - counts.mean()) * KNET_SCALE[0] / KNET_SCALE[1]))
    head = [
        "Origin Time       2000/01/01 00:00:00", "Lat.              35.000",
        "Long.             139.000", "Depth. (km)       10", "Mag.              6.0",
        "Station Code      SYN001", "Station Lat.      35.100", "Station Long.     139.100",
        "Station Height(m) 10", "Record Time       2000/01/01 00:00:15",
        "Sampling Freq(Hz) 100Hz", f"Duration Time(s)  {counts.size * DT:g}",
        f"Dir.              {direction}", "Scale Factor      3920(gal)/6182761",
        f"Max. Acc. (gal)   {peak:.3f}", "Last Correction   2000/01/01 00:00:00", "Memo.",
    ]
    rows = [" ".join(f"{c:8d}" for c in counts[i:i + 8]) for i in range(0, counts.size, 8)]
    return "\n".join(head + rows) + "\n"


def jittered(rel: float) -> str:
    """A two-column record (t_s, accel_g) whose time column jitters by ±`rel` of a step."""
    n = accel_si().size
    rng = np.random.default_rng(0)
    t = np.arange(n) * DT + rel * DT * rng.choice([-1.0, 1.0], n)
    t[0] = 0.0
    return two_columns("time_s,accel_g", a_factor=G, t=t)


def toml(body: str, top: str = "") -> str:
    return (top + "\n" if top else "") + "[structure]\n" + body


def _mcmanus(length: float = 1.0, mass: float = 1.0, force: float = 1.0,
             suffix: str = "") -> str:
    """McManus' column in a system of units: lengths / `length` [m], masses / `mass`."""
    m = MCMANUS
    lines = [f"m_e = {m['m_e'] / mass:.10g}", f"m_b = {m['m_b'] / mass:.10g}"]
    lines += [f"{k}{suffix} = {m[k] / length:.10g}" for k in ("H_e", "H_b", "B")]
    inertia = mass * length**2
    lines += [f"I_eg = {m['I_eg'] / inertia:.10g}", f"I_bg = {m['I_bg'] / inertia:.10g}"]
    lines += [f"k_f = {m['k_f'] / (force / length):.10g}"]
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------- the cases
@dataclasses.dataclass(frozen=True)
class Truth:
    """What reading a case must give: `values` (attribute -> value; floats within `rel`),
    or an `error` (class name, e.g. ``"ParameterError"``, ``"TraceError"``,
    ``"ValueError"``; a subclass counts) with its `param` (ParameterError) and a regex
    `match` of its message; `warns`: the class name of a warning that must be given;
    `predicate`: a further check of the object read (None when right, else a message)."""

    values: dict | None = None
    #: an extra check of the object read: None when right, else what is wrong
    predicate: Callable[[object], str | None] | None = None
    error: str | None = None
    param: str | None = None
    match: str = ""
    warns: str | None = None
    rel: float = 1e-6

    def __str__(self) -> str:
        if self.error is not None:
            p = f"[{self.param}]" if self.param else ""
            return f"{self.error}{p}: /{self.match}/"
        vals = ", ".join(f"{k}={_short(v)}" for k, v in (self.values or {}).items())
        if self.predicate is not None:
            doc = (self.predicate.__doc__ or "").strip().splitlines()
            vals = ", ".join(x for x in (vals, doc[0] if doc else "checked") if x)
        return vals + (f" + {self.warns}" if self.warns else "")


def _short(v) -> str:
    return f"{v:.6g}" if isinstance(v, float) else str(v)


@dataclasses.dataclass(frozen=True)
class Case:
    """One messy file: `name` (the file's name), `reader` (``"record"``, ``"trace"``,
    ``"structure"``, or any callable ``reader(path, **kwargs)``, such as a fit),
    `content` (its text, or bytes, or a function that makes them), `truth`, `kind` (the
    class of mess), `before` (the outcome before issue 24), `kwargs` (of the reader),
    `gzip` (write it compressed)."""

    name: str
    reader: str | Callable
    content: str | bytes | Callable[[], str | bytes]
    truth: Truth
    kind: str
    before: str
    kwargs: dict = dataclasses.field(default_factory=dict)
    gzip: bool = False
    #: the row runs a fit (seconds to compile): tests/test_messy.py marks it slow
    slow: bool = False

    def write(self, folder: pathlib.Path) -> pathlib.Path:
        data = self.content() if callable(self.content) else self.content
        raw = data.encode("utf-8") if isinstance(data, str) else data
        path = pathlib.Path(folder) / self.name
        path.write_bytes(gzip.compress(raw, mtime=0) if self.gzip else raw)
        return path


def _rec(pga=PGA, units=None, dt=DT, source="file header", rel=1e-6) -> Truth:
    """The truth of a record read right: its PGA [m/s²], dt [s] and units."""
    values = {"pga": pga, "dt": dt}
    if units is not None:
        values.update(units_in_file=units, units_source=source)
    return Truth(values=values, rel=rel)


_TRACE = {"dt": 0.005, "amplitude": 0.08}


def _rotation_read(tr) -> str | None:
    """A 't,theta_deg' file is read as a rotation channel of 0.08 rad peak, with no u."""
    if tr.u is not None or tr.theta is None:
        return f"read as channels {tr.channels}, not the rotation alone"
    peak = float(np.max(np.abs(tr.theta)))
    if abs(peak - 0.08) > 1e-6 or tr.units["theta"] != "deg":
        return f"peak rotation {peak:.6g} rad in {tr.units['theta']}, not 0.08 rad from deg"
    return None
_NOT_STATED = "ParameterError[units]: units not stated"

CASES: list[Case] = [
    # --- units in the column titles of a record
    Case("rec_cm_s2.csv", "record", two_columns("time_s,accel_cm/s2", a_factor=0.01),
         _rec(units="cm/s2"), "units in header", _NOT_STATED),
    Case("rec_gal.csv", "record", two_columns("time_s,accel_gal", a_factor=0.01),
         _rec(units="gal"), "units in header", _NOT_STATED),
    Case("rec_mm_s2.csv", "record", two_columns("time_s,accel_mm/s2", a_factor=0.001),
         _rec(units="mm/s2"), "units in header", _NOT_STATED),
    Case("rec_g.csv", "record", two_columns("time_s,accel_g", a_factor=G),
         _rec(units="g"), "units in header", _NOT_STATED),
    Case("rec_m_s2.csv", "record", two_columns("time_s,accel_m/s2"),
         _rec(units="m/s2"), "units in header", _NOT_STATED),
    Case("rec_bracket_gal.txt", "record", two_columns("Time[s] Accel[gal]", a_factor=0.01,
                                                      sep="\t"),
         _rec(units="gal"), "units in header", "read right (gal from 'Accel[gal]')"),
    Case("rec_t_ms.csv", "record", two_columns("t_ms,accel_g", t_factor=1e-3, a_factor=G),
         _rec(units="g"), "ms time column", _NOT_STATED),
    # --- flags that contradict the header, and units that make no sense
    Case("rec_cm_s2_flag_m_s2.csv", "record", two_columns("time_s,accel_cm/s2", a_factor=0.01),
         Truth(error="ParameterError", param="units", match=r"states units cm/s2 .* but m/s2"),
         "contradicting flag", "PGA 31 g read, no warning", kwargs={"units": "m/s2"}),
    Case("rec_gal_flag_g.csv", "record", two_columns("time_s,accel_gal", a_factor=0.01),
         Truth(error="ParameterError", param="units", match=r"states units gal .* but g"),
         "contradicting flag", "PGA 307 g read, no warning", kwargs={"units": "g"}),
    Case("rec_cm_s2_no_title_flag_m_s2.csv", "record", two_columns("", a_factor=0.01),
         Truth(error="ParameterError", param="check_plausible",
               match=r"PGA 30 g is implausible.*would be 0\.3 g \(cm/s2\)"),
         "implausible PGA", "PGA 30 g read, no warning", kwargs={"units": "m/s2"}),
    Case("rec_cm_s2_no_title_flag_m_s2_override.csv", "record", two_columns("", a_factor=0.01),
         _rec(pga=PGA * 100, units="m/s2", source="given"),
         "implausible PGA (override)", "TypeError: no keyword check_plausible",
         kwargs={"units": "m/s2", "check_plausible": False}),
    Case("rec_title_g_values_gal.csv", "record", two_columns("time_s,accel_g", a_factor=0.01),
         Truth(error="ParameterError", param="check_plausible", match=r"PGA 294 g"),
         "implausible PGA", _NOT_STATED),
    Case("rec_disp_mm.csv", "record", two_columns("time_s,disp_mm", a_factor=0.01),
         Truth(error="ValueError", match=r"states units 'mm', which are not a unit of accel"),
         "units in header", _NOT_STATED),
    # --- formats
    Case("rec_cm_s2.csv.gz", "record", two_columns("time_s,accel_cm/s2", a_factor=0.01),
         _rec(units="cm/s2"), "gzip", "ValueError: no numeric data found", gzip=True),
    Case("rec_european.csv", "record",
         two_columns("time_s;accel_g", a_factor=G, sep=";", comma=True),
         _rec(units="g"), "European CSV", "ValueError: no numeric data found"),
    Case("rec_semicolon.csv", "record", two_columns("time_s;accel_g", a_factor=G, sep=";"),
         _rec(units="g"), "';' separators", "ValueError: no numeric data found"),
    Case("rec_tab_decimal_comma.txt", "record",
         two_columns("Zeit[s]\tBeschl[m/s2]", sep="\t", comma=True),
         _rec(units="m/s2"), "European CSV",
         "ParameterError[format]: cannot detect the file format from 3 values per line"),
    Case("rec_esm.ASC", "record", esm, _rec(units="cm/s2"), "ESM format",
         "ParameterError[dt]: a one-column file has no time information"),
    Case("rec_esm_velocity.ASC", "record", lambda: esm("VELOCITY", "cm/s"),
         Truth(error="ValueError", match=r"DATA_TYPE VELOCITY"), "ESM format",
         "ParameterError[dt]: a one-column file has no time information"),
    Case("rec_knet.EW", "record", knet, _rec(units="gal", rel=2e-5), "K-NET format",
         "ParameterError[format]: cannot detect the file format from 8 values"),
    Case("rec_kiknet.NS2", "record", lambda: knet("N-S"), _rec(units="gal", rel=2e-5),
         "K-NET format", "ParameterError[format]: cannot detect the file format"),
    Case("rec_cosmos.V2", "record",
         "COSMOS Strong-Motion Data Format, V2 processed acceleration\nline 2\n"
         "  1.0  2.0  3.0\n",
         Truth(error="ValueError", match=r"unsupported format: COSMOS"),
         "unsupported format", "ParameterError[format]: cannot detect the file format"),
    Case("rec_workbook.xlsx", "record", b"PK\x03\x04" + bytes(64),
         Truth(error="ValueError", match=r"unsupported format: a zip archive"),
         "unsupported format", "ValueError: non-numeric data / no numeric data found"),
    # --- time columns
    Case("rec_jitter_1us.csv", "record", lambda: jittered(1e-4),
         Truth(values={"dt": DT, "npts": 600}, warns="ResampledWarning"),
         "jittered time", "ValueError: non-uniform time step"),
    Case("rec_jitter_5e-3.csv", "record", lambda: jittered(5e-3),
         Truth(error="ParameterError", param="time_tolerance",
               match=r"more than the tolerance time_tolerance=0\.001"),
         "jittered time", "ValueError: non-uniform time step"),
    Case("rec_jitter_5e-3_tolerance.csv", "record", lambda: jittered(5e-3),
         Truth(values={"dt": DT, "npts": 600}, warns="ResampledWarning"),
         "jittered time (tolerance given)", "TypeError: no keyword time_tolerance",
         kwargs={"time_tolerance": 2e-2}),
    # --- decay traces
    Case("tr_t_ms_disp_mm.csv", "trace", trace_csv("t_ms,disp_mm", 1e-3, 1e-3),
         Truth(values=_TRACE), "units in header", "read right"),
    Case("tr_ms_under_t.csv", "trace", trace_csv("t,u_mm", 1e-3, 1e-3),
         Truth(error="TraceError", match=r"time step of 5 s .* implausible.*t_ms"),
         "ms time column", "read as dt = 5 s, no hint"),
    Case("tr_m_under_mm.csv", "trace", trace_csv("t,disp_mm"),
         Truth(error="TraceError", match=r"never exceeds 0\.08 mm.*holds metres"),
         "m under a mm title", "read 1000x too small; fit 'converged', r = 0"),
    Case("tr_disp_mm.csv.gz", "trace", trace_csv("time_s,disp_mm", u_factor=1e-3),
         Truth(values=_TRACE), "gzip", "UnicodeDecodeError", gzip=True),
    Case("tr_european.csv", "trace", trace_csv("t;u_mm", u_factor=1e-3, sep=";", comma=True),
         Truth(values=_TRACE), "European CSV", "TraceError: unrecognised header"),
    Case("tr_tabs.tsv", "trace", trace_csv("t\tu", sep="\t"), Truth(values=_TRACE),
         "tab separators", "TraceError: unrecognised header"),
    Case("tr_blanks_decimal_comma.txt", "trace",
         trace_csv("t u_mm", u_factor=1e-3, sep=" ", comma=True), Truth(values=_TRACE),
         "European CSV", "TraceError: unrecognised header"),
    Case("tr_theta_deg.csv", "trace", trace_csv("t,theta_deg", u_factor=math.pi / 180),
         Truth(predicate=_rotation_read), "rotation as displacement",
         "TraceError: not a time, displacement or uplift column; name the columns with "
         "columns= (which reads the rotation as a displacement)"),
    Case("tr_theta_plain_deg.csv", "trace", trace_csv("t,theta", u_factor=math.pi / 180),
         Truth(error="TraceError", match=r"a rotation of 4\.58\d* rad .* name it theta_deg"),
         "rotation in degrees under a plain title",
         "TraceError: 'theta' is a rotation, not a displacement"),
    Case("tr_columns_u_theta.csv", "trace", trace_csv("t,theta_rad"),
         Truth(error="TraceError", match=r"'theta_rad' is a rotation"),
         "rotation as displacement", "rotation fitted as a displacement",
         kwargs={"columns": {"t": "t", "u": "theta_rad"}}),
    Case("tr_mm_flag_m.csv", "trace", trace_csv("t,disp_mm", u_factor=1e-3),
         Truth(error="TraceError", match=r"is in mm, but the units given say m"),
         "contradicting flag", "refused (naming both)", kwargs={"units": {"u": "m"}}),
    # --- structure files
    Case("st_mm_no_units.toml", "structure", toml(_mcmanus(length=1e-3)),
         Truth(error="ParameterError", param="check_plausible",
               match=r"B = 285 m is implausible.*millimetres"),
         "structure in mm", "a 1-km column simulated (53 mm peak, 160 impacts)"),
    Case("st_units_mm.toml", "structure", toml(_mcmanus(length=1e-3), 'units = "mm"'),
         Truth(values=MCMANUS), "structure in mm", "units key ignored: a 1-km column"),
    Case("st_units_N-mm-t.toml", "structure",
         toml(_mcmanus(length=1e-3, mass=1e3), 'units = "N-mm-t"'),
         Truth(values=MCMANUS), "structure in mm", "units key ignored: a 1-km column"),
    Case("st_units_in_table.toml", "structure",
         toml('units = "cm"\n' + _mcmanus(length=1e-2)),
         Truth(values=MCMANUS), "structure in cm", "ValueError: unknown parameter units"),
    Case("st_suffix_mm.toml", "structure", toml(_mcmanus(length=1e-3, suffix="_mm")
                                                .replace("k_f =", "\"k_f_N/mm\" =")
                                                .replace("I_eg =", "\"I_eg_kg*mm2\" =")
                                                .replace("I_bg =", "\"I_bg_kg*mm2\" =")),
         Truth(values=MCMANUS), "field suffixes", "ValueError: unknown parameter(s)"),
    Case("st_km_column.toml", "structure",
         toml(_mcmanus().replace("H_e = 1.05", "H_e = 1050")),
         Truth(error="ParameterError", param="check_plausible", match=r"H_e = 1050 m"),
         "structure in mm", "ParameterError[k_f]: k_f is too soft for the structure to stand"),
    Case("st_units_unknown.toml", "structure", toml(_mcmanus(), 'units = "furlong"'),
         Truth(error="ParameterError", param="units", match=r"unknown units 'furlong'"),
         "structure units", "units key ignored"),
]


# ------------------------------------------------- traces that only a fit can judge
#: the decay of these rows: identification.synthetic_trace's defaults (the Table 1 column
#: with k_f 800 kN/m, r 0.85, released from 0.1 m, 0.5 mm noise)
FIT_TRUTH = {"k_f": 800e3, "r": 0.85}


def fault_trace_csv(duration=8.0, rate_hz=200.0, seed=0, r=0.85, **faults) -> str:
    """A synthetic decay (`identification.synthetic_trace`) with a sensor's `faults`, as the
    CSV text `t_s,u_m`."""
    import identification

    trace, _ = identification.synthetic_trace(duration=duration, rate_hz=rate_hz, seed=seed,
                                              r=r, faults=identification.Faults(**faults))
    rows = [f"{_fmt(t)},{_fmt(u)}" for t, u in zip(trace.t, trace.u)]
    return "\n".join(["t_s,u_m", *rows]) + "\n"


def fit_file(path, **kwargs):
    """`identification.fit_decay` of the trace file at `path` (the Table 1 column)."""
    import identification
    import rockjax

    return identification.fit_decay(identification.read_trace(path), rockjax.mcmanus_column(),
                                    progress=False, **kwargs)


def _recovered(offset=None, drift=None, rel=0.01):
    """A predicate: k_f and r within `rel`, and the sensor's offset [m] / drift [m/s]
    within 0.5 mm / 0.2 mm/s of theirs."""
    def check(fit):
        """k_f, r within 1 %, offset/drift recovered"""
        bad = [f"{p} {fit.values[p]:.6g} (truth {FIT_TRUTH[p]:.6g})" for p in ("k_f", "r")
               if abs(fit.values[p] / FIT_TRUTH[p] - 1) > rel]
        for name, want, tol in (("offset", offset, 5e-4), ("drift", drift, 2e-4)):
            if want is not None and abs(fit.values.get(name, np.nan) - want) > tol:
                bad.append(f"{name} {fit.values.get(name)} (truth {want})")
        return "; ".join(bad) or None
    return check


def _diagnosed(cause, text):
    def check(fit):
        """lack of fit diagnosed as its cause"""
        d = fit.diagnosis or {}
        ok = d.get("cause") == cause and re.search(text, d.get("message", ""))
        return None if ok else f"diagnosis {d}"
    return check


_FIT_BEFORE = "fit: residuals 'consistent with noise', noise and standard errors 13x"
FIT_CASES = [
    Case(f"tr_offset_{name}.csv", fit_file, lambda o=o: fault_trace_csv(offset=o),
         Truth(predicate=_recovered(offset=o)), "sensor offset",
         _FIT_BEFORE if abs(o) < 5e-3 else "k_f -2.3 %, lag-1 autocorrelation 0.8, no warning",
         slow=True)
    for name, o in (("p4mm", 4e-3), ("m4mm", -4e-3), ("p8mm", 8e-3), ("m8mm", -8e-3))
] + [
    Case("tr_drift.csv", fit_file, lambda: fault_trace_csv(drift=1e-3, seed=6),
         Truth(predicate=_recovered(drift=1e-3)), "sensor drift",
         "no drift parameter", kwargs={"drift": True}, slow=True),
    Case("tr_clipped.csv", fit_file,
         lambda: fault_trace_csv(duration=2.0, rate_hz=100.0, seed=3, clip=0.05),
         Truth(error="TraceError", match=r"clipped.*50 mm|50 mm.*clipped|saturat"),
         "saturated trace", "read as a hold at 0.05 m; k_f +248 %", slow=True),
    Case("tr_two_releases.csv", fit_file,
         lambda: fault_trace_csv(rate_hz=100.0, seed=4, r=0.7, second=(5.0, 0.09)),
         Truth(error="TraceError", match=r"holds 2 releases.*release at 5\.0\d* s"),
         "second release", "silently fitted as one decay", slow=True),
    Case("tr_mains_hum.csv", fit_file,
         lambda: fault_trace_csv(duration=3.0, rate_hz=1000.0, seed=5, hum=(2e-3, 50.0)),
         Truth(predicate=_diagnosed("periodic", r"50(\.0)? Hz"), warns="LackOfFitWarning"),
         "mains hum", "lack of fit blamed on the model", slow=True),
]
CASES += FIT_CASES


# ---------------------------------------------------------------------------- checking
def read(case: Case, path: pathlib.Path):
    """The reader of `case` applied to `path`."""
    if callable(case.reader):
        return case.reader(path, **case.kwargs)
    if case.reader == "record":
        import rockjax

        return rockjax.read_record(path, **case.kwargs)
    if case.reader == "trace":
        import identification

        return identification.read_trace(path, **case.kwargs)
    if case.reader == "structure":
        import rockjax

        return rockjax.RockingStructure.from_toml(path, **case.kwargs)
    raise ValueError(f"unknown reader {case.reader!r}")


def _describe(obj) -> str:
    if hasattr(obj, "values") and "k_f" in getattr(obj, "values", {}):  # a fit
        v = obj.values
        sensor = "".join(f", {k} {1e3 * v[k]:.3g} mm" for k in ("offset",) if k in v)
        sensor += "".join(f", {k} {1e3 * v[k]:.3g} mm/s" for k in ("drift",) if k in v)
        diag = (obj.diagnosis or {}).get("cause")
        return (f"fit: k_f {v['k_f']:.6g} N/m, r {v['r']:.5g}{sensor}"
                + (f"; lack of fit: {diag}" if diag else ""))
    if not any(hasattr(obj, a) for a in ("pga", "amplitude", "B")):
        return repr(obj)[:200]
    if hasattr(obj, "pga"):
        return (f"PGA {obj.pga:.6g} m/s2, dt {obj.dt:g} s, {obj.npts} pts, units "
                f"{obj.units_in_file} ({obj.units_source})")
    if hasattr(obj, "amplitude"):
        peak = ("no u" if obj.amplitude is None else f"peak |u| {obj.amplitude:.6g} m")
        return f"dt {obj.dt:g} s, {peak}, channels {obj.channels}, units {dict(obj.units)}"
    return f"B {float(obj.B):.6g} m, H_e {float(obj.H_e):.6g} m, k_f {float(obj.k_f):.6g} N/m"


def _value_errors(case: Case, obj) -> list[str]:
    wrong = []
    if case.truth.predicate is not None:
        problem = case.truth.predicate(obj)
        if problem:
            wrong.append(problem)
    for key, want in (case.truth.values or {}).items():
        got = getattr(obj, key)
        got = float(got) if not isinstance(got, str) else got
        ok = (got == want if isinstance(want, str)
              else math.isclose(got, want, rel_tol=case.truth.rel, abs_tol=0.0))
        if not ok:
            wrong.append(f"{key} = {_short(got)}, expected {_short(want)}")
    return wrong


def _class_names(obj) -> set[str]:
    return {c.__name__ for c in type(obj).__mro__}


def check(case: Case, folder: pathlib.Path) -> tuple[bool, str]:
    """(whether reading `case` gives its truth, the outcome in a line)."""
    path = case.write(folder)
    truth = case.truth
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            obj = read(case, path)
        except Exception as e:  # noqa: BLE001 - the outcome is what we report
            param = getattr(e, "param", None)
            text = f"{type(e).__name__}{f'[{param}]' if param else ''}: {str(e)[:300]}"
            ok = (truth.error is not None and truth.error in _class_names(e)
                  and (truth.param is None or param == truth.param)
                  and re.search(truth.match, str(e)) is not None)
            return ok, text
    names = {n for w in caught for n in _class_names(w.message)}
    text = _describe(obj) + "".join(f" + {type(w.message).__name__}" for w in caught)
    if truth.error is not None:
        return False, "read without error: " + text
    wrong = _value_errors(case, obj)
    if truth.warns is not None and truth.warns not in names:
        wrong.append(f"no {truth.warns}")
    if truth.warns is None and caught:
        wrong.append(f"unexpected warning {type(caught[0].message).__name__}")
    return not wrong, text + ("" if not wrong else " -- WRONG: " + "; ".join(wrong))


def table(folder: pathlib.Path | None = None, cases: list[Case] | None = None) -> str:
    """The corpus (or `cases`) as a text table: case, class, outcome before issue 24,
    expected, outcome now, pass/FAIL (paths shortened to the file's name)."""
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(folder or tmp)
        for case in CASES if cases is None else cases:
            ok, outcome = check(case, folder)
            outcome = outcome.replace(str(folder) + "/", "")
            rows.append((case.name, case.kind, case.before[:60], str(case.truth)[:70],
                         outcome[:100], "pass" if ok else "FAIL"))
    head = ("case", "class", "before", "expected", "outcome", "")
    widths = [max(len(r[i]) for r in [head, *rows]) for i in range(5)]
    out = ["  ".join(c.ljust(w) for c, w in zip(head, widths)).rstrip()]
    out += ["  ".join(c.ljust(w) for c, w in zip(r, [*widths, 4])).rstrip() for r in rows]
    n_ok = sum(r[-1] == "pass" for r in rows)
    out.append(f"{n_ok}/{len(rows)} cases give their truth")
    return "\n".join(out)


def main(argv: list[str]) -> int:
    import rockjax

    rockjax.configure()
    if len(argv) >= 2 and argv[0] == "--write":
        folder = pathlib.Path(argv[1])
        folder.mkdir(parents=True, exist_ok=True)
        for case in CASES:
            print(case.write(folder))
        return 0
    if argv and argv[0] not in ("--table", "--no-fits"):
        print(__doc__)
        return 2
    print(table(cases=[c for c in CASES if not c.slow] if "--no-fits" in argv else None))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
