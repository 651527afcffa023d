"""The one unit table (`rockjax.UNITS`, rockjax/_units.py) that records, decay traces and
the command line read units with (issue 23, item 6): every unit in every spelling, the
header tokens that carry a unit, and the error that names an unknown unit.

Pure Python and NumPy: no JAX compile.
"""

from __future__ import annotations

import argparse

import numpy as np
import pytest

import identification
import rockjax
from rockjax import UnitError, UNITS
from rockjax.cli._common import record_units, split_record_units

# (spelling, kind, canonical name, size in SI): every unit of the table in every spelling
# a header or an argument may use
TABLE = [
    # length [m]
    ("m", "length", "m", 1.0),
    ("cm", "length", "cm", 0.01),
    ("mm", "length", "mm", 0.001),
    ("um", "length", "um", 1e-6),
    ("µm", "length", "um", 1e-6),
    ("μm", "length", "um", 1e-6),
    ("in", "length", "in", 0.0254),
    ("IN", "length", "in", 0.0254),
    # acceleration [m/s2]
    ("g", "acceleration", "g", 9.80665),
    ("G", "acceleration", "g", 9.80665),
    ("m/s2", "acceleration", "m/s2", 1.0),
    ("m/s^2", "acceleration", "m/s2", 1.0),
    ("m/s**2", "acceleration", "m/s2", 1.0),
    ("m/s²", "acceleration", "m/s2", 1.0),
    ("m/s/s", "acceleration", "m/s2", 1.0),
    ("m/sec2", "acceleration", "m/s2", 1.0),
    ("m/sec^2", "acceleration", "m/s2", 1.0),
    ("m/sec/sec", "acceleration", "m/s2", 1.0),
    ("mps2", "acceleration", "m/s2", 1.0),
    ("M/S^2", "acceleration", "m/s2", 1.0),
    (" m / s2 ", "acceleration", "m/s2", 1.0),
    ("cm/s2", "acceleration", "cm/s2", 0.01),
    ("cm/s^2", "acceleration", "cm/s2", 0.01),
    ("cm/s²", "acceleration", "cm/s2", 0.01),
    ("cm/s/s", "acceleration", "cm/s2", 0.01),
    ("cm/sec/sec", "acceleration", "cm/s2", 0.01),
    ("CM/SEC2", "acceleration", "cm/s2", 0.01),
    ("gal", "acceleration", "gal", 0.01),
    ("Gal", "acceleration", "gal", 0.01),
    ("GALS", "acceleration", "gal", 0.01),
    ("mm/s2", "acceleration", "mm/s2", 0.001),
    ("mm/s^2", "acceleration", "mm/s2", 0.001),
    ("mm/sec/sec", "acceleration", "mm/s2", 0.001),
    ("in/s2", "acceleration", "in/s2", 0.0254),
    ("in/sec/sec", "acceleration", "in/s2", 0.0254),
    # time [s]
    ("s", "time", "s", 1.0),
    ("sec", "time", "s", 1.0),
    ("ms", "time", "ms", 0.001),
    ("us", "time", "us", 1e-6),
    ("µs", "time", "us", 1e-6),
    ("min", "time", "min", 60.0),
    # angle [rad]
    ("rad", "angle", "rad", 1.0),
    ("radians", "angle", "rad", 1.0),
    ("mrad", "angle", "mrad", 1e-3),
    ("deg", "angle", "deg", 0.017453292519943295),
    ("degrees", "angle", "deg", 0.017453292519943295),
    ("°", "angle", "deg", 0.017453292519943295),
]


@pytest.mark.parametrize("spelling, kind, name, size", TABLE)
def test_every_unit_and_spelling(spelling, kind, name, size):
    assert UNITS.kind_of(spelling) == kind
    assert UNITS.normalize(spelling, kind) == name
    assert UNITS.factor(spelling, kind) == pytest.approx(size, rel=1e-15)
    assert UNITS[kind][name] == pytest.approx(size, rel=1e-15)
    values = np.array([0.0, 2.0, -3.5])
    np.testing.assert_allclose(UNITS.to_si(values, spelling, kind), values * size, rtol=1e-15)
    # a unit of another kind is refused, naming the kind it is of
    other = next(k for k in UNITS.kinds if k != kind)
    with pytest.raises(UnitError, match=rf"is a unit of {kind}, not of {other}"):
        UNITS.normalize(spelling, other)


def test_the_table_is_covered_and_canonical():
    """Every canonical name appears in TABLE above, every spelling of the table maps to a
    canonical name of its kind, and the SI unit of each kind has size 1."""
    assert set(UNITS) == {"length", "acceleration", "time", "angle"}
    assert {(k, n) for _, k, n, _ in TABLE} == {(k, n) for k in UNITS for n in UNITS[k]}
    for spelling, (kind, name) in UNITS.spellings.items():
        assert name in UNITS[kind], spelling
    for kind, si in UNITS.si.items():
        assert UNITS[kind][si] == 1.0
    assert UNITS["acceleration"]["g"] == rockjax.G_STANDARD
    assert tuple(UNITS["acceleration"]) == ("g", "m/s2", "cm/s2", "gal", "mm/s2", "in/s2")
    with pytest.raises(TypeError):
        UNITS["length"]["ft"] = 0.3048  # read-only


@pytest.mark.parametrize("unit", ["furlong", "ft/s2", "cm/s3", "", "inch", "kg"])
def test_unknown_unit_is_named_with_the_known_ones(unit):
    with pytest.raises(UnitError) as info:
        UNITS.normalize(unit, "acceleration", what="units")
    msg = str(info.value)
    assert msg.startswith(f"units: unknown unit {unit!r} of acceleration; ")
    assert msg.endswith("known units of acceleration: g, m/s2, cm/s2, gal, mm/s2, in/s2")
    assert isinstance(info.value, ValueError)
    assert (info.value.unit, info.value.kind) == (unit, "acceleration")
    assert info.value.known == ("g", "m/s2", "cm/s2", "gal", "mm/s2", "in/s2")
    with pytest.raises(UnitError, match=rf"unknown unit {unit!r} of length; known units of "
                                        r"length: m, cm, mm, um, in"):
        UNITS.factor(unit, "length")
    assert UNITS.kind_of(unit) is None
    with pytest.raises(ValueError, match=r"unknown kind of unit 'speed'"):
        UNITS.normalize("m", "speed")


@pytest.mark.parametrize(
    "token, expected",
    [
        ("accel_cm/s2", ("accel", "cm/s2")),
        ("Accel[gal]", ("Accel", "gal")),
        ("Acceleration (m/s^2)", ("Acceleration", "m/s^2")),
        ("t_ms", ("t", "ms")),
        ("u_mm", ("u", "mm")),
        ("u [mm]", ("u", "mm")),
        ("u(cm)", ("u", "cm")),
        ("time_s", ("time", "s")),
        ("uplift [furlong]", ("uplift", "furlong")),  # brackets: the caller checks the unit
        ("max_peak", ("max_peak", None)),  # an underscore suffix only when it is a unit
        ("accel", ("accel", None)),
        ("_mm", ("_mm", None)),
    ],
)
def test_split_token(token, expected):
    assert UNITS.split_token(token) == expected


def test_split_token_of_given_kinds():
    assert UNITS.split_token("u_g") == ("u", "g")
    assert UNITS.split_token("u_g", ("time", "length")) == ("u_g", None)
    assert UNITS.split_token("u_mm", "length") == ("u", "mm")


def test_records_traces_and_cli_share_the_table(tmp_path):
    """The readers and the command line accept the same spellings and convert with the
    same sizes: a cm/s2 record, a trace in cm and ms, --units gal, FILE:cm/s^2."""
    rec = tmp_path / "a.dat"
    rec.write_text("t[s] a[cm/s^2]\n0 100\n0.01 -50\n0.02 0\n")
    got = rockjax.read_record(rec)
    assert got.units_in_file == "cm/s2"
    np.testing.assert_allclose(got.accel, [1.0, -0.5, 0.0])

    trace = tmp_path / "tr.csv"
    rows = "\n".join(f"{5 * i},{10.0 - i}" for i in range(12))
    trace.write_text("t_ms,u [cm]\n" + rows + "\n")
    tr = identification.read_trace(trace)
    assert dict(tr.units) == {"t": "ms", "u": "cm"}
    np.testing.assert_allclose(tr.t, 0.005 * np.arange(12), rtol=1e-15)
    np.testing.assert_allclose(tr.u, 0.01 * (10.0 - np.arange(12)), rtol=1e-15)
    sec = tmp_path / "sec.csv"
    sec.write_text("t,u\n" + rows + "\n")
    # (5 s steps and a 10-um peak are implausible for a decay trace: spellings only here)
    assert dict(identification.read_trace(sec, units={"t": "sec", "u": "µm"},
                                          check_plausible=False).units) == {
        "t": "s", "u": "um"}
    assert identification.TIME_UNITS["sec"] == 1.0 and identification.LENGTH_UNITS["in"] == 0.0254

    assert record_units("Gal") == "gal" and record_units("m/s^2") == "m/s2"
    with pytest.raises(argparse.ArgumentTypeError, match=r"unknown unit 'ft/s2' of "
                                                         r"acceleration; known units"):
        record_units("ft/s2")
    assert split_record_units("a.dat:cm/s^2") == ("a.dat", "cm/s2")
    assert split_record_units("a.dat:GAL") == ("a.dat", "gal")
    assert split_record_units("a.dat:mm") == ("a.dat:mm", None)  # a length: part of the path
