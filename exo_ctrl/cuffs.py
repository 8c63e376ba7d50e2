"""Elastic cuffs coupling the exoskeleton and the patient.

A cuff is a spring–damper between a frame on an exoskeleton link and the
equally named frame on the patient link (``left_thigh_cuff`` …).  In the
sagittal plane (x forward, z up) the force on the exoskeleton is

    f = -K (Δp - r₀) - C Δṗ,   Δp = p_exo - p_patient,

and the patient receives -f.  r₀ is the offset at which the strap is
slack, captured when the device is fitted (zero when the frames coincide).
Each body feels the force through its frame Jacobian: τ_exo = J_exoᵀ f,
τ_patient = -J_patientᵀ f.

All eight cuff points (four per body) are computed in one batch.  A point
in the x–z plane is the complex number p = x + i z; a link turned by θ about
the lateral axis turns its points by e^{iθ} about the joint.  A point on a
thigh is p = h + e^{iα} a, on a shank p = h + e^{iα} a + e^{iβ} b, where h is
the hip, a and b the link vectors at q = 0 and α = s_h q_hip,
β = α + s_k q_knee the link rotations (signs and vectors read from the
Pinocchio model at q = 0; see :mod:`exo_ctrl.model`).  Then
ṗ = α̇ i e^{iα} a + β̇ i e^{iβ} b, and the generalised force of a force f
(also complex) is Re(conj(i e^{iα} a) f) on α and the same with b on β,
mapped back to the joints by the sign matrices.  Tests check positions and
Jacobians against Pinocchio's frame kinematics.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from . import _validate as v
from .model import CUFF_NAMES, BodyModel

__all__ = ["CuffParams", "CuffSet"]


@dataclass(frozen=True)
class CuffParams:
    """Cuff spring–damper, the same for the four cuffs.

    Attributes:
        stiffness_N_per_m: K, paper Table I (c_H, c_S = 8 N/mm) [N/m].
        damping_N_s_per_m: C, not in the paper; 100 N·s/m gives a damping
            ratio of about 0.3 for the shank cuff mode of the default
            patient (chosen) [N·s/m].
    """

    stiffness_N_per_m: float = 8000.0
    damping_N_s_per_m: float = 100.0

    def __post_init__(self) -> None:
        v.positive("cuff stiffness", self.stiffness_N_per_m, "N/m")
        v.non_negative("cuff damping", self.damping_N_s_per_m, "N·s/m")


class CuffSet:
    """The four cuffs between an exoskeleton and a patient, computed in one batch.

    Joint vectors are stacked as ``q_all = [q_exo (4), q_patient (4)]`` in
    :data:`~exo_ctrl.model.JOINT_NAMES` order.

    Args:
        exo: the exoskeleton.
        patient: the patient.
        params: spring and damper.
        patient_offset_xz: where the patient's world origin sits in the
            exoskeleton's world (x, z) [m] (aligns the hips).
    """

    def __init__(
        self,
        exo: BodyModel,
        patient: BodyModel,
        params: CuffParams,
        patient_offset_xz: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        self.params = params
        n = 8  # 4 cuffs x 2 bodies; rows 0-3 exo, 4-7 patient
        base = np.zeros(n, dtype=complex)
        vec_a = np.zeros(n, dtype=complex)
        vec_b = np.zeros(n, dtype=complex)
        sel_a = np.zeros((n, 8))  # α_i = sel_a[i] @ q_all
        sel_b = np.zeros((n, 8))
        offset = complex(*patient_offset_xz)
        for b, body in enumerate((exo, patient)):
            data = body.model.createData()
            pin.framesForwardKinematics(body.model, data, pin.neutral(body.model))
            shift = offset if b == 1 else 0.0
            for c, cuff in enumerate(CUFF_NAMES):
                i = 4 * b + c
                side = cuff.split("_")[0]
                leg = body.legs[side]
                hip_col = 4 * b + (0 if side == "left" else 2)
                hip_id, knee_id = body.joint_ids[hip_col - 4 * b], body.joint_ids[hip_col - 4 * b + 1]
                hip = _xz(data.oMi[hip_id].translation) + shift
                knee = _xz(data.oMi[knee_id].translation) + shift
                point = _xz(data.oMf[body.cuff_frame_ids[c]].translation) + shift
                base[i] = hip
                sel_a[i, hip_col] = leg.sign_hip
                if cuff.endswith("thigh"):
                    vec_a[i] = point - hip
                else:
                    vec_a[i] = knee - hip
                    vec_b[i] = point - knee
                    sel_b[i, hip_col] = leg.sign_hip
                    sel_b[i, hip_col + 1] = leg.sign_knee
        self._base = base
        self._ab = np.concatenate((vec_a, vec_b))  # (16,)
        self._sel = np.vstack((sel_a, sel_b))  # (16, 8)
        self._sel_t = np.ascontiguousarray(self._sel.T)
        # Work arrays, allocated once.
        self._ang = np.zeros(16)
        self._angc = np.zeros(16, dtype=complex)
        self._rot = np.zeros(16, dtype=complex)  # e^{iθ} a (rotated link vectors)
        self._irot = np.zeros(16, dtype=complex)  # i e^{iθ} a
        self._pos = np.zeros(n, dtype=complex)
        self._vel = np.zeros(n, dtype=complex)
        self._tmp16 = np.zeros(16, dtype=complex)
        self._dp = np.zeros(4, dtype=complex)
        self._dv = np.zeros(4, dtype=complex)
        self._f = np.zeros(4, dtype=complex)
        self._f16 = np.zeros(16, dtype=complex)
        self._gen = np.zeros(16)
        self.rest_offset = np.zeros(4, dtype=complex)
        #: Generalised cuff forces on [exo, patient] joints [N·m], (8,).
        self.joint_torque = np.zeros(8)
        self._k = -float(params.stiffness_N_per_m)
        self._c = -float(params.damping_N_s_per_m)

    # ------------------------------------------------------------------ kinematics

    def _kinematics(self, q_all: np.ndarray) -> None:
        np.dot(self._sel, q_all, out=self._ang)
        np.multiply(self._ang, 1j, out=self._angc)
        np.exp(self._angc, out=self._rot)
        np.multiply(self._rot, self._ab, out=self._rot)
        np.multiply(self._rot, 1j, out=self._irot)
        np.add(self._rot[:8], self._rot[8:], out=self._pos)
        np.add(self._pos, self._base, out=self._pos)

    def positions(self, q_all: np.ndarray) -> np.ndarray:
        """World (x, z) of the cuff points, shape (2 bodies, 4 cuffs, 2) [m]."""
        self._kinematics(np.asarray(q_all, dtype=float))
        pos = self._pos.reshape(2, 4)
        return np.stack((pos.real, pos.imag), axis=-1)

    def jacobians(self, q_all: np.ndarray) -> np.ndarray:
        """∂(x, z)/∂q_all of every cuff point, shape (2 bodies, 4 cuffs, 2, 8)."""
        self._kinematics(np.asarray(q_all, dtype=float))
        jac = self._irot[:, None] * self._sel  # (16, 8) complex
        jac = jac[:8] + jac[8:]
        out = np.stack((jac.real, jac.imag), axis=1)  # (8, 2, 8)
        return out.reshape(2, 4, 2, 8)

    def fit(self, q_all: np.ndarray) -> None:
        """Fit the straps: make the present offsets the slack (zero-force) ones."""
        self._kinematics(np.asarray(q_all, dtype=float))
        self.rest_offset[:] = self._pos[:4] - self._pos[4:]

    # ------------------------------------------------------------------ forces

    def compute(self, q_all: np.ndarray, v_all: np.ndarray) -> np.ndarray:
        """Cuff forces on the exoskeleton at (q_all, v_all), as complex fx + i fz [N].

        Also fills :attr:`joint_torque` (J_exoᵀ f on the exo joints,
        -J_patientᵀ f on the patient's).  Returns a buffer overwritten by the
        next call.
        """
        self._kinematics(q_all)
        # Velocities: ṗ = Σ (sel @ v) i e^{iθ} a.
        np.dot(self._sel, v_all, out=self._ang)
        np.multiply(self._irot, self._ang, out=self._tmp16)
        np.add(self._tmp16[:8], self._tmp16[8:], out=self._vel)
        dp, dv, f = self._dp, self._dv, self._f
        np.subtract(self._pos[:4], self._pos[4:], out=dp)
        np.subtract(dp, self.rest_offset, out=dp)
        np.subtract(self._vel[:4], self._vel[4:], out=dv)
        np.multiply(dp, self._k, out=f)
        np.multiply(dv, self._c, out=dv)
        np.add(f, dv, out=f)
        # Generalised forces: Re(conj(i e^{iθ} a) f_point), f_point = +f (exo), -f (patient).
        f16 = self._f16
        f16[0:4] = f
        np.negative(f, out=f16[4:8])
        f16[8:] = f16[:8]
        np.conjugate(self._irot, out=self._tmp16)
        np.multiply(self._tmp16, f16, out=self._tmp16)
        np.dot(self._sel_t, self._tmp16.real, out=self.joint_torque)
        return f


def _xz(p: np.ndarray) -> complex:
    return complex(float(p[0]), float(p[2]))
