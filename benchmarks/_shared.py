"""What the benchmark scripts share: where the shared ground-motion records are."""

from __future__ import annotations

import os
import pathlib


def shared_folder() -> pathlib.Path:
    """The folder of the shared records: `$ROCKJAX_SHARED_DATA`, else
    `../shared/data/ground_motions` beside the repository (they are never copied into it)."""
    env = os.environ.get("ROCKJAX_SHARED_DATA")
    if env:
        return pathlib.Path(env)
    return pathlib.Path(__file__).resolve().parents[2] / "shared" / "data" / "ground_motions"
