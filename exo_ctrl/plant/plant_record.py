"""The plant's record: the layout of its state, parameters and outputs.

One structured record (:func:`~exo_ctrl._jit.record`) holds everything the
plant's step kernels (:mod:`exo_ctrl.plant.plant`) read and write; the
components' own records (drives, cuffs, foot contact) are fields of it.
"""

from __future__ import annotations

import numpy as np

from .._jit import shared_dtype
from .compliance import COMPLIANCE_FIELDS
from .contact import CONTACT_FIELDS
from .cuffs import CUFF_FIELDS
from .end_stops import END_STOP_FIELDS
from .motor import motor_fields
from .patient_feet import PATIENT_FEET_FIELDS
from .pelvis import PELVIS_FIELDS

__all__ = ["PLANT_FIELDS", "plant_fields"]


#: Fields of the plant's record.  State and work per joint of [exo, patient]
#: (8 each): ``q``, ``v`` [rad, rad/s], ``acc`` the last step's acceleration
#: [rad/s²], ``q_mid``, ``v_mid`` the mid-step state, ``tau`` the joint
#: torques at mid-step [N·m], ``armature`` the combined model's armature
#: [kg·m²].  Per drive (4 each): ``drive_torque`` applied at the joint,
#: ``sensor_torque`` read by the joint torque sensor, ``patient_torque``
#: [N·m]; ``damping_m`` = h D_m of the drives, ``arm_base`` = i_G² J_rotor,
#: ``arm_const`` = i_G² J_rotor + h b [kg·m²]; the last step's applied
#: ``voltage`` [V] and mean ``current`` [A]; ``cuff_force`` on the
#: exoskeleton, (x, z) per cuff [N].  Parameters: ``b`` joint damping
#: [N·m·s/rad] and ``friction`` dry friction [N·m] (8 each), the step ``h``
#: [s], ``has_friction``, ``has_motors``; ``armature_changed``: the last
#: first half-step changed the exo armature (D_m changes only when a drive's
#: current enters or leaves its limit); ``resolve``: the second half-step held
#: a drive at its current limit and stepped nothing (solve the accelerations
#: again).  :func:`plant_fields` adds the stops' and the compliance's fields,
#: the drives' record ``motors``, the cuffs' record ``cuffs`` and the foot
#: contact's ``contact`` (:mod:`exo_ctrl.plant.contact`), the patient's feet on
#: the belt ``patient_feet`` (:mod:`exo_ctrl.plant.patient_feet`) and the pelvis's
#: ``pelvis`` (:mod:`exo_ctrl.plant.pelvis`).
def plant_fields() -> list[tuple]:
    """The plant record's fields: PLANT_FIELDS and its components' fields and records."""
    return [
        *PLANT_FIELDS,
        *END_STOP_FIELDS,
        *COMPLIANCE_FIELDS,
        ("motors", shared_dtype(motor_fields(4), align=True)),
        ("cuffs", shared_dtype(CUFF_FIELDS, align=True)),
        ("contact", shared_dtype(CONTACT_FIELDS, align=True)),
        ("patient_feet", shared_dtype(PATIENT_FEET_FIELDS, align=True)),
        ("pelvis", shared_dtype(PELVIS_FIELDS, align=True)),
    ]


_DRIVE_ROWS = (
    "drive_torque", "sensor_torque", "patient_torque", "damping_m", "arm_base", "arm_const",
    "voltage", "current", "effort",
)  # fmt: skip
PLANT_FIELDS = [
    *((name, np.float64, (8,)) for name in ("q", "v", "acc", "q_mid", "v_mid", "tau", "armature")),
    *((name, np.float64, (4,)) for name in _DRIVE_ROWS),
    ("cuff_force", np.float64, (4, 2)),
    ("b", np.float64, (8,)),
    ("friction", np.float64, (8,)),
    ("h", np.float64),
    ("has_friction", np.bool_),
    ("has_motors", np.bool_),
    ("armature_changed", np.bool_),
    ("resolve", np.bool_),
]
