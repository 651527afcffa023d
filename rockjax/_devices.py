"""All CPU cores by default: one JAX CPU device per usable core, set at `import rockjax`.

JAX's CPU backend exposes a single device unless told otherwise, and a batch split over one
device runs on one core. `simulate_batch` (and `rockjax sweep`) shard every chunk over
`jax.local_devices()`, so rockjax asks for one CPU device per core when it is imported,
through JAX's own setting `jax_num_cpu_devices`, and only when all of these hold:

- JAX's backend is not yet initialised (no JAX computation has run before `import rockjax`;
  after that the device count is fixed for the process);
- the user has not chosen a count: `JAX_NUM_CPU_DEVICES` (or `jax_num_cpu_devices` set in
  code) and `--xla_force_host_platform_device_count` in `XLA_FLAGS` are respected as given;
- `ROCKJAX_CPU_DEVICES` is not set; set it to a number to choose the count rockjax asks for
  (`ROCKJAX_CPU_DEVICES=1` keeps JAX's single device).

Extra CPU devices cost nothing to code that does not use them: a single run still runs on
device 0.
"""

from __future__ import annotations

import os

import jax

#: what `use_all_cores` did at import: "set", or why it left the count alone
DEVICE_CHOICE: dict = {"action": "not run", "count": None}


def usable_cores() -> int:
    """The cores this process may run on (its CPU affinity), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # not Linux
        return max(1, os.cpu_count() or 1)


def _requested() -> int | None:
    """`ROCKJAX_CPU_DEVICES` as a count, None if unset; an error naming it if invalid."""
    raw = os.environ.get("ROCKJAX_CPU_DEVICES", "").strip()
    if not raw:
        return None
    try:
        n = int(raw)
    except ValueError:
        n = 0
    if n < 1:
        raise ValueError(f"ROCKJAX_CPU_DEVICES must be a positive integer, got {raw!r}")
    return n


def use_all_cores() -> dict:
    """Ask JAX for one CPU device per usable core (or `ROCKJAX_CPU_DEVICES`), unless the
    backend is already initialised or the user chose a count. Returns (and records in
    `DEVICE_CHOICE`) what it did."""
    from jax._src import xla_bridge

    requested = _requested()
    if xla_bridge.backends_are_initialized():
        choice = {"action": "backend already initialised", "count": None}
    elif "xla_force_host_platform_device_count" in os.environ.get("XLA_FLAGS", ""):
        choice = {"action": "XLA_FLAGS sets the count", "count": None}
    elif requested is None and jax.config.jax_num_cpu_devices != -1:
        choice = {"action": "jax_num_cpu_devices set by the user",
                  "count": int(jax.config.jax_num_cpu_devices)}
    else:
        n = usable_cores() if requested is None else requested
        jax.config.update("jax_num_cpu_devices", n)
        choice = {"action": "set", "count": n}
    DEVICE_CHOICE.clear()
    DEVICE_CHOICE.update(choice)
    return choice
