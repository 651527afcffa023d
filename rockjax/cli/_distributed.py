"""`jax.distributed` for the command line: the flags, starting and stopping the processes
(the split of the runs and the gathers are `rockjax.Processes`, used by `rockjax.sweep`).

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
import socket
import sys
import time

import rockjax
from rockjax._distributed import ProcessError, stdout_to_stderr

from ._common import CLIError, converter, EXIT_USAGE, positive_int

#: how long a process waits for the coordinator and the others by default [s] (JAX's 300)
DEFAULT_TIMEOUT = 300.0
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


def _host_port(text):
    """(host, port) of --coordinator HOST:PORT (an IPv6 host in brackets: [::1]:1234)."""
    host, sep, port = str(text).rpartition(":")
    host = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    if not sep or not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise CLIError(f"--coordinator must be HOST:PORT with a port 1-65535, got {text!r}")
    return host, int(port)


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
        _host_port(args.coordinator)
    wanted = bool(given) or args.distributed
    if args.coordinator_timeout is not None and not wanted:
        raise CLIError("--coordinator-timeout applies with --distributed or --coordinator only")
    return wanted


# ------------------------------------------------------------------------------ start
@dataclasses.dataclass
class Cluster(rockjax.Processes):
    """`rockjax.Processes` (the block split and the gathers) and the command's connection:
    stdout sent to stderr while connected, and a prompt exit when a process was lost."""

    #: undoes the redirection of stdout to stderr held while connected
    quiet: contextlib.ExitStack | None = dataclasses.field(default=None, repr=False)
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
        """Leave jax.distributed (every process waits for the others here); stdout is
        this process's own again."""
        if self.lost is not None:
            # JAX's shutdown (here or at exit) would wait for the lost process until its
            # heartbeat timeout (100 s) and then abort with a stack trace: say why, leave
            print(f"rockjax sweep: error: {self.lost}", file=sys.stderr, flush=True)
            os._exit(EXIT_USAGE)
        if self.active:
            import jax

            self.active = False
            try:
                jax.distributed.shutdown()
            finally:
                self.quiet.close()


def start(args):
    """The Cluster of this process: jax.distributed started as the flags ask, or one
    process that connects nowhere. Call before any JAX computation."""
    if not requested(args):
        return Cluster()
    import jax

    if getattr(jax.config, "jax_cpu_collectives_implementation", "gloo") in (None, "none"):
        jax.config.update("jax_cpu_collectives_implementation", "gloo")
    timeout = DEFAULT_TIMEOUT if args.coordinator_timeout is None else args.coordinator_timeout
    deadline = time.monotonic() + timeout
    if args.coordinator is not None and args.process_id is not None:
        _check_coordinator(args.coordinator, args.process_id, timeout)
    kwargs = {"coordinator_address": args.coordinator, "num_processes": args.num_processes,
              "process_id": args.process_id,
              "initialization_timeout": max(1, math.ceil(deadline - time.monotonic()))}
    quiet = contextlib.ExitStack()
    quiet.enter_context(stdout_to_stderr())  # until stop(): gloo prints to C's stdout
    try:
        jax.distributed.initialize(**kwargs)
    except BaseException as e:
        quiet.close()
        raise _start_error(e, args) from None
    return Cluster(jax.process_index(), jax.process_count(), True, quiet=quiet)


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


def _check_coordinator(text, process_id, timeout):
    """One-line errors before JAX tries (JAX ends the process on a failed connection):
    process 0 must be able to listen on PORT; the others wait for it to answer."""
    host, port = _host_port(text)
    if process_id == 0:
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                s.bind(("", port))
            except OSError as e:
                raise CLIError(
                    f"--coordinator {text}: process 0 cannot listen on port {port} "
                    f"({e.strerror or e}); choose a free port"
                ) from None
        return
    _wait_for(host, port, text, timeout)


def _wait_for(host, port, text, timeout):
    """Return once something listens at host:port; a CLIError after `timeout` seconds."""
    deadline = time.monotonic() + timeout
    while True:
        left = deadline - time.monotonic()
        try:
            with socket.create_connection((host, port), timeout=max(0.1, min(2.0, left))):
                return
        except socket.gaierror as e:
            raise CLIError(f"--coordinator {text}: unknown host {host!r} ({e.strerror})") from None
        except OSError as e:
            if left <= 0:
                raise CLIError(
                    f"--coordinator {text}: no coordinator answered within {timeout:g} s "
                    f"({e.strerror or e}); start process 0 there, or raise "
                    "--coordinator-timeout"
                ) from None
        time.sleep(min(0.25, max(0.0, left)))
