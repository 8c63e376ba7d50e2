"""exo_ctrl: model-based control and estimation of a treadmill gait exoskeleton.

The pieces meet as: gait plan → inverse kinematics → controller → motors →
plant (exoskeleton + patient + cuffs) → sensors → estimator, with a recorder
watching.  Units are SI throughout; see the README for frames and signs.

:func:`read_recording` is the recorder package's, imported on its first use:
that package imports rerun (about 0.3 s here), which a run without a
recording (a library run, a sweep's worker) never needs; so is
:func:`compare_recordings` (:mod:`exo_ctrl.comparison.recordings`).
:func:`compare` runs a scenario once per controller and returns the table
of their figures (:mod:`exo_ctrl.comparison`).
"""

from ._version import __version__
from .comparison import CompareTable, compare
from .exceptions import (
    ExoCtrlError,
    InvalidLog,
    InvalidModel,
    InvalidParameter,
    InvalidScenario,
    MissingDependency,
    PluginError,
    RecordingError,
    SimulationDiverged,
    SweepError,
    UnreachableFootTarget,
)
from .model import (
    CUFF_NAMES,
    JOINT_NAMES,
    BodyModel,
    LegGeometry,
    default_urdf_path,
    load_body,
    load_exo,
    load_human_patient,
    load_patient,
)
from .plan.gait import FootTrajectory, GaitParams, GaitPlan
from .plan.kinematics import (
    JointTrajectory,
    forward_kinematics,
    inverse_kinematics,
    joint_accelerations,
    joint_rates,
    plan_joints,
)
from .scenario import Scenario, load_scenario
from .sim import SimConfig, SimResult, simulate

__all__ = [
    "CUFF_NAMES",
    "JOINT_NAMES",
    "BodyModel",
    "CompareTable",
    "ExoCtrlError",
    "FootTrajectory",
    "GaitParams",
    "GaitPlan",
    "InvalidLog",
    "InvalidModel",
    "InvalidParameter",
    "InvalidScenario",
    "JointTrajectory",
    "LegGeometry",
    "MissingDependency",
    "PluginError",
    "RecordingError",
    "Scenario",
    "SimConfig",
    "SimResult",
    "SimulationDiverged",
    "SweepError",
    "UnreachableFootTarget",
    "__version__",
    "compare",
    "compare_recordings",
    "default_urdf_path",
    "forward_kinematics",
    "inverse_kinematics",
    "joint_accelerations",
    "joint_rates",
    "load_body",
    "load_exo",
    "load_human_patient",
    "load_patient",
    "load_scenario",
    "plan_joints",
    "read_recording",
    "simulate",
]


def __getattr__(name: str) -> object:
    """``read_recording`` and ``compare_recordings``, imported on first use (module docstring)."""
    if name == "read_recording":
        from .record import read_recording

        return read_recording
    if name == "compare_recordings":
        from .comparison.recordings import compare_recordings

        return compare_recordings
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
