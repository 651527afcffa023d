"""rockjax: a differentiable simulator of rigid structures rocking on a two-spring foundation.

Implements "Simplified Expressions for Modelling Rigid Rocking Structures on Two-spring
Foundations": the SDOF equation of motion (Eq. 1), its closed-form restoring forces
(Eqs 4-20) and the geometrically exact numerical pushover they were checked against.

rockjax enables JAX's 64-bit mode on import (float64 is the default dtype of every result);
pass float32 arrays explicitly, e.g. ``structure.astype(jnp.float32)``, for the fast mode.

On import it also asks JAX for one CPU device per core (``jax_num_cpu_devices``) when the
backend is not yet initialised and the user has not chosen a count (``XLA_FLAGS``,
``JAX_NUM_CPU_DEVICES``, ``ROCKJAX_CPU_DEVICES``), so that `simulate_batch` uses every core.
"""

import jax as _jax

_jax.config.update("jax_enable_x64", True)

from ._devices import use_all_cores as _use_all_cores  # noqa: E402

# one CPU device per core, so that batches use every core (see rockjax/_devices.py)
_use_all_cores()

from . import (  # noqa: E402
    datasets as datasets,
    integrators as integrators,
    models as models,
    pulses as pulses,
)
from ._batch import (  # noqa: E402
    DEFAULT_TAIL as DEFAULT_TAIL,
    simulate_batch as simulate_batch,
    Summary as Summary,
)
from ._distributed import Processes as Processes  # noqa: E402
from ._excitation import (  # noqa: E402
    AbstractExcitation as AbstractExcitation,
    FreeVibration as FreeVibration,
    GroundMotion as GroundMotion,
)
from ._fidelity import FidelityWarning as FidelityWarning  # noqa: E402
from ._fragility import fragility as fragility, FragilityResult as FragilityResult  # noqa: E402
from ._intensity import (  # noqa: E402
    integrate_record as integrate_record,
    pga as pga,
    pgd as pgd,
    pgv as pgv,
    spectral_acceleration as spectral_acceleration,
)
from ._kinematics import (  # noqa: E402
    theta_from_u as theta_from_u,
    u_from_theta as u_from_theta,
    uplift as uplift,
    uplift_from_theta as uplift_from_theta,
)
from ._pushover import (  # noqa: E402
    overturn_displacement as overturn_displacement,
    pushover as pushover,
    PushoverResult as PushoverResult,
)
from ._records import (  # noqa: E402
    common_time_step as common_time_step,
    G_STANDARD as G_STANDARD,
    read_record as read_record,
    Record as Record,
)
from ._response import Response as Response, STATUS as STATUS  # noqa: E402
from ._simulate import simulate as simulate  # noqa: E402
from ._spectrum import (  # noqa: E402
    overturning_spectrum as overturning_spectrum,
    OverturningSpectrum as OverturningSpectrum,
)
from ._status import Status as Status  # noqa: E402
from ._structure import (  # noqa: E402
    DERIVED as DERIVED,
    mcmanus_column as mcmanus_column,
    RockingStructure as RockingStructure,
)
from ._sweep import sweep as sweep, SweepResult as SweepResult  # noqa: E402
from ._units import UnitError as UnitError, UNITS as UNITS  # noqa: E402
from .models import (  # noqa: E402
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
