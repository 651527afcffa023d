"""rockjax: a differentiable simulator of rigid structures rocking on a two-spring foundation.

Implements "Simplified Expressions for Modelling Rigid Rocking Structures on Two-spring
Foundations": the SDOF equation of motion (Eq. 1), its closed-form restoring forces
(Eqs 4-20) and the geometrically exact numerical pushover they were checked against.

`import rockjax` leaves JAX's configuration as it is. Call ``rockjax.configure()`` first,
before any JAX computation: it turns on JAX's float64 mode (the default dtype of every
result) and asks for one CPU device per usable core, so that `simulate_batch` uses every
core. A program that does not call it still gets float64 from the first entry point that
computes, with one `ConfigurationWarning`; ``rockjax.configure(x64=False)`` (or
``JAX_ENABLE_X64=0``) keeps float32, which runs with ``method="rk4"`` or ``"dopri5"``: pass
float32 arrays, e.g. ``structure.astype(jnp.float32)``.
"""

from . import (
    datasets as datasets,
    integrators as integrators,
    models as models,
    pulses as pulses,
)
from ._batch import (
    DEFAULT_TAIL as DEFAULT_TAIL,
    simulate_batch as simulate_batch,
    Summary as Summary,
)
from ._compare import (
    compare_models as compare_models,
    ks_distance as ks_distance,
    ModelComparison as ModelComparison,
)
from ._config import Configuration as Configuration, configure as configure
from ._distributed import Processes as Processes
from ._draws import read_draws as read_draws
from ._errors import (
    ConfigurationWarning as ConfigurationWarning,
    ParameterError as ParameterError,
)
from ._excitation import (
    AbstractExcitation as AbstractExcitation,
    FreeVibration as FreeVibration,
    GroundMotion as GroundMotion,
    RecordTable as RecordTable,
)
from ._execution import Execution as Execution
from ._fidelity import FidelityWarning as FidelityWarning
from ._fragility import fragility as fragility, FragilityResult as FragilityResult
from ._intensity import (
    integrate_record as integrate_record,
    pga as pga,
    pgd as pgd,
    pgv as pgv,
    spectral_acceleration as spectral_acceleration,
)
from ._kinematics import (
    theta_from_u as theta_from_u,
    u_from_theta as u_from_theta,
    uplift as uplift,
    uplift_from_theta as uplift_from_theta,
)
from ._predictive import fragility_band as fragility_band, FragilityBand as FragilityBand
from ._pushover import (
    overturn_displacement as overturn_displacement,
    pushover as pushover,
    PushoverResult as PushoverResult,
)
from ._records import (
    common_time_step as common_time_step,
    G_STANDARD as G_STANDARD,
    read_record as read_record,
    Record as Record,
    ResampledWarning as ResampledWarning,
)
from ._response import Response as Response, STATUS as STATUS
from ._rocking_spectrum import (
    rocking_spectrum as rocking_spectrum,
    RockingSpectrum as RockingSpectrum,
)
from ._simulate import simulate as simulate
from ._spectrum import (
    overturning_spectrum as overturning_spectrum,
    OverturningSpectrum as OverturningSpectrum,
)
from ._spectrum_band import spectrum_band as spectrum_band, SpectrumBand as SpectrumBand
from ._status import Status as Status
from ._structure import (
    DERIVED as DERIVED,
    mcmanus_column as mcmanus_column,
    RockingStructure as RockingStructure,
)
from ._sweep import sweep as sweep, sweep_store as sweep_store, SweepResult as SweepResult
from ._units import UnitError as UnitError, UNITS as UNITS
from .models import (
    AbstractRestoringForce as AbstractRestoringForce,
    AbstractRockingModel as AbstractRockingModel,
    Exact as Exact,
    get_model as get_model,
    Housner as Housner,
    IMPACT_RULES as IMPACT_RULES,
    MODELS as MODELS,
    restoring_force as restoring_force,
    RigidBody as RigidBody,
    SDOF as SDOF,
    Simplified as Simplified,
    Smooth as Smooth,
    TwoSpring2DOF as TwoSpring2DOF,
)

__version__ = "0.1.0"
