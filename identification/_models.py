r"""The models a decay trace can be fitted with, and the parameters that act in each.

Any model of rockjax's fidelity ladder (`rockjax.MODELS`: the SDOF laws `"housner"`,
`"simplified"`, `"exact"`, `"smooth"`, the rigid body `"rigid_body"`, the 2-DOF body
`"two_spring_2dof"`, and any model registered there later whose class has a `FitSpec`), or
a model instance (`rockjax.TwoSpring2DOF(damping=...,
contact=...)`). Which of the fit's parameters act in a model is declared once per model
class, in a `FitSpec` (`FIT_SPECS`, `register_fit_spec`), so that a parameter the trace
cannot inform is refused rather than fitted to a meaningless value with a broken standard
error:

- `k_f` acts unless the model is a rigid interface (the SDOF with a law whose class
  variable `rigid` is True, e.g. `housner`: the limit $k_f \to \infty$);
- `r` acts unless the model has a contact law set to `"continuous"` (the 2-DOF body whose
  springs and dashpots carry the impacts: no restitution coefficient is used);
- `c_f`, the coefficient [N s/m] of each compression-only dashpot, acts in a model whose
  spec declares dashpots (the 2-DOF body, its field `damping`);
- `u0` and `t0` (the release) act in every model.

**The start of c_f.** When `c_f` is fitted and neither `initial` nor the model instance
gives a positive value, it starts at 5 % of critical damping of the vertical mode of the
body on its two springs, at the starting $k_f$: two springs $k_f$ and two dashpots $c_f$
under the mass $M = m_e + m_b$ give $\zeta = c_f / \sqrt{2 k_f M}$, so
$c_{f,0} = 0.05\sqrt{2 k_{f,0} M}$ (678 N s/m for Table 1 at $k_f$ = 550 kN/m).
"""

from __future__ import annotations

import dataclasses
import math

import rockjax

CONTACTS = ("impact", "continuous")
"""The contact laws of the 2-DOF body (`rockjax.TwoSpring2DOF(contact=...)`)."""
DAMPING_RATIO_START = 0.05
"""The damping ratio of the vertical mode that the default start of c_f gives."""
DEFAULT_PARAMS = ("k_f", "r", "u0", "t0")
"""The parameters fitted by default, less those that do not act in the model (with
continuous contact, `c_f` takes the place of `r`)."""


@dataclasses.dataclass(frozen=True)
class FitSpec:
    """What a fit needs to know of a kind of model, declared once per model class
    (`FIT_SPECS`) instead of probed off the instance.

    - `rung`: its place on the ladder: `"sdof"` (the SDOF laws: k_f unbounded, next up the
      rigid body), `"body"` (the rigid body's own equation), `"2dof"` (the 2-DOF body);
    - `stiff`: k_f acts (False: a rigid interface, the limit k_f -> infinity; an SDOF's
      law declares it in its class variable `rigid`);
    - `contact`: the model has a contact law (its field `contact`, `CONTACTS`): r acts
      unless it is `"continuous"`; the fit's horizons and starts are those of such a model;
    - `dashpots`: the model has a dashpot coefficient (its field `damping`): c_f acts.
    """

    rung: str
    stiff: bool = True
    contact: bool = False
    dashpots: bool = False


FIT_SPECS: dict = {
    rockjax.SDOF: FitSpec("sdof"),
    rockjax.RigidBody: FitSpec("body"),
    rockjax.TwoSpring2DOF: FitSpec("2dof", contact=True, dashpots=True),
}
"""The `FitSpec` of each model class (a model of another class cannot be fitted until its
spec is added here, with `register_fit_spec`)."""


def register_fit_spec(model_class: type, spec: FitSpec):
    """Declare what a fit needs of `model_class` (a `rockjax.AbstractRockingModel`)."""
    if not isinstance(spec, FitSpec):
        raise TypeError(f"spec must be an identification.FitSpec, got {type(spec).__name__}")
    FIT_SPECS[model_class] = spec


def fit_spec(model) -> FitSpec:
    """The `FitSpec` of a model instance (ValueError for a class without one)."""
    spec = FIT_SPECS.get(type(model))
    if spec is None:
        raise ValueError(
            f"the {type(model).__name__} model cannot be fitted: identification does not know "
            "which parameters act in it (declare them with identification.register_fit_spec)"
        )
    if spec.rung == "sdof" and type(model.law).rigid:  # the law's declared class variable
        spec = dataclasses.replace(spec, stiff=False)
    return spec


@dataclasses.dataclass(frozen=True)
class FitModel:
    """A model resolved for a fit: the rockjax model instance, its ladder name, its
    `FitSpec`, and the parameters (of `PARAM_NAMES`) that act in it."""

    model: object  # a rockjax.AbstractRockingModel
    name: str  # its name in rockjax.MODELS, else its class name
    acting: tuple
    spec: FitSpec = FitSpec("sdof")

    @property
    def contact(self) -> str | None:
        """The contact law (`"impact"`, `"continuous"`), None for a model without one."""
        return self.model.contact if self.spec.contact else None

    @property
    def has_dashpots(self) -> bool:
        return "c_f" in self.acting

    def describe(self) -> str:
        """The model in words: `simplified`, `two_spring_2dof (contact continuous)`."""
        return self.name + (f" (contact {self.contact})" if self.contact else "")


def _ladder_name(obj, spec: FitSpec) -> str:
    """The name of a model instance in `rockjax.MODELS` (an SDOF by its law)."""
    target = obj.law if spec.rung == "sdof" else obj
    for name, ctor in rockjax.MODELS.items():
        if type(target) is ctor:
            return name
    return type(target).__name__


def resolve_model(model, impact: str = "paper", contact: str | None = None) -> FitModel:
    """The `FitModel` of `model` (a name of `rockjax.MODELS`, a restoring-force law or a
    model instance) with the SDOF impact rule `impact` and, for a model with a contact law
    (the 2-DOF body), `contact` (None: the model's own). ValueError naming what is wrong."""
    obj = rockjax.get_model(model, impact)  # ValueError naming the model if unknown
    spec = fit_spec(obj)
    name = model if isinstance(model, str) else _ladder_name(obj, spec)
    if contact is not None:
        if contact not in CONTACTS:
            raise ValueError(f"contact must be one of {CONTACTS}, got {contact!r}")
        if not spec.contact:
            raise ValueError(
                f"contact applies to the 2-DOF body (model='two_spring_2dof') only: the {name} "
                "model has no contact law of its own (its impacts are Eq. 2 with r); leave "
                "contact out"
            )
        obj = dataclasses.replace(obj, contact=contact)
    acting = ["u0", "t0"]
    if spec.stiff:
        acting.append("k_f")
    if not (spec.contact and obj.contact == "continuous"):
        acting.append("r")
    if spec.dashpots:
        acting.append("c_f")
    return FitModel(model=obj, name=name, acting=tuple(acting), spec=spec)


def default_params(model="simplified", *, impact: str = "paper", contact: str | None = None):
    """The parameters `fit_decay` fits by default with this model: `DEFAULT_PARAMS` (k_f,
    r, u0, t0) less those that do not act in it; with continuous contact (r does not act),
    the dashpots' `c_f` in place of `r`.

    ```python
    identification.default_params("two_spring_2dof", contact="continuous")
    # ('k_f', 'c_f', 'u0', 't0')
    ```
    """
    return fitted_by_default(resolve_model(model, impact, contact))


def fitted_by_default(fm: FitModel) -> tuple:
    """`default_params` of a resolved model."""
    out = [p for p in DEFAULT_PARAMS if p in fm.acting]
    if "r" not in fm.acting and fm.has_dashpots:
        out.insert(1 if "k_f" in out else 0, "c_f")
    return tuple(out)


def default_notes(fm: FitModel) -> list:
    """Notes on the default parameters left out because they do not act in the model."""
    notes = []
    if "k_f" not in fm.acting:
        notes.append(f"k_f is not fitted: the {fm.name} model is a rigid interface (the limit "
                     "k_f -> infinity), where k_f does not act")
    if "r" not in fm.acting:
        extra = "; c_f (the dashpots) is fitted in its place" if fm.has_dashpots else ""
        notes.append("r is not fitted: with contact='continuous' the springs and dashpots "
                     f"carry the impacts, so r does not act{extra}")
    return notes


def refuse_inactive(fm: FitModel, params: tuple):
    """ValueError for the first parameter of `params` that does not act in the model."""
    for p in params:
        if p in fm.acting:
            continue
        if p == "c_f":
            raise ValueError(
                f"c_f (the dashpot coefficient of the 2-DOF body) is not a parameter of the "
                f"{fm.describe()} model: fit it with model='two_spring_2dof', or leave c_f out "
                f"of params (got {params})"
            )
        if p == "r":
            raise ValueError(
                "r does not act with contact='continuous': the springs and dashpots of the "
                "2-DOF body carry the impacts, and the trace cannot inform r (its standard "
                f"error would be meaningless); leave r out of params (got {params}) and fit "
                "c_f for the dissipation"
            )
        raise ValueError(
            f"k_f does not act in the {fm.describe()} model (a rigid interface, the limit "
            f"k_f -> infinity): leave k_f out of params (got {params}), or fit a model on "
            "springs"
        )


def default_horizons(fm: FitModel) -> tuple:
    """The growing horizons of a fit (fractions of the motion after the release):
    (0.25, 0.5, 1.0); for a model with a contact law (the 2-DOF body) (0.125, 0.25, 0.5,
    1.0). Energy flows between the 2-DOF body's vertical bounce and its rocking, so its
    response after the first second or two depends so sharply on k_f that the misfit over
    a 4 s trace has a minimum every few % of k_f, while over its first 0.5 s it has one
    (from half to twice the truth): the first stage must be that short."""
    return (0.125, 0.25, 0.5, 1.0) if fm.contact is not None else (0.25, 0.5, 1.0)


SDOF_START_OFFSETS = ((0.0, 0.0), (0.0, 1.0), (0.0, -1.0), (math.log(2), 0.0),
                      (-math.log(2), 0.0), (math.log(2), 1.0), (-math.log(2), 1.0),
                      (math.log(4), 0.0))
"""(log k_f shift, dissipation shift: logit r or log c_f) of each start of the SDOF-like
models: the dissipation first, since the decay envelope and the impact times (the phase)
depend on it most."""
CONTACT_START_OFFSETS = ((0.0, 0.0), (-math.log(2), 0.0), (math.log(2), 0.0), (0.0, 1.0),
                         (0.0, -1.0), (-math.log(4), 0.0), (math.log(4), 0.0),
                         (-math.log(2), 1.0))
"""The same for a model with a contact law (the 2-DOF body): k_f first. Its misfit has
one minimum over the first 0.5 s of a trace, but a flat one away from the truth (with
impact contact, from 1.3 to 3 times the true k_f the first landing looks the same):
starts at half and twice k_f find the basin that one start misses."""


def start_offsets(fm: FitModel) -> tuple:
    """The shifts of the starts of a fit with this model."""
    return CONTACT_START_OFFSETS if fm.contact is not None else SDOF_START_OFFSETS


def default_starts(fm: FitModel) -> int:
    """The default number of starts: 3 for a model with a contact law (the start, half and
    twice its k_f), else 2."""
    return 3 if fm.contact is not None else 2


K_F_CAP = 1e5
"""k_f of a model other than the SDOF laws is bounded, smoothly, below this many times
the stability limit k_f,min = W H_c / (2 B^2) (7.9e8 N/m for Table 1: a settlement
delta_0 under 1 µm, a rigid foundation for any purpose)."""


def k_f_cap(fm: FitModel, k_min: float) -> float | None:
    """The upper bound of k_f in a fit with this model [N/m]; None for the SDOF laws.

    A fit of the wrong model can run k_f off towards the rigid limit. The SDOF laws take
    that in their stride (and the fits of `tests/test_fit_robustness.py` rely on it); the
    rigid body's and the 2-DOF body's integrations grow stiff (one such fit of the rigid
    body took 9 minutes), and the 2-DOF body's initial state (a root find) loses its
    derivatives beyond about 1e11 N/m, which stops the fit with an error."""
    return None if fm.spec.rung == "sdof" else K_F_CAP * k_min


def c_f_start(structure, k_f: float) -> float:
    """The default start of c_f [N s/m]: `DAMPING_RATIO_START` of critical damping of the
    vertical mode, $0.05\\sqrt{2 k_f (m_e + m_b)}$."""
    mass = float(structure.m_e) + float(structure.m_b)
    return DAMPING_RATIO_START * math.sqrt(2.0 * k_f * mass)


def model_damping(fm: FitModel) -> float:
    """The dashpot coefficient of the model instance [N s/m] (0 without dashpots)."""
    if not fm.has_dashpots:
        return 0.0
    try:
        return float(fm.model.damping)
    except (TypeError, ValueError):
        return 0.0


TOP = ("two_spring_2dof with contact='continuous' and c_f fitted (the 2-DOF body on its "
       "springs and dashpots)")
"""The top of the ladder, in words."""


def models_above(fm: FitModel, params: tuple) -> list:
    """The models up the ladder from this one (fitting `params`), nearest first, in words;
    empty at the top (the 2-DOF body with continuous contact and c_f fitted).

    SDOF laws (simplified, exact, smooth, housner) -> rigid_body (when registered in
    `rockjax.MODELS`) -> two_spring_2dof with contact='continuous' and c_f fitted.
    """
    if fm.spec.rung == "sdof" and "rigid_body" in rockjax.MODELS:
        return ["rigid_body", TOP]
    if fm.has_dashpots and fm.contact == "continuous":
        return [] if "c_f" in params else ["the same model with c_f fitted"]
    return [TOP]


def next_model(fm: FitModel, params: tuple) -> str | None:
    """The next model up the ladder (`models_above`), None at the top."""
    above = models_above(fm, params)
    return above[0] if above else None
