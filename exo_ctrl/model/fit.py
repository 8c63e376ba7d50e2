"""Does a device fit its patient?  Link lengths and cuff points compared, before a run.

An exoskeleton whose thigh or shank differs from the patient's by more than
:data:`LENGTH_TOLERANCE_M` strains the cuffs over the whole gait (the joint
axes cannot both be aligned), and a cuff placed beyond the end of the
patient's segment straps nothing.  :func:`fit_warnings` names each such
mismatch with both lengths and the command that makes a fitted device;
a run goes on (the user may study a poor fit on purpose) with the warnings in
its summary.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from .loader import BodyModel
from .names import CUFF_NAMES

__all__ = ["LENGTH_TOLERANCE_M", "cuff_distances", "fit_warnings"]

#: The largest difference between a device's and its patient's segment lengths
#: that counts as fitted [m]: the adjustment step of clinical gait trainers'
#: telescopic links is about 1 cm (Lokomat: Colombo et al., J. Rehabil. Res.
#: Dev. 37(6), 2000), so a fitted device is within two steps.
LENGTH_TOLERANCE_M = 0.02

#: How to make a fitted device (shown in the warnings).
FIT_HINT = (
    "'exo-ctrl urdf --kind patient --height M --mass KG --out P.urdf' prints the link lengths "
    "of a fitted exoskeleton"
)


def cuff_distances(body: BodyModel) -> dict[str, float]:
    """Each cuff's distance along its segment from the joint above it [m], legs straight.

    Thigh cuffs from the hip, shank cuffs from the knee, keyed by
    :data:`~exo_ctrl.model.CUFF_NAMES`; at q = 0 the legs hang straight, so the
    distance is the joint's height above the cuff point.
    """
    model = body.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, pin.neutral(model))
    out = {}
    for k, (name, frame) in enumerate(zip(CUFF_NAMES, body.cuff_frame_ids, strict=True)):
        joint = body.joint_ids[k]  # cuff k rides the link after joint k (hip → thigh, knee → shank)
        top = data.oMi[joint].translation
        out[name] = float(np.linalg.norm(data.oMf[frame].translation - top))
    return out


def fit_warnings(exo: BodyModel, patient: BodyModel) -> list[str]:
    """What does not fit between an exoskeleton and its patient, one sentence each ([] fits).

    Checks, per leg: thigh and shank lengths differing by more than
    :data:`LENGTH_TOLERANCE_M`, and each exoskeleton cuff farther along its
    segment than the patient's segment is long.
    """
    out = []
    exo_cuffs = cuff_distances(exo)
    for side in ("left", "right"):
        ours, theirs = exo.legs[side], patient.legs[side]
        for segment in ("thigh", "shank"):
            a = getattr(ours, f"{segment}_length")
            b = getattr(theirs, f"{segment}_length")
            if abs(a - b) > LENGTH_TOLERANCE_M:
                out.append(
                    f"the exoskeleton's {side} {segment} is {a:.3f} m and the patient's "
                    f"{b:.3f} m ({1e3 * abs(a - b):.0f} mm apart, over the "
                    f"{1e3 * LENGTH_TOLERANCE_M:.0f} mm of a fitted device): the cuffs strain "
                    f"over the gait; {FIT_HINT}"
                )
            cuff = exo_cuffs[f"{side}_{segment}"]
            if cuff > b + 1e-9:
                out.append(
                    f"the exoskeleton's {side} {segment} cuff sits {cuff:.3f} m along the "
                    f"{segment}, beyond the end of the patient's {b:.3f} m {segment}"
                )
    return out
