"""Joint fits of several decay traces (shared k_f, r; u0, t0 of each trace), fits compiled
once, and the command line's persistent compilation cache (issue 15, item 3).

The traces are SYNTHETIC: `rockjax.simulate` of the Table 1 column at k_f = 800 kN/m,
r = 0.85 released from three different u0, 1.6 to 2.5 s at 100 Hz, one with a logger
clock starting at 1.5 s, plus 0.5 mm Gaussian noise. One joint fit (module fixture)
compiles the joint step; the command-line test reuses it in-process.
"""

from __future__ import annotations

import collections
import contextlib
import json
import subprocess
import sys
import warnings

import jax
import jax.monitoring
import numpy as np
import pytest

import identification
import rockjax
from identification import fit_decay
from rockjax.cli import _common, main

K_F, R = 800e3, 0.85
NOISE = 5e-4  # m
# (u0 [m], duration [s], clock offset [s]) of each trace
SPECS = ((0.10, 2.5, 0.0), (0.08, 2.0, 1.5), (0.06, 1.6, 0.0))
FIT = dict(initial={"k_f": 1.2e6}, starts=2, max_iter=24, progress=False)


def make_traces(seed=0):
    """The three SYNTHETIC traces (see the module docstring)."""
    s = rockjax.mcmanus_column().replace(k_f=K_F)
    rng = np.random.default_rng(seed)
    out = []
    for i, (u0, dur, offset) in enumerate(SPECS):
        ts = np.round(np.arange(0.0, dur + 1e-9, 0.01), 10)
        res = rockjax.simulate(s, rockjax.FreeVibration(u0), ts[-1], ts=ts, r=R)
        u = np.asarray(res.u) + rng.normal(0.0, NOISE, ts.size)
        out.append(identification.DecayTrace(ts + offset, u, source=f"synthetic_{i}"))
    return out


@contextlib.contextmanager
def compile_events():
    """Count JAX's trace and compile events (by name) while the block runs."""
    counts = collections.Counter()

    def listener(name, secs, **kw):
        if name.startswith("/jax/core/compile/"):
            counts[name] += 1

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        yield counts
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)


def quiet(fn, *args, **kwargs):
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        return fn(*args, **kwargs)


@pytest.fixture(scope="module")
def traces():
    return make_traces()


@pytest.fixture(scope="module")
def joint(traces):
    return quiet(fit_decay, traces, rockjax.mcmanus_column(), **FIT)


def test_joint_fit_recovers_shared_k_f_and_r(joint):
    assert isinstance(joint, identification.JointFitResult) and joint.converged
    assert joint.names == ("k_f", "r") and joint.n_traces == 3
    for p, truth in (("k_f", K_F), ("r", R)):
        z = (joint.values[p] - truth) / joint.stderr[p]
        assert abs(z) < 3, (p, joint.values[p], joint.stderr[p], z)
    assert abs(joint.values["k_f"] / K_F - 1) < 0.1 and abs(joint.values["r"] / R - 1) < 0.01


def test_joint_fit_recovers_each_release(joint, traces):
    for (u0, _, offset), d, tr, resp in zip(SPECS, joint.per_trace, traces, joint.responses):
        for p, truth in (("u0", u0), ("t0", offset)):
            z = (d["values"][p] - truth) / d["stderr"][p]
            assert abs(z) < 3, (d["source"], p, d["values"][p], d["stderr"][p], z)
        assert d["n_points"] == tr.n and resp.u.shape == (tr.n,)
        assert d["sigma"] == pytest.approx(NOISE, rel=0.2)
        assert not d["lack_of_fit"]["fires"]
    # each trace's release, and its sensor's zero (fitted: the traces pin it)
    own = [p for p in ("u0", "t0", "offset", "offset_uplift") if p in joint.per_trace[0]["values"]]
    assert own[:3] == ["u0", "t0", "offset"]
    assert joint.joint_names == ("k_f", "r") + tuple(f"{p}[{i}]" for i in range(3) for p in own)
    c = joint.correlation
    n = len(joint.joint_names)
    assert c.shape == (n, n) and np.allclose(np.diag(c), 1.0)
    json.dumps(joint.summary())  # JSON-ready


def test_second_identical_fit_compiles_nothing(joint, traces):
    with compile_events() as counts:
        again = quiet(fit_decay, traces, rockjax.mcmanus_column(), **FIT)
    assert not counts, dict(counts)  # no tracing, no lowering, no XLA compile
    assert again.values == joint.values


@pytest.mark.slow  # moved out of the default suite (issue 23): compile-bound; CI runs it
def test_a_list_of_one_trace_is_the_single_fit(traces):
    short = traces[2]
    kw = dict(FIT, max_iter=8, horizons=(1.0,))
    single = quiet(fit_decay, short, rockjax.mcmanus_column(), **kw)
    assert isinstance(single, identification.FitResult)
    with compile_events() as counts:  # a second single fit reuses its compiled code
        single2 = quiet(fit_decay, short, rockjax.mcmanus_column(), **kw)
    assert not counts, dict(counts)
    assert single2.values == single.values
    one = quiet(fit_decay, [short], rockjax.mcmanus_column(), **kw)
    for p in ("k_f", "r"):
        assert one.values[p] == pytest.approx(single.values[p], rel=1e-6)
        assert one.stderr[p] == pytest.approx(single.stderr[p], rel=1e-3)
    for p in ("u0", "t0"):
        assert one.per_trace[0]["values"][p] == pytest.approx(single.values[p], rel=1e-6,
                                                              abs=1e-9)


@pytest.mark.parametrize("case, match", [
    ("empty", "trace: an empty list"),
    ("not_a_trace", r"trace\[1\]: trace must be an identification.DecayTrace"),
    ("structures", r"structure: trace\[1\]'s structure differs"),
    ("n_structures", "structure: 1 structures for 2 traces"),
    ("uplift", r"trace\[1\] has uplift channel, unlike trace\[0\]"),
    ("keyword", "unexpected keyword"),
])
def test_bad_joint_input_names_the_parameter(traces, case, match):
    s = rockjax.mcmanus_column()
    with_up = identification.DecayTrace(traces[1].t, traces[1].u, np.zeros(traces[1].n))
    args = {
        "empty": ([], s),
        "not_a_trace": ([traces[0], 3.0], s),
        "structures": (traces[:2], [s, s.replace(k_f=9e5)]),
        "n_structures": (traces[:2], [s]),
        "uplift": ([traces[0], with_up], s),
        "keyword": (traces[:2], s),
    }[case]
    kw = {"banana": 1} if case == "keyword" else {}
    with pytest.raises((ValueError, TypeError), match=match):
        fit_decay(*args, **kw)


@pytest.mark.slow  # moved out of the default suite (issue 23): compile-bound; CI runs it
def test_cli_fits_several_files(joint, traces, tmp_path, capsys):
    paths = []
    for i, tr in enumerate(traces):
        p = tmp_path / f"tr{i}.csv"
        np.savetxt(p, np.column_stack([tr.t, tr.u]), delimiter=",", header="t,u",
                   comments="")
        paths.append(str(p))
    rc = main(["fit", *paths, "--json", "--starts", "2", "--plot", str(tmp_path / "j.png")])
    out = json.loads(capsys.readouterr().out)
    assert rc == 0 and out["joint"] is True and out["files"] == paths
    assert set(out["values"]) == {"k_f", "r"} and len(out["traces"]) == 3
    assert out["traces"][1]["values"]["t0"] == pytest.approx(1.5, abs=0.01)
    assert out["traces"][2]["trace"]["n_points"] == traces[2].n
    assert out["values"]["k_f"] == pytest.approx(joint.values["k_f"], rel=0.05)
    assert (tmp_path / "j.png").stat().st_size > 10_000
    rc = main(["fit", *paths[:2], "--starts", "2"])
    text = capsys.readouterr().out
    assert rc == 0 and "joint fit of 2 traces (shared: k_f, r)" in text
    assert "tr1.csv" in text and "std. error" in text


def test_compile_cache_dir_settings(tmp_path, monkeypatch):
    for var in (_common.COMPILE_CACHE_ENV, "ROCKJAX_NO_COMPILE_CACHE", "ROCKJAX_CACHE"):
        monkeypatch.delenv(var, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert _common.compile_cache_dir() == tmp_path / "xdg" / "rockjax" / "jax"
    assert _common.compile_cache_dir(disabled=True) is None
    monkeypatch.setenv(_common.COMPILE_CACHE_ENV, str(tmp_path / "c"))
    assert _common.compile_cache_dir() == tmp_path / "c"
    monkeypatch.setenv("ROCKJAX_NO_COMPILE_CACHE", "1")
    assert _common.compile_cache_dir() is None
    monkeypatch.setenv("ROCKJAX_NO_COMPILE_CACHE", "0")
    monkeypatch.setenv(_common.COMPILE_CACHE_ENV, "off")
    assert _common.compile_cache_dir() is None


def _simulate_cli(tmp_path, env_cache, *flags):
    env = dict(__import__("os").environ, **{_common.COMPILE_CACHE_ENV: env_cache})
    return subprocess.run([sys.executable, "-m", "rockjax.cli", *flags, "simulate", "--u0",
                           "0.05", "--t1", "0.5", "--json"], capture_output=True, text=True,
                          cwd=tmp_path, env=env, timeout=600)


@pytest.mark.slow  # out of the default suite (the suite in 8 minutes); CI runs it
def test_cli_writes_the_compile_cache_unless_turned_off(tmp_path):
    cache = tmp_path / "cache"
    r = _simulate_cli(tmp_path, str(cache))
    assert r.returncode == 0, r.stderr
    assert cache.is_dir() and any(cache.iterdir())  # compiled programs written there
    off = tmp_path / "off"
    r = _simulate_cli(tmp_path, str(off), "--no-compile-cache")
    assert r.returncode == 0, r.stderr
    assert not off.exists()
    r = _simulate_cli(tmp_path, "off")
    assert r.returncode == 0 and not (tmp_path / "off").exists()


def test_persisted_programs_are_read_back_without_tracing(tmp_path, monkeypatch):
    """`identification._aot.persisted`: with the compile cache on, a program is exported
    to disk once; another instance (as in a new process) reads it instead of tracing."""
    import jax.numpy as jnp

    from identification import _aot

    monkeypatch.setattr(_aot, "store", lambda: tmp_path)
    traced = []

    def f(x, scale):
        traced.append(1)
        return jnp.sin(x) * scale, x + 1

    def structure(x, scale):
        return jax.tree.structure((0, 0))

    x = jnp.linspace(0.0, 1.0, 7)
    first = _aot.persisted(f, structure)(x, 2.0)
    assert len(traced) == 1 and len(list(tmp_path.glob("f-*.export"))) == 1
    again = _aot.persisted(f, structure)(x, 2.0)  # a new instance: read from disk
    assert len(traced) == 1
    np.testing.assert_array_equal(again[0], first[0])
    np.testing.assert_array_equal(again[1], x + 1)
    _aot.persisted(f, structure)(x, 3.0)  # another static value: another program
    assert len(traced) == 2 and len(list(tmp_path.glob("f-*.export"))) == 2
    monkeypatch.setattr(_aot, "store", lambda: None)  # cache off: plain filter_jit
    _aot.persisted(f, structure)(x, 4.0)
    assert len(traced) == 3 and len(list(tmp_path.glob("f-*.export"))) == 2


@pytest.mark.slow  # compiles the joint residuals and Jacobian outside the fit (~1 min)
def test_joint_posterior_problem(joint):
    """The joint fit's posterior: every fitted parameter (shared and each trace's own),
    the physical values at the optimum the fit's, the Laplace sd of k_f and r near the
    fit's standard errors, and a gradient that a float64 central difference confirms."""
    from identification._residuals import _checks_as_nan

    pb = joint.posterior_problem()
    assert pb.names == joint.joint_names and pb.source == "joint decay"
    assert pb.priors["k_f"].kind == "lognormal" and pb.priors["r"].kind == "uniform"
    assert pb.priors["u0[1]"].kind == "flat" and pb.units["t0[2]"] == "s"
    z0 = jax.numpy.asarray(pb.z0)
    x0 = pb.to_physical(z0)
    for p in joint.names:
        assert float(x0[p]) == pytest.approx(joint.values[p], rel=1e-9)
    for i, d in enumerate(joint.per_trace):
        assert float(x0[f"u0[{i}]"]) == pytest.approx(d["values"]["u0"], rel=1e-9)
    # the Laplace sd in z of k_f, r (log-type coordinates) against the fit's SE: the
    # marginalised noise and the fit's sandwich estimate agree to ~30 %
    jac = np.asarray(jax.jacfwd(pb.physical_vector)(z0))
    sd = np.sqrt(np.diag(jac @ pb.cov0 @ jac.T))
    for j, p in enumerate(joint.names):
        assert sd[j] == pytest.approx(joint.stderr[p], rel=0.3), p
    se_z = np.sqrt(np.diag(pb.cov0))
    z1 = z0 + 0.5 * jax.numpy.asarray(se_z)
    with _checks_as_nan():
        g = np.asarray(jax.grad(pb.log_density)(z1))
        fd = np.array([(float(pb.log_density(z1 + h * e)) - float(pb.log_density(z1 - h * e)))
                       / (2 * h) for h, e in zip(1e-3 * se_z, np.eye(z0.size))])
    assert np.max(np.abs(g * se_z)) > 0.1
    np.testing.assert_allclose(g * se_z, fd * se_z, rtol=1e-3, atol=2e-3)
    with pytest.raises(ValueError, match="not a parameter"):
        joint.posterior_problem({"c_f": "flat()"})
