"""Cuff-force estimation from the joint torque sensors, live and along logged series.

Modules, in the order they build on each other:

- :mod:`.cuff_geometry`: cuff lever arms and directions, the components of a
  cuff force, the map between external joint torques and cuff forces;
- :mod:`.errors`: errors of an estimate against the simulated truth;
- :mod:`.observer`: :class:`CuffForceEstimator`, the live momentum observer;
- :mod:`.kalman`: :class:`CuffForceKalman`, a Kalman filter on the coupled
  exoskeleton–cuff–patient model (the device's patient and cuff models),
  its compiled step in :mod:`.kalman_step`;
- :mod:`.series`: the observer or the filter along a logged series;
- :mod:`.bias`: torque-sensor bias, its effect and its measurement;
- :mod:`.csvlog`: sensor logs as CSV files;
- :mod:`.identification` (with :mod:`.segment_fit`): the patient's segment
  inertial parameters from a calibration run;
- :mod:`.interface`: the public :class:`Estimator` a user's estimator
  subclasses, and :mod:`.plugin`, its place in the run.
"""

from ..exceptions import InvalidLog
from .bias import BiasEstimate, bias_effect_bound, estimate_bias
from .csvlog import CSV_DQ_COLUMNS, CSV_REQUIRED_COLUMNS, read_csv_log, write_csv_log
from .cuff_geometry import (
    CuffGeometry,
    cuff_components,
    cuff_forces_from_torque,
    cuff_normal_components,
)
from .errors import (
    EstimateErrors,
    EstimateErrorStats,
    estimate_components,
    normal_component_errors,
)
from .excitation import ExcitationReport
from .identification import (
    CalibrationSamples,
    Identification,
    PriorSpread,
    calibration_samples,
    identify_patient,
)
from .interface import Estimator, EstimatorDevice
from .kalman import (
    COMPONENTS,
    ESTIMATORS,
    MODEL_DRIVEN,
    CuffForceKalman,
    KalmanNoise,
    kalman_components,
    model_driven,
)
from .observer import DEFAULT_GAIN_PER_S, CuffForceEstimator
from .plugin import PluginEstimator, estimator_name
from .series import EstimateSeries, estimate_series, first_order_filter, kalman_series

__all__ = [
    "COMPONENTS",
    "CSV_DQ_COLUMNS",
    "CSV_REQUIRED_COLUMNS",
    "DEFAULT_GAIN_PER_S",
    "ESTIMATORS",
    "MODEL_DRIVEN",
    "BiasEstimate",
    "CalibrationSamples",
    "CuffForceEstimator",
    "CuffForceKalman",
    "CuffGeometry",
    "EstimateErrorStats",
    "EstimateErrors",
    "EstimateSeries",
    "Estimator",
    "EstimatorDevice",
    "ExcitationReport",
    "Identification",
    "InvalidLog",
    "KalmanNoise",
    "PluginEstimator",
    "PriorSpread",
    "bias_effect_bound",
    "calibration_samples",
    "cuff_components",
    "cuff_forces_from_torque",
    "cuff_normal_components",
    "estimate_bias",
    "estimate_components",
    "estimate_series",
    "estimator_name",
    "first_order_filter",
    "identify_patient",
    "kalman_components",
    "kalman_series",
    "model_driven",
    "normal_component_errors",
    "read_csv_log",
    "write_csv_log",
]
