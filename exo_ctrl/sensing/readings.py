"""What the device's sensors give a controller, an estimator and the supervisor each tick."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["SensorReadings"]


@dataclass
class SensorReadings:
    """One tick's sensor readings, arrays of shape (4,) in JOINT_NAMES order.

    Attributes:
        q: joint angles from the encoders [rad].
        dq: joint speeds [rad/s].
        tau: joint torques at the drive outputs, from the torque sensors [N·m].
        cuff_force_est: estimated cuff forces on the exoskeleton, (4, 2) [N],
            when an estimator runs (None otherwise).
        cuff_force_std: the estimate's own standard deviation per cuff, (4,)
            [N], when the estimator states one (the Kalman filter's
            covariance; None otherwise).
        belt_speed: the treadmill's belt-speed reading, (1,) [m/s], when the
            run models the belt (None otherwise;
            :mod:`exo_ctrl.sensing.belt_encoder`).

    """

    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    cuff_force_est: np.ndarray | None = None
    cuff_force_std: np.ndarray | None = None
    belt_speed: np.ndarray | None = None
