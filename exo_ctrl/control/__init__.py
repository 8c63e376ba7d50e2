"""Controllers: plan and sensor readings in, drive voltages out.

- :mod:`~exo_ctrl.control.interface`: the public interface a user's
  controller implements (:class:`Controller`, given :class:`Device` once and
  a :class:`PlanRow` each tick; voltages or torques out).
- :mod:`~exo_ctrl.control.builtin`: the built-in PD and CT as public
  Controller classes (:class:`PD`, :class:`CT`; gains in, compiled law inside).
- :mod:`~exo_ctrl.control.plugin`: a user's controller in the run (its name,
  its import from ``module:Class``, the tick's adapter).
- :mod:`~exo_ctrl.control.current_loop`: torque commands into the drivers'
  current references (their current loop: :mod:`exo_ctrl.plant.current_mode`).
- :mod:`~exo_ctrl.control.base`: what the tick calls (:class:`TickController`),
  its record's common fields, the PD gains.
- :mod:`~exo_ctrl.control.pd`: the paper's PD voltage law.
- :mod:`~exo_ctrl.control.computed_torque`: PD plus model-based feedforward.
- :mod:`~exo_ctrl.control.qp`: CT + PD distributed by a QP under drive limits
  and predicted cuff-force bounds.
"""

from ..sensing.readings import SensorReadings
from .base import COMMAND_FIELDS, PDGains, TickController
from .builtin import CT, PD
from .computed_torque import ComputedTorqueController, feedforward_torque
from .interface import COMMAND_KINDS, Controller, Device, PlanRow
from .pd import PDController
from .plugin import PluginController, controller_name
from .qp import QPController, TorqueQP

__all__ = [
    "COMMAND_FIELDS",
    "COMMAND_KINDS",
    "CT",
    "PD",
    "ComputedTorqueController",
    "Controller",
    "Device",
    "PDController",
    "PDGains",
    "PlanRow",
    "PluginController",
    "QPController",
    "SensorReadings",
    "TickController",
    "TorqueQP",
    "controller_name",
    "feedforward_torque",
]
