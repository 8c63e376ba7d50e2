"""Transitional re-exports: the names other packages import from ``exo_ctrl.model.body``.

The model package is split into :mod:`~exo_ctrl.model.names`,
:mod:`~exo_ctrl.model.geometry`, :mod:`~exo_ctrl.model.checks`,
:mod:`~exo_ctrl.model.loader` and :mod:`~exo_ctrl.model.combined`; import
from :mod:`exo_ctrl.model` instead.  This module goes once every import is
repointed.
"""

from __future__ import annotations

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

__all__ = [
    "CUFF_NAMES",
    "DEFAULT_URDF_NAMES",
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
