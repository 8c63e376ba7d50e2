"""The paper's PD voltage controller (§V)."""

from __future__ import annotations

import numpy as np

from .. import _validate as v
from .._jit import kernel
from ..plan.kinematics import JointTrajectory
from ..sensing.readings import SensorReadings
from .base import PDGains

__all__ = ["PDController", "pd_volts"]


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
        self._gains = np.array([self.gains.kp, self.gains.kd])
        self._u = np.zeros(4)
        self._no_ff = np.zeros(4)
        self._last_row = np.zeros(1)  # where a compiled tick writes it too

    def command(self, k: int, sensors: SensorReadings) -> np.ndarray:
        """PD voltages [V] for tick k."""
        return self._pd(self.plan_row(k), sensors, self._no_ff)

    def plan_row(self, k: int) -> int:
        """The plan row of tick k, kept as :attr:`last_row`."""
        row = k % self._period if self._period else k
        self._last_row[0] = row
        return row

    @property
    def last_row(self) -> int:
        """The plan row of the last tick."""
        return int(self._last_row[0])

    def _pd(self, row: int, sensors: SensorReadings, u_ff: np.ndarray) -> np.ndarray:
        """PD voltages plus ``u_ff`` [V] towards plan row ``row``."""
        plan = self.plan
        q, dq = sensors.q, sensors.dq
        if not (type(q) is type(dq) is np.ndarray):
            q, dq = v.arrays((4,), sensors_q=q, sensors_dq=dq)
        if pd_volts(self._u, self._gains, plan.q, plan.dq, row, q, dq, u_ff) < 0:
            v.refuse_shapes((4,), sensors_q=q, sensors_dq=dq)
        return self._u


@kernel
def pd_volts(
    out: np.ndarray,
    gains: np.ndarray,
    q_des: np.ndarray,
    dq_des: np.ndarray,
    row: int,
    q: np.ndarray,
    dq: np.ndarray,
    u_ff: np.ndarray,
) -> int:
    """Write k_p (q*[row] - q) + k_d (q̇*[row] - q̇) + u_ff [V] to ``out`` (gains: k_p; k_d)."""
    if q.shape[0] != 4 or dq.shape[0] != 4:
        return -1  # nothing written
    for j in range(4):
        out[j] = (
            gains[0, j] * (q_des[row, j] - q[j]) + gains[1, j] * (dq_des[row, j] - dq[j])
        ) + u_ff[j]
    return 0
