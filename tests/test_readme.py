"""The README runs (issue 13, item 7): every ```python block of README.md, in order, in one
namespace, as written. El Centro comes from the local copy beside the checkout (or
$ROCKJAX_SHARED_DATA); without it the blocks run on the package's synthetic motion and only
the check of the paper's Fig. 10 numbers skips."""

from __future__ import annotations

import re

import numpy as np
import pytest
from conftest import REPO, shared_ground_motions

import rockjax
from rockjax import datasets

BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def readme_blocks():
    return BLOCK.findall((REPO / "README.md").read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def readme(tmp_path_factory):
    """(namespace after every block, whether El Centro was the real record)."""
    mp = pytest.MonkeyPatch()
    tmp = tmp_path_factory.mktemp("readme")
    el = shared_ground_motions() / "IELC180.AT2"
    real = el.is_file()
    mp.setenv("ROCKJAX_CACHE", str(tmp / "cache"))
    if real:
        mp.setenv("ROCKJAX_EL_CENTRO", str(el))
    else:  # a fresh clone without network: the blocks still run, on a synthetic motion
        mp.setattr(datasets, "el_centro", lambda **kw: datasets.synthetic_ground_motion())
    mp.chdir(tmp)
    ns: dict = {}
    try:
        for i, code in enumerate(readme_blocks(), start=1):
            exec(compile(code, f"README.md, python block {i}", "exec"), ns)
    finally:
        mp.undo()
    return ns, real


def test_readme_has_python_blocks():
    blocks = readme_blocks()
    assert len(blocks) >= 4
    assert any("simulate_batch" in b for b in blocks)
    assert any("identification" in b for b in blocks)


def test_readme_blocks_run_and_state_true_values(readme):
    ns, _ = readme
    s = ns["s"]
    assert float(s.u_crit) == pytest.approx(5.497e-3, abs=1e-6)
    assert float(s.P_crit) == pytest.approx(439.0, abs=0.05)
    assert float(s.u_overturn) == pytest.approx(0.3750, abs=5e-5)
    free = ns["free"]
    assert int(free.n_impacts) == 17 and free.status_name == "completed"
    assert free.impacts.shape == (17,) and float(free.peak_u) == pytest.approx(0.100)
    rec = ns["rec"]
    assert rec.dt == pytest.approx(0.01)
    out = ns["out"]  # the last batch of the README
    assert np.all(np.isfinite(np.asarray(out.peak_u)))


def test_readme_el_centro_numbers(readme):
    ns, real = readme
    if not real:
        pytest.skip("the Fig. 10 numbers are about the real El Centro record (not found)")
    quake, rec = ns["quake"], ns["rec"]
    assert rec.npts == 4000 and rec.units_in_file == "g"
    assert int(quake.n_impacts) == 243
    assert 1e3 * float(quake.peak_u) == pytest.approx(102.58, abs=0.005)


def test_readme_quotes_the_fidelity_finding():
    text = (REPO / "README.md").read_text(encoding="utf-8")
    head = text[: text.index("## Quick start")]
    assert "over-predicts" in head and "benchmarks/fidelity.md" in head
    assert "ROCKJAX_SHARED_DATA" in text
    assert isinstance(rockjax.__version__, str)
