"""The paper's PD voltage controller (§V)."""

from __future__ import annotations

import numpy as np

from ..kinematics import JointTrajectory
from .base import PDGains, SensorReadings

__all__ = ["PDController"]


class PDController:
    """U = k_p (q* - q) + k_d (q̇* - q̇) per drive [V].

    Args:
        plan: joint targets at the control ticks: row k for tick k, or row
            k mod ``plan.period_ticks`` for a plan holding one period.
        gains: the PD gains.

    """

    name = "pd"

    def __init__(self, plan: JointTrajectory, gains: PDGains | None = None) -> None:
        self.plan = plan
        self._period = plan.period_ticks
        self.gains = gains or PDGains()
        self._kp = np.array(self.gains.kp)
        self._kd = np.array(self.gains.kd)
        self._u = np.zeros(4)
        self._e = np.zeros(4)

    def command(self, k: int, sensors: SensorReadings) -> np.ndarray:
        """PD voltages [V] for tick k."""
        return self._pd(k, sensors)

    def _pd(self, k: int, sensors: SensorReadings) -> np.ndarray:
        u, e = self._u, self._e
        i = k % self._period if self._period else k
        np.subtract(self.plan.q[i], sensors.q, out=e)
        np.multiply(self._kp, e, out=u)
        np.subtract(self.plan.dq[i], sensors.dq, out=e)
        np.multiply(self._kd, e, out=e)
        np.add(u, e, out=u)
        return u
