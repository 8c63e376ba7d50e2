"""The environment's action on the device: a command the tick takes as any controller's.

The environment never steps the plant itself: its action becomes a
controller's command on the run's one tick path
(:meth:`~exo_ctrl.sim.tick.Runner.act`), so it meets the drives, the
current loop, the supervisor and the log as every controller's does.

- ``"voltage"`` and ``"torque"``: a plug-in controller
  (:class:`~exo_ctrl.control.interface.Controller`, run through
  :class:`~exo_ctrl.control.plugin.PluginController` as a user's is) whose
  :meth:`command` returns the pending action: drive voltages [V], or joint
  torques [N·m] that become the drivers' current references
  (:mod:`exo_ctrl.control.current_loop`, :mod:`exo_ctrl.plant.current_mode`).
- ``"residual"``: :class:`ResidualController` wraps the run's built-in
  controller (PD, CT or QP) and adds the pending action [V] to its voltages.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from ..control import Controller
from ..control.interface import PlanRow
from ..sensing.readings import SensorReadings

__all__ = ["ResidualController", "TorqueAction", "VoltageAction", "action_controller"]


class VoltageAction(Controller):
    """A controller whose command is the environment's pending action: voltages [V].

    Attributes:
        pending: the action the next ticks apply, (4,) [V] (set by the environment).

    """

    command_kind: ClassVar[str] = "voltage"

    def __init__(self) -> None:
        self.pending = np.zeros(4)

    def command(
        self, t_s: float, plan: PlanRow, sensors: SensorReadings, cuff_force_est_N: np.ndarray
    ) -> np.ndarray:
        """The pending action (held from one environment step to the next)."""
        return self.pending


class TorqueAction(VoltageAction):
    """As :class:`VoltageAction`, the pending action joint torques [N·m] (the current loop's)."""

    command_kind: ClassVar[str] = "torque"


def action_controller(kind: str) -> VoltageAction:
    """A new action controller for ``"voltage"`` or ``"torque"`` actions."""
    return TorqueAction() if kind == "torque" else VoltageAction()


class ResidualController:
    """A built-in controller's voltages plus the environment's residual [V].

    On the tick's internal interface (:class:`~exo_ctrl.control.base.TickController`):
    its record is the wrapped controller's, whose ``u_cmd`` (the log's
    ``voltage_cmd``) then holds the sum; every other attribute is the
    wrapped controller's.

    Args:
        inner: the run's built-in controller.

    Attributes:
        pending: the residual the next ticks add, (4,) [V] (set by the environment).

    """

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.pending = np.zeros(4)
        self._u = inner.record["u_cmd"][0]

    def command(self, k: int, sensors: SensorReadings) -> np.ndarray:
        """The built-in controller's voltages for tick k plus the residual [V], (4,)."""
        u = self.inner.command(k, sensors)
        self._u[:] = u + self.pending
        return self._u

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)
