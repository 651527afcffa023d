"""Fragility curves (issue 16, item 4): `rockjax.sweep`, `rockjax.fragility`, `rockjax fragility`.

The maximum-likelihood fit is checked against a brute-force maximisation of the same
likelihood written here (a dense grid, then Nelder-Mead from its best point, with scipy's
`log_ndtr`), on simulated sweeps and on Bernoulli data drawn from a known curve. The
simulated sweep runs four generated records (`rockjax.datasets.synthetic_ground_motion`)
on the rigid_body model with a bound on impacts that makes some runs fail, so that the
failed-run rule is exercised on real failures. One test runs the command line on three
shared real records (on three synthetic AT2 files where the shared folder is absent).
"""

from __future__ import annotations

import contextlib
import io
import json
import pathlib
import warnings

import numpy as np
import pytest
import scipy.optimize
import scipy.special

import rockjax
from rockjax.cli import main

G = rockjax.G_STANDARD
SCALES = np.geomspace(0.3, 4.0, 16)
MAX_IMPACTS = 40  # some of the strong runs of the generated records rock past it


# ---------------------------------------------------------------------------- helpers
def brute_force_mle(x, y):
    """(median, beta) maximising sum y ln Phi(z) + (1-y) ln Phi(-z), z = ln(x/theta)/beta,
    by a 121 x 121 grid over (ln theta, ln beta) and Nelder-Mead from its best point."""
    lx, y = np.log(np.asarray(x, float)), np.asarray(y, bool)

    def nll(p):
        z = (lx - p[0]) / np.exp(p[1])
        return -np.sum(np.where(y, scipy.special.log_ndtr(z), scipy.special.log_ndtr(-z)))

    T, B = np.meshgrid(np.linspace(lx.min() - 1, lx.max() + 1, 121),
                       np.linspace(np.log(0.01), np.log(5.0), 121), indexing="ij")
    Z = (lx[None, None, :] - T[..., None]) / np.exp(B)[..., None]
    L = np.where(y, scipy.special.log_ndtr(Z), scipy.special.log_ndtr(-Z)).sum(-1)
    i, j = np.unravel_index(np.argmax(L), L.shape)
    best = scipy.optimize.minimize(nll, [T[i, j], B[i, j]], method="Nelder-Mead",
                                   options={"xatol": 1e-10, "fatol": 1e-12, "maxiter": 5000})
    assert best.success
    return float(np.exp(best.x[0])), float(np.exp(best.x[1])), -float(best.fun)


def records_of_pga(pgas_g):
    """Two-sample records whose PGA is pgas_g [g]: the IM of each run is its scale times it."""
    return [rockjax.Record(dt=0.01, accel=[0.0, p * G]) for p in pgas_g]


def bernoulli_sweep(n_records, scales, theta, beta, seed, status_of=None):
    """A SweepResult of Bernoulli outcomes at PGA = pga_r * scale, P = Phi(ln(PGA/theta)/beta),
    over records of PGA 0.5-2 g (no simulation: completed or overturned)."""
    rng = np.random.default_rng(seed)
    pgas = rng.uniform(0.5, 2.0, n_records)
    x = pgas[:, None] * np.asarray(scales)[None, :]
    p = 0.5 * scipy.special.erfc(-np.log(x / theta) / beta / np.sqrt(2))
    over = rng.random(x.shape) < p
    z = np.zeros(x.shape)
    return rockjax.SweepResult(
        structure=rockjax.mcmanus_column(), records=records_of_pga(pgas),
        labels=[f"r{i}" for i in range(n_records)], scales=scales, peak_u=z, peak_uplift=z,
        n_impacts=z, status=over.astype(int) if status_of is None else status_of(over),
        t_overturn=z, t_end=z)


@pytest.fixture(scope="module")
def records():
    """Four generated records of 8 s, PGA 2.0, 2.6, 3.2 and 3.8 m/s²."""
    return [rockjax.datasets.synthetic_ground_motion(duration=8.0, dt=0.01, pga=2.0 + 0.6 * s,
                                                     seed=s) for s in range(4)]


@pytest.fixture(scope="module")
def simulated(column, records):
    """4 generated records x 16 scales on rigid_body, each to its end + 2 s, at most 40
    impacts: completed, overturned and max_impacts runs."""
    return rockjax.sweep(column, records, SCALES, model="rigid_body", tail=2.0,
                         max_impacts=MAX_IMPACTS, progress=False)


@pytest.fixture(scope="module")
def fit_pga(simulated):
    return rockjax.fragility(simulated, "PGA", n_bootstrap=300)


# ------------------------------------------------------------------------------ sweep
def test_sweep_is_simulate_batch_per_record_and_scale(simulated, column, records):
    """rockjax.sweep holds simulate_batch's summaries at [record, scale]."""
    s = simulated
    assert s.peak_u.shape == (4, 16) and s.labels == tuple(f"synthetic (seed {i})" for i in
                                                           range(4))
    rec, sc = (a.ravel() for a in np.meshgrid(np.arange(4), np.arange(16), indexing="ij"))
    out = rockjax.simulate_batch(column, records, tail=2.0, scale=SCALES[sc], record=rec,
                                 model="rigid_body", max_impacts=MAX_IMPACTS,
                                 summary_only=True)
    for field in ("peak_u", "peak_uplift", "n_impacts", "status", "t_end"):
        np.testing.assert_allclose(getattr(s, field)[rec, sc], np.asarray(getattr(out, field)),
                                   rtol=0, err_msg=field)
    counts = s.status_counts()
    assert counts["completed"] and counts["overturned"] and counts["max_impacts"]
    assert sum(counts.values()) == 64
    assert s.model == "rigid_body" and s.options["max_impacts"] == MAX_IMPACTS


def test_sweep_csv_plot_and_process_blocks(simulated, tmp_path):
    """`SweepResult.to_csv` writes the rows of `rockjax sweep --out` (scale-major, then
    record; statuses as names), `plot()` the two panels; `Processes.block` splits n runs
    into contiguous blocks that differ by at most one and cover every run once."""
    import csv

    path = tmp_path / "sweep.csv"
    simulated.to_csv(path, label="column")
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == simulated.n_runs and rows[0]["structure"] == "column"
    assert [r["record"] for r in rows[:4]] == list(simulated.labels)
    assert [float(r["scale"]) for r in rows[::4]] == simulated.scales.tolist()
    assert [float(r["peak_u_m"]) for r in rows[4:8]] == simulated.peak_u[:, 1].tolist()
    assert [r["status"] for r in rows[:4]] == simulated.status_names()[:, 0].tolist()
    assert rows[0]["model"] == "rigid_body" and rows[0]["impact"] == "landings"
    assert rows[0]["r"] == "Eq 3" and rows[0]["method"] == "rk4"
    fig = simulated.plot(title="t")
    assert len(fig.axes) == 2 and fig.axes[0].get_title() == "t"
    for n, count in ((12, 2), (7, 3), (2, 3)):
        blocks = [rockjax.Processes(i, count).block(n) for i in range(count)]
        assert blocks[0][0] == 0 and blocks[-1][1] == n
        assert all(a[1] == b[0] for a, b in zip(blocks, blocks[1:]))
        assert max(hi - lo for lo, hi in blocks) - min(hi - lo for lo, hi in blocks) <= 1


def test_sweep_fraction_leaves_failed_runs_out(simulated):
    st = simulated.status
    over, usable = (st == 1).sum(0), np.isin(st, (0, 1)).sum(0)
    want = np.where(usable > 0, over / np.maximum(usable, 1), np.nan)
    np.testing.assert_array_equal(simulated.fraction_overturned(), want)
    np.testing.assert_array_equal(simulated.failed_by_scale(), (st >= 2).sum(0))
    # the old rule (failed runs as survivors) differs wherever a scale has a failure
    assert np.any((over / 4 != want) & (usable > 0))


# -------------------------------------------------------------------------------- fit
@pytest.mark.parametrize("im", ["PGA", "Sa(0.5)", "scale"])
def test_mle_matches_brute_force(simulated, im):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # not separated: a finite-beta maximum
        f = rockjax.fragility(simulated, im, n_bootstrap=0)
    u = f.used
    med, beta, ll = brute_force_mle(f.im_values[u], f.exceeded[u])
    assert f.median == pytest.approx(med, rel=1e-3)
    assert f.beta == pytest.approx(beta, rel=1e-3)
    assert f.log_likelihood == pytest.approx(ll, abs=1e-6)
    assert not f.separated and f.band is None and f.resampled == "none"


def test_mle_matches_brute_force_on_bernoulli_data():
    s = bernoulli_sweep(12, np.geomspace(0.05, 1.5, 20), theta=0.35, beta=0.5, seed=3)
    f = rockjax.fragility(s, n_bootstrap=0)
    med, beta, _ = brute_force_mle(f.im_values.ravel(), f.exceeded.ravel())
    assert f.median == pytest.approx(med, rel=1e-3) and f.beta == pytest.approx(beta, rel=1e-3)


def test_recovers_known_median_and_beta():
    """10,000 Bernoulli trials from theta = 0.4 g, beta = 0.35: the standard errors are
    about 0.6 % on theta and 3 % on beta."""
    s = bernoulli_sweep(250, np.geomspace(0.05, 1.5, 40), theta=0.4, beta=0.35, seed=11)
    f = rockjax.fragility(s, n_bootstrap=100)
    assert f.median == pytest.approx(0.4, rel=0.03)
    assert f.beta == pytest.approx(0.35, rel=0.12)
    assert f.median_ci[0] < f.median < f.median_ci[1]
    assert f.beta_ci[0] < f.beta < f.beta_ci[1]


def test_failed_runs_left_out_and_counted(simulated, fit_pga):
    f, st = fit_pga, simulated.status
    assert f.n_failed == {"max_impacts": int((st == 2).sum()), "solver_failure": 0}
    assert f.n_failed["max_impacts"] > 0
    np.testing.assert_array_equal(f.used, np.isin(st, (0, 1)))
    assert f.n_used + f.n_failed["max_impacts"] == f.n_runs == 64
    assert f.n_exceeded == int((st == 1).sum())
    # the fit is that of the runs used alone: counting the failures as survivors moves it
    as_survivors = rockjax.fragility(
        rockjax.SweepResult(**{**vars(simulated), "status": np.where(st >= 2, 0, st)}),
        n_bootstrap=0)
    assert as_survivors.n_used == 64 and as_survivors.median > f.median
    d = f.to_dict()
    assert d["n_failed"]["max_impacts"] == f.n_failed["max_impacts"]
    assert sum(row.count("max_impacts") for row in d["status"]) == f.n_failed["max_impacts"]


def test_im_values_are_the_scaled_record_ims(simulated, records):
    for im, one in [("PGA", lambda r: rockjax.pga(r) / G), ("PGV", rockjax.pgv),
                    ("Sa(0.5)", lambda r: float(rockjax.spectral_acceleration(r, 0.5)) / G)]:
        f = rockjax.fragility(simulated, im, n_bootstrap=0)
        want = np.array([one(r) for r in records])[:, None] * SCALES
        np.testing.assert_allclose(f.im_values, want, rtol=1e-12, err_msg=im)
    f = rockjax.fragility(simulated, "Sa(0.5)", n_bootstrap=0)
    assert (f.im, f.im_unit) == ("Sa(0.5 s)", "g")
    f = rockjax.fragility(simulated, "pgv", n_bootstrap=0)
    assert (f.im, f.im_unit) == ("PGV", "m/s")


def test_uplift_and_rotation_limits(simulated, column, fit_pga):
    over = simulated.status == 1
    f = rockjax.fragility(simulated, limit=("uplift", 0.01), n_bootstrap=0)
    np.testing.assert_array_equal(f.exceeded, over | (simulated.peak_uplift >= 0.01))
    assert f.limit == "uplift >= 0.01 m" and f.n_exceeded > fit_pga.n_exceeded
    assert f.median < fit_pga.median
    theta = np.asarray(rockjax.theta_from_u(column, simulated.peak_u))
    g = rockjax.fragility(simulated, limit="rotation=0.03", n_bootstrap=0)
    np.testing.assert_array_equal(g.exceeded, over | (theta >= 0.03))
    assert g.limit == "rotation >= 0.03 rad"
    assert over.sum() < g.n_exceeded < g.n_used
    lower = rockjax.fragility(simulated, limit=("rotation", 0.02), n_bootstrap=0)
    assert lower.median < g.median  # a lower threshold is reached at a lower IM
    assert np.all(g.exceeded[over]) and np.all(f.exceeded[over])


def test_bootstrap_band_contains_the_curve_and_narrows():
    scales = np.geomspace(0.05, 1.5, 25)
    few = rockjax.fragility(bernoulli_sweep(8, scales, 0.4, 0.4, seed=5), n_bootstrap=400)
    many = rockjax.fragility(bernoulli_sweep(64, scales, 0.4, 0.4, seed=5), n_bootstrap=400,
                             grid=few.grid)
    for f in (few, many):
        p = f.probability(f.grid)
        assert np.all(f.band[0] <= p + 1e-9) and np.all(p <= f.band[1] + 1e-9)
        assert f.median_ci[0] < f.median < f.median_ci[1]
        assert f.resampled == "records" and sum(f.bootstrap_counts.values()) == 400
    width = lambda f: np.mean(f.band[1] - f.band[0])  # noqa: E731
    assert width(many) < 0.6 * width(few)
    ci = lambda c: np.log(c[1] / c[0])  # noqa: E731
    assert ci(many.median_ci) < 0.6 * ci(few.median_ci)
    same = rockjax.fragility(bernoulli_sweep(8, scales, 0.4, 0.4, seed=5), n_bootstrap=400)
    np.testing.assert_array_equal(same.band, few.band)  # seeded


def test_probability_to_dict_and_plot(fit_pga, tmp_path):
    f = fit_pga
    assert f.probability(f.median) == pytest.approx(0.5, abs=1e-12)
    assert f.probability(0.0) == 0.0
    p = f.probability([0.5 * f.median, f.median, 2 * f.median])
    assert p.shape == (3,) and p[0] < 0.5 < p[2]
    with pytest.raises(ValueError, match="im must be finite"):
        f.probability(-1.0)
    d = json.loads(json.dumps(f.to_dict(), allow_nan=False))
    assert d["median"] == f.median and d["im_unit"] == "g" and len(d["band"]["im"]) == 200
    assert d["bootstrap_counts"]["fit"] + d["bootstrap_counts"]["separated"] > 0
    ax = f.plot()
    ax.figure.savefig(tmp_path / "f.png")
    assert (tmp_path / "f.png").stat().st_size > 10_000
    assert "90% bootstrap band" in ax.get_legend().get_texts()[0].get_text()


# ------------------------------------------------------------------------ degenerate
def test_separated_data_give_beta_zero_with_a_warning():
    s = bernoulli_sweep(3, [0.1, 0.2, 0.4, 0.8], theta=1.0, beta=1.0, seed=0,
                        status_of=lambda over: np.tile([0, 0, 1, 1], (3, 1)))
    s = rockjax.SweepResult(**{**vars(s), "records": records_of_pga([1.0, 1.0, 1.0])})
    with pytest.warns(RuntimeWarning, match="separated by PGA"):
        f = rockjax.fragility(s, n_bootstrap=50)
    assert f.separated and f.beta == 0.0
    assert f.median == pytest.approx(np.sqrt(0.2 * 0.4), rel=1e-12)
    np.testing.assert_array_equal(f.probability([0.19, f.median, 0.41]), [0.0, 0.5, 1.0])
    assert f.bootstrap_counts["separated"] == 50 and f.log_likelihood == 0.0
    assert json.dumps(f.to_dict(), allow_nan=False)


@pytest.mark.parametrize("status, match", [
    (0, "no run reached the limit"), (1, "every one of the 8 runs used reached"),
    (2, "no run completed or overturned"),
])
def test_degenerate_data_raise(status, match):
    s = bernoulli_sweep(2, [0.5, 1.0, 2.0, 4.0], 1.0, 1.0, seed=0,
                        status_of=lambda over: np.full(over.shape, status))
    with pytest.raises(ValueError, match=match):
        rockjax.fragility(s)


# ------------------------------------------------------------------------- bad inputs
@pytest.mark.parametrize("kwargs, error, match", [
    ({"im": "PGX"}, ValueError, "im must be"), ({"im": "Sa(0)"}, ValueError, "im must be"),
    ({"im": "Sa(-1)"}, ValueError, "im must be"), ({"im": 1.0}, ValueError, "im must be"),
    ({"limit": "collapse"}, ValueError, "limit must be"),
    ({"limit": ("drift", 0.1)}, ValueError, "limit must be"),
    ({"limit": ("uplift", -0.01)}, ValueError, "limit: the uplift threshold must be positive"),
    ({"limit": "rotation=abc"}, ValueError, "limit: the rotation threshold must be a number"),
    ({"n_bootstrap": -1}, ValueError, "n_bootstrap"), ({"n_bootstrap": 2.5}, ValueError,
                                                       "n_bootstrap"),
    ({"n_bootstrap": True}, ValueError, "n_bootstrap"),
    ({"confidence": 1.0}, ValueError, "confidence"), ({"confidence": 0}, ValueError,
                                                      "confidence"),
    ({"seed": "a"}, ValueError, "seed"), ({"grid": [1.0]}, ValueError, "grid"),
    ({"grid": [0.0, 1.0]}, ValueError, "grid"),
])
def test_bad_fragility_inputs_name_the_parameter(kwargs, error, match):
    s = bernoulli_sweep(3, [0.2, 0.5, 1.0, 2.0], 0.5, 0.5, seed=1)
    with pytest.raises(error, match=match):
        rockjax.fragility(s, **kwargs)


def test_bad_sweep_inputs_name_the_parameter(column, tmp_path):
    rec = records_of_pga([1.0])
    with pytest.raises(TypeError, match="sweep_result must be a rockjax.SweepResult"):
        rockjax.fragility({"status": []})
    with pytest.raises(ValueError, match="scales must be"):
        rockjax.sweep(column, rec, [])
    with pytest.raises(ValueError, match="scales must be"):
        rockjax.sweep(column, rec, [1.0, -2.0])
    with pytest.raises(ValueError, match="records: the sequence is empty"):
        rockjax.sweep(column, [], [1.0])
    with pytest.raises(TypeError, match="records: item 0 is a float"):
        rockjax.sweep(column, [1.0], [1.0])
    with pytest.raises(TypeError, match="sweep sets scale itself"):
        rockjax.sweep(column, rec, [1.0], scale=2.0)
    with pytest.raises(ValueError, match="structure: one structure"):
        rockjax.sweep(column.replace(k_f=np.array([1e6, 2e6])), rec, [1.0])
    with pytest.raises(ValueError, match="labels: 2 labels for 1 records"):
        rockjax.sweep(column, rec, [1.0], labels=["a", "b"])
    with pytest.raises(ValueError, match="peak_u must have shape"):
        rockjax.SweepResult(structure=column, records=rec, labels=["a"], scales=[1.0, 2.0],
                            peak_u=np.zeros(2), peak_uplift=np.zeros((1, 2)),
                            n_impacts=np.zeros((1, 2)), status=np.zeros((1, 2)),
                            t_overturn=np.zeros((1, 2)), t_end=np.zeros((1, 2)))
    zero = rockjax.SweepResult(**{**vars(bernoulli_sweep(2, [1.0, 2.0], 1.0, 1.0, 0)),
                                  "records": [rockjax.Record(dt=0.01, accel=[0.0, 0.0])] * 2})
    with pytest.raises(ValueError, match="im: PGA is zero for record"):
        rockjax.fragility(zero)


# ------------------------------------------------------------------------ command line
def _main(argv):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(argv)
        except SystemExit as e:  # argparse: --help, usage errors
            rc = e.code
    return rc, out.getvalue(), err.getvalue()


@pytest.fixture(scope="module")
def cli_records(tmp_path_factory):
    """Three real records from the shared folder; without it (a fresh clone), three
    synthetic AT2 files in g, so that the CLI is checked either way."""
    from conftest import shared_ground_motions
    from test_records import synthetic, write_at2

    names = ["IELC180.AT2", "RSN1106_KOBE_KJM000.AT2", "RSN753_LOMAP_CLS000.AT2"]
    d = shared_ground_motions()
    if all((d / n).is_file() for n in names):
        return [str(d / n) for n in names]
    tmp = tmp_path_factory.mktemp("fragility_records")
    return [str(write_at2(tmp / f"synthetic{i}.AT2",
                          synthetic(seed=i, dt=0.01, duration=12.0, pga=3.07)))
            for i in range(3)]


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_cli_json_plot_text_on_real_records(cli_records, tmp_path, column):
    """`rockjax fragility` on three real records (synthetic ones in a fresh clone): --json
    and --plot, the same fit as rockjax.sweep + rockjax.fragility in Python, the text
    report, and a sweep too weak to overturn anything refused in one line."""
    paths = cli_records
    base = ["fragility", *(a for p in paths for a in ("--record", p)), "--model", "rigid_body",
            "--t1", "12", "--bootstrap", "200"]
    png = tmp_path / "fragility.png"
    rc, out, err = _main(base + ["--scales", "0.3:4:10", "--json", "--plot", str(png)])
    assert rc == 0, err
    d = json.loads(out)
    f, sw = d["fragility"], d["sweep"]
    assert (f["im"], f["im_unit"], f["limit"], f["model"]) == ("PGA", "g", "overturned",
                                                               "rigid_body")
    assert sw["n_runs"] == 30 and sum(sw["status_counts"].values()) == 30
    assert f["n_used"] + sum(f["n_failed"].values()) == 30 and 0 < f["n_exceeded"] < 30
    assert f["median_ci"][0] < f["median"] < f["median_ci"][1] and f["beta"] > 0
    assert sw["records"] == [pathlib.Path(p).stem for p in paths]
    assert png.stat().st_size > 10_000 and d["plot"] == str(png)
    assert "rk4 batch" not in err  # no progress bar with --json
    ref = rockjax.fragility(
        rockjax.sweep(column, paths, sw["scales"], model="rigid_body", t1=12.0,
                      substeps=4, fidelity_warning=False), n_bootstrap=200)
    assert f["median"] == pytest.approx(ref.median, rel=1e-12)
    assert f["beta"] == pytest.approx(ref.beta, rel=1e-12)
    np.testing.assert_allclose(f["band"]["lower"], ref.band[0], atol=1e-12)
    rc, text, err = _main(base + ["--scales", "0.3:4:10", "--im", "Sa(1.0)"])
    assert rc == 0, err
    assert "fit           P(overturned | Sa(1 s)) = Phi(ln(Sa(1 s)/median)/beta)" in text
    assert "over the 30 runs that completed or overturned" in text and "no failed runs" in text
    assert "median        " in text and "90% interval" in text and "beta          " in text
    assert "bootstrap     200 resamples of the records (seed 0)" in text
    rc, out, err = _main(base + ["--scales", "0.001:0.002:10"])
    assert rc == 2 and not out
    assert err.startswith(
        "rockjax fragility: error: --scales: no run reached the limit (overturned)")
    assert "raise the scales" in err
    assert len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("args, match", [
    (["--im", "PGX"], "argument --im: im must be 'PGA'"),
    (["--limit", "uplift=-1"], "--limit must be overturned, uplift=METRES"),
    (["--limit", "drift"], "--limit must be overturned"),
    (["--bootstrap", "-3"], "--bootstrap must be >= 0"),
    (["--confidence", "1.5"], "--confidence must lie in"),
    (["--structure", "a.toml", "--structure", "b.toml"], "--structure: one structure"),
    (["--plot", "x.txt"], "--plot must end in"),
    (["--scales", "0"], "scale factors must be positive"),
])
def test_cli_errors_one_line(args, match, tmp_path):
    rec = tmp_path / "r.txt"
    rec.write_text("0 0\n0.01 0.1\n")
    rc, out, err = _main(["fragility", "--record", f"{rec}:g", "--scales", "1,2", *args])
    assert rc == 2 and match in err and len(err.strip().splitlines()) == 1


def test_cli_help():
    rc, out, _ = _main(["fragility", "--help"])
    assert rc == 0
    for flag in ("--record", "--scales", "--im", "--limit", "--bootstrap", "--plot", "--json",
                 "--model", "Sa(T)"):
        assert flag in out
    rc, out, _ = _main(["--help"])
    assert "fragility" in out
    rc, _, err = _main(["fragility", "--record", "x.AT2"])
    assert rc == 2 and "the following arguments are required: --scales" in err


def test_report(fit_pga):
    """`FragilityResult.report` (the text of `rockjax fragility`): the fit, the median and
    beta with their intervals, the IM at P = 10, 50, 90 % and the resamples."""
    f, lines = fit_pga, fit_pga.report().splitlines()
    assert lines[0].startswith(f"fit           P(overturned | PGA) = Phi(ln(PGA/median)/beta), "
                               f"maximum likelihood over the {f.n_used} runs")
    assert f"({f.n_exceeded} reached the limit); " in lines[0]
    n_failed = sum(f.n_failed.values())
    assert n_failed > 0 and lines[0].endswith(
        f"{n_failed} failed runs left out (max_impacts {f.n_failed['max_impacts']})")
    lo, hi = f.median_ci
    assert lines[1] == f"median        {f.median:.4g} g  (90% interval {lo:.4g} to {hi:.4g} g)"
    assert lines[2].startswith(f"beta          {f.beta:.4g}  (90% interval ")
    q = [f.median * np.exp(f.beta * z) for z in (-1.2815515655446004, 0, 1.2815515655446004)]
    np.testing.assert_allclose(f.probability(np.array(q)), [0.1, 0.5, 0.9], rtol=1e-9)
    assert lines[3] == ("quantiles     PGA at P = 10, 50, 90 %: "
                        + ", ".join(f"{x:.4g}" for x in q) + " g")
    assert lines[4].startswith("bootstrap     300 resamples of the records (seed 0): fit ")
