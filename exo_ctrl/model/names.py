"""Names and orders shared by every part of exo_ctrl: legs, joints, cuffs, default files.

The driven joints, the cuffs and the legs always appear in the orders given
here (arrays of four joint values are ``[left_hip, left_knee, right_hip,
right_knee]``; arrays of four cuff values follow :data:`CUFF_NAMES`).
"""

from __future__ import annotations

__all__ = [
    "CUFF_NAMES",
    "DEFAULT_URDF_NAMES",
    "FRICTION_SMOOTHING_RAD_S",
    "JOINT_NAMES",
    "SIDES",
]

#: Leg prefixes, left first.
SIDES: tuple[str, str] = ("left", "right")

#: Canonical order of the driven joints everywhere in exo_ctrl.
JOINT_NAMES: tuple[str, str, str, str] = ("left_hip", "left_knee", "right_hip", "right_knee")

#: Canonical order of the cuffs; each is a frame ``<name>_cuff`` on both bodies.
CUFF_NAMES: tuple[str, str, str, str] = ("left_thigh", "left_shank", "right_thigh", "right_shank")

#: File name of each kind's committed URDF (in the repository's ``urdf/``).
DEFAULT_URDF_NAMES: dict[str, str] = {"exo": "exoskeleton.urdf", "patient": "patient.urdf"}

#: Speed scale ε of the smoothed dry joint friction f tanh(q̇ / ε) used by the
#: plant and the feedforward [rad/s].
FRICTION_SMOOTHING_RAD_S = 0.01
