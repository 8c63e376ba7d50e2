r"""The leg's effective mass at the foot, per plan row: what ``path``'s wall damps.

The wall of :mod:`exo_ctrl.control.modes.path` acts on the foot through the
force loop of the free part, so the patient's leg and the exoskeleton's
(its inertia felt divided by 1 + K_f) move together against it.  Their
operational-space inertia at the foot [kg], on the device's models at the
plan's angles q*(r) of row r (the patient's joints taken as the
exoskeleton's: the device's models are aligned):

.. math::  Λ = (J M^{-1} J^T)^{-1},\qquad
           M = M_p(q) + D\,\bigl(M_e(q) + i_G^2 J_r\,I\bigr)\,D,\qquad
           D = \operatorname{diag}(1 + K_f)^{-1/2},

per leg (the 2×2 blocks of the joint-space inertias: the legs hang from a
fixed pelvis and do not couple), J the foot Jacobian of the exoskeleton's
legs (:func:`~exo_ctrl.model.leg_kernels.foot_point`), M_p and M_e
Pinocchio's CRBA on the patient and exoskeleton models, i_G² J_r the
drives' reflected rotor inertia.  D M_e D is exact for equal gains K_f and
the symmetric choice otherwise.  A mass m_n = nᵀ Λ n along the wall's
normal n then gives the wall's damping for a damping ratio ζ,
b_n = 2 ζ √(k m_n).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from ...model import BodyModel
from ...model.leg_kernels import foot_point
from ...plant.drive import MotorParams

__all__ = ["foot_mass_table", "joint_inertia"]


def joint_inertia(body: BodyModel, q: np.ndarray, data: Any = None) -> np.ndarray:
    """The joint-space inertia of ``body``'s four driven joints at angles q [rad], (4, 4) [kg·m²].

    ``data``: Pinocchio data of ``body.model`` to reuse (None: a new one).
    """
    model = body.model
    full = pin.neutral(model)
    full[list(body.q_index)] = q
    m = pin.crba(model, model.createData() if data is None else data, full)
    m = np.triu(m) + np.triu(m, 1).T  # CRBA fills the upper triangle
    idx = list(body.q_index)
    return m[np.ix_(idx, idx)]


def foot_mass_table(
    q_plan: np.ndarray,
    exo: BodyModel,
    patient: BodyModel | None,
    motor: MotorParams,
    force_gain: np.ndarray,
    legs: Any,
) -> np.ndarray:
    """Λ per plan row and leg (module docstring), (rows, 2, 3): Λ_xx, Λ_xz, Λ_zz [kg].

    Args:
        q_plan: the plan's joint angles per row, (rows, 4) [rad].
        exo: the exoskeleton model the device holds.
        patient: the patient model the device holds (None: the exoskeleton's
            rendered inertia alone).
        motor: the drive the device believes in (its reflected rotor inertia).
        force_gain: K_f per joint, (4,).
        legs: a record element with the exoskeleton's leg geometry
            (:data:`~exo_ctrl.model.leg_kernels.LEG_FIELDS`).

    """
    q_plan = np.asarray(q_plan, dtype=float)
    scale = 1.0 / np.sqrt(1.0 + np.asarray(force_gain, dtype=float))
    rotor = motor.reflected_inertia_kgm2 * np.eye(4)
    rows = q_plan.shape[0]
    m = np.empty((rows, 4, 4))
    exo_data = exo.model.createData()
    patient_data = None if patient is None else patient.model.createData()
    for r, q in enumerate(q_plan):
        m[r] = scale[:, None] * (joint_inertia(exo, q, exo_data) + rotor) * scale[None, :]
        if patient is not None:
            m[r] += joint_inertia(patient, q, patient_data)
    out = np.empty((rows, 2, 3))
    jac = np.empty((rows, 2, 2))
    for leg in range(2):
        for r, q in enumerate(q_plan):
            _, _, jxh, jxk, jzh, jzk = foot_point(legs, leg, q[2 * leg], q[2 * leg + 1])
            jac[r] = (jxh, jxk), (jzh, jzk)
        i = slice(2 * leg, 2 * leg + 2)
        inv_m_jt = np.linalg.solve(m[:, i, i], np.swapaxes(jac, 1, 2))
        lam = np.linalg.inv(jac @ inv_m_jt)
        out[:, leg] = np.stack((lam[:, 0, 0], lam[:, 0, 1], lam[:, 1, 1]), axis=-1)
    return out
