r"""The planned motion's torque against the drives' reach, said before the run.

Computed torque's feedforward τ_ff (:mod:`exo_ctrl.control.computed_torque`,
with the stance legs' load where the pelvis is supported) is the drive
torque the plan needs on the device's own models.  A drive gives at most
its peak torque i_G k_m I_max (:attr:`~exo_ctrl.plant.drive.MotorParams.peak_torque_Nm`,
at the driver's current limit, which :func:`~exo_ctrl.sim.drive_for` caps at
the exoskeleton URDF's effort limit).  Where |τ_ff| exceeds it the drive
saturates whatever the feedback asks, and the leg falls behind its plan: the
stance knee before each touchdown sags, and the swing foot meets the belt
early (docs/performance.md, touchdowns under load).  Nothing on the tick
path: the check reads the feedforward table once, when the run is built.
"""

from __future__ import annotations

import numpy as np

from .. import _validate as v
from ..exceptions import InvalidParameter
from ..model import JOINT_NAMES

__all__ = ["torque_reach_warning"]


def torque_reach_warning(torque_ff_Nm: np.ndarray, peak_torque_Nm: float) -> str | None:
    """The sentence for a plan whose feedforward exceeds the drives' peak torque, else None.

    Args:
        torque_ff_Nm: τ_ff along the plan, (rows, 4) [N·m], joints in
            :data:`~exo_ctrl.model.JOINT_NAMES` order.
        peak_torque_Nm: the drives' peak torque at the joint [N·m], > 0.

    Raises:
        InvalidParameter: a table not of finite torques in 4 columns, a peak
            torque not > 0.

    """
    table = np.asarray(torque_ff_Nm, dtype=float)
    if table.ndim != 2 or table.shape[1] != 4:
        raise InvalidParameter("torque_ff shape", table.shape, "(rows, 4): one column per joint")
    if not np.isfinite(table).all():
        raise InvalidParameter("torque_ff", "a non-finite entry", "finite torques [N·m]")
    cap = v.positive("peak_torque", peak_torque_Nm, "N·m")
    peaks = np.abs(table).max(axis=0, initial=0.0)
    over = [f"{JOINT_NAMES[j]} (up to {peaks[j]:.0f} N·m)" for j in range(4) if peaks[j] > cap]
    if not over:
        return None
    return (
        f"the plan needs more torque than the drives' {cap:.0f} N·m at {', '.join(over)} "
        "(computed torque's feedforward on the device's models): the drives saturate there "
        "and the legs fall behind the plan, which makes touchdowns under body-weight support "
        "harder; a stronger drive, more support or a gentler gait lowers it "
        "(docs/performance.md, touchdowns under load)"
    )
