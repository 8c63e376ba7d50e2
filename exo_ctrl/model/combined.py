"""One Pinocchio model of the exoskeleton and the patient side by side."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from ..exceptions import InvalidModel
from .loader import BodyModel

__all__ = ["combined_model"]


def combined_model(exo: BodyModel, patient: BodyModel) -> pin.Model:
    """One Pinocchio model of both bodies, q = v = [q_exo (4), q_patient (4)].

    Used by the plant (one ABA for both bodies) and by the QP's cuff model
    (one CRBA and one nonLinearEffects for both).

    The patient's model is appended to the exoskeleton's at the world frame,
    its joint and frame names prefixed with ``patient/`` (appendModel refuses
    clashing names).  Both are fixed-base, so the trees stay independent and
    ABA on the result is ABA on each model apart.
    """
    g_exo, g_pat = exo.model.gravity.vector, patient.model.gravity.vector
    if not np.array_equal(g_exo, g_pat):
        raise InvalidModel(
            patient.source,
            "",
            f"its gravity {g_pat.tolist()} differs from the exoskeleton's {g_exo.tolist()}; "
            "the plant needs the same gravity in both models",
        )
    pat = pin.Model(patient.model)
    for i in range(1, pat.njoints):
        pat.names[i] = "patient/" + pat.names[i]
    for i in range(1, pat.nframes):
        frame = pat.frames[i]
        frame.name = "patient/" + frame.name
        pat.frames[i] = frame
    model = pin.appendModel(exo.model, pat, 0, pin.SE3.Identity())
    model.gravity = pin.Motion(exo.model.gravity)
    ids = [model.getJointId(exo.model.names[j]) for j in exo.joint_ids]
    ids += [model.getJointId(pat.names[j]) for j in patient.joint_ids]
    order = [(model.joints[j].idx_q, model.joints[j].idx_v) for j in ids]
    if model.nq != 8 or model.nv != 8 or order != [(i, i) for i in range(8)]:
        raise InvalidModel(
            f"{exo.source} + {patient.source}",
            "",
            f"the combined model's coordinates {order} are not [exo, patient] in joint order",
        )
    return model
