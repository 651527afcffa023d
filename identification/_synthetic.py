"""The SYNTHETIC decay traces shipped with the package (``data/``): simulations with known
parameters, made by ``data/make_synthetic_traces.py``, not measurements."""

from __future__ import annotations

import json

from ._trace import SYNTHETIC_TRACES

__all__ = ["synthetic_trace_path", "synthetic_truth"]


def synthetic_trace_path(name: str):
    """The packaged CSV file of a SYNTHETIC decay trace.

    Parameters
    ----------
    name : str
        One of :data:`SYNTHETIC_TRACES`: ``"synthetic_decay_clean"``,
        ``"synthetic_decay_noisy"`` or ``"synthetic_decay_exact"`` (without ``.csv``).

    Returns
    -------
    pathlib.Path or importlib.resources.abc.Traversable
        The file ``<name>.csv`` of ``rockjax._data`` (the repository's ``data/`` folder);
        pass it to :func:`read_trace`.

    Raises
    ------
    ValueError
        If `name` is not a shipped synthetic trace.
    """
    return _packaged(name, ".csv")


def synthetic_truth(name: str) -> dict:
    """The true parameters and settings of a SYNTHETIC decay trace (its JSON sidecar).

    Parameters
    ----------
    name : str
        One of :data:`SYNTHETIC_TRACES`.

    Returns
    -------
    dict
        Keys ``synthetic`` (True), ``description``, ``model``, ``k_f`` [N/m], ``r`` [-],
        ``u0`` [m], ``t0`` [s], ``noise_std_u`` [m], ``noise_std_uplift`` [m], ``seed``,
        ``rate_hz`` [Hz], ``duration_s`` [s], ``structure`` (the other Table 1 fields, SI
        units), ``generator`` and ``rockjax_version``.
    """
    with _packaged(name, ".json").open("r", encoding="utf-8") as f:
        return json.load(f)


def _packaged(name: str, suffix: str):
    if name not in SYNTHETIC_TRACES:
        raise ValueError(
            f"unknown synthetic trace {name!r}; expected one of {', '.join(SYNTHETIC_TRACES)}"
        )
    import rockjax  # lazy: reading a trace file needs no JAX

    res = rockjax.datasets.packaged_data_path(name + suffix)
    if not res.is_file():
        raise FileNotFoundError(
            f"synthetic trace file {name + suffix} not found (expected at {res}); "
            "run `python data/make_synthetic_traces.py`"
        )
    return res
