"""All CPU cores by default (`rockjax/_devices.py`): what `import rockjax` does to JAX's CPU
device count, in fresh processes, for each way a user can choose the count."""

import json
import os
import subprocess
import sys

import pytest

PROBE = """
import json, sys
if sys.argv[1] == "jax-first":
    import jax.numpy as jnp
    jnp.ones(1).block_until_ready()  # the backend starts before rockjax is imported
import jax, rockjax
from rockjax._devices import DEVICE_CHOICE, usable_cores
print(json.dumps({"devices": len(jax.local_devices()), "cores": usable_cores(),
                  "choice": DEVICE_CHOICE}))
"""


def probe(env_extra, mode="plain"):
    env = {k: v for k, v in os.environ.items()
           if k not in ("XLA_FLAGS", "JAX_NUM_CPU_DEVICES", "ROCKJAX_CPU_DEVICES")}
    env.update(env_extra)
    out = subprocess.run([sys.executable, "-c", PROBE, mode], env=env, capture_output=True,
                         text=True, timeout=120)
    return out


def result(env_extra, mode="plain"):
    out = probe(env_extra, mode)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_one_device_per_core_by_default():
    r = result({})
    assert r["choice"] == {"action": "set", "count": r["cores"]}
    assert r["devices"] == r["cores"]


@pytest.mark.parametrize("env, n, action", [
    ({"XLA_FLAGS": "--xla_force_host_platform_device_count=3"}, 3, "XLA_FLAGS sets the count"),
    ({"JAX_NUM_CPU_DEVICES": "3"}, 3, "jax_num_cpu_devices set by the user"),
    ({"ROCKJAX_CPU_DEVICES": "3"}, 3, "set"),
    ({"ROCKJAX_CPU_DEVICES": "1"}, 1, "set"),
])
def test_a_users_choice_is_respected(env, n, action):
    r = result(env)
    assert r["devices"] == n
    assert r["choice"]["action"] == action


def test_a_started_backend_is_left_alone():
    r = result({}, mode="jax-first")
    assert r["devices"] == 1
    assert r["choice"]["action"] == "backend already initialised"


def test_a_bad_count_names_the_variable():
    out = probe({"ROCKJAX_CPU_DEVICES": "many"})
    assert out.returncode != 0
    assert "ROCKJAX_CPU_DEVICES must be a positive integer" in out.stderr
