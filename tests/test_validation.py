"""Every row of docs/validation.md: a bad input is rejected before any integration starts.

Python API: the exception names the parameter (or the file and line). CLI: exit code 2, one
line on stderr, no traceback, nothing on stdout. The CLI runs in-process (fast); three
cases go through the real entry point in a subprocess. An autouse fixture replaces every
integrator with one that fails the test, so a bad input that slipped through to a run is
caught here rather than run. No El Centro, no simulations, no JIT compilation.
"""

from __future__ import annotations

import pathlib
import re
import types

import jax
import numpy as np
import pytest
from conftest import REPO, run_cli

import rockjax
from identification import DecayTrace, fit_decay, read_trace
from rockjax import (
    FreeVibration,
    GroundMotion,
    read_record,
    Record,
    RockingStructure,
    simulate,
    simulate_batch,
    Smooth,
    TwoSpring2DOF,
)
from rockjax.cli import main

DOC = REPO / "docs" / "validation.md"

S = rockjax.mcmanus_column()
BASE = S.to_dict()
FV = FreeVibration(0.1)
ACC = np.sin(0.1 * np.arange(100))
GM = GroundMotion(dt=0.01, accel=ACC)
GM2 = GroundMotion(dt=0.01, accel=np.stack([ACC, -ACC]))
T20 = 0.01 * np.arange(20)
U20 = 0.1 * np.cos(5.0 * T20)
TRACE = DecayTrace(T20, U20)
NAN, INF = float("nan"), float("inf")


def _nan_at(a, i=3):
    a = np.array(a, float)
    a[i] = np.nan
    return a


# ------------------------------------------------------------------------------- files
def _toml(**changes):
    text = (REPO / "data" / "mcmanus_column.toml").read_text()
    for key, value in changes.items():
        text, n = re.subn(rf"^{key} = \S+", f"{key} = {value}", text, flags=re.M)
        assert n == 1, key
    return text


def _csv(rows, header="t,u"):
    lines = [] if header is None else [header]
    lines += [",".join(str(x) for x in row) for row in rows]
    return "\n".join(lines) + "\n"


ROWS = [(float(t), float(u)) for t, u in zip(T20, U20)]
T_GAP = np.where(T20 > 0.095, T20 + 1.0, T20)

FILES = {
    # structures (TOML)
    "neg_me.toml": _toml(m_e="-1.0"),
    "zero_B.toml": _toml(B="0.0"),
    "neg_I.toml": _toml(I_eg="-1.0"),
    "zero_kf.toml": _toml(k_f="0.0"),
    "soft.toml": _toml(k_f="1000.0"),
    "nan.toml": _toml(k_f="nan"),
    "str.toml": _toml(k_f='"stiff"'),
    "unknown.toml": _toml() + "zeta = 0.05\n",
    "nokey.toml": _toml().replace("\nB = 0.285", "\n"),
    "notable.toml": "structure = 5\n",
    "syntax.toml": "[structure\n",
    # records
    "good.txt": "Accel[g]\n0 0.1\n0.01 0.2\n0.02 0.3\n",
    "slow.txt": "Accel[g]\n0 0.1\n0.02 0.2\n0.04 0.3\n",
    "odd.txt": "Accel[g]\n0 0.1\n0.0073 0.2\n0.0146 0.3\n",
    "unitsg.at2": "title\ndate\nUNITS OF G\nNPTS= 3, DT= .01 SEC\n1 2 3\n",
    "recdir/notes.md": "no records here\n",
    "empty.txt": "",
    "header_only.txt": "Accel[g]\nno data in this file\n",
    "nan.txt": "Accel[g]\n0 0.1\n0.01 nan\n0.02 0.1\n",
    "inf.txt": "Accel[g]\n0 0.1\n0.01 inf\n0.02 0.1\n",
    "text.txt": "Accel[g]\n0 0.1\n0.01 abc\n",
    "back.txt": "Accel[g]\n0 0.1\n0.02 0.2\n0.01 0.1\n",
    "nonuni.txt": "Accel[g]\n0 0.1\n0.01 0.2\n0.03 0.1\n0.04 0.1\n",
    "ragged.txt": "Accel[g]\n0 0.1\n0.01 0.2 4\n",
    "three.txt": "Accel[g]\n0 0.1 3\n0.01 0.2 3\n",
    "npts.at2": "title\ndate\nUNITS OF G\nNPTS= 3, DT= .01 SEC\n1 2\n",
    "hdr.at2": "title\ndate\nNPTS= 3, DT= .01 SEC\n1 2 3\n",
    "dt0.at2": "title\ndate\nUNITS OF G\nNPTS= 3, DT= 0 SEC\n1 2 3\n",
    "nan.at2": "title\ndate\nUNITS OF G\nNPTS= 3, DT= .01 SEC\n1 nan 3\n",
    "cm.at2": "title\nUNITS OF CM/SEC\nc\nNPTS= 3, DT= .01 SEC\n1 2 3\n",
    "one.txt": "Accel[g]\n0 0.1\n",
    "conflict.txt": "Accel[g], units: m/s2\n0 1\n0.01 2\n",
    "nounits.txt": "0 0.1\n0.01 0.2\n0.02 0.1\n",
    "onecol.txt": "Accel[g]\n0.1\n0.2\n0.3\n",
    # decay traces
    "good.csv": _csv(ROWS),
    "zero.csv": _csv([(t, 0.0) for t, _ in ROWS]),
    "short.csv": _csv(ROWS[:5]),
    "hdronly.csv": _csv([]),
    "repeat.csv": _csv(ROWS[:5] + [(ROWS[4][0], 0.0)] + ROWS[6:]),
    "back_trace.csv": _csv(ROWS[:5] + [(0.0, 0.0)] + ROWS[6:]),
    "nan.csv": _csv(ROWS[:5] + [(ROWS[5][0], "nan")] + ROWS[6:]),
    "inf.csv": _csv(ROWS[:5] + [(ROWS[5][0], "inf")] + ROWS[6:]),
    "text.csv": _csv(ROWS[:5] + [(ROWS[5][0], "abc")] + ROWS[6:]),
    "gap.csv": _csv(zip(T_GAP, U20)),
    "noheader.csv": _csv(ROWS, header=None),
    "wronghdr.csv": _csv(ROWS, header="time,disp,temp"),
    "twotime.csv": _csv([(t, t, u) for t, u in ROWS], header="t,time,u"),
    "noU.csv": "t\n" + "".join(f"{t}\n" for t, _ in ROWS),  # time alone (an uplift alone
    # or a rotation alone is a trace: any channel of the motion is fitted)
    "inch.csv": _csv(ROWS, header="t,u [inch]"),
    "tmm.csv": _csv(ROWS, header="t_mm,u"),
    "dispmm.csv": _csv(ROWS, header="t,disp_mm"),
    "big.csv": _csv([(t, 1000.0 * u) for t, u in ROWS]),
    "lab.csv": _csv(ROWS, header="time_s,disp_mm"),
    "onecol.csv": _csv([(t,) for t, _ in ROWS], header="t"),
    "missingcol.csv": _csv(ROWS[:3] + [(ROWS[3][0],)] + ROWS[4:]),
    "upl.csv": _csv(ROWS, header="t,u,uplift"),
    "empty.csv": "",
    "comments.csv": "# a comment\n# another\n",
}


@pytest.fixture(scope="module")
def d(tmp_path_factory) -> pathlib.Path:
    """A folder holding every file above, a sub-folder `adir`, and a non-UTF-8 TOML."""
    root = tmp_path_factory.mktemp("validation")
    for name, text in FILES.items():
        (root / name).parent.mkdir(exist_ok=True)
        (root / name).write_text(text)
    (root / "latin1.toml").write_bytes(b"[structure]\nm_e = 1.0 # \xe9\xff\n")
    (root / "adir").mkdir()
    return root


@pytest.fixture(autouse=True)
def no_integration(monkeypatch):
    """Every integrator fails the test: bad inputs must be rejected before a run starts."""

    def started(*args, **kwargs):
        raise AssertionError("an integration started: the bad input was not rejected first")

    for module, name in (
        ("rockjax.integrators._integrators", "_restart_solve"),
        ("rockjax.integrators._integrators", "_run_jit"),
        ("rockjax._batch", "_stepper_chunk_jit"),
        ("rockjax._batch", "_diffrax_chunk_jit"),
        ("rockjax._plotting", "pushover_curves"),
    ):
        monkeypatch.setattr(f"{module}.{name}", started, raising=False)


@pytest.mark.parametrize(
    "run",
    [
        lambda: simulate(S, FV, 0.1, ts=np.array([0.0, 0.1])),
        lambda: simulate(S, FV, 0.1, ts=np.array([0.0, 0.1]), method="rk4"),
        lambda: simulate(S, FV, 0.1, ts=np.array([0.0, 0.1]), model="two_spring_2dof"),
        lambda: simulate_batch(S, GM, 0.1, summary_only=True),
        lambda: simulate_batch(S, GM, 0.1, method="diffrax", summary_only=True),
    ],
    ids=["diffrax", "rk4", "2dof", "batch-rk4", "batch-diffrax"],
)
def test_guard_catches_a_run(run):
    """The no_integration guard works: a valid input reaches it."""
    with pytest.raises(AssertionError, match="integration started"):
        run()


# --------------------------------------------------------------------------- Python API
def case(row, tag, fn, match, exc=ValueError):
    return pytest.param(fn, exc, match, id=f"{row}-{tag}")


def _struct(**changes):
    return lambda d: RockingStructure(**{**BASE, **changes})


def _replace(**changes):
    return lambda d: S.replace(**changes)


def _sim(*args, **kwargs):
    return lambda d: simulate(*args, **kwargs)


def _batch(*args, **kwargs):
    return lambda d: simulate_batch(*args, **kwargs)


def _fit(trace=TRACE, structure=S, **kwargs):
    return lambda d: fit_decay(trace, structure, **kwargs)


def _rec(name, **kwargs):
    return lambda d: read_record(d / name, **kwargs)


def _trace(name, **kwargs):
    return lambda d: read_trace(d / name, **kwargs)


REC = Record(dt=0.01, accel=ACC)


K_MIN = float(S.W * S.H_c / (2.0 * S.B**2))

API = [
    # structure
    case("S1", "m_e-0", _replace(m_e=0.0), "m_e (mass) must be positive"),
    case("S1", "m_b-neg", _struct(m_b=-1.0), "m_b (mass) must be positive"),
    case("S2", "H_e-0", _replace(H_e=0.0), "H_e (height) must be positive"),
    case("S2", "H_b-neg", _replace(H_b=-0.1), "H_b (height) must be positive"),
    case("S3", "B-0", _replace(B=0.0), "B (half-width) must be positive"),
    case("S4", "I_eg-neg", _replace(I_eg=-1.0), "I_eg (rotary inertia) must be non-negative"),
    case("S4", "I_bg-neg", _struct(I_bg=-1.0), "I_bg (rotary inertia) must be non-negative"),
    case("S5", "k_f-0", _replace(k_f=0.0), "k_f (spring stiffness) must be positive"),
    case("S5", "k_f-neg", _replace(k_f=-1.0), "k_f (spring stiffness) must be positive"),
    case("S6", "g-0", _replace(g=0.0), "g (gravitational acceleration) must be positive"),
    case("S7", "k_f-nan", _replace(k_f=NAN), "k_f must be finite"),
    case("S7", "m_e-inf", _replace(m_e=INF), "m_e must be finite"),
    case("S7", "I_bg-nan", _replace(I_bg=NAN), "I_bg must be finite"),
    case("S7", "toml-nan", lambda d: RockingStructure.from_toml(d / "nan.toml"),
         "k_f must be finite"),
    case("S8", "k_f-soft", _replace(k_f=1000.0), "k_f is too soft for the structure to stand"),
    case("S8", "k_f-at-limit", _replace(k_f=K_MIN), "k_f is too soft"),
    case("S8", "batched", _replace(k_f=np.array([5e5, 1e3])), "k_f is too soft"),
    case("S9", "from_dict", lambda d: RockingStructure.from_dict({**BASE, "zeta": 0.05}),
         "unknown parameter(s) zeta"),
    case("S9", "replace", _replace(zeta=0.05), "unknown parameter(s) zeta"),
    case("S9", "toml", lambda d: RockingStructure.from_toml(d / "unknown.toml"),
         "unknown.toml: unknown parameter(s) zeta"),
    case("S10", "from_dict", lambda d: RockingStructure.from_dict(
        {k: v for k, v in BASE.items() if k != "B"}), "missing parameter(s) B"),
    case("S10", "toml", lambda d: RockingStructure.from_toml(d / "nokey.toml"),
         "nokey.toml: missing parameter(s) B"),
    case("S11", "str", lambda d: RockingStructure.from_dict({**BASE, "B": "0.3"}),
         "parameter B must be a number"),
    case("S11", "bool", lambda d: RockingStructure.from_dict({**BASE, "m_b": True}),
         "parameter m_b must be a number"),
    case("S11", "toml", lambda d: RockingStructure.from_toml(d / "str.toml"),
         "str.toml: parameter k_f must be a number"),
    case("S12", "list", lambda d: RockingStructure.from_dict([1.0]),
         "expected a table of structure parameters"),
    case("S12", "toml", lambda d: RockingStructure.from_toml(d / "notable.toml"),
         "notable.toml: expected a table of structure parameters"),
    case("S13", "syntax", lambda d: RockingStructure.from_toml(d / "syntax.toml"),
         "syntax.toml: not valid TOML"),
    case("S13", "not-utf8", lambda d: RockingStructure.from_toml(d / "latin1.toml"),
         "latin1.toml: not valid TOML"),
    case("S14", "missing", lambda d: RockingStructure.from_toml(d / "missing.toml"),
         "structure file not found", FileNotFoundError),
    case("S15", "dir", lambda d: RockingStructure.from_toml(d / "adir"),
         "structure file is a directory", IsADirectoryError),
    # excitations
    case("E1", "free-nan", lambda d: FreeVibration(NAN), "u0 must be finite"),
    case("E1", "free-inf", lambda d: FreeVibration(-INF), "u0 must be finite"),
    case("E1", "ground-nan", lambda d: GroundMotion(dt=0.01, accel=ACC, u0=NAN),
         "u0 must be finite"),
    case("E2", "free-nan", lambda d: FreeVibration(0.1, NAN), "v0 must be finite"),
    case("E2", "ground-inf", lambda d: GroundMotion(dt=0.01, accel=ACC, v0=INF),
         "v0 must be finite"),
    case("E3", "dt-0", lambda d: GroundMotion(dt=0.0, accel=ACC), "dt must be positive"),
    case("E3", "dt-neg", lambda d: GroundMotion(dt=-0.01, accel=ACC), "dt must be positive"),
    case("E3", "dt-nan", lambda d: GroundMotion(dt=NAN, accel=ACC), "dt must be positive"),
    case("E3", "dt-inf", lambda d: GroundMotion(dt=INF, accel=ACC),
         "dt must be positive and finite"),
    case("E4", "accel-nan", lambda d: GroundMotion(dt=0.01, accel=_nan_at(ACC)),
         "accel holds NaN or inf values"),
    case("E5", "accel-1", lambda d: GroundMotion(dt=0.01, accel=np.zeros(1)),
         "accel must hold at least 2 samples"),
    case("E5", "accel-scalar", lambda d: GroundMotion(dt=0.01, accel=0.0),
         "accel must hold at least 2 samples"),
    case("E6", "scale-nan", lambda d: GroundMotion(dt=0.01, accel=ACC, scale=NAN),
         "scale must be finite"),
    case("E6", "from_file", lambda d: GroundMotion.from_file(d / "good.txt", scale=INF),
         "scale must be finite"),
    # records
    case("R24", "at2", _rec("unitsg.at2", units="m/s2"),
         "the file states units g ('UNITS OF G' in its header) but m/s2 was given"),
    case("R24", "columns", lambda d: GroundMotion.from_file(d / "good.txt", units="m/s2"),
         "the file states units g"),
    case("R1", "missing", _rec("missing.at2"), "ground-motion record not found",
         FileNotFoundError),
    case("R2", "dir", _rec("adir"), "ground-motion record path is a directory",
         IsADirectoryError),
    case("R3", "empty", _rec("empty.txt"), "empty.txt: file is empty"),
    case("R4", "header-only", _rec("header_only.txt"), "header_only.txt: no numeric data"),
    case("R5", "nan", _rec("nan.txt"), "nan.txt, line 3: non-finite value (NaN or inf)"),
    case("R5", "inf", _rec("inf.txt"), "inf.txt, line 3: non-finite value (NaN or inf)"),
    case("R5", "at2-nan", _rec("nan.at2"), "nan.at2, line 5: non-finite value"),
    case("R6", "text", _rec("text.txt"), "text.txt, line 3: non-numeric data"),
    case("R7", "backwards", _rec("back.txt"),
         "back.txt, line 4: time is not strictly increasing (t=0.01 s after t=0.02 s)"),
    case("R8", "non-uniform", _rec("nonuni.txt"), "nonuni.txt, line 4: non-uniform time step"),
    case("R9", "ragged", _rec("ragged.txt"), "expected 2 columns (time, acceleration)"),
    case("R10", "three", _rec("three.txt"), "cannot detect the file format"),
    case("R11", "npts", _rec("npts.at2"), "the header says NPTS=3 but 2 values were found"),
    case("R12", "header", _rec("hdr.at2"), "line 4: expected the PEER AT2 header"),
    case("R13", "DT-0", _rec("dt0.at2"), "line 4: DT must be > 0"),
    case("R14", "one-sample", _rec("one.txt"), "a record needs at least 2 samples"),
    case("R15", "units", _rec("good.txt", units="furlong"), "unknown units='furlong'"),
    case("R15", "from_file", lambda d: GroundMotion.from_file(d / "good.txt", units="ft/s2"),
         "unknown units='ft/s2'"),
    case("R16", "cm", _rec("cm.at2"), "the header states units 'CM/SEC'"),
    case("R17", "conflict", _rec("conflict.txt"), "conflicting units"),
    case("R18", "no-units", _rec("nounits.txt"),
         "the units of the acceleration are not stated in the file"),
    case("R19", "one-column", _rec("onecol.txt"), "a one-column file has no time information"),
    case("R20", "dt-neg", _rec("good.txt", dt=-1.0), "dt must be finite and > 0"),
    case("R20", "dt-nan", _rec("good.txt", dt=NAN), "dt must be finite and > 0"),
    case("R20", "dt-text", _rec("good.txt", dt="abc"), "dt must be a number"),
    case("R20", "from_file", lambda d: GroundMotion.from_file(d / "good.txt", dt=0.0),
         "dt must be finite and > 0"),
    case("R21", "dt-mismatch", _rec("good.txt", dt=0.5),
         "a time step of 0.5 s was given but the file"),
    case("R22", "format", _rec("good.txt", format="xml"), "unknown format='xml'"),
    case("R23", "dt", lambda d: Record(dt=0.0, accel=np.zeros(3)),
         "Record: dt must be finite and > 0"),
    case("R23", "dt-text", lambda d: Record(dt="x", accel=np.zeros(3)),
         "Record: dt must be a number"),
    case("R23", "accel-nan", lambda d: Record(dt=0.01, accel=[0.0, NAN]),
         "Record: accel contains NaN or inf"),
    case("R23", "accel-2d", lambda d: Record(dt=0.01, accel=np.zeros((2, 2))),
         "Record: accel must be 1-D"),
    case("R23", "accel-text", lambda d: Record(dt=0.01, accel=["a", "b"]),
         "Record: accel must be an array of numbers"),
    case("R23", "units", lambda d: Record(dt=0.01, accel=np.zeros(3), units_in_file="ft/s2"),
         "Record: units_in_file must be one of g, m/s2, cm/s2, gal"),
    # simulate, simulate_batch
    case("M1", "simulate", _sim(S, "x", 1.0), "excitation must be a FreeVibration"),
    case("M1", "batch", _batch(S, None, 1.0), "excitation must be a FreeVibration"),
    case("M2", "t1-0", _sim(S, FV, 0.0), "t1 must be positive and finite"),
    case("M2", "t1-neg", _sim(S, FV, -1.0), "t1 must be positive and finite"),
    case("M2", "t1-inf", _sim(S, FV, INF), "t1 must be positive and finite"),
    case("M2", "t1-nan", _sim(S, FV, NAN), "t1 must be positive and finite"),
    case("M2", "batch-0", _batch(S, GM, 0.0), "t1 must be a positive, finite scalar"),
    case("M2", "batch-nan", _batch(S, FV, NAN), "t1 must be a positive, finite scalar"),
    case("M2", "batch-array", _batch(S, GM, np.ones(2)), "t1 must be a positive, finite scalar"),
    case("M3", "decreasing", _sim(S, FV, 1.0, ts=np.array([0.0, 0.5, 0.2])),
         "ts must be strictly increasing"),
    case("M3", "repeated", _sim(S, FV, 1.0, ts=np.array([0.0, 0.5, 0.5])),
         "ts must be strictly increasing"),
    case("M3", "batch", _batch(S, GM, 0.5, ts=np.array([0.0, 0.3, 0.2])),
         "ts must be strictly increasing"),
    case("M4", "beyond-t1", _sim(S, FV, 1.0, ts=np.array([0.0, 2.0])),
         "ts must lie within [0, t1]"),
    case("M4", "negative", _sim(S, FV, 1.0, ts=np.array([-0.1, 0.5])),
         "ts must lie within [0, t1]"),
    case("M4", "batch", _batch(S, GM, 0.5, ts=np.array([0.0, 0.6])),
         "ts must lie within [0, t1]"),
    case("M5", "2d", _sim(S, FV, 1.0, ts=np.zeros((2, 2))), "ts must be a 1-D array"),
    case("M5", "empty", _sim(S, FV, 1.0, ts=np.array([])), "ts must be a 1-D array"),
    case("M5", "scalar", _sim(S, FV, 1.0, ts=0.5), "ts must be a 1-D array"),
    case("M5", "nan", _sim(S, FV, 1.0, ts=np.array([0.0, NAN])), "ts must be finite"),
    case("M5", "batch-2d", _batch(S, GM, 0.5, ts=np.zeros((2, 2))), "ts must be a 1-D array"),
    case("M6", "traced-t1", lambda d: jax.jit(lambda t1: simulate(S, FV, t1).u)(1.0),
         "ts must be given when t1 is traced"),
    case("M7", "above-1", _sim(S, FV, 1.0, r=1.5), "r must lie in [0, 1]"),
    case("M7", "negative", _sim(S, FV, 1.0, r=-0.1), "r must lie in [0, 1]"),
    case("M7", "nan", _sim(S, FV, 1.0, r=NAN), "r must lie in [0, 1]"),
    case("M7", "rk4", _sim(S, FV, 1.0, r=2.0, method="rk4"), "r must lie in [0, 1]"),
    case("M7", "batch", _batch(S, GM, 1.0, r=1.5), "r must lie in [0, 1]"),
    case("M7", "batch-per-run", _batch(S, GM, 1.0, r=np.array([0.5, -0.1])),
         "r must lie in [0, 1]"),
    case("M7", "batch-nan", _batch(S, GM, 1.0, r=NAN), "r must be finite"),
    case("M8", "simulate", _sim(S, FV, 1.0, impact="never"), "impact must be one of"),
    case("M8", "batch", _batch(S, GM, 1.0, impact="never"), "impact must be one of"),
    case("M8", "fit", _fit(impact="never"), "impact must be one of"),
    case("M9", "adjoint", _sim(S, FV, 1.0, adjoint="sideways"),
         "adjoint must be 'reverse' or 'forward'"),
    case("M10", "rtol-0", _sim(S, FV, 1.0, rtol=0.0), "rtol must be a positive number"),
    case("M10", "atol-neg", _sim(S, FV, 1.0, atol=-1.0), "atol must be a positive number"),
    case("M10", "rtol-nan", _sim(S, FV, 1.0, rtol=NAN), "rtol must be a positive number"),
    case("M10", "batch", _batch(S, GM, 1.0, rtol=0.0), "rtol must be a positive number"),
    case("M11", "simulate", _sim(S, FV, 1.0, max_impacts=0),
         "max_impacts must be a positive integer"),
    case("M11", "batch", _batch(S, GM, 1.0, max_impacts=1.5),
         "max_impacts must be a positive integer"),
    case("M12", "dt-0", _sim(S, FV, 1.0, dt=0.0), "dt must be a positive number of seconds"),
    case("M12", "dt-nan", _sim(S, FV, 1.0, dt=NAN), "dt must be a positive number of seconds"),
    case("M12", "batch-inf", _batch(S, FV, 1.0, dt=INF),
         "dt must be a positive number of seconds"),
    case("M13", "simulate", _sim(S, FV, 1.0, method="euler"),
         "method must be 'diffrax', 'rk4' or 'dopri5'"),
    case("M13", "batch", _batch(S, GM, 1.0, method="euler"), "method must be one of"),
    case("M14", "simulate", _sim(S, FV, 1.0, method="rk4", substeps=0),
         "substeps must be a positive integer"),
    case("M14", "batch", _batch(S, GM, 1.0, substeps=1.5), "substeps must be a positive integer"),
    case("M15", "simulate", _sim(S, FV, 1.0, model="fancy"), "model must be one of"),
    case("M15", "batch", _batch(S, GM, 1.0, model="fancy"), "model must be one of"),
    case("M15", "get_model", lambda d: rockjax.get_model("fancy"), "model must be one of"),
    case("M15", "restoring_force", lambda d: rockjax.restoring_force(S, 0.1, model=None),
         "model must be one of"),
    case("M15", "fit", _fit(model="fancy"), "model must be one of"),
    case("M16", "impact-rule", _sim(S, FV, 1.0, impact="sometimes"), "impact must be one of"),
    case("M17", "none", _sim(None, FV, 1.0), "structure must be a RockingStructure"),
    case("M18", "str", _sim(S, FV, "abc"), "t1 must be a positive, finite number of seconds"),
    case("M18", "none", _sim(S, FV, None), "t1 must be positive and finite"),
    case("M19", "inf", _sim(S, FV, 1.0, dt=INF), r"dt must be a positive number of seconds"),
    case("M20", "zero", _sim(S, FV, 1.0, max_steps=0), "max_steps must be a positive integer"),
    case("M21", "simulate", _sim(S.astype(np.float32), FV, 1.0), "runs in float64"),
    case("M21", "batch", _batch(S.astype(np.float32), FV, 1.0, method="diffrax"),
         "runs in float64"),
    case("D4", "array", lambda d: rockjax.Smooth(width=np.array(1.5)),
         "width must be in"),
    case("P1", "nan", lambda d: rockjax.pushover(S, np.nan), "u must be finite"),
    case("P2", "reach", lambda d: rockjax.pushover(S, np.array([0.1, 100.0])),
         "u must be smaller than the body's reach"),
    case("B1", "structure", _batch(None, GM, 1.0), "structure must be a RockingStructure"),
    case("B2", "lengths", _batch(S, GM, 1.0, scale=np.ones(3), r=np.full(4, 0.5)),
         "batched inputs must all have the same length (scale: 3, r: 4)"),
    case("B2", "structure-field", _batch(S.replace(k_f=np.full(2, 5e5)), GM, 1.0,
                                         scale=np.ones(3)),
         "batched inputs must all have the same length (scale: 3, k_f: 2)"),
    case("B3", "2d", _batch(S, GM, 1.0, scale=np.ones((2, 2))),
         "scale must be a scalar or a 1-D array"),
    case("B4", "scale-nan", _batch(S, GM, 1.0, scale=np.array([1.0, NAN])),
         "scale must be finite"),
    case("B4", "u0-nan", _batch(S, FV, 1.0, u0=np.array([0.1, NAN])), "u0 must be finite"),
    case("B4", "v0-inf", _batch(S, FV, 1.0, v0=INF), "v0 must be finite"),
    case("B5", "too-big", _batch(S, GM2, 1.0, record=2), "record must hold integer indices"),
    case("B5", "negative", _batch(S, GM2, 1.0, record=np.array([0, -1])),
         "record must hold integer indices"),
    case("B5", "float", _batch(S, GM2, 1.0, record=0.5), "record must hold integer indices"),
    case("B6", "free-scale", _batch(S, FV, 1.0, scale=np.ones(3)),
         "scale and record apply to a GroundMotion"),
    case("B7", "chunk-0", _batch(S, GM, 1.0, chunk_size=0), "chunk_size must be a positive"),
    case("B7", "chunk-float", _batch(S, GM, 1.0, chunk_size=1.5),
         "chunk_size must be a positive"),
    case("B8", "max_pieces", _batch(S, GM, 1.0, max_pieces=1), "max_pieces must be an integer"),
    case("B9", "devices", _batch(S, GM, 1.0, devices=0), "devices must be between 1 and"),
    case("B10", "ts-summary", _batch(S, GM, 1.0, ts=np.linspace(0, 1, 5), summary_only=True),
         "ts applies to full responses"),
    case("B11", "batch", _batch(S, GM, 1.0, dt=0.01), "dt applies to a free vibration"),
    case("B11", "simulate-rk4", _sim(S, GM, 0.5, method="rk4", dt=0.01),
         "dt applies to a free vibration"),
    case("B12", "dt-array", _batch(S, GroundMotion(dt=np.full(2, 0.01), accel=GM2.accel), 1.0),
         "the records of a batch must share one time step: dt must be a scalar"),
    case("B15", "no-common-step", lambda d: simulate_batch(
        S, [read_record(d / "good.txt"), read_record(d / "odd.txt")]),
        "have no common step coarser than"),
    case("B16", "tail-neg", _batch(S, [REC, REC], tail=-1.0),
         "tail must be a finite number of seconds >= 0"),
    case("B17", "tail-single", _batch(S, GM, 1.0, tail=1.0),
         "tail applies to a sequence of records"),
    case("B18", "t1-missing", _batch(S, GM), "t1 must be given"),
    case("B19", "empty", _batch(S, []), "the sequence of records is empty"),
    case("B20", "item", _batch(S, ["a.at2"]), "a sequence must hold Records or GroundMotions"),
    case("B21", "multi", _batch(S, [GM2]), "must hold one record"),
    case("B22", "u0", _batch(S, [GroundMotion(dt=0.01, accel=ACC, u0=0.01)]),
         "has u0 or v0; pass u0=, v0= to simulate_batch"),
    case("B23", "record", _batch(S, [REC, REC], record=np.array([0, 3])),
         "record must hold integer indices into the 2 record(s) of the sequence"),
    case("B24", "dt", _batch(S, [REC, REC], dt=0.01), "dt applies to a free vibration"),
    case("B13", "accel-3d", _batch(S, GroundMotion(dt=0.01, accel=np.zeros((2, 2, 10))), 1.0),
         "accel must be 1-D (one record) or 2-D"),
    case("B14", "impact-rule", _batch(S, GM, 1.0, impact="sometimes"), "impact must be one of"),
    # restoring-force models
    case("D1", "width-0", lambda d: Smooth(width=0.0), "width must be in (0, 1)"),
    case("D1", "width-1", lambda d: Smooth(width=1.0), "width must be in (0, 1)"),
    case("D1", "width-neg", lambda d: Smooth(width=-0.5), "width must be in (0, 1)"),
    case("D1", "width-nan", lambda d: Smooth(width=NAN), "width must be in (0, 1)"),
    case("D2", "contact", lambda d: TwoSpring2DOF(contact="bounce"),
         "contact must be one of ('impact', 'continuous')"),
    case("D3", "damping-neg", lambda d: TwoSpring2DOF(damping=-1.0),
         "damping (dashpot coefficient c_f) must be >= 0"),
    case("D3", "damping-nan", lambda d: TwoSpring2DOF(damping=NAN), "damping"),
    case("D3", "damping-inf", lambda d: TwoSpring2DOF(damping=INF), "damping"),
    # decay traces
    case("T1", "missing", _trace("missing.csv"), "decay trace file not found",
         FileNotFoundError),
    case("T2", "dir", _trace("adir"), "adir: not a regular file"),
    case("T3", "empty", _trace("empty.csv"), "line 1: empty file; expected a header line"),
    case("T3", "comments", _trace("comments.csv"), "only comment lines"),
    case("T4", "wrong", _trace("wronghdr.csv"),
         "column 'temp' is not a time, displacement or uplift column"),
    case("T4", "none", _trace("noheader.csv"), "line 1: expected header 't,u'"),
    case("T4", "one-column", _trace("onecol.csv"), "line 1: expected header 't,u'"),
    case("T5", "missing-value", _trace("missingcol.csv"), "line 5: expected 2 values (t,u), got 1"),
    case("T5", "missing-uplift", _trace("upl.csv"),
         "line 2: expected 3 values (t,u,uplift), got 2"),
    case("T6", "text", _trace("text.csv"), "line 7: column 'u': 'abc' is not a number"),
    case("T7", "nan", _trace("nan.csv"),
         "line 7: column 'u': missing value 'nan' (NaN); 1 row(s) of the file have missing"),
    case("T13", "two-times", _trace("twotime.csv"), "two time columns in the header"),
    case("T14", "no-u", _trace("noU.csv"), "no displacement, rotation or uplift column"),
    case("T15", "inch", _trace("inch.csv"), "'inch' is not a unit of length"),
    case("T15", "t-mm", _trace("tmm.csv"), "'mm' is not a unit of time"),
    case("T16", "contradiction", _trace("dispmm.csv", units={"u": "m"}),
         "column 'disp_mm' is in mm, but the units given say m for 'u'"),
    case("T17", "unknown-unit", _trace("good.csv", units={"u": "furlong"}),
         "unknown unit 'furlong'"),
    case("T18", "no-column", _trace("lab.csv", columns={"t": "zeit", "u": "disp_mm"}),
         "no column 'zeit' in the header"),
    case("T19", "columns-u-only", _trace("lab.csv", columns={"u": "disp_mm"}),
         "columns must name the columns of 't' and 'u'"),
    case("T7", "inf", _trace("inf.csv"), "column 'u': value 'inf' is not finite"),
    case("T7", "u-nan", lambda d: DecayTrace(T20, _nan_at(U20)),
         "DecayTrace.u: 1 non-finite value(s), first at index 3"),
    case("T7", "t-nan", lambda d: DecayTrace(_nan_at(T20), U20), "DecayTrace.t: 1 non-finite"),
    case("T7", "uplift-nan", lambda d: DecayTrace(T20, U20, uplift=_nan_at(U20)),
         "DecayTrace.uplift: 1 non-finite"),
    case("T8", "repeat", _trace("repeat.csv"), "repeats the previous sample"),
    case("T8", "backwards", _trace("back_trace.csv"), "time goes backwards"),
    case("T8", "DecayTrace", lambda d: DecayTrace(T20[::-1], U20),
         "DecayTrace.t: must be strictly increasing"),
    case("T9", "short", _trace("short.csv"), "only 5 sample(s) after the header"),
    case("T9", "header-only", _trace("hdronly.csv"), "only 0 sample(s) after the header"),
    case("T9", "DecayTrace", lambda d: DecayTrace(T20[:9], U20[:9]),
         "DecayTrace.t: 9 sample(s), at least 10 are needed"),
    case("T10", "gap", _trace("gap.csv"), "line 12: gap in time of 1.01 s"),
    case("T10", "DecayTrace", lambda d: DecayTrace(T_GAP, U20), "DecayTrace.t: gap in time"),
    case("T11", "u-length", lambda d: DecayTrace(T20, U20[:-1]),
         "DecayTrace.u: has 19 samples but t has 20"),
    case("T11", "uplift-length", lambda d: DecayTrace(T20, U20, uplift=U20[:-1]),
         "DecayTrace.uplift: has 19 samples"),
    case("T12", "2d", lambda d: DecayTrace(T20.reshape(2, 10), U20),
         "DecayTrace.t: must be 1-D"),
    case("T12", "text", lambda d: DecayTrace(["a"] * 20, U20), "DecayTrace.t: cannot convert"),
    # fit_decay
    case("F1", "unknown", _fit(params=("k_f", "zeta")), "params must be distinct names"),
    case("F1", "empty", _fit(params=()), "params must be distinct names"),
    case("F1", "repeated", _fit(params=("k_f", "k_f")), "params must be distinct names"),
    case("F2", "string", _fit(params="k_f"), "params must be a sequence of names"),
    case("F3", "starts-0", _fit(starts=0), "starts must be a positive integer"),
    case("F3", "starts-float", _fit(starts=1.5), "starts must be a positive integer"),
    case("F4", "max_iter-0", _fit(max_iter=0), "max_iter must be a positive integer"),
    case("F5", "unknown", _fit(initial={"zeta": 1.0}), "initial has unknown parameter(s)"),
    case("F5", "not-dict", _fit(initial=5.0), "initial must be a dict"),
    case("F6", "r-1", _fit(initial={"r": 1.0}), "initial r must lie strictly inside (0, 1)"),
    case("F6", "r-0", _fit(initial={"r": 0.0}), "initial r must lie strictly inside (0, 1)"),
    case("F6", "r-above", _fit(initial={"r": 1.5}), "initial r must lie strictly inside (0, 1)"),
    case("F7", "k_f-low", _fit(initial={"k_f": 1000.0}),
         "initial k_f must exceed the stability limit"),
    case("F8", "u0-nan", _fit(initial={"u0": NAN}), "initial u0 must be finite"),
    case("F8", "k_f-inf", _fit(initial={"k_f": INF}), "initial k_f must be finite"),
    case("F8", "r-nan", _fit(initial={"r": NAN}), "initial r must be finite"),
    case("F8", "u0-text", _fit(initial={"u0": "x"}), "initial u0 must be a number"),
    case("F9", "empty", _fit(horizons=()), "horizons must be a non-empty sequence"),
    case("F9", "zero", _fit(horizons=(0.0, 1.0)), "horizons must be a non-empty sequence"),
    case("F9", "above-1", _fit(horizons=(0.5, 1.5)), "horizons must be a non-empty sequence"),
    case("F10", "tol", _fit(tol=-1.0), "tol must be a finite number >= 0"),
    case("F10", "uplift_weight", _fit(uplift_weight=NAN),
         "uplift_weight must be a finite number >= 0"),
    case("F11", "None", _fit(trace=None), "trace must be an identification.DecayTrace"),
    case("F11", "duck-nan", _fit(trace=types.SimpleNamespace(t=T20, u=_nan_at(U20))),
         "DecayTrace.u: 1 non-finite"),
    case("F12", "zero", _fit(trace=DecayTrace(T20, np.zeros(20))),
         "the trace's displacement is zero everywhere"),
    case("F15", "params", _fit(params=("k_f", "c_f")),
         "c_f (the dashpot coefficient of the 2-DOF body) is not a parameter of the simplified"),
    case("F15", "initial", _fit(initial={"c_f": 500.0}), "initial c_f: c_f (the dashpot"),
    case("F16", "continuous", _fit(params=("k_f", "r"), model="two_spring_2dof",
                                   contact="continuous"),
         "r does not act with contact='continuous'"),
    case("F17", "housner", _fit(params=("k_f", "r"), model="housner"),
         "k_f does not act in the housner model"),
    case("F18", "bad", _fit(model="two_spring_2dof", contact="sliding"),
         "contact must be one of ('impact', 'continuous'), got 'sliding'"),
    case("F18", "sdof", _fit(contact="continuous"),
         "contact applies to the 2-DOF body (model='two_spring_2dof') only"),
    case("F19", "negative", _fit(model="two_spring_2dof", initial={"c_f": -1.0}),
         "initial c_f must be >= 0"),
    case("F19", "zero-fitted", _fit(model="two_spring_2dof", params=("k_f", "c_f"),
                                    initial={"c_f": 0.0}),
         "initial c_f must be positive to be fitted"),
    case("F20", "2dof", _fit(model="two_spring_2dof", initial={"k_f": 1e9}),
         "initial k_f must lie below 7.94108e+07 N/m (10000 x the stability limit)"),
    case("F13", "str", _fit(structure="table1"), "structure must be a rockjax.RockingStructure"),
    case("F13", "batch", _fit(structure=S.replace(k_f=np.full(2, 5e5))),
         "structure must be a single structure"),
    # pulses and overturning spectra
    case("O1", "period", lambda d: rockjax.pulses.one_sine(1.0, -1.0),
         "period must be a positive finite number, got -1.0"),
    case("O1", "duration", lambda d: rockjax.pulses.rectangular(1.0, "x"),
         "duration must be a positive number, got 'x'"),
    case("O2", "nan", lambda d: rockjax.pulses.one_cosine(NAN, 1.0),
         "amplitude must be finite [m/s²], got nan"),
    case("O3", "few", lambda d: rockjax.pulses.one_sine(1.0, 1.0, steps=4),
         "steps must be at least 8 for a one_sine pulse, got 4"),
    case("O3", "float", lambda d: rockjax.pulses.rectangular(1.0, 1.0, steps=2.5),
         "steps must be a positive integer, got 2.5"),
    case("O4", "pulse", lambda d: rockjax.pulses.pulse("square", 1.0, 1.0),
         "kind must be one of ['cosine', 'one_cosine', 'one_sine', 'rectangular', 'sine'], "
         "got 'square'"),
    case("O4", "spectrum", lambda d: rockjax.overturning_spectrum(S, "square", [1.0]),
         "kind must be one of"),
    case("O5", "negative", lambda d: rockjax.overturning_spectrum(S, "sine", [1.0, -2.0]),
         "periods must be positive and finite [s]"),
    case("O5", "empty", lambda d: rockjax.overturning_spectrum(S, "sine", []),
         "periods must be a non-empty 1-D array [s]"),
    case("O6", "rtol", lambda d: rockjax.overturning_spectrum(S, "sine", [1.0], rtol=0.5),
         "rtol must lie in [1e-8, 0.1], got 0.5"),
    case("O6", "n_scan", lambda d: rockjax.overturning_spectrum(S, "sine", [1.0], n_scan=2),
         "n_scan must be an integer in [8, 4096], got 2"),
    case("O7", "batch", lambda d: rockjax.overturning_spectrum(
        S.replace(k_f=np.full(2, 5e5)), "sine", [1.0]),
        "structure: one structure (scalar fields), got arrays in k_f"),
]


@pytest.mark.parametrize("fn, exc, match", API)
def test_api_rejects(d, fn, exc, match):
    with pytest.raises(exc, match=re.escape(match)):
        fn(d)


# ---------------------------------------------------------------------------------- CLI
SIM = ["simulate", "--u0", "0.1", "--t1", "0.5"]
SWEEP = ["sweep", "--units", "g", "--record", "good.txt"]


def cli(row, tag, argv, match):
    return pytest.param(argv, match, id=f"{row}-{tag}")


CLI = [
    # pulses and spectra
    cli("O4", "pulse", ["spectrum", "--pulse", "square", "--periods", "1"],
        "argument --pulse: invalid choice: 'square'"),
    cli("O5", "periods", ["spectrum", "--pulse", "sine", "--periods", "1,-1"],
        "argument --periods: --periods must be positive and finite, got '1,-1'"),
    cli("O5", "ratios", ["spectrum", "--pulse", "sine", "--ratios", "0:1:3"],
        "argument --ratios: --ratios must be positive and finite"),
    cli("O6", "rtol", ["spectrum", "--pulse", "sine", "--ratios", "1", "--rtol", "2"],
        "--rtol must lie in [1e-8, 0.1], got 2.0"),
    # structure files
    cli("S1", "simulate", SIM + ["--structure", "neg_me.toml"], "m_e (mass) must be positive"),
    cli("S3", "pushover", ["pushover", "--structure", "zero_B.toml"], "B (half-width)"),
    cli("S4", "simulate", SIM + ["--structure", "neg_I.toml"], "I_eg (rotary inertia)"),
    cli("S5", "pushover", ["pushover", "--structure", "zero_kf.toml"], "k_f (spring stiffness)"),
    cli("S7", "simulate", SIM + ["--structure", "nan.toml"], "k_f must be finite"),
    cli("S8", "pushover", ["pushover", "--structure", "soft.toml"], "k_f is too soft"),
    cli("S8", "fit", ["fit", "good.csv", "--structure", "soft.toml"], "k_f is too soft"),
    cli("S8", "sweep", SWEEP + ["--structure", "soft.toml"], "--structure: k_f is too soft"),
    cli("S9", "simulate", SIM + ["--structure", "unknown.toml"], "unknown parameter(s) zeta"),
    cli("S10", "simulate", SIM + ["--structure", "nokey.toml"], "missing parameter(s) B"),
    cli("S11", "simulate", SIM + ["--structure", "str.toml"], "parameter k_f must be a number"),
    cli("S12", "simulate", SIM + ["--structure", "notable.toml"], "expected a table"),
    cli("S13", "syntax", ["pushover", "--structure", "syntax.toml"], "not valid TOML"),
    cli("S13", "not-utf8", SWEEP + ["--structure", "latin1.toml"], "not valid TOML"),
    cli("S14", "pushover", ["pushover", "--structure", "missing.toml"], "structure file not found"),
    cli("S15", "simulate", SIM + ["--structure", "adir"], "structure file is a directory"),
    # records
    cli("R1", "simulate", ["simulate", "--record", "missing.at2"], "record not found"),
    cli("R1", "sweep", ["sweep", "--record", "missing.at2"], "--record: ground-motion record not"),
    cli("R2", "simulate", ["simulate", "--record", "adir"], "is a directory"),
    cli("R3", "simulate", ["simulate", "--record", "empty.txt"], "file is empty"),
    cli("R3", "sweep", ["sweep", "--record", "empty.txt"], "--record: empty.txt: file is empty"),
    cli("R5", "simulate", ["simulate", "--record", "nan.txt"], "non-finite value (NaN or inf)"),
    cli("R5", "sweep", ["sweep", "--record", "inf.txt"], "non-finite value (NaN or inf)"),
    cli("R6", "simulate", ["simulate", "--record", "text.txt"], "non-numeric data"),
    cli("R7", "simulate", ["simulate", "--record", "back.txt"], "time is not strictly increasing"),
    cli("R8", "simulate", ["simulate", "--record", "nonuni.txt"], "non-uniform time step"),
    cli("R8", "sweep", ["sweep", "--record", "nonuni.txt"], "non-uniform time step"),
    cli("R11", "simulate", ["simulate", "--record", "npts.at2"], "NPTS=3 but 2 values"),
    cli("R11", "sweep", ["sweep", "--record", "npts.at2"], "NPTS=3 but 2 values"),
    cli("R12", "simulate", ["simulate", "--record", "hdr.at2"], "expected the PEER AT2 header"),
    cli("R14", "simulate", ["simulate", "--record", "one.txt"], "at least 2 samples"),
    cli("R15", "simulate", ["simulate", "--record", "good.txt", "--units", "furlong"],
        "argument --units: unknown unit 'furlong' of acceleration; known units"),
    cli("R16", "simulate", ["simulate", "--record", "cm.at2"], "not a unit of acceleration"),
    cli("R18", "simulate", ["simulate", "--record", "nounits.txt"], "units of the acceleration"),
    cli("R18", "sweep", ["sweep", "--record", "nounits.txt"], "units of the acceleration"),
    cli("R19", "simulate", ["simulate", "--record", "onecol.txt"],
        "pass --record-dt <time step in s>"),
    cli("R24", "simulate", ["simulate", "--record", "unitsg.at2", "--units", "m/s2"],
        "but m/s2 was given; omit --units or pass --units g"),
    cli("R24", "sweep", ["sweep", "--record", "unitsg.at2:m/s2"],
        "--units: unitsg.at2: the file states units g"),
    cli("R20", "simulate", ["simulate", "--record", "onecol.txt", "--record-dt", "0"],
        "argument --record-dt: --record-dt must be a positive number"),
    cli("R21", "simulate", ["simulate", "--record", "good.txt", "--record-dt", "0.5"],
        "--record-dt: good.txt: a time step of 0.5 s was given but the file has a time step "
        "of 0.01 s; omit --record-dt"),
    # simulation parameters
    cli("M2", "simulate-t1-0", ["simulate", "--u0", "0.1", "--t1", "0"], "argument --t1"),
    cli("M2", "simulate-t1-inf", ["simulate", "--u0", "0.1", "--t1", "inf"], "argument --t1"),
    cli("M2", "simulate-t1-nan", ["simulate", "--u0", "0.1", "--t1", "nan"], "argument --t1"),
    cli("M2", "sweep-t1-neg", SWEEP + ["--t1", "-1"], "argument --t1"),
    cli("M7", "simulate-above", SIM + ["--r", "1.5"], "--r: r must lie in [0, 1], got 1.5"),
    cli("M7", "simulate-negative", SIM + ["--r", "-0.1"], "--r: r must lie in [0, 1]"),
    cli("M7", "sweep", SWEEP + ["--r", "1.5"], "--r: r must lie in [0, 1]"),
    cli("M8", "impact", SIM + ["--impact", "never"], "argument --impact: invalid choice"),
    cli("M13", "method", SWEEP + ["--method", "euler"], "argument --method: invalid choice"),
    cli("M14", "substeps", SWEEP + ["--substeps", "0"], "argument --substeps"),
    cli("M15", "simulate", SIM + ["--model", "fancy"], "argument --model: invalid choice"),
    cli("M15", "fit", ["fit", "good.csv", "--model", "fancy"], "argument --model: invalid"),
    cli("M15", "sweep", SWEEP + ["--model", "fancy"], "argument --model: invalid choice"),
    cli("B15", "sweep", SWEEP + ["--record", "odd.txt"], "have no common step coarser than"),
    cli("B16", "sweep", SWEEP + ["--tail", "-1"], "argument --tail"),
    # traces
    cli("T1", "missing", ["fit", "missing.csv"], "decay trace file not found"),
    cli("T2", "dir", ["fit", "adir"], "not a regular file"),
    cli("T3", "empty", ["fit", "empty.csv"], "empty file"),
    cli("T4", "header", ["fit", "wronghdr.csv"], "--columns t=NAME,u=NAME"),
    cli("T5", "missing-value", ["fit", "missingcol.csv"], "expected 2 values (t,u), got 1"),
    cli("T6", "text", ["fit", "text.csv"], "is not a number"),
    cli("T7", "nan", ["fit", "nan.csv"], "pass --drop-nan to drop them"),
    cli("T17", "units", ["fit", "good.csv", "--units", "u=furlong"], "--units u=furlong"),
    cli("F14", "mm-as-m", ["fit", "big.csv"], "is the trace in mm?"),
    cli("T8", "backwards", ["fit", "back_trace.csv"], "time goes backwards"),
    cli("T8", "repeat", ["fit", "repeat.csv"], "repeats the previous sample"),
    cli("T9", "short", ["fit", "short.csv"], "at least 10 are needed"),
    cli("T10", "gap", ["fit", "gap.csv"], "gap in time of 1.01 s"),
    # fit options
    cli("F1", "unknown", ["fit", "good.csv", "--params", "zeta"], "argument --params"),
    cli("F1", "repeated", ["fit", "good.csv", "--params", "k_f", "k_f"],
        "--params: each parameter at most once"),
    cli("F3", "starts", ["fit", "good.csv", "--starts", "0"], "argument --starts"),
    cli("F15", "c_f-flag", ["fit", "good.csv", "--c-f", "500"],
        "--c-f: c_f (the dashpot coefficient of the 2-DOF body) is not a parameter"),
    cli("F15", "params", ["fit", "good.csv", "--params", "k_f", "c_f"],
        "is not a parameter of the simplified model"),
    cli("F16", "params", ["fit", "good.csv", "--model", "two_spring_2dof", "--contact",
                          "continuous", "--params", "k_f", "r"],
        "r does not act with contact='continuous'"),
    cli("F16", "r-flag", ["fit", "good.csv", "--model", "two_spring_2dof", "--contact",
                          "continuous", "--r", "0.5"],
        "--r does not act with --contact continuous"),
    cli("F17", "housner", ["fit", "good.csv", "--model", "housner", "--params", "k_f"],
        "k_f does not act in the housner model"),
    cli("F18", "sdof", ["fit", "good.csv", "--contact", "continuous"],
        "--contact: contact applies to the 2-DOF body"),
    cli("F18", "choice", ["fit", "good.csv", "--model", "two_spring_2dof", "--contact",
                          "sliding"], "argument --contact: invalid choice"),
    cli("F19", "c_f-zero", ["fit", "good.csv", "--model", "two_spring_2dof", "--c-f", "0"],
        "argument --c-f: --c-f must be a positive number"),
    cli("F12", "zero", ["fit", "zero.csv"], "displacement is zero everywhere"),
    # command line only
    cli("C1", "umax", ["pushover", "--umax", "-1"], "argument --umax"),
    cli("C1", "umax-nan", ["pushover", "--umax", "nan"], "argument --umax"),
    cli("C1", "record-dt", SWEEP + ["--record-dt", "-1"], "argument --record-dt"),
    cli("C2", "u0-nan", ["simulate", "--u0", "nan"], "argument --u0: --u0 must be finite"),
    cli("C2", "u0-text", ["simulate", "--u0", "abc"], "argument --u0: --u0 must be a number"),
    cli("C2", "v0-inf", ["simulate", "--u0", "0.1", "--v0", "inf"], "argument --v0"),
    cli("C2", "scale-nan", ["simulate", "--record", "good.txt", "--scale", "nan"],
        "argument --scale"),
    cli("C2", "r-nan", SIM + ["--r", "nan"], "argument --r: --r must be finite"),
    cli("C2", "sweep-r-inf", SWEEP + ["--r", "inf"], "argument --r"),
    cli("C3", "simulate", ["simulate", "--u0", "0.1", "--t1", "1e300"], "shorten --t1"),
    cli("C3", "simulate-record", ["simulate", "--record", "good.txt", "--t1", "1e300"],
        "shorten --t1"),
    cli("C3", "sweep", SWEEP + ["--tail", "1e300"], "shorten --tail"),
    cli("C4", "units", SWEEP + ["--units", "cm"],
        "argument --units: 'cm' is a unit of length, not of acceleration"),
    cli("C5", "neither", ["simulate"], "give --u0 M (free vibration) or --record FILE"),
    cli("C5", "both", ["simulate", "--u0", "0.1", "--record", "good.txt"], "not both"),
    cli("C6", "pushover", ["pushover", "--plot", "x.txt"], "--plot must end in .png"),
    cli("C6", "fit", ["fit", "good.csv", "--plot", "x.txt"], "--plot must end in .png"),
    cli("C6", "sweep", SWEEP + ["--plot", "x.txt"], "--plot must end in .png"),
    cli("C7", "points", ["pushover", "--points", "1"], "argument --points"),
    cli("C8", "negative", SWEEP + ["--scales", "-1"], "argument --scales"),
    cli("C8", "nan", SWEEP + ["--scales", "nan"], "argument --scales"),
    cli("C8", "range", SWEEP + ["--scales", "1:2:0"], "argument --scales"),
    cli("C9", "out", SWEEP + ["--out", "nodir/x.csv"], "--out: directory not found"),
    cli("C9", "out-dir", SWEEP + ["--out", "adir"], "--out is a directory"),
    cli("C10", "command", ["nosuchcommand"], "invalid choice"),
    cli("C10", "option", ["pushover", "--bogus"], "unrecognized arguments: --bogus"),
    cli("C10", "required", ["fit"], "the following arguments are required"),
    cli("C11", "umax", ["pushover", "--umax", "100"], "--umax must be below the body's reach"),
    cli("C12", "u0", ["simulate", "--u0", "100"], "--u0 100 m is beyond u_overturn = 0.375 m"),
    cli("C9", "simulate", SIM + ["--out", "nodir/x.csv"], "--out: directory not found"),
    cli("C9", "pushover", ["pushover", "--plot", "nodir/x.png"], "--plot: directory not found"),
    cli("C13", "units-twice", ["sweep", "--units", "g", "--units", "g", "--record", "good.txt"],
        "--units: given twice before the first --record"),
    cli("C14", "units-after", ["sweep", "--record", "good.txt:g", "--units", "m/s2"],
        "already has units"),
    cli("C15", "empty-dir", ["sweep", "--record", "recdir"], "no record files in this folder"),
    cli("C16", "twice", ["sweep", "--record", "good.txt", "--record", "good.txt"], "given twice"),
    cli("C17", "pairs", ["fit", "good.csv", "--units", "u"],
        "--units takes CHANNEL=VALUE pairs"),
    cli("C18", "fit-r", ["fit", "good.csv", "--r", "1.0"],
        "--r must lie strictly inside (0, 1) for a fit"),
]


def _one_line(rc, out, err, match):
    assert rc not in (0, None), (rc, out, err)
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    assert match in lines[0], lines[0]
    assert lines[0].startswith("rockjax"), lines[0]
    assert out == "", out  # rejected before any output (or any run)


@pytest.mark.parametrize("argv, match", CLI)
def test_cli_rejects(d, monkeypatch, capsys, argv, match):
    monkeypatch.chdir(d)
    try:
        rc = main(list(argv))
    except SystemExit as e:  # argparse errors
        rc = e.code
    cap = capsys.readouterr()
    _one_line(rc, cap.out, cap.err, match)
    assert not (d / "sweep.csv").exists()


@pytest.mark.parametrize(
    "argv, match",
    [
        (["simulate", "--u0", "nan"], "argument --u0"),
        (["simulate", "--record", "npts.at2"], "NPTS=3 but 2 values"),
        (["fit", "short.csv"], "at least 10 are needed"),
    ],
    ids=["argparse", "record", "trace"],
)
def test_cli_rejects_subprocess(d, argv, match):
    """The real entry point, as a user runs it."""
    r = run_cli(*argv, cwd=d)
    _one_line(r.returncode, r.stdout, r.stderr, match)
    assert r.returncode == 2


# --------------------------------------------------------------------------- the table
_ROW = re.compile(r"^\|\s*([A-Z]\d+)\s*\|")


def _table_ids():
    return [m.group(1) for line in DOC.read_text().splitlines() if (m := _ROW.match(line))]


def _case_ids(params):
    return {p.id.split("-")[0] for p in params}


def test_table_has_rows_and_every_row_is_tested():
    ids = _table_ids()
    assert len(ids) >= 25, f"docs/validation.md has only {len(ids)} table rows"
    assert len(ids) == len(set(ids)), "duplicate row IDs in docs/validation.md"
    tested = _case_ids(API) | _case_ids(CLI)
    assert not set(ids) - tested, f"rows without a test: {sorted(set(ids) - tested)}"
    assert not tested - set(ids), f"tests of rows not in the table: {sorted(tested - set(ids))}"


def test_table_documents_what_is_not_an_error():
    text = " ".join(DOC.read_text().split())
    assert "## What is not an error" in DOC.read_text()
    for phrase in ("status `\"overturned\"` and `t_overturn = 0`", "never as NaN",
                   "`completed`, `overturned`, `max_impacts`", "`solver_failure`"):
        assert phrase in text, phrase
