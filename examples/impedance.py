"""A joint impedance controller with gravity compensation, on exo_ctrl's controller interface.

    τ = K (q* − q) + D (q̇* − q̇) + g_exo(q) + g_patient(q)   [N·m]

K [N·m/rad] and D [N·m·s/rad] per joint; g(q) the gravity torques of the
device's exoskeleton model and of its nominal patient (coaxial with the
exoskeleton, so the patient's weight reaches the drives at the same joints),
from Pinocchio.  The controller commands torques: the drivers' current loop
follows them as currents, and the supply and current limits and the safety
supervisor apply as to the built-in controllers.

Run it (a short run; ``--controller examples.impedance:Impedance`` from the
command line does the same from the repository's root)::

    python examples/impedance.py
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from exo_ctrl import SimConfig, simulate
from exo_ctrl.control import Controller, Device, PlanRow, SensorReadings


class Impedance(Controller):
    """Joint impedance around the plan plus the device's gravity model."""

    command_kind = "torque"

    def __init__(self, stiffness_Nm_per_rad: float = 1000.0, damping_Nm_s_per_rad: float = 40.0):
        self.K = stiffness_Nm_per_rad
        self.D = damping_Nm_s_per_rad

    def setup(self, device: Device) -> None:
        """Pinocchio data and joint buffers for both of the device's models, once per run."""
        self.bodies = []
        for body in (device.exo, device.patient):
            model = body.model
            self.bodies.append((model, model.createData(), pin.neutral(model), body.q_index))
        self.tau = np.zeros(4)

    def command(
        self, t_s: float, plan: PlanRow, sensors: SensorReadings, cuff_force_est_N: np.ndarray
    ) -> np.ndarray:
        """Joint torques [N·m] for one tick."""
        self.tau[:] = self.K * (plan.q - sensors.q) + self.D * (plan.dq - sensors.dq)
        for model, data, q, index in self.bodies:
            q[index] = sensors.q
            self.tau += pin.computeGeneralizedGravity(model, data, q)[index]
        return self.tau


def main(duration_s: float = 3.6) -> dict:
    """Simulate the default scenario with :class:`Impedance`; its summary."""
    result = simulate(SimConfig(controller=Impedance(), duration_s=duration_s))
    summary = result.summary()
    print(summary["controller"], summary["status"], summary["rms_tracking_error_rad"])
    return summary


if __name__ == "__main__":
    main()
