"""Uncertainty carried into predictions (issue 25, item 4): `rockjax.read_draws`,
`rockjax.fragility_band`, `rockjax.spectrum_band` and `--draws` on the command line.

Two generated records of 6 s (`rockjax.datasets.synthetic_ground_motion`) at 12 scales on
rigid_body, three draws of k_f and r: every band of the module shares one compiled
program (three draws and the point estimate, the same records and scales), and so does
the command line's run. Draws that are all equal must give a band of zero width whose
curve is the point estimate's fit exactly; spreading the draws must widen it.
"""

from __future__ import annotations

import contextlib
import io
import json

import numpy as np
import pytest

import rockjax
from rockjax.cli import main

SCALES = np.round(np.geomspace(0.5, 8.0, 12), 3)
TAIL = 1.0


def spread_draws(column, spread):
    """Three draws: k_f times e^(-spread, 0, spread), r = 0.75 times its square root."""
    f = np.exp(spread * np.array([-1.0, 0.0, 1.0]))
    return {"k_f": float(column.k_f) * f, "r": np.clip(0.75 * np.sqrt(f), 0.0, 1.0)}


def write_draws(path, header, rows, units="# units: k_f N/m, r -"):
    path.write_text((units + "\n" if units else "") + header + "\n"
                    + "".join(",".join(str(v) for v in row) + "\n" for row in rows))
    return path


@pytest.fixture(scope="module")
def records():
    return [rockjax.datasets.synthetic_ground_motion(duration=6.0, dt=0.01, pga=3.0, seed=i)
            for i in range(2)]


@pytest.fixture(scope="module")
def bands(column, records):
    """Bands of equal draws (spread 0) and of draws spread by 0.1 and 0.4."""
    return {s: rockjax.fragility_band(column, records, SCALES, spread_draws(column, s),
                                      model="rigid_body", tail=TAIL)
            for s in (0.0, 0.1, 0.4)}


# ------------------------------------------------------------------------ fragility band
def test_equal_draws_give_the_point_estimate_with_zero_width(bands, column):
    """Equal draws (k_f of Table 1, r = 0.75): every draw's fit is the fit of the structure
    with that r, the band has zero width and every curve is that fit's, exactly."""
    b = bands[0.0]
    assert b.n_draws == 3 and b.counts["fit"] == 3
    assert np.all(b.medians == b.medians[0]) and np.all(b.betas == b.betas[0])
    np.testing.assert_array_equal(b.band[0], b.band[1])
    np.testing.assert_array_equal(b.median_curve, b.band[0])
    np.testing.assert_allclose(b.pooled, b.median_curve, rtol=1e-15, atol=0)  # (3x)/3
    assert b.median_ci[0] == b.median_ci[1] == b.medians[0]
    # the point estimate: the structure as given, r from Eq. 3 (not 0.75): its own fit,
    # computed by rockjax.fragility on its runs
    assert b.point is not None and b.point.n_bootstrap == 0
    assert b.status.shape == (3, 2, SCALES.size) and b.im_values.shape == (2, SCALES.size)
    at = b.at([0.5, 1.0, 2.0])
    np.testing.assert_array_equal(at["lower"], at["upper"])
    assert b.probability(1.0) == pytest.approx(float(at["pooled"][1]), abs=0)


def test_equal_draws_at_the_given_r_equal_the_point_fit(column, records):
    """Draws equal to the structure as given (Table 1's k_f and Eq. 3's r): the median
    curve and every draw's (θ, β) are the point estimate's fit, bit for bit."""
    r0 = float(column.restitution)
    b = rockjax.fragility_band(column, records, SCALES,
                               {"k_f": [float(column.k_f)] * 3, "r": [r0] * 3},
                               model="rigid_body", tail=TAIL)
    pt = b.point
    assert np.all(b.medians == pt.median) and np.all(b.betas == pt.beta)
    np.testing.assert_array_equal(b.median_curve, pt.probability(b.grid))
    np.testing.assert_array_equal(b.band[1] - b.band[0], 0.0)
    np.testing.assert_array_equal(b.status[0], b.point.status)


@pytest.mark.slow
def test_equal_draws_equal_rockjax_fragility_of_a_sweep(column, records):
    """The same against an independent `rockjax.sweep` + `rockjax.fragility` (records of
    one time step: the sweep's common grid is each record's own)."""
    r0 = float(column.restitution)
    b = rockjax.fragility_band(column, records, SCALES,
                               {"k_f": [float(column.k_f)] * 3, "r": [r0] * 3},
                               model="rigid_body", tail=TAIL)
    ref = rockjax.fragility(rockjax.sweep(column, records, SCALES, model="rigid_body",
                                          tail=TAIL, progress=False), n_bootstrap=0)
    assert np.all(b.medians == ref.median) and np.all(b.betas == ref.beta)
    np.testing.assert_array_equal(b.status[0], ref.status)


def test_band_widens_with_the_spread_of_the_draws(bands):
    width = {s: float(np.max(b.band[1] - b.band[0])) for s, b in bands.items()}
    assert width[0.0] == 0.0 < width[0.1] < width[0.4]
    b = bands[0.4]
    assert len(set(b.medians.tolist())) == 3  # three different fits
    assert np.all(b.band[0] <= b.median_curve) and np.all(b.median_curve <= b.band[1])
    np.testing.assert_allclose(b.pooled, b.curves.mean(axis=0), rtol=0, atol=1e-15)
    lo, hi = np.quantile(b.curves, [0.05, 0.95], axis=0)
    np.testing.assert_allclose(b.band, [lo, hi], rtol=0, atol=1e-15)
    # at() is exact at any IM, and agrees with the tabulated curves on the grid
    np.testing.assert_allclose(b.at(b.grid)["median"], b.median_curve, rtol=0, atol=1e-15)
    ims = b.im_at(0.5)
    assert ims["upper"] <= ims["median"] <= ims["lower"]


def test_summary_report_plot(bands, tmp_path):
    b = bands[0.4]
    d = json.loads(json.dumps(b.summary()))
    assert d["n_draws"] == 3 and d["units"]["k_f"] == "N/m" and d["units"]["median"] == "g"
    assert [p["name"] for p in d["draws"]] == ["k_f", "r"]
    assert len(d["curves"]["lower"]) == b.grid.size and d["point"]["median"] > 0
    assert set(d["im_at"]) == {"0.1", "0.5", "0.9"}
    text = b.report()
    for head in ("draws         3: k_f", "fits          fit 3", "median        ",
                 "point         median", "PGA at P=50%  median curve"):
        assert head in text, text
    ax = b.plot()
    ax.figure.savefig(tmp_path / "band.png")
    assert (tmp_path / "band.png").stat().st_size > 10_000


def test_bad_draws_name_the_problem(column, records):
    kf = float(column.k_f)
    cases = [({"k_f": [kf, kf], "kf": [1, 2]}, "'kf' is not a parameter"),
             ({"k_f": [kf, np.nan]}, "k_f of draw 1 is nan"),
             ({"k_f": [kf]}, "1 draw(s); a band needs at least 2"),
             ({"k_f": [kf, kf], "r": [0.5]}, "different numbers of draws"),
             ({"r": [0.5, 1.5]}, "r of draw 1 is 1.5"),
             ({"k_f": [kf, 1.0]}, "draw 1 (k_f = 1): k_f is too soft"),
             ({"c_f": [1.0, 2.0]}, "c_f (the 2-DOF body's dashpots) needs")]
    for draws, match in cases:
        with pytest.raises(rockjax.ParameterError, match=match.replace("(", r"\(")
                           .replace(")", r"\)")) as e:
            rockjax.fragility_band(column, records, SCALES, draws, model="rigid_body")
        assert e.value.param == "draws"


def test_a_posteriors_draws_dict_keeps_only_what_predicts():
    """`identification.Posterior.draws_dict()` holds the fit's nuisances beside k_f and r
    (t0, u0, the sensor zeros, a joint fit's u0[1]): they are left out, as `read_draws`
    leaves out their columns; an unknown name is still an error."""
    from rockjax._draws import check_draws

    kept = check_draws({"k_f": [6e5, 7e5], "r": [0.8, 0.7], "t0": [0.01, 0.02],
                        "u0[1]": [0.1, 0.1], "offset": [0.0, 1e-4]})
    assert sorted(kept) == ["k_f", "r"] and kept["k_f"][1] == 7e5
    with pytest.raises(rockjax.ParameterError, match="'t0' is not a parameter"):
        check_draws({"k_f": [6e5, 7e5], "t0": [0.01, 0.02]}, ignore=())


# ---------------------------------------------------------------------------- read_draws
def test_read_draws(tmp_path):
    p = write_draws(tmp_path / "d.csv", "k_f,r,u0,c_f",
                    [[5e5, 0.7, 0.01, 10.0], [6e5, 0.75, 0.02, 20.0]],
                    units="# units: k_f N/m, r -, u0 m, c_f N*s/m")
    d = rockjax.read_draws(p)
    assert list(d) == ["k_f", "r", "c_f"]  # u0, a fit's nuisance parameter, left out
    np.testing.assert_array_equal(d["k_f"], [5e5, 6e5])
    np.testing.assert_array_equal(d["c_f"], [10.0, 20.0])
    p = write_draws(tmp_path / "n.csv", "k_f,r", [[5e5, 0.7], [6e5, 0.75]], units=None)
    assert list(rockjax.read_draws(p)) == ["k_f", "r"]  # no units line: SI
    p = write_draws(tmp_path / "j.csv", "k_f,r,u0[0],t0[1],beta",
                    [[5e5, 0.7, 0, 0, 0.1], [6e5, 0.75, 0, 0, 0.2]],
                    units="# units: k_f N/m, r -, u0[0] m, t0[1] s, beta -")
    with pytest.raises(rockjax.ParameterError, match="column beta is not a parameter"):
        rockjax.read_draws(p)  # a joint fit's indexed nuisances are left out, beta is not
    assert list(rockjax.read_draws(p, ignore=("u0", "t0", "beta"))) == ["k_f", "r"]


@pytest.mark.parametrize("header, rows, units, match", [
    ("k_f,kf", [[1, 2], [3, 4]], "# units: k_f N/m, kf N/m", "column kf is not a parameter"),
    ("k_f,r", [[5e5, 0.7], [5e5, "nan"]], None, "line 3: column r is 'nan', not a finite"),
    ("k_f,r", [[5e5, 0.7], [5e5, ""]], None, "line 3: column r is '', not a finite"),
    ("k_f,r", [[5e5, 0.7]], None, "1 draw(s); a band needs at least 2"),
    ("k_f,r", [[5e5, 0.7], [5e5]], None, "line 3: 1 values for the 2 columns"),
    ("k_f,r", [[5e2, 0.7], [6e2, 0.7]], "# units: k_f kN/m, r -", "column k_f is in 'kN/m'"),
    ("k_f,r", [[5e5, 0.7], [6e5, 0.7]], "# units: k_f N/m", "no unit for column r"),
    ("u0", [[1], [2]], None, "no column to predict with"),
])
def test_read_draws_errors(tmp_path, header, rows, units, match):
    p = write_draws(tmp_path / "d.csv", header, rows, units=units)
    with pytest.raises(rockjax.ParameterError, match=match.replace("(", r"\(")
                       .replace(")", r"\)")):
        rockjax.read_draws(p)


# -------------------------------------------------------------------------- command line
def _main(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(argv)
        except SystemExit as e:
            rc = e.code
    return rc, out.getvalue(), err.getvalue()


def test_cli_fragility_draws_json(bands, records, column, tmp_path):
    """`rockjax fragility --draws --json` on the records written to files: the library's
    band (the same runs, reusing its compiled program)."""
    paths = []
    for i, rec in enumerate(records):
        a = np.asarray(rec.accel)
        paths.append(tmp_path / f"rec{i}.txt")
        np.savetxt(paths[-1], np.column_stack([np.arange(a.size) * 0.01, a]), fmt="%.17g")
    draws = spread_draws(column, 0.4)
    csv = write_draws(tmp_path / "draws.csv", "k_f,r", np.column_stack([draws["k_f"],
                                                                        draws["r"]]).tolist())
    base = ["fragility", *(x for p in paths for x in ("--record", f"{p}:m/s2")), "--scales",
            ",".join(repr(float(s)) for s in SCALES), "--model", "rigid_body", "--tail", "1"]
    png = tmp_path / "band.png"
    rc, out, err = _main(base + ["--draws", str(csv), "--json", "--plot", str(png),
                                 "--confidence", "0.8"])
    assert rc == 0, err
    d = json.loads(out)["fragility_band"]
    ref = bands[0.4]
    assert d["n_draws"] == 3 and d["confidence"] == 0.8
    np.testing.assert_allclose(d["per_draw"]["median"], ref.medians, rtol=1e-12)
    np.testing.assert_allclose(d["per_draw"]["beta"], ref.betas, rtol=1e-12)
    assert d["point"]["median"] == pytest.approx(ref.point.median, rel=1e-12)
    assert png.stat().st_size > 10_000
    rc, text, err = _main(base + ["--draws", str(csv)])
    assert rc == 0, err
    assert "median curve" in text and "pooled" in text and "draws         3: k_f" in text
    bad = write_draws(tmp_path / "bad.csv", "k_f,x", [[5e5, 1], [6e5, 2]], units=None)
    for args, match in [(["--draws", str(bad)], "--draws: "),
                        (["--draws", str(tmp_path / "none.csv")], "--draws: draws file not "),
                        (["--draws-ignore", "u0"], "--draws-ignore: applies to --draws")]:
        rc, out, err = _main(base + args)
        assert rc == 2 and err.startswith(f"rockjax fragility: error: {match}"), err
        assert len(err.strip().splitlines()) == 1


# ------------------------------------------------------------------------ spectrum band
@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_spectrum_band_of_equal_draws_is_the_spectrum(column, tmp_path):
    """Identical draws of k_f: every draw's threshold is `rockjax.overturning_spectrum`'s,
    bit for bit, and so are the median and band; `--draws` on the command line too."""
    kw = dict(n_scan=8, amplitude_rtol=0.02)
    sp = rockjax.overturning_spectrum(column, "sine", [0.5], **kw)
    b = rockjax.spectrum_band(column, "sine", [0.5], {"k_f": [float(column.k_f)] * 3}, **kw)
    np.testing.assert_array_equal(b.amplitudes, np.broadcast_to(sp.amplitude, (3, 1)))
    np.testing.assert_array_equal(b.median, sp.amplitude)
    np.testing.assert_array_equal(b.band, [sp.amplitude, sp.amplitude])
    np.testing.assert_array_equal(b.point.amplitude, sp.amplitude)
    assert b.n_none.tolist() == [0] and "0.5" in b.report()
    assert json.loads(json.dumps(b.summary()))["units"]["amplitude"] == "m/s2"
    b.plot().figure.savefig(tmp_path / "sb.png")


@pytest.mark.slow
def test_spectrum_band_widens_with_the_spread(column, tmp_path):
    kw = dict(n_scan=8, amplitude_rtol=0.01)
    narrow = rockjax.spectrum_band(column, "sine", [0.4, 1.0], spread_draws(column, 0.05), **kw)
    wide = rockjax.spectrum_band(column, "sine", [0.4, 1.0], spread_draws(column, 0.5), **kw)
    w = lambda b: b.band[1] - b.band[0]  # noqa: E731
    assert np.all(w(wide) > w(narrow)) and np.all(w(narrow) >= 0)
    csv = write_draws(tmp_path / "d.csv", "k_f,r", [[4e5, 0.7], [7e5, 0.75], [5.5e5, 0.72]])
    rc, out, err = _main(["spectrum", "--pulse", "sine", "--periods", "0.4,1", "--rtol", "0.01",
                          "--draws", str(csv), "--json"])
    assert rc == 0, err
    d = json.loads(out)["spectrum_band"]
    assert d["n_draws"] == 3 and all(lo <= hi for lo, hi in zip(d["lower"], d["upper"]))


@pytest.mark.slow
def test_dashpot_draws_run_one_draw_at_a_time(column, records):
    """c_f, a field of the 2-DOF body (not of the structure): draws of c_f = 0 are the
    undamped body's fit; draws of c_f and k_f together run and spread; the spectrum too."""
    kw = dict(model="two_spring_2dof", tail=TAIL)
    zero = rockjax.fragility_band(column, records, SCALES, {"c_f": [0.0, 0.0]}, **kw)
    assert np.all(zero.medians == zero.point.median) and np.all(zero.betas == zero.point.beta)
    b = rockjax.fragility_band(column, records, SCALES,
                               {"c_f": [200.0, 5000.0], "k_f": [4e5, 7e5]}, **kw)
    assert b.counts["fit"] == 2 and b.medians[0] != b.medians[1]
    assert b.units == {"c_f": "N s/m", "k_f": "N/m"}
    sb = rockjax.spectrum_band(column, "sine", [0.5], {"c_f": [200.0, 5000.0]},
                               model="two_spring_2dof", n_scan=8, amplitude_rtol=0.05)
    assert sb.amplitudes.shape == (2, 1) and np.all(np.isfinite(sb.amplitudes))
