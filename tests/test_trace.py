"""identification._trace: DecayTrace, read_trace and the shipped SYNTHETIC decay traces."""

from __future__ import annotations

import dataclasses
import re

import jax.numpy as jnp
import numpy as np
import pytest

import rockjax
from identification._trace import (
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
    "bad_header": (["# c", "time,disp,up", *_rows(10)], 2, r"expected header 't,u' or"),
    "no_header": (_rows(12), 1, r"expected header"),
    "nan": (["t,u,uplift", *_rows(4), "0.04,nan,0.0", *_rows(6, t0=0.05)], 6, "not finite"),
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
