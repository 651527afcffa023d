"""Batches split over `jax.distributed` processes: each runs a contiguous block of the
runs, and the blocks are gathered (`jax.experimental.multihost_utils.process_allgather`,
on CPUs over gloo) so that every process ends with every result.

`Processes()` is one process that connects nowhere; `Processes.start(...)` starts
`jax.distributed` (before any JAX computation) and `Processes.current()` is this process's
place once it has started. `rockjax.sweep(..., processes=...)` uses it; the command line
(`rockjax sweep --distributed`) starts the processes with `Processes.start`.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import json
import math
import os
import socket
import sys
import time
import zlib

import numpy as np

from ._errors import ParameterError

#: how long a process waits for the coordinator and the others by default [s] (JAX's 300)
DEFAULT_TIMEOUT = 300.0


class NoCoordinator(ParameterError):
    """No coordinator answered at `coordinator` within the timeout (`Processes.start`)."""


class ProcessError(RuntimeError):
    """A collective failed: another process failed (`lost` False) or ended or lost its
    connection (`lost` True: leave at once, JAX's shutdown would wait for it)."""

    def __init__(self, message, lost=False):
        super().__init__(message)
        self.lost = lost


@dataclasses.dataclass
class Processes:
    """This process's place among `count` processes (one process, not connected: 0 of 1).

    ```python
    procs = rockjax.Processes()  # or Processes.start(...) on each machine of a cluster
    print(procs.block(10))  # (0, 10): this process runs every one of 10 runs
    ```
    """

    index: int = 0
    count: int = 1
    active: bool = False
    #: while connected (`start`): undoes the redirection of stdout to stderr
    quiet: contextlib.ExitStack | None = dataclasses.field(default=None, repr=False,
                                                           compare=False)

    @classmethod
    def start(cls, coordinator=None, num_processes=None, process_id=None, *,
              timeout=DEFAULT_TIMEOUT):
        """Start `jax.distributed` (CPUs over gloo) and return this process's place; call
        it before any JAX computation, and `stop` at the end.

        **Arguments:** `coordinator`, "HOST:PORT" of process 0 (which listens on PORT),
        `num_processes` and `process_id` (0 to num_processes - 1); all three None: JAX
        reads them from the cluster's environment (SLURM, Open MPI, ...). `timeout` [s]:
        how long to wait for the coordinator and every process (default 300).

        **Returns:** a `Processes` (active) for `rockjax.sweep(..., processes=...)`. Until
        `stop`, file descriptor 1 goes to 2 (gloo prints to C's stdout).

        Raises a `ParameterError` naming `coordinator` when process 0 cannot listen on its
        port, the host is unknown or (`NoCoordinator`) nobody answered within `timeout`;
        `jax.distributed.initialize`'s own errors otherwise.
        """
        deadline = time.monotonic() + timeout
        if coordinator is not None and process_id is not None:
            _check_coordinator(coordinator, process_id, timeout)
        import jax

        if getattr(jax.config, "jax_cpu_collectives_implementation", "gloo") in (None, "none"):
            jax.config.update("jax_cpu_collectives_implementation", "gloo")
        quiet = contextlib.ExitStack()
        quiet.enter_context(stdout_to_stderr())  # until stop(): gloo prints to C's stdout
        try:
            jax.distributed.initialize(
                coordinator_address=coordinator, num_processes=num_processes,
                process_id=process_id,
                initialization_timeout=max(1, math.ceil(deadline - time.monotonic())))
        except BaseException:
            quiet.close()
            raise
        return cls(jax.process_index(), jax.process_count(), True, quiet=quiet)

    def stop(self):
        """Leave `jax.distributed` (every process waits for the others here); stdout is
        this process's own again. Nothing to do when not connected."""
        if self.active:
            import jax

            self.active = False
            try:
                jax.distributed.shutdown()
            finally:
                if self.quiet is not None:
                    self.quiet.close()

    @classmethod
    def current(cls):
        """This process among the jax.distributed processes (after `initialize`)."""
        import jax

        return cls(jax.process_index(), jax.process_count(), jax.process_count() > 1)

    def block(self, n, index=None):
        """[lo, hi) of this process's (or process `index`'s) runs among n: contiguous, by
        process index, sizes differing by at most one."""
        p = self.index if index is None else index
        return n * p // self.count, n * (p + 1) // self.count

    def agree(self, fingerprint, error=None):
        """Every process checks its inputs against the others': re-raises this process's
        `error`, or names the processes that failed or read different inputs."""
        fp = np.array([[0 if error is None else 1], [fingerprint or 0]], np.int64)
        everyone = self.gather(fp, self.count, error)
        if len(set(everyone[1].tolist())) > 1:
            raise ProcessError(
                "the processes read different inputs (structures, records or scales); every "
                "process needs the same files and the same command line"
            )

    def gather(self, part, n, error=None):
        """Every process's block of `part` (rows x runs of its block), joined into rows x n
        on every process. Row 0 is a flag: nonzero where a process failed; its `error` is
        raised on that process, a `ProcessError` naming it on the others."""
        if not self.active:
            if error is not None:
                raise error
            return part
        sizes = [hi - lo for lo, hi in (self.block(n, p) for p in range(self.count))]
        padded = np.zeros((part.shape[0], max(sizes)), part.dtype)
        padded[:, : part.shape[1]] = part
        from jax.experimental import multihost_utils

        try:
            full = np.asarray(multihost_utils.process_allgather(padded))
        except Exception as e:  # noqa: BLE001 - gloo: "Connection closed by peer"
            first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            raise ProcessError(
                f"process {self.index} of {self.count}: gathering from the other processes "
                f"failed ({first}); another process has ended or lost its connection, see "
                "its output", lost=True) from None
        if error is not None:
            raise error
        failed = [p for p in range(self.count) if full[p, 0].any()]
        if failed:
            whose = "its error message" if len(failed) == 1 else "their error messages"
            raise ProcessError(
                f"process {', '.join(map(str, failed))} of {self.count} failed; see {whose}")
        return np.concatenate([full[p, :, :k] for p, k in enumerate(sizes)], axis=1)


def host_port(text):
    """(host, port) of "HOST:PORT" (an IPv6 host in brackets: [::1]:1234)."""
    host, sep, port = str(text).rpartition(":")
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    if not sep or not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ParameterError(f"must be HOST:PORT with a port 1-65535, got {text!r}",
                             param="coordinator")
    return host, int(port)


def _check_coordinator(text, process_id, timeout):
    """Errors before JAX tries (JAX ends the process on a failed connection): process 0
    must be able to listen on PORT; the others wait for it to answer."""
    host, port = host_port(text)
    if process_id == 0:
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                s.bind(("", port))
            except OSError as e:
                raise ParameterError(f"process 0 cannot listen on port {port} "
                                     f"({e.strerror or e}); choose a free port",
                                     param="coordinator", value=text) from None
        return
    deadline = time.monotonic() + timeout
    while True:  # until something listens at host:port
        left = deadline - time.monotonic()
        try:
            with socket.create_connection((host, port), timeout=max(0.1, min(2.0, left))):
                return
        except socket.gaierror as e:
            raise ParameterError(f"unknown host {host!r} ({e.strerror})", param="coordinator",
                                 value=text) from None
        except OSError as e:
            if left <= 0:
                raise NoCoordinator(f"no coordinator answered within {timeout:g} s "
                                    f"({e.strerror or e}); start process 0 there",
                                    param="coordinator", value=text) from None
        time.sleep(min(0.25, max(0.0, left)))


def fingerprint(meta, arrays):
    """A checksum of JSON-able `meta` and a sequence of pytrees of arrays (records,
    structures): processes that read different inputs disagree on it (`Processes.agree`)."""
    import jax

    h = zlib.crc32(json.dumps(meta).encode())
    for leaf in jax.tree_util.tree_leaves(list(arrays)):
        try:
            data = np.ascontiguousarray(leaf, float).tobytes()
        except (TypeError, ValueError):
            data = repr(leaf).encode()
        h = zlib.crc32(data, h)
    return h


@contextlib.contextmanager
def stdout_to_stderr():
    """Send file descriptor 1 to 2 while connected: gloo prints its connection messages
    ('[Gloo] Rank 0 is connected to 1 peer ranks') to C's stdout, at times of its own,
    where they would mix with a program's output (the command line's report or its
    --json object)."""
    sys.stdout.flush()
    try:
        saved = os.dup(1)
        os.dup2(2, 1)
    except OSError:  # no file descriptors 1 or 2 to move
        yield
        return
    try:
        yield
    finally:
        sys.stdout.flush()
        try:
            ctypes.CDLL(None).fflush(None)
        except (OSError, AttributeError):  # pragma: no cover - no C library to flush
            pass
        os.dup2(saved, 1)
        os.close(saved)
