r"""Rocking models: what the integrators of `rockjax.integrators` integrate.

- `AbstractRockingModel`: the interface (state and mode, flow, events, jump maps,
  observables); `Flags` and `Observed` are what its jumps and observations return.
- `SDOF`: the paper's Eq. 1 with a restoring-force law and an impact rule.
- The laws $k(u)$: `Simplified`, `Exact`, `Smooth`, `Housner`.
- `TwoSpring2DOF`: the rigid body itself on two compression-only springs.
- `RigidBody`: the body's own one-DOF rocking equation on the same springs (rotation
  about the base centre, then about a corner; Housner's block as $k_f \to \infty$).

`get_model` turns a name of the fidelity ladder into a model.
"""

from ._base import (
    AbstractRockingModel as AbstractRockingModel,
    Flags as Flags,
    Observed as Observed,
)
from ._laws import (
    AbstractRestoringForce as AbstractRestoringForce,
    Exact as Exact,
    Housner as Housner,
    restoring_force as restoring_force,
    Simplified as Simplified,
    Smooth as Smooth,
)
from ._registry import get_model as get_model, MODELS as MODELS
from ._rigidbody import RigidBody as RigidBody
from ._sdof import IMPACT_RULES as IMPACT_RULES, SDOF as SDOF
from ._twospring import (
    linearised_frequency as linearised_frequency,
    TwoSpring2DOF as TwoSpring2DOF,
)
