"""Execute every notebook in notebooks/ so that the examples never rot.

The notebooks that use El Centro (`rockjax.datasets.el_centro()`) read the shared copy
where there is one; otherwise they get no record and no network (ROCKJAX_EL_CENTRO names a
missing file, so `el_centro()` fails at once) and must fall back to their labelled
synthetic ground motion, as in a fresh clone.
"""

from __future__ import annotations

import pathlib

import nbclient
import nbformat
import pytest

NOTEBOOKS = sorted((pathlib.Path(__file__).resolve().parents[1] / "notebooks").glob("*.ipynb"))
FALLBACK = "El Centro unavailable"  # what each notebook prints when it falls back


def test_there_are_notebooks():
    assert NOTEBOOKS, "notebooks/ holds no notebook"


def _outputs(nb, output_type):
    return [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
            if o.get("output_type") == output_type]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_executes(path, tmp_path, monkeypatch):
    # Kernels inherit the environment: the local El Centro copy, else a missing file.
    from conftest import shared_ground_motions

    record = shared_ground_motions() / "IELC180.AT2"
    real = record.is_file()
    if not real:
        record = tmp_path / "no-el-centro" / "IELC180.AT2"
    monkeypatch.setenv("ROCKJAX_EL_CENTRO", str(record))
    monkeypatch.setenv("ROCKJAX_CACHE", str(tmp_path / "cache"))
    nb = nbformat.read(path, as_version=4)
    uses_el_centro = "datasets.el_centro()" in path.read_text()
    client = nbclient.NotebookClient(
        nb, timeout=900, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute()
    assert not _outputs(nb, "error")
    printed = "".join(o.get("text", "") for o in _outputs(nb, "stream"))
    assert (FALLBACK in printed) == (uses_el_centro and not real), printed[:2000]
