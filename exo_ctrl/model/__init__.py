"""URDF models of the exoskeleton and the patient: loading, checks, geometry, the generator."""

from .body import (
    CUFF_NAMES,
    FRICTION_SMOOTHING_RAD_S,
    JOINT_NAMES,
    SIDES,
    BodyModel,
    LegGeometry,
    combined_model,
    default_urdf_path,
    human_urdf_path,
    load_body,
    load_exo,
    load_human_patient,
    load_patient,
)

__all__ = [
    "CUFF_NAMES",
    "FRICTION_SMOOTHING_RAD_S",
    "JOINT_NAMES",
    "SIDES",
    "BodyModel",
    "LegGeometry",
    "combined_model",
    "default_urdf_path",
    "human_urdf_path",
    "load_body",
    "load_exo",
    "load_human_patient",
    "load_patient",
]
