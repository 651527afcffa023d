"""Batches split over `jax.distributed` processes: each runs a contiguous block of the
runs, and the blocks are gathered (`jax.experimental.multihost_utils.process_allgather`,
on CPUs over gloo) so that every process ends with every result.

`Processes()` is one process that connects nowhere; `Processes.current()` is this
process's place once `jax.distributed.initialize` has run. `rockjax.sweep(...,
processes=...)` uses it; the command line (`rockjax sweep --distributed`) starts the
processes and hands it over.
"""

from __future__ import annotations

import contextlib
import ctypes
import dataclasses
import json
import os
import sys
import zlib

import numpy as np


class ProcessError(RuntimeError):
    """A collective failed: another process failed (`lost` False) or ended or lost its
    connection (`lost` True: leave at once, JAX's shutdown would wait for it)."""

    def __init__(self, message, lost=False):
        super().__init__(message)
        self.lost = lost


@dataclasses.dataclass
class Processes:
    """This process's place among `count` processes (one process, not connected: 0 of 1)."""

    index: int = 0
    count: int = 1
    active: bool = False

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
