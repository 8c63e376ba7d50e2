"""The simulated device, the truth: bodies, drives, cuffs, patient torques."""

from .belt import (
    BeltParams,
)
from .compliance import (
    CompliantJoint,
)
from .contact import (
    ContactParams,
    FootContact,
)
from .cuffs import (
    CuffParams,
    CuffSet,
)
from .current_mode import CURRENT_LOOP_BANDWIDTH_HZ
from .drive import (
    MOTOR_PRESETS,
    MotorParams,
    consistency_warning,
    motor_preset,
)
from .end_stops import (
    EndStopParams,
)
from .misalignment import (
    MAX_MISALIGNMENT_M,
    Misalignment,
    misaligned_patient,
)
from .motor import (
    MotorBank,
    motor_step,
)
from .patient import (
    PATIENT_TORQUES,
    PatientTorque,
    SpasticParams,
    SpasticPatient,
    make_patient_torque,
)
from .pelvis import PelvisParams
from .plant import (
    Plant,
)

__all__ = [
    "CURRENT_LOOP_BANDWIDTH_HZ",
    "MAX_MISALIGNMENT_M",
    "MOTOR_PRESETS",
    "PATIENT_TORQUES",
    "BeltParams",
    "CompliantJoint",
    "ContactParams",
    "CuffParams",
    "CuffSet",
    "EndStopParams",
    "FootContact",
    "Misalignment",
    "MotorBank",
    "MotorParams",
    "PatientTorque",
    "PelvisParams",
    "Plant",
    "SpasticParams",
    "SpasticPatient",
    "consistency_warning",
    "make_patient_torque",
    "misaligned_patient",
    "motor_preset",
    "motor_step",
]
