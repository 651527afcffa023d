"""Shared fixtures: x64 on, compile once per session, paths to the shared ground motions."""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys

import jax
import pytest

jax.config.update("jax_enable_x64", True)

import rockjax  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[1]


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
def ground_motions_dir():
    d = shared_ground_motions()
    if not d.is_dir():
        pytest.skip(f"shared ground motions not found at {d}")
    return d
