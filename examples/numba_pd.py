"""A fast controller: the paper's PD with its per-tick arithmetic compiled by numba.

    U = K_p (q* − q) + K_d (q̇* − q̇)   [V]

The same law twice on exo_ctrl's controller interface: :class:`NumpyPD`
in numpy (a few array operations, each allocating its result), and
:class:`NumbaPD`, whose ``command`` makes one call to a numba-compiled
function that writes into a buffer made once.  Both equal the built-in
``pd``.  What each costs per tick: ``tools/bench.py --scenarios
pd,numpy_pd,numba_pd`` (docs/controllers.md quotes it).

The compiled function takes only plain arrays (numba's public API; no
Python objects inside).  It compiles on its first call, about a third of
a second; ``cache=True`` would keep it compiled between processes where
this module is imported by its name.
Run it (a short run)::

    python examples/numba_pd.py
"""

from __future__ import annotations

import numba
import numpy as np

from exo_ctrl import SimConfig, simulate
from exo_ctrl.control import Controller, PlanRow, SensorReadings


@numba.njit
def pd_law(kp, kd, q_plan, dq_plan, q, dq, out):  # pragma: no cover - compiled
    """The PD's voltages into ``out``, K_p (q* − q) + K_d (q̇* − q̇) per joint [V]; ``out``."""
    for j in range(4):
        out[j] = kp[j] * (q_plan[j] - q[j]) + kd[j] * (dq_plan[j] - dq[j])
    return out


class NumbaPD(Controller):
    """The PD in volts, its arithmetic one compiled call (module docstring)."""

    command_kind = "voltage"

    def __init__(self, kp_V_per_rad: float = 300.0, kd_V_s_per_rad: float = 5.0):
        self.kp = np.full(4, kp_V_per_rad)
        self.kd = np.full(4, kd_V_s_per_rad)
        self.u = np.zeros(4)  # the command's buffer, made once

    def command(
        self, t_s: float, plan: PlanRow, sensors: SensorReadings, cuff_force_est_N: np.ndarray
    ) -> np.ndarray:
        """Drive voltages [V] for one tick."""
        return pd_law(self.kp, self.kd, plan.q, plan.dq, sensors.q, sensors.dq, self.u)


class NumpyPD(NumbaPD):
    """The same PD in numpy, for comparison (each operation allocates its result)."""

    def command(
        self, t_s: float, plan: PlanRow, sensors: SensorReadings, cuff_force_est_N: np.ndarray
    ) -> np.ndarray:
        """Drive voltages [V] for one tick."""
        return self.kp * (plan.q - sensors.q) + self.kd * (plan.dq - sensors.dq)


def main(duration_s: float = 1.2) -> float:
    """The largest joint-angle difference [rad] of :class:`NumbaPD` and the built-in PD."""
    mine = simulate(SimConfig(controller=NumbaPD(), duration_s=duration_s))
    builtin = simulate(SimConfig(duration_s=duration_s))
    difference = float(np.abs(mine.signals["q"] - builtin.signals["q"]).max())
    print(mine.summary()["controller"], mine.status, f"largest difference {difference:.3g} rad")
    return difference


if __name__ == "__main__":
    main()
