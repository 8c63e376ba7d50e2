"""URDF models of the exoskeleton and the patient: names, loading, checks, geometry, the generator.

- :mod:`~exo_ctrl.model.names`: the joint, cuff and leg names and orders.
- :mod:`~exo_ctrl.model.loader`: :class:`BodyModel` and the loaders
  (a URDF, the committed defaults, example-robot-data's human).
- :mod:`~exo_ctrl.model.checks`: checks Pinocchio's URDF parser does not make.
- :mod:`~exo_ctrl.model.geometry`: the sagittal leg geometry read from a model.
- :mod:`~exo_ctrl.model.combined`: one model of both bodies (plant, QP).
- :mod:`~exo_ctrl.model.body_params` and :mod:`~exo_ctrl.model.urdfgen`:
  the parameters of a generated body and its URDF.
- :mod:`~exo_ctrl.model.anthropometry` and :mod:`~exo_ctrl.model.cohort`:
  patients from height and mass, and a seeded virtual cohort around them.
"""

from .anthropometry import SEXES, nominal_patient, patient_from_anthropometry
from .body_params import BodyParams, SegmentInertia, segment_inertia
from .cohort import CohortPatient, CohortSpread, benchmark_cohort, draw_cohort, fitted_exo
from .combined import combined_model
from .geometry import LegGeometry
from .loader import (
    BodyModel,
    default_urdf_path,
    human_urdf_path,
    load_body,
    load_exo,
    load_human_patient,
    load_patient,
)
from .names import CUFF_NAMES, DEFAULT_URDF_NAMES, FRICTION_SMOOTHING_RAD_S, JOINT_NAMES, SIDES
from .urdfgen import build_urdf, urdf_xml, write_urdf

__all__ = [
    "CUFF_NAMES",
    "DEFAULT_URDF_NAMES",
    "FRICTION_SMOOTHING_RAD_S",
    "JOINT_NAMES",
    "SEXES",
    "SIDES",
    "BodyModel",
    "BodyParams",
    "CohortPatient",
    "CohortSpread",
    "LegGeometry",
    "SegmentInertia",
    "benchmark_cohort",
    "build_urdf",
    "combined_model",
    "default_urdf_path",
    "draw_cohort",
    "fitted_exo",
    "human_urdf_path",
    "load_body",
    "load_exo",
    "load_human_patient",
    "load_patient",
    "nominal_patient",
    "patient_from_anthropometry",
    "segment_inertia",
    "urdf_xml",
    "write_urdf",
]
