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

**Normal and shear** (:class:`CuffParams`).  Soft tissue is much softer in
shear, along the limb, than in compression, across it.  With u the unit
direction of the exoskeleton link carrying the cuff (joint → cuff point) at
the present angles, n = u turned by +90°, and the stretch split in the
link's frame, s_n = n · Δp - r₀ₙ, s_u = u · Δp - r₀ᵤ (r₀ₙ, r₀ᵤ captured at
the fit, zero for split cuffs: below), the cuff stores

    V = ½ k_u s_u² + V_n(s_n),   V_n = ½ k_n s_n²

(bonded pads, no preload), and the force on the exoskeleton's cuff point is
f = -σ_n n - σ_u u - C_n (n · Δṗ) n - C_u (u · Δṗ) u with σ_n = V_n'(s_n),
σ_u = k_u s_u.  Because n and u turn with the exoskeleton's link, the
spring also acts on that link with the moment M = σ_n (u · Δp) - σ_u (n · Δp)
(−∂V/∂θ at fixed Δp; it balances the couple Δp × f of an anisotropic spring,
and makes the spring conservative: :meth:`CuffSet.spring_energy` is its
potential).  The damper is dissipative, f · Δṗ ≤ 0.

**The fit.**  The strap holds the limb's tissue under the shell: :meth:`CuffSet.fit`
moves each split cuff's patient point, in its link's frame, onto the exoskeleton's
(Δp = 0 there; :mod:`exo_ctrl.plant.misalignment`), so the moment's lever u · Δp is
the limb's slide since the fit, not where a URDF frame sat (a knee 2 cm forward,
fitted at the default start, left them 17 mm apart along the shank).

**Preload.**  A strap tightened with preload P presses its two pads (the
shell on one side of the limb, the strap on the other) on the limb with P
each at the fit; each pad is a unilateral spring of stiffness k_n / 2 with
compression δ₀ ± s_n, δ₀ = 2P / k_n, so

    V_n = (k_n / 4) (max(0, δ₀ + s_n)² + max(0, δ₀ - s_n)²),

σ_n = k_n s_n while both pads touch (|s_n| ≤ δ₀; the net force at the fit is
zero, the pads' P each, :meth:`CuffSet.pad_forces`), and k_n / 2 with an
offset beyond, where one pad lifts off.  P = 0 is the bonded cuff of the
paper (no lift-off).

Isotropic cuffs without preload (k_u = k_n, C_u = C_n, P = 0, as before the
split) are computed as before: f = -K (Δp - r₀) - C Δṗ with r₀ fixed in the
world and no moment (the same as the above when r₀ = 0, the fit of coinciding
frames); the golden runs (tests/sim/test_golden.py) hold them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from .. import _validate as v
from .._jit import kernel, record, switch
from ..model import CUFF_NAMES, SIDES, BodyModel
from .cuff_links import add_link_torques, link_turn
from .cuff_split import split_forces

__all__ = ["CuffParams", "CuffSet"]


@dataclass(frozen=True)
class CuffParams:
    """Cuff spring–damper, the same for the four cuffs (module docstring).

    Attributes:
        stiffness_N_per_m: k_n, normal (across the link), paper Table I
            (c_H, c_S = 8 N/mm) [N/m].
        damping_N_s_per_m: C_n, normal, not in the paper; 100 N·s/m gives a
            damping ratio of about 0.3 for the shank cuff mode of the default
            patient (chosen) [N·s/m].
        shear_stiffness_N_per_m: k_u, along the link [N/m]; None: k_n
            (isotropic).  Default 3700 N/m: Schiebl et al. 2025 (Sensors
            25(15):4605, "Quantification of the mechanical properties in the
            human–exoskeleton upper arm interface") measured translational
            interface stiffnesses of 2.1–4.5 N/mm depending on the direction,
            the softest along the limb; the paper's 8 N/mm across the link
            scaled by that ratio, 2.1 / 4.5, is 3.7 N/mm.
        shear_damping_N_s_per_m: C_u, along the link [N·s/m]; None: C_n.
            Default 70 N·s/m: C_n scaled by √(k_u / k_n), the same damping
            ratio (chosen).
        preload_N: P, the strap's preload, the compressive force of each of
            its two pads on the limb at the fit [N] (default 0: bonded pads,
            no lift-off, the paper's linear cuff).

    All are stored as float.

    Raises:
        InvalidParameter: a field that is text, a bool or not finite;
            a stiffness <= 0, a damping or the preload < 0.

    """

    stiffness_N_per_m: float = 8000.0
    damping_N_s_per_m: float = 100.0
    shear_stiffness_N_per_m: float | None = 3700.0
    shear_damping_N_s_per_m: float | None = 70.0
    preload_N: float = 0.0

    def __post_init__(self) -> None:
        k = v.positive("cuff stiffness", self.stiffness_N_per_m, "N/m")
        c = v.non_negative("cuff damping", self.damping_N_s_per_m, "N·s/m")
        ks = self.shear_stiffness_N_per_m
        cs = self.shear_damping_N_s_per_m
        ks = k if ks is None else v.positive("cuff shear stiffness", ks, "N/m")
        cs = c if cs is None else v.non_negative("cuff shear damping", cs, "N·s/m")
        p = v.non_negative("cuff preload", self.preload_N, "N")
        for name, value in (
            ("stiffness_N_per_m", k),
            ("damping_N_s_per_m", c),
            ("shear_stiffness_N_per_m", ks),
            ("shear_damping_N_s_per_m", cs),
            ("preload_N", p),
        ):
            object.__setattr__(self, name, value)

    @classmethod
    def isotropic(
        cls, stiffness_N_per_m: float = 8000.0, damping_N_s_per_m: float = 100.0
    ) -> CuffParams:
        """Equal normal and shear stiffness and damping, no preload (the cuffs before the split)."""
        return cls(stiffness_N_per_m, damping_N_s_per_m, None, None, 0.0)

    @property
    def is_isotropic(self) -> bool:
        """k_u = k_n, C_u = C_n and no preload: computed as before the split."""
        return (
            self.shear_stiffness_N_per_m == self.stiffness_N_per_m
            and self.shear_damping_N_s_per_m == self.damping_N_s_per_m
            and self.preload_N == 0.0
        )


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
        along0 = np.zeros((4, 2))  # u of each cuff at q = 0 (exo cuff c turns with rotation c)
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
                    if b == 0:  # u at q = 0: the exo link's joint → cuff direction
                        arm = point - (hip if link == "thigh" else knee)
                        along0[c] = arm / max(float(np.hypot(arm[0], arm[1])), 1e-12)
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
        self._diff, self._P0 = diff, self._P.copy()  # the URDFs' points: fit starts from them
        self._DP = diff @ self._P
        self._DP0 = self._DP.copy()
        self._DPT = np.ascontiguousarray(self._DP.T)
        self._Dp0 = diff @ self._p0
        self._sel2 = np.vstack((sel, sel))
        self._k = float(params.stiffness_N_per_m)
        self._c = float(params.damping_N_s_per_m)
        #: The kernel's matrices, parameters and outputs, one record
        #: (:data:`CUFF_FIELDS`); its element is the argument of :func:`forces_of`.
        self.record = record(CUFF_FIELDS) if into is None else into
        self._rec = c = self.record[0]
        c["select"] = sel
        c["dp"] = self._DP
        c["dpt"] = self._DPT
        self._DP, self._DPT = self.record["dp"][0], self.record["dpt"][0]  # fit moves them
        c["k"], c["c"] = self._k, self._c
        c["k_u"] = float(params.shear_stiffness_N_per_m)
        c["c_u"] = float(params.shear_damping_N_s_per_m)
        c["preload"] = float(params.preload_N)
        c["split"] = not params.is_isotropic
        c["dp0"] = self._Dp0
        c["along0"] = along0
        #: u of each cuff at q = 0, (4, 2): the exo link's joint → cuff direction.
        self.along0 = self.record["along0"][0]
        self._split = bool(c["split"])
        #: The split cuffs' compile-time switch (:func:`~exo_ctrl._jit.switch`), the
        #: ``split`` argument of the kernels that compute these cuffs' forces: they
        #: call :func:`forces_of` when it is True, :func:`isotropic_forces` when None.
        self.split_switch = switch(self._split)
        self._forces = forces_of if self._split else isotropic_forces
        #: r₀ in the link's frame, (s_n, s_u) offsets captured at the fit [m], (4,) each.
        self.rest_normal = self.record["r0n"][0]
        self.rest_along = self.record["r0u"][0]
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
        """Fit the straps: make the present offsets the slack (zero-stretch) ones.

        Isotropic cuffs keep r₀ in the world; split cuffs move the patient's points
        onto the exoskeleton's (module docstring, "The fit"): r₀ = 0 up to rounding.
        """
        self._trig(np.asarray(q_all, dtype=float))
        if self._split:
            self._attach_at_shells()
        self.rest_offset[:] = self._DP @ self._cs + self._Dp0
        np.subtract(self._Dp0, self.rest_offset, out=self._offset)
        np.multiply(self._offset, self._k, out=self._k_offset)
        self.rest_normal[:] = 0.0
        self.rest_along[:] = 0.0
        normal, along = self.link_frame_offsets(q_all)
        self.rest_normal[:] = normal
        self.rest_along[:] = along

    def _attach_at_shells(self) -> None:
        """Patient cuff point 4 + c, last on link rotation 4 + c as R(θ) b in P: b += R(θ)ᵀ Δp.

        From the URDFs' points each time, so a fit depends on its posture alone.
        """
        offset = self._DP0 @ self._cs + self._Dp0  # exo minus patient: x of 4, z of 4
        P = self._P
        P[:] = self._P0
        for c in range(4):
            i = j = 4 + c
            cos, sin = self._cs[j], self._cs[8 + j]
            dx, dz = offset[c], offset[4 + c]
            bx, bz = cos * dx + sin * dz, -sin * dx + cos * dz  # R(θ)ᵀ Δp
            P[i, j] += bx
            P[i, 8 + j] -= bz
            P[8 + i, j] += bz
            P[8 + i, 8 + j] += bx
        np.matmul(self._diff, P, out=self._DP)
        self._DPT[:] = self._DP.T

    def directions(self, q_all: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """U and n of the four cuffs at q_all (the exo links' frames), each (4, 2)."""
        self._trig(np.asarray(q_all, dtype=float))
        cos, sin = self._cs[:4], self._cs[8:12]
        ux = self.along0[:, 0] * cos - self.along0[:, 1] * sin
        uz = self.along0[:, 1] * cos + self.along0[:, 0] * sin
        return np.stack((ux, uz), axis=-1), np.stack((-uz, ux), axis=-1)

    def link_frame_offsets(self, q_all: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(s_n, s_u), the stretch in the links' frames: n · Δp - r₀ₙ, u · Δp - r₀ᵤ [m], (4,)."""
        u, n = self.directions(q_all)
        dp = self._DP @ self._cs + self._Dp0
        d = np.stack((dp[:4], dp[4:]), axis=-1)
        return (
            np.sum(n * d, axis=-1) - self.rest_normal,
            np.sum(u * d, axis=-1) - self.rest_along,
        )

    def pad_forces(self, q_all: np.ndarray) -> np.ndarray:
        """Compressive force of each cuff's two pads on the limb, (4, 2) [N] (module docstring).

        Column 0: the pad the exoskeleton presses harder when it moves along
        +n relative to the limb, (k_n / 2) max(0, δ₀ + s_n); column 1 the
        other, (k_n / 2) max(0, δ₀ - s_n); δ₀ = 2P / k_n.  At the fit both are P.
        """
        s_n, _ = self.link_frame_offsets(q_all)
        k = self._k
        d0 = 2.0 * self.params.preload_N / k
        return 0.5 * k * np.stack((np.maximum(d0 + s_n, 0.0), np.maximum(d0 - s_n, 0.0)), axis=-1)

    def spring_energy(self, q_all: np.ndarray) -> float:
        """Potential energy of the cuffs' springs at q_all [J], zero at the fit (module docstring).

        Isotropic: ½ K |Δp - r₀|²; split: ½ k_u s_u² + V_n(s_n) - V_n(0).
        """
        if not self._split:
            stretch = self.stretch(q_all)
            return 0.5 * self._k * float(stretch @ stretch)
        s_n, s_u = self.link_frame_offsets(q_all)
        live = self.record["slipped"][0] == 0.0
        k, pre = self._k, self.params.preload_N
        if pre > 0.0:
            d0 = 2.0 * pre / k
            v_n = 0.25 * k * (np.maximum(d0 + s_n, 0.0) ** 2 + np.maximum(d0 - s_n, 0.0) ** 2)
            v_n -= 0.5 * k * d0**2
        else:
            v_n = 0.5 * k * s_n**2
        v_u = 0.5 * self.params.shear_stiffness_N_per_m * s_u**2
        return float(np.sum((v_n + v_u)[live]))

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
        self._forces(self._rec, q_all, v_all)
        return self.force


#: Fields of the cuffs' record: the rotation selection S (8, 8), D P (8, 16)
#: and (D P)ᵀ (16, 8) of the module docstring, stiffness ``k`` [N/m] and
#: damping ``c`` [N·s/m], ``k_offset`` = K (D p₀ - r₀) [N] (8,); outputs:
#: ``f`` the forces on the exoskeleton (fx of the 4 cuffs, fz of the 4) [N],
#: ``tau`` the generalised forces on [exo, patient] joints [N·m]; work rows
#: ``cs`` = (cos θ, sin θ), ``csr`` = (-sin θ, cos θ), ``y`` (16 each);
#: ``slipped`` per cuff (CUFF_NAMES order; 1.0: the cuff has slipped off, it
#: transmits no force, stiffness and damping zero; set only by fault
#: injection, :mod:`exo_ctrl.sim.faults`).  Split cuffs (normal and shear,
#: module docstring; ``split`` true): ``k_u``, ``c_u`` the shear stiffness
#: [N/m] and damping [N·s/m], ``preload`` P [N], ``dp0`` = D p₀ [m],
#: ``along0`` u of each cuff at q = 0, ``r0n``, ``r0u`` the fit's offsets in
#: the links' frames [m]; work row ``rel`` = (Δp, Δṗ) (x of the 4, z of the 4 each).
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
    ("k_u", np.float64),
    ("c_u", np.float64),
    ("preload", np.float64),
    ("split", np.bool_),
    ("dp0", np.float64, (8,)),
    ("along0", np.float64, (4, 2)),
    ("r0n", np.float64, (4,)),
    ("r0u", np.float64, (4,)),
    ("rel", np.float64, (16,)),
]


@kernel
def forces_of(r: Any, q_all: np.ndarray, v_all: np.ndarray) -> None:
    """The cuffs' forces and generalised forces, split or isotropic by the record's flag, in place.

    ``r``: a record of :data:`CUFF_FIELDS` (from Python the element of
    :attr:`CuffSet.record`, in a kernel also a field of another record).
    ``r.split`` chooses :func:`~exo_ctrl.plant.cuff_split.split_forces` or
    :func:`isotropic_forces` at run time.  A kernel that knows at compile
    time that its cuffs are isotropic (its ``split`` switch None) calls
    :func:`isotropic_forces` itself, and the split cuffs' code is not
    compiled into it.  Each of the two kernels has one signature: kernels
    pass ``q_all``, ``v_all`` as plain arrays (a record's field ``x`` as
    ``x[:]``), as Python does.  (Two signatures of one kernel, saved by two
    processes at the same moment, could cross in numba's cache index:
    :mod:`exo_ctrl.sim.warmup`.)
    """
    if r.split:
        split_forces(r, q_all, v_all)
    else:
        isotropic_forces(r, q_all, v_all)


@kernel
def isotropic_forces(r: Any, q_all: np.ndarray, v_all: np.ndarray) -> None:
    """The module docstring's forces and generalised forces of isotropic cuffs, in place.

    u = (cos θ, sin θ), w = (-sin θ ⊙ θ̇, cos θ ⊙ θ̇); f = D P (-K u - C w) - K (D p₀ - r₀);
    τ = Sᵀ ((Pᵀ Dᵀ f) ⊙ (-sin θ, cos θ)) summed over the two halves.
    """
    k, c = r.k, r.c
    dp, k_offset = r.dp, r.k_offset
    f, tau, cs, y = r.f, r.tau, r.cs, r.y
    for j in range(8):
        dth = link_turn(r, q_all, v_all, j)
        cj, sj = cs[j], cs[8 + j]
        y[j] = -k * cj - c * (-sj * dth)
        y[8 + j] = -k * sj - c * (cj * dth)
    for row in range(8):
        acc = 0.0
        for j in range(16):
            acc += dp[row, j] * y[j]
        f[row] = acc - k_offset[row] if r.slipped[row % 4] == 0.0 else 0.0
    for i in range(8):
        tau[i] = 0.0
    add_link_torques(r)


def _xz(p: np.ndarray) -> np.ndarray:
    return np.array([float(p[0]), float(p[2])])
