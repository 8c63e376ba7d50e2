r"""Misaligned joints: the true patient's hip and knee axes offset from the exoskeleton's.

A device is fitted so that its joint axes lie on the patient's, but the
anatomical axes are not where the device's are: the knee's instantaneous
centre moves, the hip's is hidden under soft tissue, and a fitted device is
off by centimetres.  :class:`Misalignment` gives the true patient's hip axis at
H_e + d_h and its knee axis at K_e + d_k, H_e and K_e the exoskeleton's
(the same on both legs), with the offsets d = (DX, DZ) in the sagittal plane
of the world with the legs at q = 0 (hanging straight for the default URDFs:
DX forward, DZ up, across and along the thigh) [m].

**What it means for a two-link leg strapped to two-link exo links.**  The
straps hold the limb where the exoskeleton's cuffs are: at the fit the
patient's cuff points are the exoskeleton's, C_t and C_s (as without
misalignment).  The patient's own links run between its own joints:

- thigh: from H_e + d_h to K_e + d_k, so the hip → knee vector is the
  exoskeleton's plus d_k - d_h (a knee offset along the thigh, DZ, is a
  thigh |DZ| shorter or longer than the exoskeleton's; one across, DX,
  tilts the thigh by about DX / l₁), and the thigh cuff, hip → C_t, is the
  exoskeleton's less d_h;
- shank: from K_e + d_k; its knee → cuff vector is the exoskeleton's less
  d_k; the shank itself (its inertia and its foot about the knee) is the
  patient's own.

The thigh's inertia about the patient's hip is kept (its mass, centre of mass
and inertia: a 2 cm longer femur moves the thigh's centre of mass by about
1 cm, which is left out; the knee, and the shank hanging from it, move).

When the legs move, each body turns about its own axes and the cuff points
part: with the shank turned by β from the fit on both bodies and the hips
aligned, the shank cuffs part by Δp = (R(β) - I) d_k (exo minus patient) —
an along-shank stretch u₀ · (I - R(β)ᵀ) d_k that no joint-torque estimator
built on coaxial joints can see (tests/sim/test_misalignment.py checks it
against the plant).

**Implementation.**  Only relative positions enter the cuffs, and the
patient's dynamics do not depend on where its hip is in the world, so the
patient model is changed, not the plant: in a copy of the patient's
Pinocchio model the knee joints move by d_k - d_h, the thigh cuff frames by
-d_h and the shank cuff frames by -d_k (each in its parent joint's frame at
q = 0); the plant then aligns the hips as before (``patient_offset_xz``), which
puts the whole patient d_h from where it truly is — the same cuff forces.
A part that sees the patient in the world (a foot on the belt) would see its
foot d_h off.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..exceptions import InvalidParameter
from ..model import CUFF_NAMES, SIDES, BodyModel
from ..model.geometry import leg_geometry

__all__ = ["MAX_MISALIGNMENT_M", "Misalignment", "misaligned_patient"]

#: Largest offset of a joint axis, per component [m].  Reported misalignments of
#: fitted knee exoskeletons are a few centimetres (Schiele & van der Helm 2006,
#: IEEE TNSRE 14(4):456, "Kinematic design to improve ergonomics in human
#: machine interaction": up to about 3 cm); 0.1 m is well beyond a strap's hold.
MAX_MISALIGNMENT_M = 0.1


def _offset(name: str, value: object) -> tuple[float, float]:
    """(DX, DZ) from a pair of numbers, each finite and within ±MAX_MISALIGNMENT_M [m]."""
    allowed = f"two numbers DX,DZ in [-{MAX_MISALIGNMENT_M:g}, {MAX_MISALIGNMENT_M:g}] m"
    try:
        pair = tuple(value)  # type: ignore[arg-type]
    except TypeError:
        raise InvalidParameter(name, value, allowed) from None
    if len(pair) != 2:
        raise InvalidParameter(name, value, allowed)
    out = []
    for x in pair:
        if isinstance(x, bool) or not isinstance(x, (int, float, np.floating, np.integer)):
            raise InvalidParameter(name, value, allowed)
        x = float(x)
        if not (math.isfinite(x) and abs(x) <= MAX_MISALIGNMENT_M):
            raise InvalidParameter(name, value, allowed)
        out.append(x)
    return out[0], out[1]


@dataclass(frozen=True)
class Misalignment:
    """Offsets of the true patient's joint axes from the exoskeleton's (module docstring).

    Attributes:
        hip_xz: d_h = (DX, DZ), the patient's hip axis from the exoskeleton's [m].
        knee_xz: d_k = (DX, DZ), the patient's knee axis from the exoskeleton's [m].

    Both in the world's x (forward), z (up) with the legs at q = 0; default
    (0, 0): coaxial joints.

    Raises:
        InvalidParameter: not two finite numbers each, or beyond
            ±:data:`MAX_MISALIGNMENT_M`.

    """

    hip_xz: tuple[float, float] = (0.0, 0.0)
    knee_xz: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(self, "hip_xz", _offset("misalignment_hip", self.hip_xz))
        object.__setattr__(self, "knee_xz", _offset("misalignment_knee", self.knee_xz))

    @property
    def aligned(self) -> bool:
        """Both offsets zero."""
        return self.hip_xz == (0.0, 0.0) and self.knee_xz == (0.0, 0.0)


def _moved(placement: pin.SE3, rotation: np.ndarray, world_xz: np.ndarray) -> pin.SE3:
    """``placement`` moved by a world (x, z) offset, seen in a frame turned by ``rotation``."""
    out = pin.SE3(placement)
    out.translation = placement.translation + rotation.T @ np.array([world_xz[0], 0.0, world_xz[1]])
    return out


def misaligned_patient(patient: BodyModel, misalignment: Misalignment) -> BodyModel:
    """A copy of ``patient`` whose joints are offset from the cuffs (module docstring).

    Args:
        patient: the true patient, as loaded (cuff frames where the
            exoskeleton's are at the fit).
        misalignment: the offsets.

    Returns:
        ``patient`` itself when aligned, else a new body with its own
        Pinocchio model (the original is untouched) and its leg geometry
        read again (the thigh length changes with d_k - d_h).

    """
    if misalignment.aligned:
        return patient
    d_h = np.asarray(misalignment.hip_xz)
    d_k = np.asarray(misalignment.knee_xz)
    model = pin.Model(patient.model)
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    for s, side in enumerate(SIDES):
        hip, knee = patient.joint_ids[2 * s], patient.joint_ids[2 * s + 1]
        model.jointPlacements[knee] = _moved(
            model.jointPlacements[knee], data.oMi[hip].rotation, d_k - d_h
        )
        for link, joint, shift in (("thigh", hip, -d_h), ("shank", knee, -d_k)):
            cuff = patient.cuff_frame_ids[CUFF_NAMES.index(f"{side}_{link}")]
            for fid in range(model.nframes):
                frame = model.frames[fid]
                if fid == cuff or frame.name == f"{side}_{link}_cuff_joint":
                    frame.placement = _moved(frame.placement, data.oMi[joint].rotation, shift)
                    model.frames[fid] = frame
    legs = leg_geometry(
        patient.source, model, patient.joint_ids, patient.cuff_frame_ids, patient.foot_frame_ids
    )
    return dataclasses.replace(patient, model=model, legs=legs)
