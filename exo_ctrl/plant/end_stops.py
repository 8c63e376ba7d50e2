"""Mechanical end stops of the exoskeleton's joints: the URDF's ``<limit>`` as hard stops.

A real joint cannot turn past its range of motion: a metal or elastomer
stop meets it.  Each exoskeleton joint gets a stop at its URDF ``lower`` and
``upper`` limit, a stiff unilateral spring–damper on the penetration
d = q − q_upper (or q_lower − q) > 0,

    τ_stop = −max(0, K d + C ḋ)   at the upper stop,
    τ_stop = +max(0, K d + C ḋ)   at the lower stop,

so a stop pushes the link back and never pulls it in: when the link leaves
faster than the spring relaxes (K d + C ḋ < 0) the torque is zero, not
negative.  The damping dissipates energy on every contact; the spring
stores and returns it.  The torque acts on the link from the frame, outside
the drive: the joint torque sensor (gearbox to link) does not read it, and
the estimator sees it as an external torque, as on the real device.

**Parameters** (no standard exists; chosen for the default device and
checked for stability at the default step).  K = 2·10⁴ N·m/rad: the drives'
150 N·m effort limit held against a stop penetrates 150 / K = 7.5 mrad
(0.43°), the order of an elastomer bumper's travel under full load.  The
link's inertia at the joint, with the reflected rotor inertia i_G² J_rotor
= 0.15 kg·m², is I ≥ 0.15 kg·m², so ω = √(K / I) ≤ 365 rad/s and ω h ≤ 0.37
at h = 1 ms, far inside the leapfrog's stability bound ω h < 2.  C = 50
N·m·s/rad: a damping ratio C / (2 √(K I)) ≤ 0.46, and C h / I ≤ 0.33 (the
explicit damping term stays stable).  The forces are taken at mid-step like
every other force of the plant (:mod:`exo_ctrl.plant.plant`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import _validate as v
from .._jit import kernel

__all__ = ["END_STOP_FIELDS", "EndStopParams", "end_stop_torques"]


@dataclass(frozen=True)
class EndStopParams:
    """The exoskeleton's hard stops (module docstring).

    Attributes:
        stiffness_Nm_per_rad: K [N·m/rad].
        damping_Nm_s_per_rad: C [N·m·s/rad].
        enabled: model the stops at all (off: the joints turn freely, as
            before the stops existed).

    Raises:
        InvalidParameter: K not > 0, C negative, or either not a number.

    """

    stiffness_Nm_per_rad: float = 2.0e4
    damping_Nm_s_per_rad: float = 50.0
    enabled: bool = True

    def __post_init__(self) -> None:
        k = v.positive("end_stop_stiffness", self.stiffness_Nm_per_rad, "N·m/rad")
        c = v.non_negative("end_stop_damping", self.damping_Nm_s_per_rad, "N·m·s/rad")
        object.__setattr__(self, "stiffness_Nm_per_rad", k)
        object.__setattr__(self, "damping_Nm_s_per_rad", c)
        object.__setattr__(self, "enabled", v.flag("end stops enabled", self.enabled))


#: The stops' fields of the plant's record: the limits ``stop_lower`` and
#: ``stop_upper`` [rad] of the four exoskeleton joints, ``stop_k`` K
#: [N·m/rad], ``stop_c`` C [N·m·s/rad], ``has_stops``, and the last step's
#: ``stop_torque`` [N·m] (4).
END_STOP_FIELDS = [
    ("stop_lower", np.float64, (4,)),
    ("stop_upper", np.float64, (4,)),
    ("stop_torque", np.float64, (4,)),
    ("stop_k", np.float64),
    ("stop_c", np.float64),
    ("has_stops", np.bool_),
]


@kernel
def end_stop_torques(p: Any, q: np.ndarray, dq: np.ndarray, tau: np.ndarray) -> None:
    """The stops' torques at (q, q̇) into ``p.stop_torque``, added to ``tau`` [N·m].

    ``p``: the plant's record (its :data:`END_STOP_FIELDS`); ``q``, ``dq``,
    ``tau``: joint vectors whose first four entries are the exoskeleton's.
    A joint within its range gets exactly zero and ``tau`` is left as it is.
    """
    for j in range(4):
        torque = 0.0
        if p.has_stops:
            over = q[j] - p.stop_upper[j]
            under = p.stop_lower[j] - q[j]
            if over > 0.0:
                torque = -max(0.0, p.stop_k * over + p.stop_c * dq[j])
            elif under > 0.0:
                torque = max(0.0, p.stop_k * under - p.stop_c * dq[j])
        p.stop_torque[j] = torque
        if torque != 0.0:
            tau[j] += torque
