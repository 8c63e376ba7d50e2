"""Controllers: plan and sensor readings in, drive voltages out."""

from ..sensing.readings import SensorReadings
from .base import Controller, PDGains
from .computed_torque import ComputedTorqueController, feedforward_torque
from .pd import PDController
from .qp.controller import QPController, TorqueQP

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
