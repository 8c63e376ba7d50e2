"""exo_ctrl: model-based control and estimation of a treadmill gait exoskeleton.

The pieces meet as: gait plan → inverse kinematics → controller → motors →
plant (exoskeleton + patient + cuffs) → sensors → estimator, with a recorder
watching.  Units are SI throughout; see the README for frames and signs.
"""

from .exceptions import (
    ExoCtrlError,
    InvalidLog,
    InvalidModel,
    InvalidParameter,
    MissingDependency,
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
from .record import read_recording
from .sim import SimConfig, SimResult, simulate

__version__ = "0.1.0"

__all__ = [
    "CUFF_NAMES",
    "JOINT_NAMES",
    "BodyModel",
    "ExoCtrlError",
    "FootTrajectory",
    "GaitParams",
    "GaitPlan",
    "InvalidLog",
    "InvalidModel",
    "InvalidParameter",
    "JointTrajectory",
    "LegGeometry",
    "MissingDependency",
    "RecordingError",
    "SimConfig",
    "SimResult",
    "SimulationDiverged",
    "SweepError",
    "UnreachableFootTarget",
    "__version__",
    "default_urdf_path",
    "forward_kinematics",
    "inverse_kinematics",
    "joint_accelerations",
    "joint_rates",
    "load_body",
    "load_exo",
    "load_human_patient",
    "load_patient",
    "plan_joints",
    "read_recording",
    "simulate",
]
