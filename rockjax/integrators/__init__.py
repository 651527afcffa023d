"""Integrators of rocking models; each consumes only `rockjax.models.AbstractRockingModel`.

- `solve` (`_event_restart`): one diffrax solve per mode, events located on the dense
  solution and the model's jumps applied between solves (`method="diffrax"`).
- `run` (`_stepper`): the batched stepper, fixed RK4 (`method="rk4"`) or adaptive
  Dormand–Prince 5(4) (`method="dopri5"`) steps with events located inside each step.
"""

from ._event_restart import RestartConfig as RestartConfig, solve as solve
from ._hermite import resample as resample
from ._stepper import run as run, StepperConfig as StepperConfig
