"""`fit_decay(..., model="auto")`: the rungs ranked by lack of fit and AIC."""

from __future__ import annotations

import math
import types
import warnings

import numpy as np
import pytest

import identification
import rockjax
from identification import _auto
from identification._auto import rank, ranking_table
from identification._problem import Settings


def _row(model, aic, lack=False, converged=True):
    return {"model": model, "k": 5, "aic": aic, "rms": 5e-4, "lack_of_fit": lack,
            "converged": converged, "k_f": 8e5, "seconds": 1.0}


def test_rank_puts_noise_residuals_first_then_the_lowest_aic():
    rows = [_row("simplified", -100.0, lack=True), _row("rigid_body", -90.0),
            _row("two_spring_2dof (contact impact)", -95.0),
            _row("two_spring_2dof (contact continuous)", -120.0, converged=False),
            {"model": "broken", "error": "refused"}]
    ranked = rank(rows)
    # the fits whose residuals are noise, by AIC; then the others by AIC, converged or not
    assert [r["model"] for r in ranked] == [
        "two_spring_2dof (contact impact)", "rigid_body",
        "two_spring_2dof (contact continuous)", "simplified", "broken"]
    assert ranked[0]["rank"] == 1 and ranked[0]["delta_aic"] == pytest.approx(25.0)
    assert math.isclose(ranked[2]["delta_aic"], 0.0)
    table = ranking_table(ranked)
    assert table.count("\n") == 6 and "| 1 | two_spring_2dof (contact impact) |" in table
    assert "refused: refused" in table and "FIRES" in table and "| NO |" in table


def test_rank_does_not_prefer_a_converged_misfit_to_a_closer_unconverged_fit():
    # benchmarks/model_auto.py, a 2-DOF dashpot trace (seed 101): every rung fires the
    # lack-of-fit check; the true rung's fit stopped unconverged at 1.7 mm rms, the SDOF
    # converged at 3.8 mm. An unconverged fit's AIC only bounds its rung's from above.
    rows = [_row("simplified", -4453.2, lack=True),
            _row("two_spring_2dof (contact continuous)", -5102.7, lack=True, converged=False),
            _row("rigid_body", -3973.7, lack=True, converged=False)]
    ranked = rank(rows)
    assert [r["model"] for r in ranked] == [
        "two_spring_2dof (contact continuous)", "simplified", "rigid_body"]
    assert ranked[1]["delta_aic"] == pytest.approx(649.5)
    # a fit whose residuals are noise still comes first, whatever the others' AIC
    ranked = rank(rows + [_row("two_spring_2dof (contact impact)", -4000.0)])
    assert ranked[0]["model"] == "two_spring_2dof (contact impact)"


def _stub_fit(bad_unless_finer=True):
    """A stand-in for `_fit.fit_single`: noise residuals (0.5 mm) only over the finer
    horizons of the second try, a wrong minimum (2 mm, the check firing) otherwise."""
    calls = []

    def fit_single(trace, structure, params, st, optimizer):
        calls.append((st.model, st.contact, st.horizons))
        good = st.horizons == _auto.RETRY_HORIZONS or not bad_unless_finer
        return types.SimpleNamespace(
            response=types.SimpleNamespace(u=np.zeros(400)), outliers=np.array([], int),
            rms=5e-4 if good else 2e-3, names=("k_f", "r", "u0", "t0", "offset"),
            lack_of_fit={"fires": not good}, converged=True,
            values={"k_f": 7e5 if good else 1.3e6}, fixed={})

    return fit_single, calls


def test_a_2dof_rung_in_a_wrong_minimum_is_fitted_again_over_finer_horizons():
    settings = Settings(model="auto")
    fit_single, calls = _stub_fit()
    row, fit, _ = _auto._fit_rung(None, None, settings, None, fit_single,
                                  "two_spring_2dof", "continuous")
    assert [c[2] for c in calls] == [None, _auto.RETRY_HORIZONS]
    assert row["horizons"] == "finer (second try)" and row["fits"] == 2
    assert not row["lack_of_fit"] and fit.values["k_f"] == 7e5
    assert "(2 fits)" in ranking_table(rank([row]))
    # a 2-DOF fit whose residuals are noise: one fit
    fit_single, calls = _stub_fit(bad_unless_finer=False)
    row, _, _ = _auto._fit_rung(None, None, settings, None, fit_single, "two_spring_2dof",
                                "impact")
    assert len(calls) == 1 and row["fits"] == 1 and row["horizons"] == "default"
    # the SDOF rungs, and any rung when the caller set the horizons: no second try
    for model, contact, st in (("simplified", None, settings),
                               ("two_spring_2dof", "impact",
                                Settings(model="auto", horizons=(0.5, 1.0)))):
        fit_single, calls = _stub_fit()
        row, _, _ = _auto._fit_rung(None, None, st, None, fit_single, model, contact)
        assert len(calls) == 1 and row["lack_of_fit"] and row["fits"] == 1


def test_auto_refuses_params_and_lists():
    trace, _ = identification.synthetic_trace(duration=1.0, rate_hz=50.0, noise=0.0)
    with pytest.raises(ValueError, match="leave params out"):
        identification.fit_decay(trace, model="auto", params=("k_f", "r"))
    with pytest.raises(ValueError, match="fits one trace"):
        identification.fit_decay([trace, trace], model="auto")


@pytest.mark.slow  # fits every rung (the 2-DOF body's: minutes)
def test_auto_on_an_sdof_trace_keeps_the_sdof():
    trace, truth = identification.synthetic_trace(duration=8.0, rate_hz=100.0, seed=7)
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        fit = identification.fit_decay(trace, rockjax.mcmanus_column(), model="auto",
                                       progress=False)
    print(ranking_table(fit.ranking))
    assert fit.model == "simplified" and fit.ranking[0]["model"] == "simplified"
    assert abs(fit.values["k_f"] / truth["k_f"] - 1) < 0.02
    assert len(fit.ranking) >= 3 and fit.summary()["ranking"][0]["rank"] == 1
