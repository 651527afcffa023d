"""The messy corpus of issue 24 (tests/helpers/messy.py): every file is read with its
reader and gives its truth -- the right values, or the error that names the cause (class,
parameter and message), with the warning where one is due. No row may end in a silent wrong
answer. Then the pieces behind the corpus, one behaviour per test."""

from __future__ import annotations

import gzip

import numpy as np
import pytest
from helpers import messy

import identification
import rockjax
from rockjax import _textfile, datasets


def test_the_corpus_is_large_and_covers_every_class():
    assert len(messy.CASES) >= 30
    assert len({c.name for c in messy.CASES}) == len(messy.CASES)
    kinds = {c.kind for c in messy.CASES}
    for kind in ("units in header", "contradicting flag", "structure in mm", "gzip",
                 "European CSV", "ESM format", "K-NET format", "jittered time",
                 "ms time column", "m under a mm title", "unsupported format",
                 "implausible PGA", "sensor offset", "sensor drift", "saturated trace",
                 "second release", "mains hum"):
        assert kind in kinds, kind


@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.slow) if c.slow else c
                                  for c in messy.CASES], ids=[c.name for c in messy.CASES])
def test_messy_file(case, tmp_path):
    ok, outcome = messy.check(case, tmp_path)
    assert ok, f"{case.name}: expected {case.truth}, got {outcome}"


def test_check_catches_a_wrong_value(tmp_path):
    """The corpus' checker fails a row whose truth is not met (a value, an error)."""
    case = messy.CASES[0]
    wrong = messy.Case(case.name, case.reader, case.content,
                       messy.Truth(values={"pga": 1.0}), case.kind, case.before)
    assert not messy.check(wrong, tmp_path)[0]
    wrong = messy.Case(case.name, case.reader, case.content,
                       messy.Truth(error="ValueError"), case.kind, case.before)
    ok, outcome = messy.check(wrong, tmp_path)
    assert not ok and outcome.startswith("read without error")


def test_a_row_with_its_own_reader_and_predicate(tmp_path):
    """Rows may bring their own reader (a fit, say) and a predicate on what it returns."""
    case = messy.Case("own.csv", lambda path, scale: float(path.read_text()) * scale, "2.5",
                      messy.Truth(predicate=lambda x: None if x == 5.0 else f"got {x}"),
                      "own reader", "-", kwargs={"scale": 2.0})
    assert messy.check(case, tmp_path) == (True, "5.0")
    bad = messy.Case("own.csv", case.reader, "2.0", case.truth, "own reader", "-",
                     kwargs={"scale": 2.0})
    assert messy.check(bad, tmp_path) == (False, "4.0 -- WRONG: got 4.0")


def test_table_prints_every_case():
    cases = [c for c in messy.CASES if not c.slow]  # the fits' rows: test_messy_file (slow)
    text = messy.table(cases=cases)
    assert text.count("\n") == len(cases) + 1
    assert text.endswith(f"{len(cases)}/{len(cases)} cases give their truth")


# ---------------------------------------------------------------- text: the dialects
@pytest.mark.parametrize("rows, dialect", [
    (["0.0,1.5", "0.01,-2"], _textfile.Dialect(",", False)),
    (["0.0 1.5", "0.01\t-2"], _textfile.Dialect(None, False)),
    (["0,0;1,5", "0,01;-2"], _textfile.Dialect(";", True)),
    (["0.0;1.5", "0.01;-2"], _textfile.Dialect(";", False)),
    (["0\t1,5", "0,01\t-2"], _textfile.Dialect(None, True)),
    (["0,5", "1,25"], _textfile.Dialect(None, True)),  # one column with decimal commas
    (["0.0, 1.5", "0.01, -2"], _textfile.Dialect(",", False)),
])
def test_sniff(rows, dialect):
    assert _textfile.sniff(["# comment", "t;a", *rows]) == dialect


def test_normalize_rows_leaves_plain_files_alone():
    lines = ["Time[s] Accel[g]", "0.0,1.5", "0.01,2"]
    assert datasets.normalize_rows(lines, " ")[0] is lines
    out, d = datasets.normalize_rows(["t;u_mm", "0,0;1,5", "# note; here", "0,01;-2,25"], ",")
    assert out == ["t,u_mm", "0.0,1.5", "# note; here", "0.01,-2.25"] and d.note


def test_normalize_rows_leaves_rows_with_text_alone():
    lines = ["index,t,u_mm,comment", "0,0,100,ok 0", "1,0.01,90,ok 1"]
    assert datasets.normalize_rows(lines, ",")[0] is lines


def test_read_text_gzip_and_binaries(tmp_path):
    p = tmp_path / "a.txt.gz"
    p.write_bytes(gzip.compress("\ufeffé 1\n".encode()))
    assert datasets.read_text(p) == ("é 1\n", True)
    bad = tmp_path / "b.gz"
    bad.write_bytes(gzip.compress(b"x")[:-6])
    with pytest.raises(ValueError, match=r"b\.gz: a damaged gzip file"):
        datasets.read_text(bad)
    sac = tmp_path / "c.sac"
    sac.write_bytes(b"\x00" * 600)
    with pytest.raises(ValueError, match=r"unsupported format: a binary file \(SAC, miniSEED"):
        rockjax.read_record(sac)
    zipped = tmp_path / "d.gz"
    zipped.write_bytes(gzip.compress(b"\x89HDF\r\n"))
    with pytest.raises(ValueError, match=r"a gzip-compressed file holding an HDF5 file"):
        rockjax.read_record(zipped)


# ------------------------------------------------------------------------ records
def test_esm_header_errors(tmp_path):
    text = messy.esm()
    p = tmp_path / "short.ASC"
    p.write_text(text.replace("NDATA: 600", "NDATA: 601"))
    with pytest.raises(ValueError, match=r"NDATA: 601 but 600 values"):
        rockjax.read_record(p)
    p.write_text(text.replace("UNITS: cm/s^2", "UNITS: furlong/s^2"))
    with pytest.raises(ValueError, match=r"ESM header states units 'furlong/s\^2'"):
        rockjax.read_record(p)
    p.write_text(text)
    with pytest.raises(rockjax.ParameterError, match=r"time step of 0\.02 s was given"):
        rockjax.read_record(p, dt=0.02)
    rec = rockjax.read_record(p, units="Gal")  # the same size as cm/s2: agrees
    assert rec.units_in_file == "cm/s2" and "SAMPLING_INTERVAL_S" in rec.description


def test_knet_scale_offset_and_peak_check(tmp_path):
    p = tmp_path / "SYN0010001010000.EW"
    p.write_text(messy.knet())
    rec = rockjax.read_record(p)
    counts = np.loadtxt(messy.knet().splitlines()[17:]).ravel()[:600]
    gal = counts * 3920 / 6182761
    np.testing.assert_allclose(rec.accel, (gal - gal.mean()) * 0.01, rtol=1e-12, atol=1e-15)
    assert abs(rec.accel.mean()) < 1e-12 and "mean removed" in rec.description
    assert rockjax._records.record_format(p) == "knet"
    p.write_text(messy.knet().replace("Max. Acc. (gal)   ", "Max. Acc. (gal)   9"))
    with pytest.raises(ValueError, match=r"says Max\. Acc\. 9.* gal but the data give"):
        rockjax.read_record(p)


def test_units_in_column_titles_and_time_in_ms(tmp_path):
    p = tmp_path / "r.csv"
    p.write_text(messy.two_columns("t (ms), acc_cm/s^2", t_factor=1e-3, a_factor=0.01))
    rec = rockjax.read_record(p)
    assert (rec.dt, rec.units_in_file) == (pytest.approx(0.01), "cm/s2")
    assert rec.pga == pytest.approx(messy.PGA, rel=1e-6)


def test_implausible_pga_names_the_override():
    err = rockjax.ParameterError("PGA 30 g", param="check_plausible", choices=(False,))
    assert str(err).endswith("pass check_plausible=False")


def test_jitter_warning_states_the_tolerance(tmp_path):
    p = tmp_path / "j.csv"
    p.write_text(messy.jittered(1e-4))
    with pytest.warns(rockjax._records.ResampledWarning,
                      match=r"jitters by up to 0\.000(1|11\d) of its step \(tolerance 0\.001\); "
                            r"resampled onto a uniform step of 0\.01 s"):
        rec = rockjax.read_record(p)
    assert rec.pga == pytest.approx(messy.PGA, rel=2e-3)
    with pytest.raises(rockjax.ParameterError, match=r"is 0\.000(1|11\d) of a step off.*tolerance "
                                                     r"time_tolerance=1e-05"):
        rockjax.read_record(p, time_tolerance=1e-5)
    with pytest.raises(rockjax.ParameterError, match=r"time_tolerance must be in \[0, 0\.5\)"):
        rockjax.read_record(p, time_tolerance=0.7)


def _european(text: str) -> str:
    """`text` with its rows of numbers written as European CSV (';', decimal commas)."""
    out = []
    for line in text.splitlines():
        toks = line.split()
        try:
            [float(x) for x in toks]
        except ValueError:
            out.append(line)
            continue
        out.append(";".join(x.replace(".", ",") for x in toks))
    return "\n".join(out) + "\n"


def test_real_records_gzip_and_european(ground_motions_dir, tmp_path):
    """Every shared real record reads the same gzip-compressed and as European CSV (and
    none is implausible); a real record read in the wrong units is refused."""
    units = {"elcentro_NS_full.dat": "g", "Northridge_Sylmar_County.dat": "m/s2"}
    paths = sorted(p for p in ground_motions_dir.iterdir() if p.suffix != ".md")
    assert len(paths) == 7
    for path in paths:
        rec = rockjax.read_record(path, units=units.get(path.name))
        assert 0.05 < rec.pga / rockjax.G_STANDARD < 2.0
        gz = tmp_path / (path.name + ".gz")
        gz.write_bytes(gzip.compress(path.read_bytes()))
        eu = tmp_path / ("eu_" + path.name)
        eu.write_text(_european(path.read_text(errors="replace")))
        for other in (gz, eu):
            again = rockjax.read_record(other, units=units.get(path.name),
                                        format="at2" if path.suffix == ".AT2" else None)
            assert (again.dt, again.npts, again.units_in_file) == (rec.dt, rec.npts,
                                                                   rec.units_in_file)
            np.testing.assert_array_equal(again.accel, rec.accel)
    with pytest.raises(rockjax.ParameterError, match=r"PGA 8\.27 g is implausible"):
        rockjax.read_record(ground_motions_dir / "Northridge_Sylmar_County.dat", units="g")


# ------------------------------------------------------------------------- traces
def test_trace_plausibility_override(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text(messy.trace_csv("t,u", t_factor=1e-3))
    with pytest.raises(identification.TraceError) as e:
        identification.read_trace(p)
    from rockjax.cli import fit as fit_cli
    from rockjax.cli._common import parameter_message

    cli = parameter_message(e.value, fit_cli.FLAGS)
    assert "--units t=ms" in cli and cli.endswith("pass --no-plausibility-check to read it "
                                                  "as it is")
    assert "units={'t': 'ms'}" in str(e.value) and "check_plausible=False" in str(e.value)
    assert e.value.param == "check_plausible"
    tr = identification.read_trace(p, check_plausible=False)
    assert tr.dt == pytest.approx(5.0)
    assert identification.read_trace(p, units={"t": "ms"}).dt == pytest.approx(0.005)


# ----------------------------------------------------------------------- structures
def test_structure_units_and_suffixes(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text(messy.toml(messy._mcmanus().replace("k_f = 550000", '"k_f_kN/m" = 550')
                            .replace("m_e = 122.6", "m_e_t = 0.1226"), 'units = "m"'))
    s = rockjax.RockingStructure.from_toml(p)
    assert float(s.k_f) == pytest.approx(550e3) and float(s.m_e) == pytest.approx(122.6)
    p.write_text(messy.toml(messy._mcmanus() + "B_mm = 285\n"))
    with pytest.raises(ValueError, match=r"B given twice \(B and B_mm\)"):
        rockjax.RockingStructure.from_toml(p)
    p.write_text(messy.toml(messy._mcmanus().replace("B =", "B_furlong =")))
    with pytest.raises(ValueError, match=r"B_furlong: unknown unit 'furlong' of length"):
        rockjax.RockingStructure.from_toml(p)
    p.write_text(messy.toml('units = "cm"\n' + messy._mcmanus(), 'units = "mm"'))
    with pytest.raises(ValueError, match=r"units 'mm' at the top of the file but 'cm'"):
        rockjax.RockingStructure.from_toml(p)
    p.write_text(messy.toml(messy._mcmanus(length=1e-3)))
    s = rockjax.RockingStructure.from_toml(p, check_plausible=False)
    assert float(s.B) == 285.0  # accepted as asked: SI, as written


# ---------------------------------------------------------------------- command line
def test_command_line_names_the_override(tmp_path, capsys):
    """The plausibility errors read in the command's terms (--no-plausibility-check),
    which every command that reads a file accepts."""
    from rockjax.cli import build_parser, main

    by_name = {c.name: c for c in messy.CASES}
    rec = by_name["rec_cm_s2_no_title_flag_m_s2.csv"].write(tmp_path)
    assert main(["simulate", "--record", str(rec), "--units", "m/s2"]) == 2
    err = capsys.readouterr().err
    assert "PGA 30 g is implausible" in err and err.rstrip().endswith(
        "; pass --no-plausibility-check")
    structure = by_name["st_mm_no_units.toml"].write(tmp_path)
    assert main(["pushover", "--structure", str(structure)]) == 2
    assert "B = 285 m is implausible" in capsys.readouterr().err
    parser = build_parser()
    for argv in (["simulate", "--u0", "0.01"], ["pushover"], ["fit", "x.csv"],
                 ["spectrum", "--pulse", "sine", "--periods", "1"],
                 ["sweep", "--record", "x.AT2"]):
        assert parser.parse_args(argv).check_plausible is True
        assert parser.parse_args([*argv, "--no-plausibility-check"]).check_plausible is False


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes); CI runs it
def test_time_tolerance_on_the_command_line(tmp_path):
    """`--time-tolerance` loosens the jitter a record's time column may have: refused by
    default naming the option, resampled (with its warning) when allowed."""
    from conftest import run_cli

    path = tmp_path / "jitter.csv"
    path.write_text(messy.jittered(5e-3))
    args = ("simulate", "--record", str(path), "--t1", "0.5", "--json")
    r = run_cli(*args, cwd=tmp_path)
    assert r.returncode == 2 and "--time-tolerance" in r.stderr
    r = run_cli(*args, "--time-tolerance", "0.02", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "ResampledWarning" in r.stderr or "resampled" in r.stderr
