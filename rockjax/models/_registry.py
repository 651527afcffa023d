"""The fidelity ladder by name: `get_model("simplified")` and friends."""

from __future__ import annotations

from .._errors import ParameterError
from ._base import AbstractRockingModel
from ._laws import AbstractRestoringForce, Exact, Housner, Simplified, Smooth
from ._rigidbody import RigidBody
from ._sdof import IMPACT_RULES, SDOF
from ._twospring import TwoSpring2DOF

#: name -> a constructor of the model's law or model
MODELS = {
    "housner": Housner,
    "simplified": Simplified,
    "exact": Exact,
    "smooth": Smooth,
    "two_spring_2dof": TwoSpring2DOF,
    "rigid_body": RigidBody,
}


def get_model(model, impact: str = "paper") -> AbstractRockingModel:
    """A rocking model from a name of the ladder, a restoring-force law or a model.

    - a name: `"housner"`, `"simplified"`, `"exact"`, `"smooth"` (each the SDOF Eq. 1 with
      that law and the impact rule `impact`), `"two_spring_2dof"` (the 2-DOF body) or
      `"rigid_body"` (the body's own one-DOF rocking equation, `RigidBody`); `impact`
      applies to the SDOF models only (another rule with another model raises
      `ParameterError`);
    - an `AbstractRestoringForce` (e.g. `rockjax.Smooth(width=0.1)`): the SDOF with it;
    - an `AbstractRockingModel` (e.g. `rockjax.TwoSpring2DOF(damping=...)`): itself.
    """
    if impact not in IMPACT_RULES:
        raise ParameterError(f"impact must be one of {IMPACT_RULES}, got {impact!r}",
                             param="impact")
    if isinstance(model, str) and model in MODELS:
        model = MODELS[model]()
    if isinstance(model, AbstractRestoringForce):
        return SDOF(law=model, impact=impact)
    if isinstance(model, AbstractRockingModel):
        if impact != "paper" and not isinstance(model, SDOF):
            raise ParameterError(
                f"the impact rule {impact!r} applies to the SDOF models of Eq. 1 (housner, "
                f"simplified, exact, smooth); {type(model).__name__} has its own contact "
                "law (its impacts are landings)", param="impact", omit=True)
        return model
    raise ValueError(
        f"model must be one of {', '.join(repr(m) for m in MODELS)}, an "
        f"AbstractRestoringForce or an AbstractRockingModel instance, got {model!r}"
    )
