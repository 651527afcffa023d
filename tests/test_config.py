"""A library that behaves as a library: `import rockjax` changes no JAX configuration;
`rockjax.configure()` is the explicit switch; the computing entry points turn float64 on
with one `ConfigurationWarning` unless the user opted out. Each case in a fresh process."""

import json
import os
import subprocess
import sys

import pytest

import rockjax

PROBE = r"""
import json, sys, warnings
import jax
mode = sys.argv[1]
import rockjax
out = {"x64_after_import": bool(jax.config.jax_enable_x64),
       "devices_after_import": jax.config.jax_num_cpu_devices}
if mode == "opt-out":
    rockjax.configure(x64=False, cpu_devices=None)
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    s = rockjax.mcmanus_column()
    fv = rockjax.FreeVibration(0.1)
    if mode == "opt-out":
        try:
            rockjax.simulate(s, fv, 0.2)
        except ValueError as e:
            out["error"] = str(e)
        out["f32"] = str(rockjax.simulate(s, fv, 0.2, method="rk4").u.dtype)
    else:
        rockjax.simulate(s, fv, 0.2, method="rk4")
        rockjax.simulate(s, fv, 0.2, method="rk4")
out["x64_after_run"] = bool(jax.config.jax_enable_x64)
out["dtype"] = str(s.k_f.dtype)
out["warnings"] = [str(w.message) for w in caught
                   if issubclass(w.category, rockjax.ConfigurationWarning)]
print(json.dumps(out))
"""


def run(mode, **env_extra):
    env = {k: v for k, v in os.environ.items() if k not in ("JAX_ENABLE_X64",)}
    env.update(env_extra)
    out = subprocess.run([sys.executable, "-c", PROBE, mode], env=env, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_import_changes_nothing_and_the_guard_warns_once():
    r = run("plain")
    assert r["x64_after_import"] is False and r["devices_after_import"] == -1
    assert r["x64_after_run"] is True and r["dtype"] == "float64"
    assert len(r["warnings"]) == 1
    assert "rockjax.configure()" in r["warnings"][0]


@pytest.mark.parametrize("how", ["configure", "env"])
def test_the_opt_out_is_honoured(how):
    r = run("opt-out") if how == "configure" else run("plain", JAX_ENABLE_X64="0")
    assert r["x64_after_run"] is False and r["dtype"] == "float32"
    assert r["warnings"] == []
    if how == "configure":
        assert "rockjax.configure()" in r["error"] and "float64" in r["error"]
        assert r["f32"] == "float32"


def test_configure_reports_what_it_did():
    conf = rockjax.configure()  # in the suite's process: configured already by conftest
    assert conf.x64 is True
    assert conf.devices in ("set", "backend already initialised", "XLA_FLAGS sets the count",
                            "jax_num_cpu_devices set by the user")
    with pytest.raises(rockjax.ParameterError) as e:
        rockjax.configure(cpu_devices="many")
    assert e.value.param == "cpu_devices"
    with pytest.raises(ValueError, match="x64 must be True or False"):
        rockjax.configure(x64="yes")


BATCH = r"""
import json, sys, warnings
import numpy as np
import rockjax
if sys.argv[1] == "keep-one":
    rockjax.configure(cpu_devices=None)
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    s = rockjax.mcmanus_column()
    for _ in range(2):
        rockjax.simulate_batch(s, rockjax.FreeVibration(0.0), 0.2, u0=np.array([0.05, 0.1]),
                               method="rk4", summary_only=True)
print(json.dumps([str(w.message) for w in caught if "JAX CPU device" in str(w.message)]))
"""


@pytest.mark.skipif(rockjax._devices.usable_cores() < 2, reason="one usable core")
@pytest.mark.slow  # out of the default suite (the suite in 8 minutes, issue 26); CI runs it
def test_a_batch_on_one_device_of_many_cores_advises_configure_once():
    env = {k: v for k, v in os.environ.items()
           if k not in ("XLA_FLAGS", "JAX_NUM_CPU_DEVICES", "ROCKJAX_CPU_DEVICES")}
    said = {}
    for mode in ("plain", "keep-one"):
        out = subprocess.run([sys.executable, "-c", BATCH, mode], env=env, capture_output=True,
                             text=True, timeout=300)
        assert out.returncode == 0, out.stderr
        said[mode] = json.loads(out.stdout.strip().splitlines()[-1])
    assert len(said["plain"]) == 1 and "rockjax.configure()" in said["plain"][0]
    assert said["keep-one"] == []  # the count was chosen: nothing to advise
