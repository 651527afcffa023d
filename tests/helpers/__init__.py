"""Helpers of the test suite, importable from any test as ``from helpers.X import ...``
(pytest puts tests/ on ``sys.path``, as for ``conftest``). One home for what tests share:
tests never load benchmarks/ by path; a benchmark may import these modules instead (it
puts tests/ on its path first).

- `helpers.records`: writers of synthetic ground-motion records (AT2, two columns, one);
- `helpers.matrix`: the corpus of the model × integrator matrix and its agreement rule
  (tests/test_matrix.py; `benchmarks/matrix.py` writes docs/matrix.md from it);
- `helpers.fit_models`: the synthetic decay traces of the model ladder
  (tests/test_fit_models.py; `benchmarks/fit_models.py`);
- `helpers.messy`: the messy corpus of issue 24, files with their truth (tests/test_messy.py;
  `python tests/helpers/messy.py` prints the table);
- `helpers.lengths`: the lines of code of a function (tests/test_architecture.py;
  `benchmarks/longest_functions.py`).
"""
