"""Controllers: plan and sensor readings in, drive voltages out.

- :mod:`~exo_ctrl.control.base`: what every controller sees and returns, its
  record's common fields, the PD gains.
- :mod:`~exo_ctrl.control.pd`: the paper's PD voltage law.
- :mod:`~exo_ctrl.control.computed_torque`: PD plus model-based feedforward.
- :mod:`~exo_ctrl.control.qp`: CT + PD distributed by a QP under drive limits
  and predicted cuff-force bounds.
"""

from ..sensing.readings import SensorReadings
from .base import COMMAND_FIELDS, Controller, PDGains
from .computed_torque import ComputedTorqueController, feedforward_torque
from .pd import PDController
from .qp import QPController, TorqueQP

__all__ = [
    "COMMAND_FIELDS",
    "ComputedTorqueController",
    "Controller",
    "PDController",
    "PDGains",
    "QPController",
    "SensorReadings",
    "TorqueQP",
    "feedforward_torque",
]
