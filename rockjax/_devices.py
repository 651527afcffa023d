"""The CPU device count that `rockjax.configure` asks JAX for.

JAX's CPU backend exposes a single device unless told otherwise, and a batch split over one
device runs on one core. `simulate_batch` (and `rockjax sweep`) shard every chunk over
`jax.local_devices()`, so `rockjax.configure()` (called by the command line, not by
`import rockjax`) asks for one CPU device per usable core through JAX's own setting
`jax_num_cpu_devices`, unless the user chose a count: `JAX_NUM_CPU_DEVICES` (or
`jax_num_cpu_devices` set in code) and `--xla_force_host_platform_device_count` in
`XLA_FLAGS` are respected as given, and `ROCKJAX_CPU_DEVICES` chooses the count that
``cpu_devices="all"`` asks for (`ROCKJAX_CPU_DEVICES=1` keeps JAX's single device).

JAX fixes the count when its backend starts (the first computation); after that it refuses
the setting with a RuntimeError, which is how this module finds out (JAX has no public
"backend started" query): the count then stays, and `configure` says so.

Extra CPU devices cost nothing to code that does not use them: a single run still runs on
device 0.
"""

from __future__ import annotations

import os

import jax

#: what the last `choose_cpu_devices` did: "set", or why it left the count alone
DEVICE_CHOICE: dict = {"action": "not run", "count": None}

#: the action when JAX's backend had started before the count was asked for
STARTED = "backend already initialised"


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


def _user_choice() -> dict | None:
    """The count the user chose outside rockjax (XLA_FLAGS, JAX_NUM_CPU_DEVICES or
    jax_num_cpu_devices in code), as a choice; None if none."""
    if "xla_force_host_platform_device_count" in os.environ.get("XLA_FLAGS", ""):
        return {"action": "XLA_FLAGS sets the count", "count": None}
    if jax.config.jax_num_cpu_devices != -1:
        return {"action": "jax_num_cpu_devices set by the user",
                "count": int(jax.config.jax_num_cpu_devices)}
    return None


def _ask(n: int) -> dict:
    try:
        jax.config.update("jax_num_cpu_devices", n)
    except RuntimeError:  # JAX refuses it once its backend has started
        return {"action": STARTED, "count": len(jax.local_devices())}
    return {"action": "set", "count": n}


def choose_cpu_devices(cpu_devices="all") -> dict:
    """Ask JAX for `cpu_devices` CPU devices: ``"all"``, one per usable core (or
    `ROCKJAX_CPU_DEVICES`) unless the user chose a count; an int, that count; None, leave
    the count alone. Returns (and records in `DEVICE_CHOICE`) what it did."""
    if cpu_devices is None:
        choice = {"action": "left alone", "count": None}
    elif cpu_devices == "all":
        requested = _requested()
        user = _user_choice() if requested is None else None
        choice = user or _ask(usable_cores() if requested is None else requested)
    elif isinstance(cpu_devices, int) and not isinstance(cpu_devices, bool) and cpu_devices >= 1:
        choice = _ask(cpu_devices)
    else:
        from ._errors import ParameterError

        raise ParameterError(
            f"cpu_devices must be 'all', a positive integer or None, got {cpu_devices!r}",
            param="cpu_devices")
    DEVICE_CHOICE.clear()
    DEVICE_CHOICE.update(choice)
    return choice


#: whether `advise_configure` has looked (it warns at most once per process)
_ADVISED = {"done": False}


def advise_configure() -> None:
    """Warn once (`rockjax.ConfigurationWarning`) when a batch is about to run on a single
    CPU device although this process may use more cores and nobody chose a count:
    `rockjax.configure()` was not called and none of ``XLA_FLAGS``,
    ``JAX_NUM_CPU_DEVICES`` and ``ROCKJAX_CPU_DEVICES`` is set. Cheap after the first call."""
    if _ADVISED["done"]:
        return
    _ADVISED["done"] = True
    if DEVICE_CHOICE["action"] != "not run" or _user_choice() is not None or (
            os.environ.get("ROCKJAX_CPU_DEVICES", "").strip()):
        return
    devices = jax.local_devices()
    cores = usable_cores()
    if len(devices) == 1 and devices[0].platform == "cpu" and cores > 1:
        import warnings

        from ._errors import ConfigurationWarning

        warnings.warn(
            f"this batch runs on 1 JAX CPU device although {cores} cores are usable; call "
            "rockjax.configure() before any JAX computation for one device per core (or "
            "rockjax.configure(cpu_devices=None) to keep one device and silence this)",
            ConfigurationWarning, stacklevel=3)
