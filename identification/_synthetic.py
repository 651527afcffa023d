"""The SYNTHETIC decay traces shipped with the package (``data/``): simulations with known
parameters, made by ``data/make_synthetic_traces.py``, not measurements; and
`synthetic_trace`, which makes one with a lab trace's faults (offset, drift, hum,
clipping, a second release)."""

from __future__ import annotations

import dataclasses
import json

from ._trace import SYNTHETIC_TRACES

__all__ = ["synthetic_trace", "synthetic_trace_path", "synthetic_truth"]


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


@dataclasses.dataclass(frozen=True)
class Faults:
    r"""The faults of a lab sensor that `synthetic_trace` adds to a clean decay: the
    reading is $u(t) + o + d\,t + A\sin(2\pi f t) + \varepsilon$, clipped to $\pm$`clip`.

    **Arguments:**

    - `offset` $o$ [m], `drift` $d$ [m/s]: the sensor's zero and drift (default 0).
    - `hum`: `(A [m], f [Hz])`, a steady periodic component (50 Hz mains hum, say).
    - `clip` [m]: the sensor saturates at $\pm$clip (the reading is clipped there).
    - `second`: `(t_2 [s], u_2 [m])`: the structure is set to u_2 at t_2 - 0.2 s, held, and
      released again at t_2 (the first decay should be over by then).

    **Example:**

        >>> identification.Faults(offset=4e-3)
        Faults(offset=0.004, drift=0.0, hum=None, clip=None, second=None)
    """

    offset: float = 0.0
    drift: float = 0.0
    hum: tuple | None = None
    clip: float | None = None
    second: tuple | None = None


def synthetic_trace(*, k_f: float = 800e3, r: float = 0.85, model="simplified",
                    u0: float = 0.1, rate_hz: float = 200.0, duration: float = 8.0,
                    noise: float = 5e-4, seed: int | None = 0, faults: Faults | None = None,
                    structure=None, **keywords):
    r"""A SYNTHETIC decay trace (a rockjax simulation, not a measurement) with the faults a
    lab trace can have, and its truth.

    The structure (default: the McManus column of Table 1 with `k_f` [N/m]) is released
    from rest at `u0` [m] at t = 0 and rocks with restitution `r` under `model`, sampled at
    `rate_hz` [Hz] for `duration` [s]; the sensor reads it with Gaussian noise of std
    `noise` [m] (numpy `default_rng(seed)`) and `faults` (an `identification.Faults`:
    offset, drift, mains hum, clipping, a second release; default none). The faults'
    fields are also accepted as keywords (`offset=4e-3`), the form of earlier versions.

    Returns `(DecayTrace, truth)`: truth holds every argument (and `source`), in SI units.

    ```python
    trace, truth = identification.synthetic_trace(faults=identification.Faults(offset=4e-3),
                                                  duration=2.0, seed=1)
    ```
    """
    unknown = set(keywords) - {f.name for f in dataclasses.fields(Faults)}
    if unknown:
        raise TypeError(f"synthetic_trace() got unexpected keyword arguments {sorted(unknown)}")
    if faults is not None and keywords:
        raise ValueError(f"{sorted(keywords)[0]}= and faults= both given; set it on the Faults")
    faults = Faults(**keywords) if faults is None else faults
    offset, drift, hum, clip, second = (faults.offset, faults.drift, faults.hum, faults.clip,
                                        faults.second)
    import numpy as np

    import rockjax

    from ._trace import DecayTrace

    base = rockjax.mcmanus_column() if structure is None else structure
    s = base.replace(k_f=k_f)
    t = np.arange(int(round(duration * rate_hz)) + 1) / rate_hz

    def run(ts, start):
        res = rockjax.simulate(s, rockjax.FreeVibration(start), float(ts[-1]), ts=ts, r=r,
                               model=model)
        if res.status_name != "completed":
            raise RuntimeError(f"the synthetic run did not complete: {res.status_name}")
        return np.array(res.u, float)

    u = run(t, u0)
    if second is not None:
        t2, u2 = float(second[0]), float(second[1])
        after = t >= t2
        u[(t >= t2 - 0.2) & ~after] = u2
        u[after] = run(t[after] - t[after][0], u2)
    rng = np.random.default_rng(seed)
    u = u + offset + drift * t + (rng.normal(0.0, noise, t.size) if noise else 0.0)
    if hum is not None:
        u = u + hum[0] * np.sin(2 * np.pi * hum[1] * t)
    if clip is not None:
        u = np.clip(u, -clip, clip)
    truth = {"synthetic": True, "k_f": k_f, "r": r, "model": str(model), "u0": u0, "t0": 0.0,
             "rate_hz": rate_hz, "duration_s": duration, "noise_std_u": noise, "seed": seed,
             "offset": offset, "drift": drift, "hum": hum, "clip": clip, "second": second}
    src = f"SYNTHETIC decay (k_f={k_f:g}, r={r:g}, offset={offset:g}, seed={seed})"
    return DecayTrace(t, u, source=src), truth
