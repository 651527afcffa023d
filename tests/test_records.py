"""Tests for the ground-motion record readers and the El Centro dataset helper.

Everything runs on records the project makes (`rockjax.datasets.synthetic_ground_motion`,
written to tmp_path files in the AT2, two-column and one-column layouts by the writers of
tests/helpers/records.py). One test reads the real records (read-only files outside the
repository, see PROVENANCE.md next to them) and skips without them; nothing here touches
the network.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

# the writers of synthetic records live in tests/helpers/records.py (test_sweep_cli.py,
# test_batch.py and test_sweep_distributed.py import them from here)
from helpers.records import synthetic, write_at2, write_one_column, write_two_column  # noqa: F401

from rockjax import common_time_step, datasets, G_STANDARD, read_record, Record, UNITS
from rockjax._records import on_grid  # no public name

# file -> (read_record kwargs, dt [s], npts, PGA [m/s^2], units_in_file, units_source),
# from PROVENANCE.md
EXPECTED = {
    "IELC180.AT2": ({}, 0.01, 4000, 0.3129 * G_STANDARD, "g", "file header"),
    "elCentro.AT2": ({}, 0.02, 1559, 0.3188 * G_STANDARD, "g", "file header"),
    "elcentro_NS_full.dat": ({"units": "g"}, 0.02, 2688, 0.3487 * G_STANDARD, "g", "given"),
    "RSN1106_KOBE_KJM000.AT2": ({}, 0.02, 7500, 0.8342 * G_STANDARD, "g", "file header"),
    "Northridge_Sylmar_County.dat": ({"units": "m/s2"}, 0.02, 3000, 8.2676, "m/s2", "given"),
    "RSN753_LOMAP_CLS000.AT2": ({}, 0.005, 7995, 0.6447 * G_STANDARD, "g", "file header"),
    "ChiChi.dat": ({}, 0.01, 5279, 0.3610 * G_STANDARD, "g", "file header"),
}


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


AT2_HEADER = (
    "PEER STRONG MOTION DATABASE RECORD. PROCESSING BY PACIFIC ENGINEERING.\n"
    "SYNTHETIC TEST RECORD\n"
    "ACCELERATION TIME HISTORY IN UNITS OF G.\n"
)


# --- the real records (the only test that needs the shared data) -------------------------


def test_shared_records_match_provenance(ground_motions_dir):
    """Every shared record reads as PROVENANCE.md says, with its units and their source; a
    file that states g refuses m/s2 (it was read 9.81 times too weak before). One test for
    all seven records: a checkout without them skips once."""
    for name, (kwargs, dt, npts, pga, units, source) in sorted(EXPECTED.items()):
        path = ground_motions_dir / name
        rec = read_record(path, **kwargs)
        assert rec.dt == pytest.approx(dt, rel=1e-9), name
        assert rec.npts == npts == rec.accel.shape[0], name
        assert rec.accel.dtype == np.float64 and rec.accel.ndim == 1
        # PROVENANCE.md gives 4 significant digits, so 2e-4 relative is the honest tolerance.
        assert rec.pga == pytest.approx(pga, rel=2e-4), name
        assert (rec.units_in_file, rec.units_source, rec.source) == (units, source, str(path))
        if source == "file header":
            assert read_record(path, units=units).pga == rec.pga  # the same units: fine
            with pytest.raises(ValueError, match=rf"{name}: the file states units g .* but "
                                                 r"m/s2 was given; omit units= or pass units='g'"):
                read_record(path, units="m/s2")
        else:
            with pytest.raises(ValueError, match=rf"{name}: the units of the acceleration "
                                                 r"are not stated in the file; pass units="):
                read_record(path)
    rec = read_record(ground_motions_dir / "IELC180.AT2")
    assert rec.accel[0] == pytest.approx(-0.6403182e-02 * G_STANDARD, rel=1e-12)
    assert rec.accel[-1] == pytest.approx(0.9459335e-04 * G_STANDARD, rel=1e-12)
    peak = int(np.argmax(np.abs(rec.accel)))
    assert rec.time[peak] == pytest.approx(2.15) and rec.accel[peak] < 0
    assert "EL CENTRO ARRAY #9" in rec.description and "NPTS=  4000" in rec.description
    chichi = read_record(ground_motions_dir / "ChiChi.dat", format="two_column")
    assert chichi.units_in_file == "g" and "TCU045" in chichi.description


# --- units: stated, given, refused --------------------------------------------------------


def test_stated_units_win_and_contradictions_are_refused(tmp_path):
    """A file that states g, read with units='m/s2', is refused naming both (it used to be
    read 9.81 times too weak); the same units given again are fine."""
    rec = synthetic(seed=1, duration=2.0)
    at2 = write_at2(tmp_path / "a.AT2", rec)
    two = write_two_column(tmp_path / "b.dat", rec)
    for path, stated in ((at2, "'UNITS OF G'"), (two, "'Accel[g]'")):
        base = read_record(path)
        assert base.units_in_file == "g" and base.units_source == "file header"
        np.testing.assert_allclose(base.accel, rec.accel, rtol=1e-9, atol=1e-12)
        same = read_record(path, units="g")
        assert same.units_source == "file header" and np.array_equal(same.accel, base.accel)
        with pytest.raises(ValueError) as info:
            read_record(path, units="m/s2")
        msg = str(info.value)
        assert f"{path.name}: the file states units g ({stated} in its header)" in msg
        assert "but m/s2 was given; omit units= or pass units='g'" in msg
        assert info.value.param == "units"
    si = write_two_column(tmp_path / "si.dat", rec, header="t [s]  a [m/s2]", in_g=False)
    with pytest.raises(ValueError, match=r"states units m/s2 .* but g was given"):
        read_record(si, units="g")


def test_units_source(tmp_path):
    rec = synthetic(seed=2, duration=1.0)
    quiet = write_at2(tmp_path / "quiet.AT2", rec, units_line="NO UNITS STATED HERE")
    assert read_record(quiet).units_source == "AT2 default"
    assert read_record(quiet).units_in_file == "g"
    as_si = read_record(quiet, units="m/s2")  # the header says nothing: the units given
    assert (as_si.units_in_file, as_si.units_source) == ("m/s2", "given")
    bare = write_two_column(tmp_path / "bare.dat", rec, header="", in_g=False)
    got = read_record(bare, units="m/s2")
    assert (got.units_in_file, got.units_source) == ("m/s2", "given")
    np.testing.assert_allclose(got.accel, rec.accel, rtol=1e-9)
    both = write(tmp_path, "both.dat", "Accel[g] Units: m/s2\n0 0.1\n0.01 0.2\n")
    with pytest.raises(ValueError, match=r"conflicting units .*; pass units='g' or units="):
        read_record(both)
    assert read_record(both, units="m/s2").units_source == "given"
    assert Record(dt=0.01, accel=[0.0, 1.0]).units_source == ""
    assert "units_source='given'" in repr(got)


def test_headerless_two_column_requires_units(tmp_path):
    path = write_two_column(tmp_path / "headerless.dat", synthetic(duration=1.0), header="")
    with pytest.raises(ValueError, match=r"units='g' or units='m/s2'") as info:
        read_record(path)
    assert "headerless.dat" in str(info.value)


def test_record_is_frozen_and_read_only(tmp_path):
    rec = read_record(write_at2(tmp_path / "r.AT2", synthetic(duration=1.0)))
    with pytest.raises(ValueError):
        rec.accel[0] = 1.0
    with pytest.raises(AttributeError):
        rec.dt = 0.5  # type: ignore[misc]


def test_three_layouts_read_back_the_same_record(tmp_path):
    rec = synthetic(seed=3, dt=0.005, duration=2.0)
    reads = [
        read_record(write_at2(tmp_path / "r.AT2", rec, per_line=8)),
        read_record(write_two_column(tmp_path / "r.dat", rec)),
        read_record(write_one_column(tmp_path / "r.txt", rec), units="g", dt=0.005),
    ]
    for got in reads:
        assert got.dt == pytest.approx(0.005, rel=1e-12) and got.npts == rec.npts
        np.testing.assert_allclose(got.accel, rec.accel, rtol=1e-8, atol=1e-12)


# --- the common time step of records -------------------------------------------------------


def test_common_time_step():
    assert common_time_step([0.005, 0.01, 0.02]) == 0.005
    assert common_time_step([0.02, 0.01]) == 0.01
    assert common_time_step([0.01, 0.004]) == 0.002
    # float steps of two-column files count as the nominal ones; a step that is the
    # common one comes back unchanged
    assert common_time_step([0.019999999999999997, 0.02]) == 0.019999999999999997
    assert common_time_step([0.1 + 0.2, 0.1]) == pytest.approx(0.1)
    assert common_time_step([1 / 3]) == 1 / 3
    with pytest.raises(ValueError) as info:
        common_time_step([0.01, 0.0073], names=["a.AT2", "b.dat"])
    msg = str(info.value)
    assert "a.AT2 dt = 0.01 s, b.dat dt = 0.0073 s" in msg
    assert "no common step coarser than 0.0001 s, 73 times finer" in msg
    assert common_time_step([0.01, 0.0073], max_refinement=100) == pytest.approx(1e-4)
    assert common_time_step([np.pi / 100]) == np.pi / 100  # one step is its own grid
    with pytest.raises(ValueError, match="no common step coarser than"):
        common_time_step([np.pi / 100, 0.01])
    with pytest.raises(ValueError, match="positive and finite"):
        common_time_step([0.01, 0.0])


def test_on_grid_keeps_every_sample():
    a = np.array([1.0, 3.0, -1.0, 0.5])
    fine = on_grid(a, 4)
    assert fine.size == 13 and np.array_equal(fine[::4], a)
    np.testing.assert_allclose(fine[1:4], [1.5, 2.0, 2.5])
    assert on_grid(a, 1) is not None and np.array_equal(on_grid(a, 1), a)


# --- synthetic well-formed files ---------------------------------------------------------


def test_at2_nga_header_eight_per_line_and_trailing_blank(tmp_path):
    values = np.arange(1, 12) * 1e-3
    body = " ".join(f"{v:.7E}" for v in values[:8]) + "\n"
    body += " ".join(f"{v:.7E}" for v in values[8:]) + "\n   \n"
    path = write(
        tmp_path,
        "rec.txt",
        "PEER NGA STRONG MOTION DATABASE RECORD\nSynthetic\n"
        "ACCELERATION TIME SERIES IN UNITS OF G\nNPTS =     11 , DT =   .020 SEC ,\n" + body,
    )
    rec = read_record(path)  # detected from the NPTS line, not the suffix
    assert rec.dt == 0.02 and rec.npts == 11 and rec.units_in_file == "g"
    np.testing.assert_allclose(rec.accel, values * G_STANDARD, rtol=1e-12)


def test_at2_old_nga_header_and_fortran_exponent(tmp_path):
    path = write(
        tmp_path,
        "old.at2",
        AT2_HEADER + "    3    0.0050    NPTS, DT\n 0.1D+00 -0.2D+00 0.3\n",
    )
    rec = read_record(path)
    assert rec.dt == 0.005
    np.testing.assert_allclose(rec.accel, np.array([0.1, -0.2, 0.3]) * G_STANDARD)


def test_two_column_tab_header_and_shift(tmp_path):
    rows = "\n".join(f"{1.5 + 0.01 * i:.3f}\t{0.1 * i:.3f}" for i in range(6))
    path = write(tmp_path, "a.dat", "Some title\nTime[s] Accel[m/s2]\n" + rows + "\n")
    rec = read_record(path)
    assert rec.units_in_file == "m/s2"
    assert rec.dt == pytest.approx(0.01, rel=1e-12)
    assert rec.time[0] == 0.0
    np.testing.assert_allclose(rec.accel, 0.1 * np.arange(6), atol=1e-12)
    assert rec.description == "Some title\nTime[s] Accel[m/s2]"


def test_one_column_with_dt(tmp_path):
    path = write(tmp_path, "one.txt", "0.0\n0.5\n-0.25\n")
    rec = read_record(path, dt=0.01, units="g")
    assert rec.dt == 0.01 and rec.npts == 3
    np.testing.assert_allclose(rec.accel, [0.0, 0.5 * G_STANDARD, -0.25 * G_STANDARD])
    assert read_record(path, dt=0.01, units="mps2", format="one_column").accel[1] == 0.5


# --- malformed inputs ---------------------------------------------------------------------


def test_missing_file(tmp_path):
    missing = tmp_path / "nope.AT2"
    with pytest.raises(FileNotFoundError, match="nope.AT2"):
        read_record(missing)


@pytest.mark.parametrize("name", ["empty.dat", "empty.AT2"])
def test_empty_file(tmp_path, name):
    path = write(tmp_path, name, "")
    with pytest.raises(ValueError, match=rf"{name}.*empty"):
        read_record(path, units="g")
    blank = write(tmp_path, "blank_" + name, "\n  \n\t\n")
    with pytest.raises(ValueError, match="empty"):
        read_record(blank, units="g")


def test_header_only_two_column(tmp_path):
    path = write(tmp_path, "hdr.dat", "Title\nTime[s] Accel[g]\n")
    with pytest.raises(ValueError, match=r"hdr\.dat.*no numeric data"):
        read_record(path)


@pytest.mark.parametrize("bad", ["nan", "NaN", "inf", "-Infinity"])
def test_non_finite_two_column(tmp_path, bad):
    path = write(tmp_path, "nf.dat", f"0.00 0.1\n0.01 0.2\n0.02 {bad}\n0.03 0.4\n")
    with pytest.raises(ValueError, match=r"nf\.dat, line 3: non-finite value \(NaN or inf\)"):
        read_record(path, units="g")


def test_non_finite_at2(tmp_path):
    path = write(tmp_path, "nf.AT2", AT2_HEADER + "NPTS=  4, DT= .01 SEC\n0.1 0.2\nInf 0.4\n")
    with pytest.raises(ValueError, match=r"nf\.AT2, line 6: non-finite"):
        read_record(path)


def test_non_uniform_time(tmp_path):
    path = write(tmp_path, "nu.dat", "0.00 0.1\n0.01 0.2\n0.02 0.3\n0.035 0.4\n0.045 0.5\n")
    with pytest.raises(ValueError, match=r"nu\.dat, line 4: non-uniform time step"):
        read_record(path, units="g")


@pytest.mark.parametrize(
    "rows, line", [("0.00 0.1\n0.01 0.2\n0.01 0.3\n", 3), ("0.00 0.1\n0.01 0.2\n0.00 0.3\n", 3)]
)
def test_non_increasing_time(tmp_path, rows, line):
    path = write(tmp_path, "ni.dat", rows)
    with pytest.raises(ValueError, match=rf"ni\.dat, line {line}: time is not strictly increasing"):
        read_record(path, units="g")


@pytest.mark.parametrize("npts, nvalues", [(5, 4), (3, 4)])
def test_npts_mismatch(tmp_path, npts, nvalues):
    body = " ".join(["0.1"] * nvalues) + "\n"
    path = write(tmp_path, "mm.AT2", AT2_HEADER + f"NPTS=  {npts}, DT= .01000 SEC\n" + body)
    with pytest.raises(ValueError, match=rf"mm\.AT2.*NPTS={npts} but {nvalues} values"):
        read_record(path)


def test_at2_bad_npts_line(tmp_path):
    path = write(tmp_path, "bad.AT2", AT2_HEADER + "no npts here\n0.1 0.2\n")
    with pytest.raises(ValueError, match=r"bad\.AT2, line 4: expected the PEER AT2 header"):
        read_record(path)


@pytest.mark.parametrize("units", ["ft/s2", "cm/s3", "mm", "s", ""])
def test_unknown_units(tmp_path, units):
    """An argument that is not a unit of acceleration is refused naming it and listing the
    units a record may be in (cm/s2 and gal, refused before issue 23, are read now)."""
    path = write(tmp_path, "u.dat", "0.0 0.1\n0.01 0.2\n")
    with pytest.raises(ValueError, match=r"unknown units=") as info:
        read_record(path, units=units)
    assert f"units={units!r}" in str(info.value)
    assert "g, m/s2, cm/s2, gal, mm/s2, in/s2" in str(info.value)


# (units given, header text stating them or None, factor to m/s2)
SI_UNITS = [
    ("m/s2", "Accel[m/s2]", 1.0),
    ("cm/s2", "Accel[cm/s2]", 0.01),
    ("cm/sec/sec", "ACCELERATION IN UNITS OF CM/SEC/SEC", 0.01),
    ("gal", "Accel[gal]", 0.01),
    ("Gal", "Acceleration (Gal)", 0.01),
    ("mm/s2", "a [mm/s^2]", 1e-3),
    ("g", "Accel[g]", G_STANDARD),
]


@pytest.mark.parametrize("given, header, size", SI_UNITS)
def test_records_in_other_units_give_the_same_si_record(tmp_path, given, header, size):
    """One record written in m/s2, cm/s2, gal, mm/s2 and g reads back as the same SI record,
    whether the units come from the header or from units= (issue 23)."""
    rec = synthetic(seed=3, duration=1.0)
    vals = np.asarray(rec.accel) / size
    body = "\n".join(f"{i * rec.dt:.6f} {v:.12e}" for i, v in enumerate(vals)) + "\n"
    stated = write(tmp_path, "stated.dat", f"Time[s] {header}\n" + body)
    bare = write(tmp_path, "bare.dat", body)
    from_header = read_record(stated)
    from_arg = read_record(bare, units=given)
    canonical = UNITS.normalize(given, "acceleration")
    assert (from_header.units_in_file, from_header.units_source) == (canonical, "file header")
    assert (from_arg.units_in_file, from_arg.units_source) == (canonical, "given")
    for got in (from_header, from_arg):
        np.testing.assert_allclose(got.accel, rec.accel, rtol=1e-11, atol=1e-14)
    assert read_record(stated, units=given).units_source == "file header"  # agreeing: fine


def test_header_units_win_and_a_contradicting_argument_names_both(tmp_path):
    """A header in gal read with units='m/s2' is refused naming both; units of the same
    size in another spelling (cm/s2 for gal) agree, and the header's name is kept."""
    path = write(tmp_path, "gal.dat", "Time[s] Accel[gal]\n0 1.0\n0.01 2.0\n0.02 -3.0\n")
    with pytest.raises(ValueError, match=r"gal\.dat: the file states units gal \('Accel\[gal\]' "
                                         r"in its header\) but m/s2 was given; omit units= or "
                                         r"pass units='gal'"):
        read_record(path, units="m/s2")
    rec = read_record(path, units="cm/s^2")
    assert rec.units_in_file == "gal" and rec.units_source == "file header"
    np.testing.assert_allclose(rec.accel, [0.01, 0.02, -0.03])
    at2 = write(tmp_path, "cm.AT2", "PEER\nX\nACCELERATION IN UNITS OF CM/S2\n"
                "NPTS= 3, DT= .01 SEC\n100.0 -50.0 0.0\n")
    rec = read_record(at2)  # an AT2 header's cm/s2 beats PEER's g default
    assert rec.units_in_file == "cm/s2"
    np.testing.assert_allclose(rec.accel, [1.0, -0.5, 0.0])
    with pytest.raises(ValueError, match=r"states units cm/s2 .* but g was given; omit "
                                         r"units= or pass units='cm/s2'"):
        read_record(at2, units="g")


def test_header_stating_a_length_is_refused(tmp_path):
    """A displacement record ('UNITS OF CM') is refused naming the unit, and a record
    cannot claim a unit that is not one of acceleration."""
    path = write(tmp_path, "disp.AT2", "PEER\nX\nDISPLACEMENT IN UNITS OF CM\n"
                 "NPTS= 2, DT= .01 SEC\n1 2\n")
    with pytest.raises(ValueError, match=r"disp\.AT2: the header states units 'CM', which are "
                                         r"not a unit of acceleration; records must be in g, "):
        read_record(path)
    with pytest.raises(ValueError, match=r"units_in_file must be one of g, m/s2, cm/s2, gal"):
        Record(dt=0.01, accel=[0.0, 1.0], units_in_file="cm")
    # a unit of time, or m in a description line, says nothing about the acceleration
    quiet = write(tmp_path, "q.dat", "Station depth (m)\nTime [sec] Accel[gal]\n0 1\n0.01 2\n")
    rec = read_record(quiet)
    assert (rec.units_in_file, rec.units_source) == ("gal", "file header")


def test_unsupported_header_units(tmp_path):
    path = write(
        tmp_path,
        "vel.AT2",
        "PEER NGA\nX\nVELOCITY TIME SERIES IN UNITS OF CM/SEC\nNPTS= 2, DT= .01 SEC\n1 2\n",
    )
    with pytest.raises(ValueError, match=r"vel\.AT2: the header states units 'CM/SEC'"):
        read_record(path)


def test_one_column_without_dt(tmp_path):
    path = write(tmp_path, "one.txt", "0.1\n0.2\n0.3\n")
    with pytest.raises(ValueError, match=r"one\.txt.*pass dt="):
        read_record(path, units="g")


@pytest.mark.parametrize("dt", [0.0, -0.01, float("nan")])
def test_bad_dt_argument(tmp_path, dt):
    path = write(tmp_path, "one.txt", "0.1\n0.2\n0.3\n")
    with pytest.raises(ValueError, match=r"dt must be finite and > 0"):
        read_record(path, units="g", dt=dt)


def test_zero_dt_in_at2_header(tmp_path):
    path = write(tmp_path, "z.AT2", AT2_HEADER + "NPTS=  2, DT= 0.0 SEC\n0.1 0.2\n")
    with pytest.raises(ValueError, match=r"z\.AT2, line 4: DT must be > 0"):
        read_record(path)


def test_dt_argument_conflicts_with_file(tmp_path):
    path = write(tmp_path, "c.dat", "0.0 0.1\n0.01 0.2\n0.02 0.3\n")
    assert read_record(path, units="g", dt=0.01).dt == pytest.approx(0.01)
    with pytest.raises(ValueError, match=r"c\.dat: a time step of 0\.02 s was given .*; omit dt="):
        read_record(path, units="g", dt=0.02)


@pytest.mark.parametrize(
    "text, line",
    [
        ("0.00 0.1\n0.01 0.2\n0.02 abc\n0.03 0.4\n", 3),
        ("0.00 0.1\n0.01 0.2\n\n<html> oops </html>\n", 4),
        ("Time Accel[g]\n0.00 0.1\n0.01 1.0.2\n", 3),
    ],
)
def test_garbage_in_data(tmp_path, text, line):
    path = write(tmp_path, "garbage.dat", text)
    with pytest.raises(ValueError, match=rf"garbage\.dat, line {line}: non-numeric data"):
        read_record(path, units="g")


def test_garbage_in_at2(tmp_path):
    path = write(tmp_path, "g.AT2", AT2_HEADER + "NPTS=  4, DT= .01 SEC\n0.1 0.2\n0.3 x4\n")
    with pytest.raises(ValueError, match=r"g\.AT2, line 6: non-numeric data"):
        read_record(path)


def test_wrong_column_count(tmp_path):
    path = write(tmp_path, "cols.dat", "0.00 0.1\n0.01 0.2 0.5\n")
    with pytest.raises(ValueError, match=r"cols\.dat, line 2: expected 2 columns"):
        read_record(path, units="g")
    many = write(tmp_path, "many.dat", "0.1 0.2 0.3\n")
    with pytest.raises(ValueError, match=r"many\.dat, line 1: cannot detect the file format"):
        read_record(many, units="g")


def test_too_few_samples(tmp_path):
    two_col = write(tmp_path, "short.dat", "0.0 0.1\n")
    with pytest.raises(ValueError, match=r"short\.dat: a record needs at least 2 samples"):
        read_record(two_col, units="g")
    at2 = write(tmp_path, "short.AT2", AT2_HEADER + "NPTS=  1, DT= .01 SEC\n0.1\n")
    with pytest.raises(ValueError, match=r"short\.AT2: a record needs at least 2 samples"):
        read_record(at2)


def test_unknown_format(tmp_path):
    path = write(tmp_path, "f.dat", "0.0 0.1\n0.01 0.2\n")
    with pytest.raises(ValueError, match=r"unknown format="):
        read_record(path, units="g", format="csv")


# --- datasets ----------------------------------------------------------------------------


@pytest.fixture
def isolated_cache(tmp_path, monkeypatch):
    """Empty cache under tmp_path, no ROCKJAX_EL_CENTRO, and a download that must not run."""
    cache = tmp_path / "cache"
    monkeypatch.setenv("ROCKJAX_CACHE", str(cache))
    monkeypatch.delenv("ROCKJAX_EL_CENTRO", raising=False)

    def no_network(url, dest):
        raise AssertionError("tests must not download")

    monkeypatch.setattr(datasets, "_download", no_network)
    return cache


def test_cache_dir_resolution(monkeypatch, tmp_path):
    monkeypatch.setenv("ROCKJAX_CACHE", str(tmp_path / "c"))
    assert datasets.cache_dir() == tmp_path / "c"
    monkeypatch.delenv("ROCKJAX_CACHE")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert datasets.cache_dir() == tmp_path / "xdg" / "rockjax"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert datasets.cache_dir() == tmp_path / "home" / ".cache" / "rockjax"


@pytest.fixture
def fake_el_centro(tmp_path, monkeypatch):
    """A synthetic IELC180.AT2 (4000 samples at 0.01 s) whose SHA-256 is the expected one."""
    folder = tmp_path / "local"
    folder.mkdir()
    path = write_at2(folder / "IELC180.AT2", synthetic(seed=4, dt=0.01, duration=39.99))
    monkeypatch.setattr(datasets, "EL_CENTRO_SHA256", hashlib.sha256(path.read_bytes()).hexdigest())
    return path


def test_download_into_cache(isolated_cache, monkeypatch, fake_el_centro):
    calls = []

    def fake_download(url, dest):
        calls.append(url)
        assert Path(dest).parent == isolated_cache  # temp file next to the target
        dest.write_bytes(fake_el_centro.read_bytes())

    monkeypatch.setattr(datasets, "_download", fake_download)
    rec = datasets.el_centro()
    assert calls == [datasets.EL_CENTRO_URL]
    assert rec.dt == 0.01 and rec.npts == 4000 and rec.units_in_file == "g"
    assert rec.pga == pytest.approx(3.0, rel=1e-8)
    cached = isolated_cache / "IELC180.AT2"
    assert rec.source == str(cached)
    assert sorted(p.name for p in isolated_cache.iterdir()) == ["IELC180.AT2"]
    # A second call uses the cache, even with download=False.
    assert datasets.el_centro_path(download=False) == cached
    assert len(calls) == 1


def test_local_argument_and_env_var(isolated_cache, monkeypatch, fake_el_centro):
    source = fake_el_centro
    assert datasets.el_centro_path(local=source) == source
    assert datasets.el_centro_path(local=source.parent) == source  # a directory works too
    assert datasets.el_centro(local=str(source)).npts == 4000
    monkeypatch.setenv("ROCKJAX_EL_CENTRO", str(source.parent))
    assert datasets.el_centro_path(download=False) == source
    assert not isolated_cache.exists()


def test_local_missing(isolated_cache, tmp_path):
    with pytest.raises(FileNotFoundError, match=r"not found.*ROCKJAX_EL_CENTRO"):
        datasets.el_centro_path(local=tmp_path / "nowhere.AT2")


def test_sha_mismatch_local(isolated_cache, tmp_path, fake_el_centro):
    modified = tmp_path / "IELC180.AT2"
    data = bytearray(fake_el_centro.read_bytes())
    data[-3] = ord("9") if data[-3] != ord("9") else ord("8")
    modified.write_bytes(bytes(data))
    with pytest.raises(ValueError, match="SHA-256 mismatch") as info:
        datasets.el_centro(local=tmp_path)
    message = str(info.value)
    assert str(modified) in message and datasets.EL_CENTRO_SHA256 in message
    assert datasets._sha256(modified) in message


def test_sha_mismatch_cached(isolated_cache):
    isolated_cache.mkdir()
    (isolated_cache / "IELC180.AT2").write_text("not the record\n")
    with pytest.raises(ValueError, match=r"SHA-256 mismatch.*Delete the cached file"):
        datasets.el_centro_path(download=False)


def test_sha_mismatch_download_removes_temp(isolated_cache, monkeypatch):
    def corrupt_download(url, dest):
        Path(dest).write_text("<html>rate limited</html>\n")

    monkeypatch.setattr(datasets, "_download", corrupt_download)
    with pytest.raises(ValueError, match="SHA-256 mismatch"):
        datasets.el_centro_path()
    assert list(isolated_cache.iterdir()) == []


def test_download_failure(isolated_cache, monkeypatch):
    def failing_download(url, dest):
        raise OSError("network unreachable")

    monkeypatch.setattr(datasets, "_download", failing_download)
    with pytest.raises(RuntimeError, match=r"network unreachable.*local=.*ROCKJAX_EL_CENTRO"):
        datasets.el_centro_path()
    assert list(isolated_cache.iterdir()) == []


def test_no_download_empty_cache(isolated_cache):
    with pytest.raises(FileNotFoundError, match=r"download=False.*local=.*ROCKJAX_EL_CENTRO"):
        datasets.el_centro(download=False)
    assert not isolated_cache.exists()
