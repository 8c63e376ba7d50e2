"""The gait plan: foot paths synchronised with the belt (paper §III) and the inverse kinematics."""

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

__all__ = [
    "PLAN_BYTES_PER_SAMPLE",
    "FootTrajectory",
    "GaitParams",
    "GaitPlan",
    "JointTrajectory",
    "forward_kinematics",
    "inverse_kinematics",
    "joint_accelerations",
    "joint_rates",
    "plan_joints",
]
