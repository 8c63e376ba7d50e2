"""Controllers: plan and sensor readings in, drive voltages out."""

from .base import Controller, PDGains, SensorReadings
from .computed_torque import ComputedTorqueController, feedforward_torque
from .pd import PDController

__all__ = [
    "ComputedTorqueController",
    "Controller",
    "PDController",
    "PDGains",
    "SensorReadings",
    "feedforward_torque",
]
