"""Controllers: plan and sensor readings in, drive voltages out."""

from .base import Controller, PDGains, SensorReadings
from .computed_torque import ComputedTorqueController, feedforward_torque
from .pd import PDController
from .qp import QPController, TorqueQP

__all__ = [
    "ComputedTorqueController",
    "Controller",
    "PDController",
    "PDGains",
    "QPController",
    "SensorReadings",
    "TorqueQP",
    "feedforward_torque",
]
