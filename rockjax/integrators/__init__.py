"""Integrators of rocking models; each consumes only `rockjax.models.AbstractRockingModel`.

Pick one by building it and pass it as `integrator=` to `rockjax.simulate` or
`rockjax.simulate_batch`; each holds its own settings:

- `EventRestart`: one diffrax solve per mode, events located on the dense solution and
  the model's jumps applied between solves (`_event_restart`; `method="diffrax"`).
- `RK4`: the batched stepper (`_stepper`), fixed classical RK4 steps with events located
  inside each step (`method="rk4"`).
- `Dopri5`: the same loop with adaptive Dormand–Prince 5(4) steps (`method="dopri5"`).

`AbstractIntegrator` is their abstract base (one `solve` signature). The loops themselves
(`solve`, `run`) and their static configurations are internal to the batch engine.
"""

from ._event_restart import RestartConfig as RestartConfig, solve as solve
from ._hermite import resample as resample
from ._integrators import (
    AbstractIntegrator as AbstractIntegrator,
    Dopri5 as Dopri5,
    EventRestart as EventRestart,
    max_pieces_for as max_pieces_for,
    resample_outputs as resample_outputs,
    RK4 as RK4,
)
from ._keywords import from_keywords as from_keywords
from ._stepper import run as run, StepperConfig as StepperConfig
