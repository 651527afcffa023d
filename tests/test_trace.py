"""Decay traces (identification/_trace.py): DecayTrace, read_trace and the shipped
SYNTHETIC decay traces."""

from __future__ import annotations

import dataclasses
import math
import re

import jax.numpy as jnp
import numpy as np
import pytest

import identification
import rockjax
from identification import (
    DecayTrace,
    read_trace,
    synthetic_trace_path,
    SYNTHETIC_TRACES,
    synthetic_truth,
)

SIDECAR_KEYS = {
    "synthetic",
    "description",
    "model",
    "k_f",
    "r",
    "u0",
    "t0",
    "noise_std_u",
    "noise_std_uplift",
    "seed",
    "rate_hz",
    "duration_s",
    "structure",
    "generator",
    "rockjax_version",
}
TABLE1_BUT_KF = {"m_e", "m_b", "H_e", "H_b", "B", "I_eg", "I_bg", "g"}


# ------------------------------------------------------------------ shipped synthetic data
@pytest.mark.parametrize("name", SYNTHETIC_TRACES)
def test_synthetic_trace_reads(name):
    tr = read_trace(synthetic_trace_path(name))
    truth = synthetic_truth(name)
    assert tr.n == 1601
    assert tr.t[0] == 0.0
    assert tr.duration == pytest.approx(8.0, abs=1e-12)
    np.testing.assert_allclose(np.diff(tr.t), 1 / 200.0, rtol=0, atol=1e-12)
    assert tr.uplift is not None and tr.uplift.shape == tr.u.shape
    assert tr.t.dtype == np.float64
    assert set(truth) == SIDECAR_KEYS
    assert truth["synthetic"] is True
    assert "SYNTHETIC" in truth["description"]
    assert set(truth["structure"]) == TABLE1_BUT_KF
    assert truth["generator"] == "data/make_synthetic_traces.py"
    assert truth["rate_hz"] == 200.0 and truth["duration_s"] == 8.0 and truth["t0"] == 0.0
    assert truth["u0"] == 0.10
    with synthetic_trace_path(name).open("r") as f:
        first = f.readline()
    assert first.startswith("# SYNTHETIC")


def test_synthetic_truth_values():
    clean = synthetic_truth("synthetic_decay_clean")
    noisy = synthetic_truth("synthetic_decay_noisy")
    exact = synthetic_truth("synthetic_decay_exact")
    assert (clean["model"], clean["k_f"], clean["r"]) == ("simplified", 550e3, 0.80)
    assert (noisy["model"], noisy["k_f"], noisy["r"]) == ("simplified", 800e3, 0.85)
    assert (exact["model"], exact["k_f"], exact["r"]) == ("exact", 800e3, 0.85)
    assert noisy["noise_std_u"] == 5e-4 and noisy["noise_std_uplift"] == 1e-4
    assert noisy["seed"] == 20261121
    assert clean["noise_std_u"] == 0.0 and exact["noise_std_u"] == 0.0
    assert read_trace(synthetic_trace_path("synthetic_decay_clean")).u[0] == clean["u0"]
    assert read_trace(synthetic_trace_path("synthetic_decay_exact")).u[0] == exact["u0"]


def test_synthetic_unknown_name():
    with pytest.raises(ValueError, match="unknown synthetic trace 'nope'"):
        synthetic_trace_path("nope")


def test_packaged_data_path():
    # the public lookup that identification uses for the shipped files
    p = rockjax.datasets.packaged_data_path("synthetic_decay_clean.csv")
    assert p.is_file()
    assert str(p) == str(synthetic_trace_path("synthetic_decay_clean"))
    assert rockjax.datasets.packaged_data_path("mcmanus_column.toml").is_file()
    assert not rockjax.datasets.packaged_data_path("no_such_file.csv").is_file()
    for bad in ("", ".", "..", "sub/x.csv", "..\\x.csv"):
        with pytest.raises(ValueError, match="plain file name"):
            rockjax.datasets.packaged_data_path(bad)


@pytest.fixture(scope="module")
def resimulated_clean():
    """The clean trace re-simulated from its sidecar (the only simulate call here)."""
    truth = synthetic_truth("synthetic_decay_clean")
    tr = read_trace(synthetic_trace_path("synthetic_decay_clean"))
    s = rockjax.RockingStructure(**truth["structure"], k_f=truth["k_f"])
    res = rockjax.simulate(
        s,
        rockjax.FreeVibration(truth["u0"]),
        truth["duration_s"],
        ts=jnp.asarray(tr.t),
        r=truth["r"],
        model=truth["model"],
    )
    return tr, res


def test_clean_trace_regenerates(resimulated_clean):
    """The committed file is what data/make_synthetic_traces.py makes (to 1e-9 m)."""
    tr, res = resimulated_clean
    assert res.status_name == "completed"
    np.testing.assert_allclose(tr.u, np.asarray(res.u), rtol=0, atol=1e-9)
    np.testing.assert_allclose(tr.uplift, np.asarray(res.uplift), rtol=0, atol=1e-9)
    assert res.n_impacts > 5  # a real decay with rocking, not springs only


# ------------------------------------------------------------------------ read_trace
def _rows(n, dt=0.01, t0=0.0, ncol=3):
    out = []
    for i in range(n):
        vals = [f"{t0 + i * dt:.6g}", f"{0.1 * 0.9**i:.6g}", f"{0.05 * 0.9**i:.6g}"]
        out.append(",".join(vals[:ncol]))
    return out


def _write(tmp_path, name, lines):
    p = tmp_path / name
    p.write_text("\n".join(lines) + ("\n" if lines else ""))
    return p


def _at(path, line):
    """Regex: the message names the file and the line."""
    return re.escape(f"{path}, line {line}:")


def test_read_good_two_columns_with_comments_and_whitespace(tmp_path):
    lines = ["# measured 2026-01-01", "#   SYNTHETIC? no", " t , u "]
    lines += [f"  {r.replace(',', ' ,  ')}  " for r in _rows(12, ncol=2)] + [""]
    p = _write(tmp_path, "ok.csv", lines)
    tr = read_trace(p)
    assert tr.n == 12 and tr.uplift is None
    assert tr.source == str(p)
    assert tr.duration == pytest.approx(0.11)
    assert tr.u[0] == 0.1
    assert "n=12" in repr(tr)


def test_read_good_str_path(tmp_path):
    p = _write(tmp_path, "ok3.csv", ["t,u,uplift", *_rows(10)])
    tr = read_trace(str(p))
    assert tr.n == 10 and tr.uplift is not None and tr.uplift[0] == 0.05


BAD = {
    # name: (lines, line number in the message, regex for the rest)
    "bad_header": (["# c", "time,disp,up", *_rows(10)], 2,
                   r"expected header 't,u' or.*column 'up' is not a time, displacement or "
                   r"uplift column; name the columns with columns="),
    "two_time_columns": (["t,time,u", *_rows(10)], 1, "two time columns"),
    # an uplift (or a rotation) alone is a trace now (test_trace_channels); time alone is not
    "no_displacement": (["t", *_rows(10, ncol=1)], 1,
                        "no displacement, rotation or uplift column"),
    "unknown_unit": (["t,u [inch]", *_rows(10, ncol=2)], 1,
                     r"column 'u \[inch\]': 'inch' is not a unit of length \(expected one of m,"),
    "time_in_mm": (["t_mm,u", *_rows(10, ncol=2)], 1, "'mm' is not a unit of time"),
    "no_header": (_rows(12), 1, r"expected header"),
    "nan": (["t,u,uplift", *_rows(4), "0.04,nan,0.0", *_rows(6, t0=0.05)], 6,
            r"column 'u': missing value 'nan' \(NaN\); 1 row\(s\) of the file have missing "
            r"values \(line\(s\) 6\); pass drop_nan=True to drop them"),
    "inf_text": (["t,u,uplift", *_rows(4), "0.04,inf,0.0", *_rows(6, t0=0.05)], 6,
                 "value 'inf' is not finite"),
    "inf": (["t,u,uplift", *_rows(4), "0.04,0.0,-inf", *_rows(6, t0=0.05)], 6, "not finite"),
    "backwards": (
        ["t,u,uplift", *_rows(5), "0.02,0.0,0.0", *_rows(6, t0=0.05)],
        7,
        "time goes backwards.*line 6",
    ),
    "repeated": (
        ["t,u,uplift", *_rows(5), "0.04,0.0,0.0", *_rows(6, t0=0.05)],
        7,
        "repeats the previous sample",
    ),
    "gap": (
        ["t,u,uplift", *_rows(6), *_rows(6, t0=1.0)],
        8,
        r"gap in time of 0\.95 s at line 8.*split the trace or resample",
    ),
    "too_few": (["# c", "t,u,uplift", *_rows(9)], 11, "only 9 sample.*at least 10"),
    "non_numeric": (
        ["t,u,uplift", *_rows(3), "0.03,abc,0.0", *_rows(7, t0=0.04)],
        5,
        "column 'u': 'abc' is not a number",
    ),
    "empty_value": (["t,u,uplift", *_rows(3), "0.03,,0.0", *_rows(7, t0=0.04)], 5, "''"),
    "too_many_columns": (
        ["t,u", *_rows(3, ncol=2), "0.03,0.0,0.0", *_rows(7, t0=0.04, ncol=2)],
        5,
        r"expected 2 values \(t,u\), got 3",
    ),
    "too_few_columns": (
        ["t,u,uplift", *_rows(10), "0.10,0.0"],
        12,
        r"expected 3 values \(t,u,uplift\), got 2",
    ),
    "empty": ([], 1, "empty file"),
    "only_comments": (["# SYNTHETIC", "# nothing else"], 2, "only comment lines"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_read_malformed(tmp_path, case):
    lines, line, rest = BAD[case]
    p = _write(tmp_path, f"{case}.csv", lines)
    with pytest.raises(ValueError, match=_at(p, line) + ".*" + rest):
        read_trace(p)


def test_read_missing_file(tmp_path):
    p = tmp_path / "missing.csv"
    with pytest.raises(FileNotFoundError, match=re.escape(str(p))):
        read_trace(p)


# ------------------------------------------------------------------------ DecayTrace
def _good(n=20):
    t = np.linspace(0.0, 1.0, n)
    return t, 0.1 * np.cos(2 * np.pi * t), 0.05 * np.abs(np.cos(2 * np.pi * t))


def test_decaytrace_copies_read_only():
    t, u, up = _good()
    tr = DecayTrace(t, u, up, source="x")
    t[0] = -1.0
    assert tr.t[0] == 0.0  # a copy
    assert tr.n == 20 and tr.duration == 1.0
    with pytest.raises(ValueError):
        tr.u[0] = 1.0  # read-only
    with pytest.raises(dataclasses.FrozenInstanceError):
        tr.u = u
    tr_int = DecayTrace(np.arange(10), np.zeros(10, dtype=np.int32))
    assert tr_int.t.dtype == np.float64 and tr_int.u.dtype == np.float64
    assert tr_int.uplift is None


@pytest.mark.parametrize(
    "change, match",
    [
        (lambda t, u, up: (t, u[:-1], up), r"DecayTrace\.u: has 19 samples but t has 20"),
        (lambda t, u, up: (t, u, up[:-2]), r"DecayTrace\.uplift: has 18 samples"),
        (lambda t, u, up: (t, np.where(t > 0.5, np.nan, u), up), r"DecayTrace\.u: .*non-finite"),
        (lambda t, u, up: (t, u, np.full_like(up, np.inf)), r"DecayTrace\.uplift: .*non-finite"),
        (lambda t, u, up: (np.where(t > 0.9, np.inf, t), u, up), r"DecayTrace\.t: .*non-finite"),
        (lambda t, u, up: (t[::-1], u, up), r"DecayTrace\.t: must be strictly increasing"),
        (lambda t, u, up: (t[:9], u[:9], None), r"DecayTrace\.t: 9 sample"),
        (lambda t, u, up: (t.reshape(4, 5), u, up), r"DecayTrace\.t: must be 1-D"),
        (
            lambda t, u, up: (np.where(t > 0.5, t + 5.0, t), u, up),
            r"DecayTrace\.t: gap in time .*split the trace or resample",
        ),
        (lambda t, u, up: (t, ["a"] * 20, up), r"DecayTrace\.u: cannot convert"),
    ],
)
def test_decaytrace_invalid(change, match):
    with pytest.raises(ValueError, match=match):
        DecayTrace(*change(*_good()))


def test_decaytrace_bad_source():
    t, u, _ = _good()
    with pytest.raises(ValueError, match=r"DecayTrace\.source"):
        DecayTrace(t, u, source=3)


# ------------------------------------------------------------- units, columns, missing values
def _trace_lines(header, n=12, scale_t=1.0, scale_u=1.0, extra=None):
    """A header and `n` rows of t = 0.01 i s, u = 0.1 * 0.9^i m (and uplift = u / 2),
    written in the given scales (e.g. 1e3 for ms or mm); `extra` adds a text column."""
    out = [header]
    for i in range(n):
        vals = [f"{0.01 * i * scale_t:.10g}", f"{0.1 * 0.9**i * scale_u:.10g}",
                f"{0.05 * 0.9**i * scale_u:.10g}"]
        ncol = len(header.split(",")) - (extra is not None)
        row = vals[:ncol] + ([extra] if extra is not None else [])
        out.append(",".join(row))
    return out


@pytest.mark.parametrize(
    "header, scale_t, scale_u, units",
    [
        ("time_s,disp_mm", 1.0, 1e3, {"t": "s", "u": "mm"}),
        ("t [s],u [mm]", 1.0, 1e3, {"t": "s", "u": "mm"}),
        ("t(ms),u(cm),uplift(cm)", 1e3, 1e2, {"t": "ms", "u": "cm", "uplift": "cm"}),
        ("Time (s), Displacement (mm), Uplift [mm]", 1.0, 1e3,
         {"t": "s", "u": "mm", "uplift": "mm"}),
        ("t_ms,u_m", 1e3, 1.0, {"t": "ms", "u": "m"}),
        ("u_mm,t", 1.0, 1e3, {"t": "s", "u": "mm"}),  # any order; t without a unit: SI
        ("t,u[um]", 1.0, 1e6, {"t": "s", "u": "um"}),
    ],
)
def test_read_units_in_header(tmp_path, header, scale_t, scale_u, units):
    lines = _trace_lines(header, scale_t=scale_t, scale_u=scale_u)
    if header.startswith("u_mm"):  # the columns swapped: u first
        lines = [header] + [",".join(row.split(",")[::-1]) for row in lines[1:]]
    p = _write(tmp_path, "units.csv", lines)
    tr = read_trace(p)
    np.testing.assert_allclose(tr.t, 0.01 * np.arange(12), rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(tr.u, 0.1 * 0.9 ** np.arange(12), rtol=1e-9)
    if "uplift" in units:
        np.testing.assert_allclose(tr.uplift, 0.05 * 0.9 ** np.arange(12), rtol=1e-9)
    assert dict(tr.units) == units
    cells = [c.strip() for c in header.split(",")]
    assert set(tr.columns.values()) == set(cells)
    assert tr.units_from["u"] == "header"
    info = tr.info()
    assert info["units_in_file"] == units and info["n_points"] == 12
    assert info["dt_s"] == pytest.approx(0.01) and info["duration_s"] == pytest.approx(0.11)
    assert info["max_abs_u_m"] == pytest.approx(0.1) and info["file"] == str(p)


def test_read_columns_and_units_arguments(tmp_path):
    # extra columns (a text column among them) are ignored when the columns are named
    lines = ["index,time_s,disp_mm,comment"]
    lines += [f"{i},{0.01 * i:g},{100 * 0.9**i:.10g},ok {i}" for i in range(12)]
    p = _write(tmp_path, "named.csv", lines)
    with pytest.raises(ValueError, match="column 'index' is not a time"):
        read_trace(p)
    tr = read_trace(p, columns={"t": "TIME_S", "u": "disp_mm"})
    np.testing.assert_allclose(tr.u, 0.1 * 0.9 ** np.arange(12), rtol=1e-9)
    assert dict(tr.columns) == {"t": "time_s", "u": "disp_mm"} and tr.uplift is None
    assert dict(tr.units) == {"t": "s", "u": "mm"}
    # units for a header without them
    p2 = _write(tmp_path, "plain.csv", _trace_lines("t,u", scale_u=1e3))
    tr2 = read_trace(p2, units={"u": "mm"})
    np.testing.assert_allclose(tr2.u, tr.u, rtol=1e-12)
    assert tr2.units_from == {"t": "assumed SI", "u": "units argument"}
    assert read_trace(p2).units_from["u"] == "assumed SI"
    # the same unit twice is fine, a contradiction is refused
    assert read_trace(p, columns={"t": "time_s", "u": "disp_mm"}, units={"u": "mm"}).n == 12
    with pytest.raises(ValueError, match=r"'disp_mm' is in mm, but the units given say m"):
        read_trace(p, columns={"t": "time_s", "u": "disp_mm"}, units={"u": "m"})
    with pytest.raises(ValueError, match=r"no column 'zeit' in the header \(its columns: "):
        read_trace(p, columns={"t": "zeit", "u": "disp_mm"})
    with pytest.raises(ValueError, match=r"units\['u'\]: unknown unit 'furlong'"):
        read_trace(p2, units={"u": "furlong"})
    with pytest.raises(ValueError, match="columns must name the columns of 't' and 'u'"):
        read_trace(p, columns={"u": "disp_mm"})


def test_missing_values_refused_or_dropped(tmp_path):
    lines = _trace_lines("t,u,uplift", n=15)
    lines[4] = "0.03,,0.01"
    lines[9] = "0.08,NaN,0.01"
    lines[12] = "NA,0.02,0.01"
    p = _write(tmp_path, "gaps.csv", lines)
    with pytest.raises(ValueError, match=_at(p, 5) + r" column 'u': missing value '' \(NaN\); "
                       r"3 row\(s\) of the file have missing values \(line\(s\) 5, 10, 13\); "
                       r"pass drop_nan=True to drop them") as e:
        read_trace(p)
    # the error names its parameter; the command line spells it as its option
    from rockjax.cli import fit as fit_cli
    from rockjax.cli._common import parameter_message

    assert e.value.param == "drop_nan"
    assert "pass --drop-nan to drop them" in parameter_message(e.value, fit_cli.FLAGS)
    with pytest.warns(identification.DroppedRowsWarning,
                      match=re.escape(f"{p}: dropped 3 row(s) with missing (NaN) values "
                                      "(line(s) 5, 10, 13)")):
        tr = read_trace(p, drop_nan=True)
    assert tr.n == 12 and tr.dropped_lines == (5, 10, 13)
    assert tr.info()["dropped_nan_rows"] == 3
    assert np.all(np.isfinite(tr.u))


# ------------------------------------------------------------------------------ release
def _noisy_shipped():
    return read_trace(synthetic_trace_path("synthetic_decay_noisy"))


def _with_hold(tr, seconds, seed=0, sigma=5e-4, u0=0.1):
    """The trace with `seconds` of noisy samples held at u0 before its first sample."""
    rng = np.random.default_rng(seed)
    n = int(round(seconds / tr.dt))
    t = np.concatenate([tr.t[0] + tr.dt * np.arange(n), tr.t + n * tr.dt])
    u = np.concatenate([u0 + rng.normal(0.0, sigma, n), tr.u])
    return DecayTrace(t, u), tr.t[0] + n * tr.dt


def test_release_of_traces_that_start_at_it():
    for name in SYNTHETIC_TRACES:
        tr = read_trace(synthetic_trace_path(name))
        rel = identification.detect_release(tr)
        assert not rel.held and rel.time == 0.0 and rel.level == tr.u[0], (name, rel)
        assert abs(rel.estimate) < 0.015
    noisy = _noisy_shipped()
    rel = identification.detect_release(noisy)
    assert rel.sigma == pytest.approx(5e-4, rel=0.2)  # the true noise std
    # a logger clock that starts at 2.5 s: t0 is the first sample, not 0
    shifted = DecayTrace(noisy.t + 2.5, noisy.u)
    assert identification.detect_release(shifted).time == 2.5


@pytest.mark.parametrize("seconds", [0.05, 1.0, 3.0])
def test_release_after_a_hold(seconds):
    tr, t_release = _with_hold(_noisy_shipped(), seconds)
    rel = identification.detect_release(tr)
    assert rel.held, rel
    assert abs(rel.time - t_release) < 0.015, (rel, t_release)  # 3 samples at 200 Hz
    assert rel.level == pytest.approx(0.1, abs=3e-4)
    assert rel.sigma == pytest.approx(5e-4, rel=0.2)
    d = rel.as_dict()
    assert d["release_time_s"] == rel.time and d["held"] is True


def test_release_not_fooled_by_a_spike_in_the_hold():
    tr, t_release = _with_hold(_noisy_shipped(), 1.0, seed=3)
    u = tr.u.copy()
    u[50] += 0.02  # one 40-sigma spike during the hold
    rel = identification.detect_release(DecayTrace(tr.t, u))
    assert abs(rel.time - t_release) < 0.015, rel


# ------------------------------------------------------- traces of any channel (issue 24)
@pytest.mark.parametrize("title, units, factor", [
    ("t,theta", None, 1.0), ("t,theta_deg", None, math.pi / 180), ("t,rot_rad", None, 1.0),
    ("t,theta [mrad]", None, 1e-3), ("t,theta", {"theta": "deg"}, math.pi / 180)])
def test_trace_channels_rotation_read(tmp_path, title, units, factor):
    """A rotation column is read as the channel theta [rad] (no longer refused), converted
    from the unit of its title or of `units`; u is None."""
    rows = [f"{0.01 * i:.6g},{0.08 * math.cos(0.3 * i) / factor:.9g}" for i in range(20)]
    tr = read_trace(_write(tmp_path, "rot.csv", [title, *rows]), units=units)
    assert tr.u is None and tr.uplift is None and tr.channels == ("theta",)
    assert tr.theta[0] == pytest.approx(0.08, rel=1e-8)
    assert tr.has_theta and tr.info()["max_abs_theta_rad"] == pytest.approx(0.08, rel=1e-8)
    assert tr.info()["max_abs_u_m"] is None and tr.amplitude is None


def test_trace_channels_subsets(tmp_path):
    """Any subset of u, theta and uplift (with t) is a trace; time alone, or a rotation
    read as the displacement (or a displacement with a unit of angle), is not."""
    rows = [f"{0.01 * i:.6g},{0.1 * 0.9**i:.6g},{0.01 * 0.9**i:.6g},{0.05 * 0.9**i:.6g}"
            for i in range(12)]
    tr = read_trace(_write(tmp_path, "all.csv", ["t,u,theta,uplift", *rows]))
    assert tr.channels == ("u", "theta", "uplift")
    up = read_trace(_write(tmp_path, "up.csv", ["t,uplift_mm", *[r.rsplit(",", 2)[0]
                                                                 .split(",")[0] + ","
                                                                 + r.split(",")[3]
                                                                 for r in rows]]))
    assert up.channels == ("uplift",) and up.uplift[0] == pytest.approx(0.05e-3)
    picked = read_trace(tmp_path / "all.csv", columns={"t": "t", "theta": "theta"})
    assert picked.channels == ("theta",)
    with pytest.raises(ValueError, match="'theta' is a rotation, not a displacement: read "
                       "it as the rotation channel theta"):
        read_trace(tmp_path / "all.csv", columns={"t": "t", "u": "theta"})
    with pytest.raises(ValueError, match="'u_deg' is a rotation"):
        read_trace(_write(tmp_path, "udeg.csv", ["t,u_deg", *[",".join(r.split(",")[:2])
                                                              for r in rows]]))
    with pytest.raises(ValueError, match="no channel of the motion"):
        DecayTrace(t=np.arange(12.0))
    with pytest.raises(ValueError, match="DecayTrace.theta: has 3 samples"):
        DecayTrace(t=np.arange(12.0), theta=np.zeros(3))


def test_trace_channels_rotation_in_degrees_under_rad_title(tmp_path):
    """A rotation beyond 1 rad read in rad is refused with a hint (degrees?)."""
    rows = [f"{0.01 * i:.6g},{5 * math.cos(0.3 * i):.6g}" for i in range(20)]
    with pytest.raises(identification.TraceError,
                       match=r"name it theta_deg or pass units=\{'theta': 'deg'\}"):
        read_trace(_write(tmp_path, "deg.csv", ["t,theta", *rows]))
    assert read_trace(tmp_path / "deg.csv", check_plausible=False).theta[0] == 5.0
