"""Shared fixtures: `rockjax.configure()` (x64 on), compile once per session, the generated
ground motion that the tests use, and the path to the shared real records (optional).

No test needs a file from outside the repository: the dynamics tests run on
`synthetic_motion()`, a record that the project generates. Only the few comparisons that
are about one real record (the paper's Fig. 10 El Centro numbers) use the fixture
`ground_motions_dir` and skip where the shared folder is absent.
"""

from __future__ import annotations

import os
import pathlib
import shutil
import subprocess
import sys
import tempfile

import jax
import pytest

import rockjax

# before anything computes: float64 and one CPU device per core, as the command line does
# (`import rockjax` alone changes nothing; the computing entry points would turn float64 on
# with a ConfigurationWarning, an error under the suite's filterwarnings=error)
rockjax.configure()

REPO = pathlib.Path(__file__).resolve().parents[1]

# The command line keeps JAX's persistent compilation cache in ~/.cache/rockjax/jax. The
# suite gives each worker a temporary folder of its own (inherited by the CLI subprocesses),
# so that tests never write to the user's home and two workers never share an entry; a
# test that checks the cache's location sets its own.
_COMPILE_CACHE = tempfile.mkdtemp(
    prefix=f"rockjax-compile-cache-{os.environ.get('PYTEST_XDIST_WORKER', 'main')}-")
os.environ["ROCKJAX_COMPILE_CACHE"] = _COMPILE_CACHE


def pytest_sessionfinish(session, exitstatus):
    shutil.rmtree(_COMPILE_CACHE, ignore_errors=True)


def pytest_runtest_logfinish(nodeid, location):
    """With ROCKJAX_MEMLOG=FILE, each worker appends "worker nodeid peak-RSS-kB" after every
    test: where a worker's memory grows (issue 24: a worker peaked at 5.8 GB;
    `python benchmarks/worker_memory.py` reads the log)."""
    path = os.environ.get("ROCKJAX_MEMLOG")
    if path:
        import resource

        rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        with open(path, "a") as f:
            f.write(f"{os.environ.get('PYTEST_XDIST_WORKER', 'main')} {nodeid} {rss}\n")


#: a worker whose resident memory exceeds this after a test module drops JAX's compiled
#: programs [bytes] (ROCKJAX_TEST_RSS_LIMIT overrides it; 0: after every module)
RSS_LIMIT = float(os.environ.get("ROCKJAX_TEST_RSS_LIMIT", 2e9))


def _rss() -> int:
    """The resident memory of this process now [bytes] (0 where /proc is missing)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


@pytest.fixture(autouse=True, scope="module")
def _free_compiled_programs():
    """After a test module, a worker above `RSS_LIMIT` drops JAX's compiled programs and
    traces (`jax.clear_caches()`): a worker kept every program of every module it ran and
    grew to about 5 GB (issue 24). Dropping them after every module bounds the memory
    better but compiles more (measured on four modules in one process: 2.6 GB and 353 s
    against 3.8 GB and 297 s), so only a worker that has grown pays for it."""
    yield
    if _rss() > RSS_LIMIT:
        import gc

        jax.clear_caches()
        gc.collect()


@pytest.fixture(autouse=True)
def _no_process_wide_compile_cache():
    """No test leaves JAX's persistent compilation cache on in the test process itself.
    With it on, every later compile of the worker also serialises its executable to disk,
    and XLA:CPU's serialisation has crashed long-lived workers (segfaults inside
    `put_executable_and_time` and `backend_compile_and_load`, twice in full runs of the
    suite on the 2-core machine). The command line's cache is tested in subprocesses."""
    yield
    assert jax.config.jax_compilation_cache_dir is None, (
        "this test turned on JAX's persistent compilation cache in the test process")

#: The tests' stand-in for El Centro 1940 NS (IELC180): `rockjax.datasets.
#: synthetic_ground_motion` with El Centro's length, step and PGA (40 s, 0.01 s,
#: 3.068 m/s² = 0.3129 g). Seed 20 is chosen for physics like El Centro's on the Table 1
#: column: at x1 it completes after 237 impacts (El Centro: 243) with a peak of 31 mm, and
#: it overturns the column from x1.65 up (El Centro: x1.64) with all scales up to x1.54
#: completed (on a 0.005 grid to x2.5, rk4 and dopri5 agreeing at every scale).
SYNTHETIC_MOTION = dict(duration=40.0, dt=0.01, pga=3.068, seed=20)


def synthetic_motion():
    """The generated test record (`SYNTHETIC_MOTION`), a `rockjax.Record` in m/s²."""
    return rockjax.datasets.synthetic_ground_motion(**SYNTHETIC_MOTION)


def shared_ground_motions() -> pathlib.Path:
    """`../shared/data/ground_motions` beside the checkout, or $ROCKJAX_SHARED_DATA."""
    env = os.environ.get("ROCKJAX_SHARED_DATA")
    if env:
        return pathlib.Path(env)
    return REPO.parent / "shared" / "data" / "ground_motions"


def run_cli(*args, cwd=None):
    """Run the real console entry point in a subprocess (as a user would)."""
    return subprocess.run(
        [sys.executable, "-m", "rockjax.cli", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
    )


@pytest.fixture(scope="session")
def column():
    """The Table 1 McManus column."""
    return rockjax.mcmanus_column()


@pytest.fixture(scope="session")
def synthetic_record():
    """`synthetic_motion()`, generated once per session."""
    return synthetic_motion()


@pytest.fixture(scope="session")
def ground_motions_dir():
    """The shared real records; skips the test where they are absent. Use it only for a
    comparison about one specific real record (the suite allows at most 5 such skips)."""
    d = shared_ground_motions()
    if not d.is_dir():
        pytest.skip(f"shared ground motions not found at {d}")
    return d
