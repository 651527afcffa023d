"""Generate the SYNTHETIC free-vibration decay traces shipped in data/ (rockjax._data).

Run from anywhere: ``python data/make_synthetic_traces.py``. Writes, next to this script,
``<name>.csv`` (comment lines starting ``# SYNTHETIC``, then ``t,u,uplift`` in s, m, m) and
``<name>.json`` (the true parameters and settings) for each trace below. Every trace is a
rockjax simulation of the McManus (1980) column of Table 1 with a chosen foundation
stiffness k_f and restitution r, released from u0 at rest; they are NOT measurements.
The output is deterministic (fixed seeds), so re-running reproduces the committed files.

`noisy_variant(seed, rate_hz=...)` makes more traces like ``synthetic_decay_noisy`` (same
truth and noise, another seed or sampling rate) for tests; it writes nothing.
"""

from __future__ import annotations

import io
import json
import pathlib

import jax.numpy as jnp
import numpy as np

import rockjax

HERE = pathlib.Path(__file__).resolve().parent
RATE_HZ = 200.0
DURATION_S = 8.0
N_SAMPLES = 1601  # t = np.arange(N_SAMPLES) / RATE_HZ, 0 .. 8 s
U0 = 0.10  # m, initial top displacement, released at rest
FMT = "%.10g"  # ~10 significant digits: rounding error < 1e-11 m for |u| <= 0.1 m

TRACES = {
    "synthetic_decay_clean": dict(
        description=(
            "SYNTHETIC free-vibration decay of the McManus column (Table 1 geometry and "
            "masses, k_f = 550 kN/m as in the paper), simplified restoring force, no noise."
        ),
        model="simplified",
        k_f=550e3,
        r=0.80,
        noise_std_u=0.0,
        noise_std_uplift=0.0,
        seed=None,
    ),
    "synthetic_decay_noisy": dict(
        description=(
            "SYNTHETIC free-vibration decay of the McManus column with k_f = 800 kN/m, "
            "simplified restoring force, Gaussian noise of std 0.5% of u0 (5e-4 m) on u "
            "and 1e-4 m on uplift."
        ),
        model="simplified",
        k_f=800e3,
        r=0.85,
        noise_std_u=5e-4,  # 0.5% of u0
        noise_std_uplift=1e-4,
        seed=20261121,
    ),
    "synthetic_decay_exact": dict(
        description=(
            "SYNTHETIC free-vibration decay of the McManus column with k_f = 800 kN/m made "
            "with the geometrically EXACT restoring force, no noise: fitting it with the "
            "simplified model measures the model-mismatch error."
        ),
        model="exact",
        k_f=800e3,
        r=0.85,
        noise_std_u=0.0,
        noise_std_uplift=0.0,
        seed=None,
    ),
}


def sample_times(rate_hz: float = RATE_HZ) -> np.ndarray:
    """The sample times [s]: 0 .. 8 s at `rate_hz` (default 200 Hz: 1601 samples)."""
    if rate_hz == RATE_HZ:
        return np.arange(N_SAMPLES) / RATE_HZ
    return np.arange(round(DURATION_S * rate_hz) + 1) / rate_hz


def simulate_trace(k_f: float, r: float, model: str, u0: float = U0, structure=None,
                   rate_hz: float = RATE_HZ):
    """Noise-free (t, u, uplift) of a free-vibration run, as numpy float64 arrays."""
    t = sample_times(rate_hz)
    base = rockjax.mcmanus_column() if structure is None else structure
    s = base.replace(k_f=k_f)
    res = rockjax.simulate(
        s, rockjax.FreeVibration(u0), float(t[-1]), ts=jnp.asarray(t), r=r, model=model
    )
    if res.status_name != "completed":
        raise RuntimeError(f"simulation did not complete: {res.status_name}")
    return t, np.asarray(res.u, dtype=np.float64), np.asarray(res.uplift, dtype=np.float64)


def add_noise(u, up, seed: int, noise_std_u: float, noise_std_uplift: float):
    """(u, uplift) with Gaussian noise from numpy's default_rng(seed): u first, then uplift."""
    rng = np.random.default_rng(seed)
    u = u + rng.normal(0.0, noise_std_u, size=u.shape)
    up = up + rng.normal(0.0, noise_std_uplift, size=up.shape)
    return u, up


def noisy_variant(seed: int, rate_hz: float = RATE_HZ, clean=None):
    """(t, u, uplift) like ``synthetic_decay_noisy`` (its k_f, r, model and noise levels:
    0.5 % of u0 on u) with another `seed` and/or sampling rate; `clean`: the noise-free
    (t, u, uplift) of that rate, if already simulated (to add noise with many seeds)."""
    spec = TRACES["synthetic_decay_noisy"]
    if clean is None:
        clean = simulate_trace(spec["k_f"], spec["r"], spec["model"], rate_hz=rate_hz)
    t, u, up = clean
    u, up = add_noise(u, up, seed, spec["noise_std_u"], spec["noise_std_uplift"])
    return t, u, up


def make(name: str, spec: dict) -> None:
    t, u, up = simulate_trace(spec["k_f"], spec["r"], spec["model"])
    if spec["seed"] is not None:
        u, up = add_noise(u, up, spec["seed"], spec["noise_std_u"], spec["noise_std_uplift"])
    structure = rockjax.mcmanus_column().to_dict()
    structure.pop("k_f")
    truth = {
        "synthetic": True,
        "description": spec["description"],
        "model": spec["model"],
        "k_f": spec["k_f"],
        "r": spec["r"],
        "u0": U0,
        "t0": 0.0,
        "noise_std_u": spec["noise_std_u"],
        "noise_std_uplift": spec["noise_std_uplift"],
        "seed": spec["seed"],
        "rate_hz": RATE_HZ,
        "duration_s": DURATION_S,
        "structure": structure,
        "generator": "data/make_synthetic_traces.py",
        "rockjax_version": rockjax.__version__,
    }
    noise = (
        f"Gaussian noise std {spec['noise_std_u']:g} m on u, {spec['noise_std_uplift']:g} m "
        f"on uplift (numpy default_rng seed {spec['seed']})"
        if spec["seed"] is not None
        else "no noise"
    )
    header = [
        "SYNTHETIC data: a rockjax simulation, NOT a measurement.",
        f"SYNTHETIC {name}: model={spec['model']}, k_f={spec['k_f']:g} N/m, r={spec['r']:g}, "
        f"u0={U0:g} m released at rest at t=0, {noise}.",
        "SYNTHETIC structure: McManus (1980) column, Table 1 (except k_f); true values in "
        f"{name}.json.",
        f"SYNTHETIC generated by data/make_synthetic_traces.py (rockjax {rockjax.__version__}); "
        "columns t [s], u [m] top displacement, uplift [m].",
    ]
    body = io.StringIO()
    np.savetxt(body, np.column_stack([t, u, up]), fmt=FMT, delimiter=",")
    path = HERE / f"{name}.csv"
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.writelines(f"# {line}\n" for line in header)
        f.write("t,u,uplift\n")
        f.write(body.getvalue())
    (HERE / f"{name}.json").write_text(json.dumps(truth, indent=2) + "\n")
    print(f"wrote {path.name} ({len(t)} rows) and {name}.json")


def main() -> None:
    for name, spec in TRACES.items():
        make(name, spec)


if __name__ == "__main__":
    main()
