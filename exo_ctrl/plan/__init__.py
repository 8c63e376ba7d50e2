"""The gait plan: foot paths synchronised with the belt (paper §III) and the inverse kinematics.

Also the exercises other than the gait (:mod:`.exercise`: the calibration swing).
"""

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
    "Ramp",
    "RampedGait",
    "RowLayout",
    "calibration_plan",
    "fill_rows",
    "forward_kinematics",
    "inverse_kinematics",
    "joint_accelerations",
    "joint_rates",
    "layout",
    "plan_joints",
    "plan_row",
    "smoothstep",
]
