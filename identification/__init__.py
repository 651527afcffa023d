"""identification: fit k_f and r of a rocking structure to measured free-vibration traces.

Built on rockjax's public API. Read a trace with `read_trace` (CSV `t,u[,uplift]`, SI
units), fit it with `fit_decay`; the synthetic traces in `data/` (`synthetic_trace_path`,
`synthetic_truth`) are labelled synthetic everywhere.
"""

from ._fit import (
    fit_decay as fit_decay,
    FitResult as FitResult,
    IdentifiabilityWarning as IdentifiabilityWarning,
    OutlierWarning as OutlierWarning,
    PARAM_NAMES as PARAM_NAMES,
)
from ._optim import levenberg_marquardt as levenberg_marquardt
from ._trace import (
    DecayTrace as DecayTrace,
    read_trace as read_trace,
    synthetic_trace_path as synthetic_trace_path,
    SYNTHETIC_TRACES as SYNTHETIC_TRACES,
    synthetic_truth as synthetic_truth,
)
