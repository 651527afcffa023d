"""The CPU device count (`rockjax/_devices.py`): `import rockjax` leaves it alone, and
`rockjax.configure()` asks for one device per core, in fresh processes, for each way a user
can choose the count."""

import json
import os
import subprocess
import sys

import pytest

PROBE = """
import json, sys
mode = sys.argv[1]
if mode == "jax-first":
    import jax.numpy as jnp
    jnp.ones(1).block_until_ready()  # the backend starts before rockjax is configured
import jax, rockjax
from rockjax._devices import usable_cores
asked = jax.config.jax_num_cpu_devices
conf = None if mode == "import-only" else rockjax.configure(
    cpu_devices=json.loads(sys.argv[2]))
print(json.dumps({"devices": len(jax.local_devices()), "cores": usable_cores(),
                  "asked_at_import": asked,
                  "conf": None if conf is None else [conf.devices, conf.cpu_devices]}))
"""


def probe(env_extra, mode="plain", cpu_devices="all"):
    env = {k: v for k, v in os.environ.items()
           if k not in ("XLA_FLAGS", "JAX_NUM_CPU_DEVICES", "ROCKJAX_CPU_DEVICES")}
    env.update(env_extra)
    out = subprocess.run([sys.executable, "-c", PROBE, mode, json.dumps(cpu_devices)],
                         env=env, capture_output=True, text=True, timeout=120)
    return out


def result(env_extra, mode="plain", cpu_devices="all"):
    out = probe(env_extra, mode, cpu_devices)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_import_leaves_the_count_alone():
    r = result({}, mode="import-only")
    assert r["asked_at_import"] == -1
    assert r["devices"] == 1


def test_configure_asks_for_one_device_per_core():
    r = result({})
    assert r["conf"] == ["set", r["cores"]]
    assert r["devices"] == r["cores"]


def test_configure_takes_a_count():
    r = result({}, cpu_devices=3)
    assert r["conf"] == ["set", 3] and r["devices"] == 3


@pytest.mark.parametrize("env, n, action", [
    ({"XLA_FLAGS": "--xla_force_host_platform_device_count=3"}, 3, "XLA_FLAGS sets the count"),
    ({"JAX_NUM_CPU_DEVICES": "3"}, 3, "jax_num_cpu_devices set by the user"),
    ({"ROCKJAX_CPU_DEVICES": "3"}, 3, "set"),
    ({"ROCKJAX_CPU_DEVICES": "1"}, 1, "set"),
])
def test_a_users_choice_is_respected(env, n, action):
    r = result(env)
    assert r["devices"] == n
    assert r["conf"][0] == action


def test_a_started_backend_is_left_alone_and_said_so():
    r = result({}, mode="jax-first")
    assert r["devices"] == 1
    assert r["conf"] == ["backend already initialised", 1]


def test_a_bad_count_names_the_variable():
    out = probe({"ROCKJAX_CPU_DEVICES": "many"})
    assert out.returncode != 0
    assert "ROCKJAX_CPU_DEVICES must be a positive integer" in out.stderr
