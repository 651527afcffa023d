"""The fidelity warning: the paper's SDOF under a ground motion that rocks the body well
past lift-off.

Eq. 1 lumps the whole mass and the whole inertial force at the top mass. Under a ground
motion the body itself responds to about Gamma = H_e (m_e H_e + m_b H_b) / I_c of that
forcing (0.779 for Table 1), and on the ensemble of `benchmarks/fidelity.md` the paper's
SDOF peak is off by a median of tens of per cent once the body lifts off by more than a
few u_crit. `docs/models.md` says which model fits which scene.
"""

from __future__ import annotations

import warnings

import jax
import numpy as np

from .models import SDOF

#: peak |u| / u_crit beyond which the warning fires
LIFT_OFF_LIMIT = 3.0


class FidelityWarning(UserWarning):
    """The paper's SDOF model ran a scene it is known to represent poorly (see
    `docs/models.md`). Silence it with `fidelity_warning=False` or
    `warnings.filterwarnings("ignore", category=rockjax.FidelityWarning)`."""


def _concrete(x):
    return not isinstance(x, jax.core.Tracer)


#: what the warning advises, in Python terms (the command line passes its own options)
ADVICE = ("use model=\"rigid_body\" (the body's own one-DOF equation, about as fast) or "
          "\"two_spring_2dof\". See docs/models.md; silence with fidelity_warning=False")


def sdof_lift_off_message(model, structure, forced, peak_u, model_name=None, advice=ADVICE):
    """The warning's text when the paper's SDOF (`model`, an `SDOF`) lifted a structure off
    by more than `LIFT_OFF_LIMIT` u_crit under a ground motion; else None. `peak_u` [m] may
    be batched (the message then counts the runs). `advice` ends it (`ADVICE`)."""
    if not (forced and isinstance(model, SDOF)):
        return None
    if not (_concrete(peak_u) and _concrete(structure.u_crit)):
        return None  # inside jit, grad or vmap: nothing to look at
    ratio = np.atleast_1d(np.asarray(peak_u) / np.asarray(structure.u_crit))
    over = np.isfinite(ratio) & (ratio > LIFT_OFF_LIMIT)
    if not over.any():
        return None
    name = model_name or type(model.law).__name__.lower()
    runs = "" if ratio.size == 1 else f" in {int(over.sum())} of {ratio.size} runs"
    return (
        f"the paper's SDOF model ({name!r}) lifted the structure off to "
        f"{float(ratio[over].max()):.0f} u_crit{runs}: under ground motion Eq. 1 puts the "
        "whole inertial force at the top mass and over-predicts the rocking body's peak by "
        f"a median of tens of per cent (benchmarks/fidelity.md); {advice}"
    )


def warn_sdof_lift_off(model, structure, forced, peak_u, enabled=True, stacklevel=3):
    """Warn (`FidelityWarning`) with `sdof_lift_off_message`, when `enabled`."""
    if not enabled:
        return
    msg = sdof_lift_off_message(model, structure, forced, peak_u)
    if msg:
        warnings.warn(msg, FidelityWarning, stacklevel=stacklevel)
