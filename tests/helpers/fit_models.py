"""SYNTHETIC decay traces of the model ladder (rockjax simulations plus Gaussian noise,
released at rest from u0 = 0.1 m at t = 0, Table 1 geometry and masses), for
tests/test_fit_models.py and `python benchmarks/fit_models.py` (which fits every model to
each and prints the table of docs/identification.md):

- `sdof`: the shipped `synthetic_decay_noisy` (simplified SDOF, k_f = 800 kN/m, r = 0.85,
  8 s at 200 Hz, noise 0.5 mm on u and 0.1 mm on uplift);
- `2dof_continuous`: the 2-DOF body on its springs with continuous contact and
  compression-only dashpots at 5 % of critical of the vertical mode, c_f =
  0.05 sqrt(2 k_f (m_e + m_b)) = 678 N s/m, k_f = 550 kN/m (the trace of issue 14);
- `2dof_impact`: the 2-DOF body with impact contact (Housner's impact at each landing, r
  from Eq. 3 = 0.735, no dashpots), k_f = 550 kN/m;
- `rigid_body`: the body's one-DOF rotational equation (`model="rigid_body"`), k_f = 550
  kN/m, r from Eq. 3;

the last three 4 s at 100 Hz with noise 0.5 mm on u (no uplift channel), integrated with
`method="dopri5"` at rtol 1e-10.
"""

from __future__ import annotations

import math

import numpy as np

import identification
import rockjax

K_F = 550e3  # [N/m] k_f of the 2-DOF and rigid-body traces
U0 = 0.1  # [m] release displacement
DURATION = 4.0  # [s]
RATE_HZ = 100.0
NOISE = 5e-4  # [m] std of the displacement noise
ZETA = 0.05  # damping ratio of the vertical mode given by the dashpots (continuous)
SEEDS = {"2dof_continuous": 14, "2dof_impact": 15, "rigid_body": 16}
TRACES = ("sdof", "2dof_continuous", "2dof_impact", "rigid_body")
def dashpot(structure, k_f=K_F, zeta=ZETA):
    """c_f [N s/m] giving the damping ratio `zeta` of the vertical mode: sqrt(2 k_f M)."""
    return zeta * math.sqrt(2.0 * k_f * (float(structure.m_e) + float(structure.m_b)))


def _model_of(name, structure):
    if name == "2dof_continuous":
        return rockjax.TwoSpring2DOF(damping=dashpot(structure), contact="continuous")
    if name == "2dof_impact":
        return rockjax.TwoSpring2DOF(contact="impact")
    return name


def make_trace(name):
    """(trace, truth) of the SYNTHETIC trace `name` (see the module docstring); truth: the
    true values of k_f, r (None where r does not act), c_f (None without dashpots), u0, t0
    and the generating model."""
    if name == "sdof":
        path = identification.synthetic_trace_path("synthetic_decay_noisy")
        truth = identification.synthetic_truth("synthetic_decay_noisy")
        return identification.read_trace(path), {
            "k_f": truth["k_f"], "r": truth["r"], "c_f": None, "u0": truth["u0"],
            "t0": truth["t0"], "model": "simplified"}
    if name not in SEEDS:
        raise ValueError(f"unknown trace {name!r}; expected one of {TRACES}")
    s = rockjax.mcmanus_column().replace(k_f=K_F)
    ts = np.arange(int(round(DURATION * RATE_HZ)) + 1) / RATE_HZ
    res = rockjax.simulate(s, rockjax.FreeVibration(U0), DURATION, ts=ts,
                           model=_model_of(name, s), method="dopri5", rtol=1e-10,
                           atol=1e-12)
    if res.status_name != "completed":
        raise RuntimeError(f"the {name} trace did not complete: {res.status_name}")
    u = np.asarray(res.u) + np.random.default_rng(SEEDS[name]).normal(0.0, NOISE, ts.size)
    truth = {"k_f": K_F, "r": None if name == "2dof_continuous" else float(s.restitution),
             "c_f": dashpot(s) if name == "2dof_continuous" else None, "u0": U0, "t0": 0.0,
             "model": name}
    if name == "2dof_impact":
        truth["c_f"] = 0.0
    return identification.DecayTrace(ts, u, source=f"SYNTHETIC {name}"), truth
