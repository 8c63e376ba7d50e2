"""The gait plan: foot paths synchronised with the belt (paper §III) and the inverse kinematics.

Also the exercises other than the gait (:mod:`.exercise`: the calibration swing),
a session's belt-speed profile (:mod:`.profile`), the gait's adaptation to the
belt speed (:mod:`.adapt`) and the gait generated online from the measured
belt speed (:mod:`.online`).
"""

from .adapt import SpeedAdaptation, max_step_length
from .exercise import EXERCISES, calibration_plan
from .gait import (
    FootTrajectory,
    GaitParams,
    GaitPlan,
)
from .kinematics import (
    PLAN_BYTES_PER_SAMPLE,
    JointTrajectory,
    forward_kinematics,
    inverse_kinematics,
    joint_accelerations,
    joint_rates,
    plan_joints,
)
from .loading import StanceSink
from .online import OnlineGait
from .profile import SpeedProfile
from .ramp import Ramp, RampedGait, smoothstep
from .rows import NO_TAIL, RowLayout, fill_rows, layout, plan_row

__all__ = [
    "EXERCISES",
    "NO_TAIL",
    "PLAN_BYTES_PER_SAMPLE",
    "FootTrajectory",
    "GaitParams",
    "GaitPlan",
    "JointTrajectory",
    "OnlineGait",
    "Ramp",
    "RampedGait",
    "RowLayout",
    "SpeedAdaptation",
    "SpeedProfile",
    "StanceSink",
    "calibration_plan",
    "fill_rows",
    "forward_kinematics",
    "inverse_kinematics",
    "joint_accelerations",
    "joint_rates",
    "layout",
    "max_step_length",
    "plan_joints",
    "plan_row",
    "smoothstep",
]
