"""`jax.distributed` for the command line: the flags, and the processes started and stopped
in the command's terms (`rockjax.Processes.start` connects them; the split of the runs and
the gathers are `rockjax.Processes`, used by `rockjax.sweep`).

A plain command never connects anywhere. Only `--distributed` (JAX reads the cluster's
environment: SLURM, Open MPI, ...) or the three flags `--coordinator`, `--num-processes`
and `--process-id` start `jax.distributed`, and they do so before any JAX computation.
Each process then runs its own contiguous block of the runs on its local devices; the
blocks are gathered with `jax.experimental.multihost_utils.process_allgather` (on CPUs
over gloo), so every process ends with every result and process 0 writes them.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import sys

import rockjax
from rockjax._distributed import DEFAULT_TIMEOUT, host_port, NoCoordinator, ProcessError

from ._common import CLIError, converter, EXIT_USAGE, positive_int

#: the flags that name the processes explicitly, all or none
_EXPLICIT = ("coordinator", "num_processes", "process_id")


def add_distributed_arguments(parser):
    """--distributed, --coordinator, --num-processes, --process-id, --coordinator-timeout."""
    g = parser.add_argument_group(
        "several processes or machines (jax.distributed)",
        "Run the sweep as N processes, each on its own block of the runs (its local "
        "devices), with the same command line and the same input files everywhere; process "
        "0 gathers the results and writes the CSV, JSON and plot exactly as one process "
        "would, the others write nothing. Without these flags nothing connects anywhere.",
    )
    g.add_argument("--distributed", action="store_true",
                   help="start jax.distributed from the cluster's environment (JAX detects "
                   "SLURM, Open MPI, ...: e.g. srun rockjax sweep ... --distributed); flags "
                   "given beside it win")
    g.add_argument("--coordinator", metavar="HOST:PORT", help="address of process 0, which "
                   "listens on PORT (with --num-processes and --process-id)")
    g.add_argument("--num-processes", type=positive_int("--num-processes"), metavar="N",
                   help="how many processes take part (with --coordinator and --process-id)")
    g.add_argument("--process-id", metavar="I",
                   type=converter("--process-id", int, lambda i: i >= 0, "be 0 or more"),
                   help="this process's index, 0 to N-1; 0 runs the coordinator and writes "
                   "the outputs")
    g.add_argument("--coordinator-timeout", default=None, metavar="S",
                   type=converter("--coordinator-timeout", float,
                                  lambda x: math.isfinite(x) and x > 0,
                                  "be a positive number of seconds",
                                  noun="a positive number of seconds"),
                   help=f"seconds to wait for the coordinator and every process to connect "
                   f"(default {DEFAULT_TIMEOUT:g})")


def requested(args):
    """Whether the command line asks for jax.distributed (flags checked)."""
    given = [f for f in _EXPLICIT if getattr(args, f, None) is not None]
    if given and len(given) < len(_EXPLICIT) and not args.distributed:
        missing = [f"--{f.replace('_', '-')}" for f in _EXPLICIT if f not in given]
        raise CLIError(
            f"{', '.join(missing)} missing: give all of --coordinator, --num-processes and "
            "--process-id, or --distributed to read the rest from the cluster's environment"
        )
    if args.num_processes is not None and args.process_id is not None:
        if args.process_id >= args.num_processes:
            raise CLIError(
                f"--process-id {args.process_id} is out of range for --num-processes "
                f"{args.num_processes} (0 to {args.num_processes - 1})"
            )
    if args.coordinator is not None:
        try:
            host_port(args.coordinator)
        except ValueError as e:
            raise CLIError(f"--coordinator {e.message}") from None
    wanted = bool(given) or args.distributed
    if args.coordinator_timeout is not None and not wanted:
        raise CLIError("--coordinator-timeout applies with --distributed or --coordinator only")
    return wanted


# ------------------------------------------------------------------------------ start
@dataclasses.dataclass
class Cluster(rockjax.Processes):
    """`rockjax.Processes` and the command's way out: a failed collective as a one-line
    error, and a prompt exit when a process was lost."""

    #: why a collective failed (another process died): then `stop` leaves at once
    lost: str | None = None

    @contextlib.contextmanager
    def collective(self):
        """A failed collective as a one-line CLIError (a lost process noted for `stop`)."""
        try:
            yield
        except ProcessError as e:
            if e.lost:
                self.lost = str(e)
            raise CLIError(str(e)) from None

    def stop(self):
        """`rockjax.Processes.stop`; after a lost process, say why and leave at once."""
        if self.lost is not None:
            # JAX's shutdown (here or at exit) would wait for the lost process until its
            # heartbeat timeout (100 s) and then abort with a stack trace: say why, leave
            print(f"rockjax sweep: error: {self.lost}", file=sys.stderr, flush=True)
            os._exit(EXIT_USAGE)
        super().stop()


def start(args):
    """The Cluster of this process: jax.distributed started as the flags ask, or one
    process that connects nowhere. Call before any JAX computation."""
    if not requested(args):
        return Cluster()
    timeout = DEFAULT_TIMEOUT if args.coordinator_timeout is None else args.coordinator_timeout
    try:
        return Cluster.start(args.coordinator, args.num_processes, args.process_id,
                             timeout=timeout)
    except NoCoordinator as e:
        raise CLIError(f"--coordinator {e.value}: {e.message}, or raise --coordinator-timeout"
                       ) from None
    except rockjax.ParameterError:
        raise
    except BaseException as e:
        raise _start_error(e, args) from None


def _start_error(e, args):
    """The error of a failed jax.distributed.initialize, naming the flag where it can."""
    if isinstance(e, RuntimeError) and "before any JAX" in str(e):
        return CLIError("--distributed/--coordinator: JAX has already started in this "
                        "process; run rockjax sweep in a fresh process")
    if isinstance(e, ValueError) and args.distributed:
        return CLIError(f"--distributed: JAX found no cluster in the environment ({e}); "
                        "give --coordinator, --num-processes and --process-id")
    if isinstance(e, ValueError):
        return CLIError(f"--coordinator: {e}")
    return e
