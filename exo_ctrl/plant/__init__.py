"""The simulated device, the truth: bodies, drives, cuffs, patient torques."""

from .compliance import (
    CompliantJoint,
)
from .cuffs import (
    CuffParams,
    CuffSet,
)
from .drive import (
    MOTOR_PRESETS,
    MotorParams,
    consistency_warning,
    motor_preset,
)
from .end_stops import (
    EndStopParams,
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
from .plant import (
    Plant,
)

__all__ = [
    "MOTOR_PRESETS",
    "PATIENT_TORQUES",
    "CompliantJoint",
    "CuffParams",
    "CuffSet",
    "EndStopParams",
    "MotorBank",
    "MotorParams",
    "PatientTorque",
    "Plant",
    "SpasticParams",
    "SpasticPatient",
    "consistency_warning",
    "make_patient_torque",
    "motor_preset",
    "motor_step",
]
