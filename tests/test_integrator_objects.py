"""Integrators as objects (`rockjax.integrators`) and models abstract-or-final.

The keyword form (`method="rk4", substeps=2`) builds the same integrator object that
`integrator=` takes: both give bit-identical results, and a keyword that contradicts the
object is refused, naming it.
"""

import inspect

import diffrax as dfx
import equinox as eqx
import numpy as np
import pytest

import rockjax
from rockjax import integrators as I
from rockjax.models import AbstractRockingModel, get_model, MODELS

S = rockjax.mcmanus_column()
FV = rockjax.FreeVibration(0.10)


def test_abstract_integrator_cannot_be_built():
    with pytest.raises(TypeError):
        I.AbstractIntegrator()


@pytest.mark.parametrize(
    "build, param",
    [
        (lambda: I.RK4(substeps=0), "substeps"),
        (lambda: I.RK4(max_pieces=1), "max_pieces"),
        (lambda: I.RK4(max_impacts=0), "max_impacts"),
        (lambda: I.Dopri5(rtol=0.0), "rtol"),
        (lambda: I.Dopri5(atol=-1.0), "atol"),
        (lambda: I.Dopri5(dt=float("nan")), "dt"),
        (lambda: I.EventRestart(rtol=-1e-3), "rtol"),
        (lambda: I.EventRestart(max_steps=0), "max_steps"),
        (lambda: I.EventRestart(adjoint="sideways"), "adjoint"),
    ],
)
def test_integrator_settings_are_checked(build, param):
    with pytest.raises(ValueError, match=f"^{param} must"):
        build()


def test_integrator_names_and_adjoints():
    assert (I.EventRestart.method, I.RK4.method, I.Dopri5.method) == ("diffrax", "rk4", "dopri5")
    assert I.RK4.batched and I.Dopri5.batched and not I.EventRestart.batched
    assert I.EventRestart(adjoint=dfx.ForwardMode()).config().adjoint == "forward"
    assert I.EventRestart(adjoint=dfx.RecursiveCheckpointAdjoint()).config().adjoint == "reverse"


def test_default_integrators_keep_each_entry_points_defaults():
    """simulate: event restart at rtol 1e-10; simulate_batch: RK4 (and its diffrax at 1e-8)."""
    from rockjax._batch import DEFAULT_INTEGRATORS as BATCH
    from rockjax._simulate import DEFAULT_INTEGRATORS as SIM

    assert SIM["diffrax"] == I.EventRestart(rtol=1e-10, atol=1e-12, adjoint="reverse")
    assert SIM["dopri5"].rtol == 1e-10 and SIM["dopri5"].atol == 1e-12
    assert BATCH["rk4"] == I.RK4()
    assert BATCH["diffrax"].rtol == 1e-8 and BATCH["diffrax"].adjoint == "forward"
    assert BATCH["dopri5"].rtol == 1e-8 and BATCH["dopri5"].atol == 1e-10


@pytest.mark.parametrize("where", ["simulate", "simulate_batch"])
def test_keywords_build_the_integrator(where):
    from rockjax.integrators._keywords import from_keywords

    defaults = {"diffrax": I.EventRestart(), "rk4": I.RK4(), "dopri5": I.Dopri5()}
    got = from_keywords(None, {"method": "rk4", "substeps": 8, "rtol": 1e-3},
                        defaults=defaults, default="diffrax", where=where)
    assert got == I.RK4(substeps=8)  # rtol does not apply to fixed steps: ignored
    got = from_keywords(None, {"rtol": 1e-6, "adjoint": "forward"}, defaults=defaults,
                        default="diffrax", where=where)
    assert got == I.EventRestart(rtol=1e-6, adjoint="forward")
    assert from_keywords(None, {}, defaults=defaults, default="rk4", where=where) is defaults["rk4"]


@pytest.mark.parametrize(
    "integrator, keywords, param",
    [
        (I.RK4(substeps=2), dict(substeps=4), "substeps"),
        (I.RK4(), dict(method="diffrax"), "method"),
        (I.EventRestart(), dict(rtol=1e-6), "rtol"),
        (I.EventRestart(), dict(substeps=2), "substeps"),
        (I.Dopri5(), dict(solver=dfx.Tsit5()), "solver"),
    ],
)
def test_contradicting_keyword_is_refused_naming_it(integrator, keywords, param):
    for run in (rockjax.simulate, rockjax.simulate_batch):
        with pytest.raises(ValueError, match=f"^{param}=.* contradicts integrator="):
            run(S, FV, 1.0, integrator=integrator, **keywords)


def test_agreeing_keyword_unknown_keyword_and_wrong_integrator():
    from rockjax.integrators._keywords import from_keywords

    it = I.RK4(substeps=2)
    assert from_keywords(it, {"method": "rk4", "substeps": 2}, defaults={}, default="rk4",
                         where="simulate") is it
    with pytest.raises(TypeError, match="unexpected keyword argument 'subteps'"):
        rockjax.simulate(S, FV, 1.0, subteps=2)
    with pytest.raises(ValueError, match="integrator must be"):
        rockjax.simulate(S, FV, 1.0, integrator="rk4")


def test_object_and_keyword_forms_agree_bit_for_bit():
    ts = np.linspace(0.0, 2.0, 9)
    a = rockjax.simulate(S, FV, 2.0, ts=ts, integrator=I.RK4(substeps=2))
    b = rockjax.simulate(S, FV, 2.0, ts=ts, method="rk4", substeps=2)
    for name in ("u", "v", "theta", "uplift", "peak_u", "n_impacts", "impact_times"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))


def test_simulate_has_few_parameters():
    for f in (rockjax.simulate, rockjax.simulate_batch):
        named = [p for p in inspect.signature(f).parameters.values()
                 if p.kind is not inspect.Parameter.VAR_KEYWORD]
        assert "integrator" in inspect.signature(f).parameters
        assert len(named) <= 19  # was 18 and 24; simulate: 9
    assert len(inspect.signature(rockjax.simulate).parameters) <= 10


# ------------------------------------------------------------------ models: abstract or final
def test_every_method_of_the_abstract_model_is_abstract():
    concrete = [name for name, v in vars(AbstractRockingModel).items()
                if (inspect.isfunction(v) or isinstance(v, property))
                and not getattr(v, "__isabstractmethod__", False)
                and not name.startswith("__")]
    assert concrete == []


@pytest.mark.parametrize("name", sorted(MODELS))
def test_models_declare_their_capabilities_as_data(name):
    m = get_model(name)
    assert isinstance(m, AbstractRockingModel)
    for attr in ("kinematics_of_u", "recrossing_conditions", "impacts_accumulate",
                 "peak_from_state"):
        assert isinstance(getattr(m, attr), bool)
    assert isinstance(m.contacts, int) and m.contacts >= 1
    # the fixed-step stepper's pieces per step: as the models' own defaults were
    assert I.max_pieces_for(m) == {"housner": 32, "two_spring_2dof": 8}.get(name, 4)
    assert I.RK4().config(m, forced=True, n_steps=1, full=False).grazing_roots == (
        name == "rigid_body")
    assert I.RK4(grazing_roots=False).config(m, forced=True, n_steps=1,
                                             full=False).grazing_roots is False
    if not m.kinematics_of_u:
        with pytest.raises(NotImplementedError):
            m.theta_uplift_of_u(S, 0.01)
    else:
        theta, up = m.theta_uplift_of_u(S, 0.01)
        assert np.isfinite(float(theta)) and np.isfinite(float(up))
    # the peak's coordinate: the state's first component and its rate where declared so,
    # else u and v; the peak |u| of its value at overturning is u_overturn
    y, mode = m.init(S.evaluated(), 0.3 * float(S.u_crit), 0.02, 1.0, True)
    q, dq = m.peak_coordinate(S.evaluated(), y, mode)
    obs = m.observe(S.evaluated(), y, mode)
    want = (y[0], y[1]) if m.peak_from_state else (obs.u, obs.v)
    assert (float(q), float(dq)) == (float(want[0]), float(want[1]))
    assert float(m.u_of_peak(S.evaluated(), abs(q))) == pytest.approx(abs(float(obs.u)),
                                                                      rel=1e-14)
    assert float(m.u_of_peak(S.evaluated(), m.peak_limit(S.evaluated()))) == float(
        m.u_overturn(S.evaluated()))


def test_a_model_missing_a_method_cannot_be_built():
    class Half(AbstractRockingModel):
        pass

    with pytest.raises(TypeError):
        Half()
    assert issubclass(type(get_model("simplified")), eqx.Module)


def test_spectrum_amplitude_rtol_keeps_its_old_name():
    with pytest.raises(ValueError, match="rtol=0.01 contradicts amplitude_rtol=0.02"):
        rockjax.overturning_spectrum(S, "sine", [1.0], amplitude_rtol=0.02, rtol=0.01)
    with pytest.raises(ValueError, match="rtol must lie in"):
        rockjax.overturning_spectrum(S, "sine", [1.0], amplitude_rtol=0.5)


def test_keywords_given_as_none_are_not_given():
    from rockjax.integrators._keywords import from_keywords

    it = I.EventRestart()
    assert from_keywords(it, {"substeps": None, "dt": None}, defaults={}, default="rk4",
                         where="simulate_batch") is it
