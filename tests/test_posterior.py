"""Posteriors by NUTS (`identification.sample_posterior`, issue 25 item 3).

Default suite: the diagnostics against known cases, and the sampler on a toy problem (one
compiled program, shared by the tests): a Gaussian it must reproduce, and the same
problem's far second mode, whose chains disagree and must be flagged loudly. The decay-fit
posteriors (Laplace agreement on a well-posed trace, a bimodal k_f) are slow.
"""

from __future__ import annotations

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
    rho, x = 0.5, np.zeros((4, 4000))
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


def test_bad_arguments():
    with pytest.raises(ValueError, match="chains"):
        identification.sample_posterior(TOY, chains=0)
    with pytest.raises(ValueError, match="priors"):
        identification.sample_posterior(TOY, priors={"a": "flat"})
    with pytest.raises(TypeError, match="posterior_problem"):
        identification.sample_posterior(object())
    with pytest.raises(ValueError, match="init"):
        identification.sample_posterior(TOY, chains=2, init=np.zeros((3, 2)))
