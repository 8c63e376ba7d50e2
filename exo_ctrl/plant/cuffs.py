"""Elastic cuffs coupling the exoskeleton and the patient.

A cuff is a spring–damper between a frame on an exoskeleton link and the
equally named frame on the patient link (``left_thigh_cuff`` …).  In the
sagittal plane (x forward, z up) the force on the exoskeleton is

    f = -K (Δp - r₀) - C Δṗ,   Δp = p_exo - p_patient,

and the patient receives -f.  r₀ is the offset at which the strap is
slack, captured when the device is fitted (zero when the frames coincide).
Each body feels the force through its frame Jacobian: τ_exo = J_exoᵀ f,
τ_patient = -J_patientᵀ f.

All eight cuff points (four per body) are computed in one batch of small
matrix products.  A link turned by θ about the lateral axis turns its points
by R(θ) about the joint.  A point on a thigh is p = h + R(α) a, on a shank
p = h + R(α) a + R(β) b, where h is the hip, a and b link vectors at q = 0 and
α = s_h q_hip, β = α + s_k q_knee the link rotations (signs and vectors read
from the Pinocchio model at q = 0; see :mod:`exo_ctrl.model.geometry`).  With the
eight link rotations θ = S q_all and u = (cos θ, sin θ), every point's
(x, z) is linear in u: p = P u + p₀, with P built once.  Then
ṗ = P w with w = (-sin θ ⊙ θ̇, cos θ ⊙ θ̇), the cuff stretch is
Δp = D P u + D p₀ - r₀ (D takes exo minus patient), and the generalised force
of the point forces F = Dᵀ f is Sᵀ ((Pᵀ F) ⊙ (-sin θ, cos θ)) summed over the
two halves.  Tests check positions and Jacobians against Pinocchio's frame
kinematics.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from .. import _validate as v
from .._jit import kernel, record
from ..model import CUFF_NAMES, SIDES, BodyModel

__all__ = ["CuffParams", "CuffSet"]


@dataclass(frozen=True)
class CuffParams:
    """Cuff spring–damper, the same for the four cuffs.

    Attributes:
        stiffness_N_per_m: K, paper Table I (c_H, c_S = 8 N/mm) [N/m].
        damping_N_s_per_m: C, not in the paper; 100 N·s/m gives a damping
            ratio of about 0.3 for the shank cuff mode of the default
            patient (chosen) [N·s/m].

    Both are stored as float.

    Raises:
        InvalidParameter: a field that is text, a bool or not finite;
            stiffness <= 0 or damping < 0.

    """

    stiffness_N_per_m: float = 8000.0
    damping_N_s_per_m: float = 100.0

    def __post_init__(self) -> None:
        k = v.positive("cuff stiffness", self.stiffness_N_per_m, "N/m")
        c = v.non_negative("cuff damping", self.damping_N_s_per_m, "N·s/m")
        object.__setattr__(self, "stiffness_N_per_m", k)
        object.__setattr__(self, "damping_N_s_per_m", c)


class CuffSet:
    """The four cuffs between an exoskeleton and a patient, computed in one batch.

    Joint vectors are stacked as ``q_all = [q_exo (4), q_patient (4)]`` in
    :data:`~exo_ctrl.model.JOINT_NAMES` order.  Forces are on the
    exoskeleton, laid out as ``(fx of the 4 cuffs, fz of the 4 cuffs)``;
    :attr:`force` is the same as a (4, 2) view.

    Args:
        exo: the exoskeleton.
        patient: the patient.
        params: spring and damper.
        patient_offset_xz: where the patient's world origin sits in the
            exoskeleton's world (x, z) [m] (aligns the hips).
        into: a record of :data:`CUFF_FIELDS` to hold the cuffs' state (a
            field of its owner's record); default a record of its own.

    """

    def __init__(
        self,
        exo: BodyModel,
        patient: BodyModel,
        params: CuffParams,
        patient_offset_xz: tuple[float, float] = (0.0, 0.0),
        into: np.ndarray | None = None,
    ) -> None:
        self.params = params
        # 8 points (rows 0-3 exo cuffs, 4-7 patient cuffs), 8 link rotations
        # (per body: left thigh, left shank, right thigh, right shank).
        base = np.zeros((8, 2))
        vec = np.zeros((8, 8, 2))  # point i, rotation j -> link vector at q = 0
        sel = np.zeros((8, 8))  # rotation j = sel[j] @ q_all
        for b, body in enumerate((exo, patient)):
            data = body.model.createData()
            pin.framesForwardKinematics(body.model, data, pin.neutral(body.model))
            shift = np.asarray(patient_offset_xz) if b == 1 else np.zeros(2)
            for s_idx, side in enumerate(SIDES):
                leg = body.legs[side]
                col = 4 * b + 2 * s_idx  # q_all column of this hip; +1 knee
                rot_thigh, rot_shank = col, col + 1
                sel[rot_thigh, col] = leg.sign_hip
                sel[rot_shank, col] = leg.sign_hip
                sel[rot_shank, col + 1] = leg.sign_knee
                hip_id, knee_id = body.joint_ids[2 * s_idx], body.joint_ids[2 * s_idx + 1]
                hip = _xz(data.oMi[hip_id].translation) + shift
                knee = _xz(data.oMi[knee_id].translation) + shift
                for link in ("thigh", "shank"):
                    c = CUFF_NAMES.index(f"{side}_{link}")
                    i = 4 * b + c
                    point = _xz(data.oMf[body.cuff_frame_ids[c]].translation) + shift
                    base[i] = hip
                    if link == "thigh":
                        vec[i, rot_thigh] = point - hip
                    else:
                        vec[i, rot_thigh] = knee - hip
                        vec[i, rot_shank] = point - knee
        ax, az = vec[..., 0], vec[..., 1]
        # (x; z) of the 8 points = P (cos θ; sin θ) + p0, rows: 8 x then 8 z.
        self._P = np.block([[ax, -az], [az, ax]])
        #: P of the module docstring, (16, 16): rows x then z of the 8 points
        #: (exo cuffs 0-3, patient cuffs 4-7), columns cos θ then sin θ.
        self.points = self._P
        self._p0 = np.concatenate((base[:, 0], base[:, 1]))
        diff = np.zeros((8, 16))  # exo minus patient, rows: 4 x then 4 z
        for c in range(4):
            for k in range(2):
                diff[4 * k + c, 8 * k + c] = 1.0
                diff[4 * k + c, 8 * k + 4 + c] = -1.0
        self._DP = diff @ self._P
        self._DPT = np.ascontiguousarray(self._DP.T)
        self._Dp0 = diff @ self._p0
        self._sel2 = np.vstack((sel, sel))
        self._k = float(params.stiffness_N_per_m)
        self._c = float(params.damping_N_s_per_m)
        #: The kernel's matrices, parameters and outputs, one record
        #: (:data:`CUFF_FIELDS`), the argument of :func:`cuff_forces`.
        self.record = record(CUFF_FIELDS) if into is None else into
        c = self.record[0]
        c["select"] = sel
        c["dp"] = self._DP
        c["dpt"] = self._DPT
        c["k"], c["c"] = self._k, self._c
        #: S, the rotation selection (8, 8): link rotation j = S[j] @ q_all.
        self.select = self.record["select"][0]
        # State and work arrays, allocated once.
        #: Strap offsets (exo minus patient, x then z) at which a cuff is slack [m], (8,).
        self.rest_offset = np.zeros(8)
        self._offset = self._Dp0.copy()  # D p0 - r0
        self._k_offset = self.record["k_offset"][0]
        np.multiply(self._offset, self._k, out=self._k_offset)
        self._theta = np.zeros(16)
        self._cs = np.zeros(16)  # (cos θ, sin θ)
        self._csr = np.zeros(16)  # (-sin θ, cos θ)
        self._f = self.record["f"][0]
        #: Cuff forces on the exoskeleton of the last :meth:`compute`, (4, 2) view [N].
        self.force = self._f.reshape(2, 4).T
        #: The same forces as (fx of the 4 cuffs, fz of the 4 cuffs), (8,) [N].
        self.force_flat = self._f
        #: Generalised cuff forces on [exo, patient] joints [N·m], (8,).
        self.joint_torque = self.record["tau"][0]

    # ------------------------------------------------------------------ kinematics

    def _trig(self, q_all: np.ndarray) -> None:
        th = self._theta
        np.dot(self._sel2, q_all, out=th)
        np.cos(th[:8], out=self._cs[:8])
        np.sin(th[8:], out=self._cs[8:])
        np.negative(self._cs[8:], out=self._csr[:8])
        self._csr[8:] = self._cs[:8]

    def positions(self, q_all: np.ndarray) -> np.ndarray:
        """World (x, z) of the cuff points, shape (2 bodies, 4 cuffs, 2) [m]."""
        self._trig(np.asarray(q_all, dtype=float))
        pos = self._P @ self._cs + self._p0
        return np.stack((pos[:8], pos[8:]), axis=-1).reshape(2, 4, 2)

    def jacobians(self, q_all: np.ndarray) -> np.ndarray:
        """∂(x, z)/∂q_all of every cuff point, shape (2 bodies, 4 cuffs, 2, 8)."""
        self._trig(np.asarray(q_all, dtype=float))
        # ∂p/∂θ_j = P[:, j] (-sin θ_j) + P[:, 8 + j] cos θ_j
        d_theta = self._P[:, :8] * self._csr[:8] + self._P[:, 8:] * self._csr[8:]
        jac = d_theta @ self._sel2[:8]  # (16, 8): rows 8 x then 8 z
        return np.stack((jac[:8], jac[8:]), axis=1).reshape(2, 4, 2, 8)

    def fit(self, q_all: np.ndarray) -> None:
        """Fit the straps: make the present offsets the slack (zero-force) ones."""
        self._trig(np.asarray(q_all, dtype=float))
        self.rest_offset[:] = self._DP @ self._cs + self._Dp0
        np.subtract(self._Dp0, self.rest_offset, out=self._offset)
        np.multiply(self._offset, self._k, out=self._k_offset)

    def stretch(self, q_all: np.ndarray) -> np.ndarray:
        """Cuff stretch Δp - r₀ (exo minus patient), x of the 4 cuffs then z [m], (8,)."""
        self._trig(np.asarray(q_all, dtype=float))
        return self._DP @ self._cs + self._offset

    # ------------------------------------------------------------------ forces

    def compute(self, q_all: np.ndarray, v_all: np.ndarray) -> np.ndarray:
        """Cuff forces on the exoskeleton at (q_all, v_all), (4, 2) [N].

        Also fills :attr:`joint_torque` (J_exoᵀ f on the exo joints,
        -J_patientᵀ f on the patient's).  Returns :attr:`force`, overwritten
        by the next call.
        """
        cuff_forces(self.record, q_all, v_all)
        return self.force


#: Fields of the cuffs' record: the rotation selection S (8, 8), D P (8, 16)
#: and (D P)ᵀ (16, 8) of the module docstring, stiffness ``k`` [N/m] and
#: damping ``c`` [N·s/m], ``k_offset`` = K (D p₀ - r₀) [N] (8,); outputs:
#: ``f`` the forces on the exoskeleton (fx of the 4 cuffs, fz of the 4) [N],
#: ``tau`` the generalised forces on [exo, patient] joints [N·m]; work rows
#: ``cs`` = (cos θ, sin θ), ``csr`` = (-sin θ, cos θ), ``y`` (16 each);
#: ``slipped`` per cuff (CUFF_NAMES order; 1.0: the cuff has slipped off, it
#: transmits no force, stiffness and damping zero; set only by fault
#: injection, :mod:`exo_ctrl.sim.faults`).
CUFF_FIELDS = [
    ("select", np.float64, (8, 8)),
    ("dp", np.float64, (8, 16)),
    ("dpt", np.float64, (16, 8)),
    ("k", np.float64),
    ("c", np.float64),
    ("k_offset", np.float64, (8,)),
    ("f", np.float64, (8,)),
    ("tau", np.float64, (8,)),
    ("cs", np.float64, (16,)),
    ("csr", np.float64, (16,)),
    ("y", np.float64, (16,)),
    ("slipped", np.float64, (4,)),
]


@kernel
def cuff_forces(cuffs: np.ndarray, q_all: np.ndarray, v_all: np.ndarray) -> None:
    """The module docstring's forces and generalised forces, in place.

    ``cuffs``: the record array of :data:`CUFF_FIELDS`.
    u = (cos θ, sin θ), w = (-sin θ ⊙ θ̇, cos θ ⊙ θ̇); f = D P (-K u - C w) - K (D p₀ - r₀);
    τ = Sᵀ ((Pᵀ Dᵀ f) ⊙ (-sin θ, cos θ)) summed over the two halves.
    """
    forces_of(cuffs[0], q_all, v_all)


@kernel
def forces_of(r: Any, q_all: np.ndarray, v_all: np.ndarray) -> None:
    """:func:`cuff_forces` on the record ``r`` itself (also a field of another record)."""
    k, c = r.k, r.c
    select, dp, dpt, k_offset = r.select, r.dp, r.dpt, r.k_offset
    f, tau, cs, csr, y = r.f, r.tau, r.cs, r.csr, r.y
    for j in range(8):
        th = 0.0
        dth = 0.0
        for i in range(8):
            s = select[j, i]
            if s != 0.0:
                th += s * q_all[i]
                dth += s * v_all[i]
        cj, sj = np.cos(th), np.sin(th)
        cs[j] = cj
        cs[8 + j] = sj
        csr[j] = -sj
        csr[8 + j] = cj
        y[j] = -k * cj - c * (-sj * dth)
        y[8 + j] = -k * sj - c * (cj * dth)
    for row in range(8):
        acc = 0.0
        for j in range(16):
            acc += dp[row, j] * y[j]
        f[row] = acc - k_offset[row] if r.slipped[row % 4] == 0.0 else 0.0
    for i in range(8):
        tau[i] = 0.0
    for j in range(16):
        g = 0.0
        for row in range(8):
            g += dpt[j, row] * f[row]
        g *= csr[j]
        jj = j if j < 8 else j - 8
        for i in range(8):
            s = select[jj, i]
            if s != 0.0:
                tau[i] += s * g


def _xz(p: np.ndarray) -> np.ndarray:
    return np.array([float(p[0]), float(p[2])])
