"""Posteriors by NUTS (`identification.sample_posterior`, issue 25 item 3).

Default suite: the diagnostics against known cases, and the sampler on a toy problem (one
compiled program, shared by the tests): a Gaussian it must reproduce, and the same
problem's far second mode, whose chains disagree and must be flagged loudly. The decay-fit
posteriors (Laplace agreement on a well-posed trace, a bimodal k_f) are slow.
"""

from __future__ import annotations

import dataclasses
import json
import math
import warnings

import jax.numpy as jnp
import numpy as np
import pytest

import identification
from identification._posterior import diagnostics, ess_threshold

MU = np.array([1.0, -2.0])
COV = np.array([[1.0, 0.8], [0.8, 2.0]])
PREC = np.linalg.inv(COV)
FAR = 40.0  # the second mode's shift in a (40 sd): no chain crosses


def _toy_log_likelihood(z):
    """A Gaussian (MU, COV) and a far second mode of equal height at a + FAR."""
    d1 = z - jnp.asarray(MU)
    d2 = d1 - jnp.asarray([FAR, 0.0])
    q1, q2 = d1 @ PREC @ d1, d2 @ PREC @ d2
    return jnp.logaddexp(-0.5 * q1, -0.5 * q2)


def _toy_problem():
    P = identification.Prior
    return identification.PosteriorProblem(
        names=("a", "b"), log_likelihood=_toy_log_likelihood,
        to_physical=lambda z: {"a": z[0], "b": z[1]}, z0=MU, cov0=COV,
        priors={"a": P.flat(), "b": P.flat()}, units={"a": "m", "b": "-"}, source="toy")


TOY = _toy_problem()
CHAINS, DRAWS, WARMUP = 4, 250, 100


@pytest.fixture(scope="module")
def toy_posterior():
    """The Gaussian mode: chains started around it (the default start) stay in it."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", identification.PosteriorWarning)
        return identification.sample_posterior(TOY, chains=CHAINS, draws=DRAWS,
                                               warmup=WARMUP, seed=1)


# ------------------------------------------------------------------- diagnostics


def test_diagnostics_known_cases():
    rng = np.random.default_rng(0)
    iid = rng.standard_normal((4, 1000))
    rhat, ess = diagnostics(iid)
    assert rhat < 1.01 and 0.8 * 4000 < ess < 1.25 * 4000
    # AR(1), rho = 0.5: ESS = N (1 - rho) / (1 + rho) = N / 3
    rho, x = 0.5, np.zeros((4, 1000))  # the shape of iid: one compile of each diagnostic
    e = rng.standard_normal(x.shape)
    for t in range(1, x.shape[1]):
        x[:, t] = rho * x[:, t - 1] + math.sqrt(1 - rho**2) * e[:, t]
    rhat, ess = diagnostics(x)
    assert rhat < 1.01 and abs(ess / (x.size / 3) - 1) < 0.25
    # chains that disagree (one shifted by 1 sd)
    shifted = iid + np.array([[0.0], [0.0], [0.0], [1.0]])
    assert diagnostics(shifted)[0] > 1.05
    assert ess_threshold(4, 1000) == 400 and ess_threshold(2, 100) == 20


# ------------------------------------------------------------------ the sampler


def test_toy_gaussian_reproduced(toy_posterior):
    post = toy_posterior
    assert post.ok and not post.problems and post.divergences == 0
    a, b = post.draws["a"], post.draws["b"]
    assert a.shape == (CHAINS * DRAWS,)
    se_mean = np.sqrt(np.diag(COV) / min(post.ess.values()))
    assert abs(a.mean() - MU[0]) < 4 * se_mean[0] and abs(b.mean() - MU[1]) < 4 * se_mean[1]
    cov = np.cov(np.stack([a, b]))
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), np.sqrt(np.diag(COV)), rtol=0.15)
    assert abs(cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1]) - 0.8 / math.sqrt(2)) < 0.08
    lo, hi = post.interval("a", 0.9)
    assert lo < MU[0] < hi and abs((hi - lo) / (2 * 1.645) - 1.0) < 0.15
    assert max(post.rhat.values()) <= 1.01


def test_outputs(toy_posterior, tmp_path):
    post = toy_posterior
    s = post.summary()
    json.dumps(s)
    assert s["ok"] is True and set(s["parameters"]) == {"a", "b"}
    pa = s["parameters"]["a"]
    assert pa["q05"] < pa["q50"] < pa["q95"] and pa["laplace_value"] == MU[0]
    assert pa["laplace_se"] == pytest.approx(1.0)
    rep = post.report()
    assert rep.startswith("posterior") and "WARNING" not in rep and "R-hat" in rep
    d = post.draws_dict(100)
    assert set(d) == {"a", "b"} and d["a"].shape == (100,)
    assert post.draws_dict()["a"].shape == (CHAINS * DRAWS,)
    assert post.draws_dict(5000, seed=2)["b"].shape == (5000,)
    path = tmp_path / "draws.csv"
    post.to_csv(path)
    lines = path.read_text().splitlines()
    assert lines[0] == "# units: a m, b -" and lines[1] == "a,b"
    back = np.loadtxt(path, delimiter=",", skiprows=2)
    np.testing.assert_allclose(back[:, 0], post.draws["a"])
    import matplotlib

    matplotlib.use("Agg")
    fig = post.plot(pair=("a", "b"))
    assert len(fig.axes) == 3
    with pytest.raises(KeyError, match="not a parameter"):
        post.interval("k_f")


def test_disagreeing_chains_are_flagged_loudly(toy_posterior):
    # two chains in each mode: R-hat far above 1.01, never a good-looking result
    init = np.array([MU, MU, MU + [FAR, 0.0], MU + [FAR, 0.0]])
    with pytest.warns(identification.PosteriorWarning, match="R-hat") as rec:
        post = identification.sample_posterior(TOY, chains=CHAINS, draws=DRAWS,
                                               warmup=WARMUP, seed=1, init=init)
    assert "a " in str(rec[0].message)  # the parameter is named
    assert not post.ok and post.rhat["a"] > 1.5
    assert post.report().startswith("WARNING")
    assert post.summary()["ok"] is False and post.summary()["problems"]
    # the chains did stay in their modes
    means = post.chains_draws["a"].mean(axis=1)
    assert np.allclose(means[:2], MU[0], atol=1) and np.allclose(means[2:], MU[0] + FAR,
                                                                 atol=1)

@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_serial_chains_run_blackjax_nuts_on_static_loops(toy_posterior, monkeypatch):
    # chains run one after another (chains_together=False, the fixed-step decay path) build
    # NUTS's trajectories in scans of static length instead of blackjax's while loops
    # (XLA runs a gradient ~6x faster there): the same transitions as blackjax's own
    # loops, run vectorised in toy_posterior
    import identification._posterior as P

    calls = []
    bounded = P._bounded_while
    monkeypatch.setattr(P, "_bounded_while",
                        lambda c, b, i, n: calls.append(n) or bounded(c, b, i, n))
    serial = identification.sample_posterior(
        dataclasses.replace(TOY, chains_together=False), chains=CHAINS, draws=DRAWS,
        warmup=WARMUP, seed=1)
    assert set(calls) == {P.MAX_DOUBLINGS, 2 ** (P.MAX_DOUBLINGS - 1)}  # both loops
    np.testing.assert_allclose(np.asarray(serial.z), np.asarray(toy_posterior.z),
                               rtol=0, atol=1e-8)
    assert serial.n_leapfrog == toy_posterior.n_leapfrog
    # the bounded loop is lax.while_loop's: it stops where the condition fails
    out = P._bounded_while(lambda c: c[0] < c[1], lambda c: (c[0] + 1, c[1]), (0, 7), 20)
    assert int(out[0]) == 7
    import jax

    assert jax.numpy.asarray(out[0]).dtype == jax.numpy.asarray(0).dtype



def test_bad_arguments():
    with pytest.raises(ValueError, match="chains"):
        identification.sample_posterior(TOY, chains=0)
    with pytest.raises(ValueError, match="priors"):
        identification.sample_posterior(TOY, priors={"a": "flat"})
    with pytest.raises(TypeError, match="posterior_problem"):
        identification.sample_posterior(object())
    with pytest.raises(ValueError, match="init"):
        identification.sample_posterior(TOY, chains=2, init=np.zeros((3, 2)))


# ------------------------------------------------------------ decay fits (slow)


@pytest.fixture(scope="module")
def decay_fit():
    """A well-posed SYNTHETIC decay trace (8 s at 200 Hz, 0.5 mm noise) and its fit. (Short
    traces, 3 s at 100 Hz say, pin k_f down poorly: their posteriors reach towards the
    rigid limit, far from the Laplace Gaussian, and mix slowly: benchmarks/
    posterior_coverage.md.)"""
    import rockjax

    trace, truth = identification.synthetic_trace(duration=8.0, noise=5e-4, seed=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fit = identification.fit_decay(trace, rockjax.mcmanus_column())
    return fit, truth


@pytest.mark.slow
@pytest.mark.timeout(1800)  # the compiles take minutes on a loaded machine
def test_decay_posterior_problem(decay_fit):
    import jax

    fit, _ = decay_fit
    pb = fit.posterior_problem()
    assert pb.names == fit.names and pb.source == "decay"
    assert pb.priors["r"].kind == "uniform" and pb.priors["k_f"].kind == "lognormal"
    z0 = jnp.asarray(pb.z0)
    from identification._residuals import _checks_as_nan

    se = np.sqrt(np.diag(pb.cov0))  # the Laplace sd of each coordinate of z
    z1 = z0 + 0.5 * jnp.asarray(se)  # off the optimum: a gradient of order 1 / se
    with _checks_as_nan():
        lp = float(pb.log_density(z0))
        g = np.asarray(jax.grad(pb.log_density)(z1))
        fd = np.array([(float(pb.log_density(z1 + h * e)) - float(pb.log_density(z1 - h * e)))
                       / (2 * h) for h, e in zip(1e-3 * se, np.eye(z0.size))])
    assert math.isfinite(lp)
    # in units of the posterior's own scale (gradient x sd: of order 1 here)
    assert np.max(np.abs(g * se)) > 0.1
    np.testing.assert_allclose(g * se, fd * se, rtol=1e-3, atol=1e-3)
    # the physical values at z0 are the fit's
    x0 = pb.to_physical(z0)
    for p in fit.names:
        assert float(x0[p]) == pytest.approx(fit.values[p], rel=1e-9, abs=1e-12)
    with pytest.raises(ValueError, match="not a parameter"):
        fit.posterior_problem({"c_f": "flat"})
    assert fit.posterior_problem({"k_f": "lognormal(8e5, 0.5)"}).priors["k_f"].a == 8e5


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_decay_posterior_agrees_with_laplace(decay_fit):
    """Where the Laplace approximation holds (a well-posed trace), the posterior agrees:
    mean within 0.5 SE of the fit's value, sd within 30 % of the SE, for k_f and r."""
    from identification._posterior_decay import laplace_check

    fit, truth = decay_fit
    post = identification.sample_posterior(fit, chains=4, draws=200, warmup=100, seed=0)
    assert post.ok, post.problems
    check = laplace_check(post, tol_mean=0.5, tol_sd=0.3)
    for p in ("k_f", "r"):
        assert check[p]["agrees"], (p, check[p])
        assert post.laplace["value"][p] == pytest.approx(fit.values[p])
        assert post.laplace["se"][p] == pytest.approx(fit.stderr[p], rel=0.2)
        lo, hi = post.interval(p, 0.99)
        assert lo < truth[p] < hi


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_cli_fit_posterior(tmp_path):
    from conftest import run_cli

    trace, _ = identification.synthetic_trace(duration=2.0, rate_hz=100.0, noise=5e-4, seed=4)
    csv = tmp_path / "decay.csv"
    np.savetxt(csv, np.column_stack([trace.t, trace.u]), delimiter=",", header="t,u",
               comments="")
    out_csv = tmp_path / "draws.csv"
    r = run_cli("fit", str(csv), "--params", "k_f", "r", "u0", "t0", "--offset", "no",
                "--posterior", "--chains", "2", "--draws", "50", "--warmup", "50",
                "--prior", "k_f=lognormal(8e5,1)", "--draws-out", str(out_csv), "--json",
                cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    post = out["posterior"]
    assert set(post["parameters"]) == {"k_f", "r", "u0", "t0"}
    assert post["priors"]["k_f"] == "lognormal(median=800000, sigma_ln=1)"
    assert isinstance(post["ok"], bool) and "rhat" in post["parameters"]["k_f"]
    lines = out_csv.read_text().splitlines()
    assert lines[0].startswith("# units: k_f N/m, r -") and lines[1] == "k_f,r,u0,t0"
    assert len(lines) == 2 + 2 * 50
    bad = run_cli("fit", str(csv), "--prior", "k_f=lognormal(8e5,1)", cwd=tmp_path)
    assert bad.returncode != 0 and "--prior needs --posterior" in bad.stderr
    bad = run_cli("fit", str(csv), "--posterior", "--prior", "q=flat", cwd=tmp_path)
    assert bad.returncode != 0 and "--prior" in bad.stderr and "not a parameter" in bad.stderr


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_decay_posterior_runs_on_the_checked_fixed_step_likelihood(decay_fit, monkeypatch):
    """The posterior's likelihood is the fixed-step one (RK4 on the trace's step) only
    because it agrees with the fit's adaptive solver: on points the check did not use, the
    two log likelihoods differ by a constant to well within 0.05; and a check that cannot
    pass keeps the adaptive solver (chains vectorised again)."""
    import jax

    from identification import _posterior_decay as PD
    from identification._residuals import _checks_as_nan

    fit, _ = decay_fit
    pb = fit.posterior_problem()
    assert pb.chains_together is False and "fixed-step likelihood (RK4" in pb.likelihood_note
    assert pb.log_likelihood.model.grid_dt is not None
    exact = dataclasses.replace(pb.log_likelihood,
                                model=dataclasses.replace(pb.log_likelihood.model,
                                                          grid_dt=None, grid_t1=None))
    L = np.linalg.cholesky(pb.cov0)
    w = 1.5 * np.random.default_rng(7).standard_normal((12, pb.z0.size))
    Z = jnp.asarray(pb.z0 + w @ L.T)
    with _checks_as_nan():
        a = np.asarray(jax.jit(jax.vmap(pb.log_likelihood))(Z))
        b = np.asarray(jax.jit(jax.vmap(exact))(Z))
    assert np.all(np.isfinite(a)) and np.all(np.isfinite(b))
    assert np.ptp(b) > 3.0  # the points span the posterior: log L moves by several units
    assert np.std(a - b) < 0.05
    monkeypatch.setattr(PD, "GRID_LOGL_SD", 1e-12)
    pb2 = fit.posterior_problem()
    assert pb2.chains_together is True and pb2.log_likelihood.model.grid_dt is None
    assert pb2.likelihood_note.startswith("adaptive solver")
    monkeypatch.undo()
    # a check that proves nothing is not taken: a fit that leaves a parameter unpinned (its
    # Laplace sd beyond what the chains' whitening keeps) ...
    wide = np.array(pb.cov0) * 1e6
    fast, note = PD._on_grid(exact, np.asarray(pb.z0), wide)
    assert fast is None and "does not pin" in note
    # ... or points over which log L hardly moves
    tiny = np.array(pb.cov0) * 1e-12
    fast, note = PD._on_grid(exact, np.asarray(pb.z0), tiny)
    assert fast is None and "do not probe" in note
