"""identification: fit k_f and r of a rocking structure to measured free-vibration traces.

Built on rockjax's public API. Read a trace with `read_trace` (CSV with a header such as
`t,u[,uplift]` in SI units, or with units such as `time_s,disp_mm`; converted to SI), fit
it with `fit_decay` (k_f, r, and the release displacement u0 and time t0, found in the
trace by `detect_release`; with any model of rockjax's ladder, the 2-DOF body's dashpots
c_f included, and a lack-of-fit check of the residuals; docs/identification.md); the
synthetic traces in `data/` (`synthetic_trace_path`, `synthetic_truth`) are labelled
synthetic everywhere. `fit_decay([trace_1, trace_2, ...], structure)` fits several traces
of one structure at once: k_f and r shared, u0 and t0 of each trace (`JointFitResult`).
`read_outcomes` and `fit_outcomes` fit a specimen to pass/fail runs (toppled or stood under
pulses) with rockjax's overturning spectra (`OutcomeFit`; docs/outcomes.md).
Shake-table runs (a table record and the response, `read_shake_table`) are fitted by the
same machinery with the table as the excitation (`fit_shake_table`: k_f, r, c_f, the
clock offset, each channel's sensor zero and noise).
"""

from ._anomalies import split_releases as split_releases
from ._bayes import (
    parse_prior as parse_prior,
    PosteriorProblem as PosteriorProblem,
    Prior as Prior,
)
from ._fit import fit_decay as fit_decay, Schedule as Schedule
from ._joint import JointFitResult as JointFitResult
from ._lack import residual_statistics as residual_statistics
from ._models import (
    CONTACTS as CONTACTS,
    DEFAULT_PARAMS as DEFAULT_PARAMS,
    default_params as default_params,
    FitModel as FitModel,
    FitSpec as FitSpec,
    register_fit_spec as register_fit_spec,
    resolve_model as resolve_model,
)
from ._optim import levenberg_marquardt as levenberg_marquardt
from ._outcome_grid import (
    block_threshold_grid as block_threshold_grid,
    structure_threshold_grid as structure_threshold_grid,
    ThresholdGrid as ThresholdGrid,
    uniform_block as uniform_block,
)
from ._outcome_table import (
    OutcomeError as OutcomeError,
    OutcomeTable as OutcomeTable,
    read_outcomes as read_outcomes,
    shakebot_path as shakebot_path,
)
from ._outcomes import fit_outcomes as fit_outcomes, OutcomeFit as OutcomeFit
from ._outliers import OUTLIER_SIGMAS as OUTLIER_SIGMAS
from ._posterior import (
    Posterior as Posterior,
    PosteriorWarning as PosteriorWarning,
    sample_posterior as sample_posterior,
)
from ._problem import NUISANCE as NUISANCE, PARAM_NAMES as PARAM_NAMES, UNITS as UNITS
from ._release import detect_release as detect_release, Release as Release
from ._result import (
    ConvergenceWarning as ConvergenceWarning,
    FitResult as FitResult,
    IdentifiabilityWarning as IdentifiabilityWarning,
    LackOfFitWarning as LackOfFitWarning,
    OutlierWarning as OutlierWarning,
)
from ._shake import (
    read_shake_table as read_shake_table,
    ShakeTableRun as ShakeTableRun,
    synthetic_shake_table as synthetic_shake_table,
)
from ._shakefit import (
    fit_shake_table as fit_shake_table,
    ShakeTableFitResult as ShakeTableFitResult,
)
from ._synthetic import (
    Faults as Faults,
    synthetic_trace as synthetic_trace,
    synthetic_trace_path as synthetic_trace_path,
    synthetic_truth as synthetic_truth,
)
from ._trace import (
    CHANNELS as CHANNELS,
    DecayTrace as DecayTrace,
    DroppedRowsWarning as DroppedRowsWarning,
    LENGTH_UNITS as LENGTH_UNITS,
    read_trace as read_trace,
    SYNTHETIC_TRACES as SYNTHETIC_TRACES,
    TIME_UNITS as TIME_UNITS,
    TraceError as TraceError,
)
