r"""Cuff forces over a horizon, affine in the drive torques held over it.

The cuffs are springs (K = 8 N/mm) with the patient's leg on them: modes of
5–12 Hz, slow against the 1 ms tick, so a force bound must look ahead over
about half a cuff period.  Per leg (hip, knee; the legs do not couple), with
δ = q_exo − q_patient the patient's lag behind the exoskeleton, J the
patient's cuff Jacobians (rows thigh x, z, shank x, z; 4×2), G = JᵀJ, and
the cuffs isotropic spring–dampers with the joint axes aligned (as fitted),
the cuff forces on the exoskeleton are, to first order in δ (split cuffs,
normal and shear apart: :mod:`~exo_ctrl.control.qp.split_cuffs`, with
G_K = Jᵀ𝒦J for K G, G_C = Jᵀ𝒞J for C G and f = −𝒦J δ − 𝒞J δ̇),

.. math::

    f = -J s, \qquad s = K δ + C \dot δ \quad [\text{N·m per m², joint space}].

The drive's voltage U(τ) = R τ/(i_G k_m) + i_G ω₀/k_E is held over the horizon (move
blocking), so the joint torque is τ − D (q̇ − ω₀) with the back-EMF damping D = i_G k_m
(i_G/k_E)/R ≈ 330 N·m·s/rad; a drive ``held`` at its cap keeps τ (its driver holds the
current, :mod:`~exo_ctrl.control.qp.torque_box`): D = 0.  Linearised at the measured
(q, ω₀), with u_e = q̇_e − ω₀, u_p = q̇_p − ω₀:

.. math::

    \dot δ = u_e - u_p, \\
    M_e' \dot u_e = τ - h_e - (D + b_e) u_e - G (K δ + C (u_e - u_p)), \\
    M_p \dot u_p = -h_p + d - b_p u_p + G (K δ + C (u_e - u_p)),

M_e' = M_e + i_G² J_rotor, h the Coriolis, gravity, damping and friction
torques at the measured state, b the URDF joint damping, d the patient's own
joint torque (held; estimated by
:class:`~exo_ctrl.control.qp.observer.CuffStateObserver`).  With
z = (δ, u_e, u_p, τ, 1) this is ż = F z (9×9 per leg), so z(t) = e^{Ft} z(0),
z(0) = (δ̂, 0, −δ̂̇, τ, 1), and s(t_i) — hence f(t_i) = A_i τ + b_i — is
affine in τ.  e^{FΔ} (Δ = gcd of the horizon points) is computed by
:func:`~exo_ctrl.control.qp.expm.expm_top` (only rows 0–5 of these block
matrices are formed), and squared on to e^{FΔ 2^k}; the point nΔ (default
5, 10, 20, 30, 40 ms: half the slowest cuff period; n = 1, 2, 4, 6, 8) needs
only the two rows S of s = S z, which are S e^{FΔ 2^{k₀}} times the squares
of n's other binary digits.  All in compiled kernels
(:func:`exo_ctrl._jit.kernel`) on the model's record (:func:`horizon_fields`).

Accuracy (tests/control/qp/test_prediction.py): against the plant
(nonlinear, elastic cuffs, drive current dynamics) stepped 40 ms with the
voltage held, given the true δ, δ̇: ≤ 4.9 N (isotropic), 5.5 N (split) on forces up to
150 N, 7.2 N with the drives held; 19.2 N with the nominal patient model.  Neglected: the
drive's electrical time constant (0.7 ms), the change of M, h, J over 40 ms,
the speed dependence of the Coriolis and friction torques, the cuff's
nonlinearity in δ.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin

from ..._jit import Status, kernel, record, switch
from ...exceptions import InvalidParameter
from ...model import FRICTION_SMOOTHING_RAD_S, BodyModel, combined_model
from ...plant.cuffs import CuffParams, CuffSet
from ...plant.drive import MotorParams
from .expm import NM, NZ, PS_BLOCK, expm_top, mul_top, power_rows
from .split_cuffs import split_gains, split_rows

__all__ = ["DEFAULT_HORIZON_TICKS", "CuffHorizonModel", "horizon_fields"]

#: Default horizon points, in control ticks after the present one.
DEFAULT_HORIZON_TICKS = (5, 10, 20, 30, 40)


def horizon_fields(n_points: int, n_squares: int) -> list[tuple[Any, ...]]:
    """The fields of a :class:`CuffHorizonModel`'s record (numpy dtype syntax).

    Parameters: ``losses`` (rows b_e, f_e, b_p, f_p: URDF damping [N·m·s/rad] and friction
    [N·m] per joint), the cuff points' ``points`` P and ``select`` S (the plant's CuffSet; P:
    rows x then z of its 8 points, columns cos θ then sin θ), ``damp_e`` D + b_e, ``held`` (> 0:
    at its cap, b_e alone), ``damp_p`` b_p [N·m·s/rad], ``stiffness`` K = k_n [N/m], ``damping``
    C = C_n [N·s/m], ``shear_stiffness`` k_u [N/m], ``shear_damping`` C_u [N·s/m], ``split``
    (k_u ≠ k_n or C_u ≠ C_n), ``along0`` (the exo links' directions u at q = 0, per cuff),
    ``block`` Δ [s] and ``powers`` n_i = t_i/Δ.  The linearisation:
    ``q_all``, ``v_all`` (the state both bodies are evaluated at), the mass
    matrices, bias torques and cuff Jacobians; for split cuffs also W_K, W_C
    (``wk``, ``wc``, [N/rad], [N·s/rad]) and G_K, G_C (``gk``, ``gc``,
    [N·m/rad], [N·m·s/rad]) per leg.  The prediction ``A``, ``b``;
    then the scratch of :func:`predict`: ``f`` (rows 0–5 of F Δ), ``ge``,
    ``gp`` (the generalised forces on the exoskeleton and the patient per
    column of z), ``sv``, ``sv_tmp`` (the s rows of a power of e^{FΔ};
    ``sv4``, ``sv4_tmp``: its δ and δ̇ rows, split cuffs), ``x_powers``,
    ``tmp`` (:func:`~exo_ctrl.control.qp.expm.expm_top`'s), ``squares`` (e^{FΔ 2^k}, k < n_squares).
    """
    f8 = np.float64
    return [
        ("losses", f8, (4, 4)),
        ("points", f8, (16, 16)),
        ("select", f8, (8, 8)),
        ("damp_e", f8, (4,)),
        ("held", f8, (4,)),
        ("damp_p", f8, (4,)),
        ("stiffness", f8),
        ("damping", f8),
        ("shear_stiffness", f8),
        ("shear_damping", f8),
        ("split", np.bool_),
        ("along0", f8, (4, 2)),
        ("block", f8),
        ("powers", np.int64, (n_points,)),
        ("q_all", f8, (8,)),
        ("v_all", f8, (8,)),
        ("mass_exo", f8, (4, 4)),
        ("mass_patient", f8, (4, 4)),
        ("bias_exo", f8, (4,)),
        ("bias_patient", f8, (4,)),
        ("jac", f8, (2, 4, 2)),
        ("wk", f8, (2, 4, 2)),
        ("wc", f8, (2, 4, 2)),
        ("gk", f8, (2, 2, 2)),
        ("gc", f8, (2, 2, 2)),
        ("A", f8, (8 * n_points, 4)),
        ("b", f8, (8 * n_points,)),
        ("f", f8, (NM, NZ)),
        ("ge", f8, (2, NZ)),
        ("gp", f8, (2, NZ)),
        ("sv", f8, (2, NZ)),
        ("sv_tmp", f8, (2, NZ)),
        ("sv4", f8, (4, NZ)),
        ("sv4_tmp", f8, (4, NZ)),
        ("x_powers", f8, (PS_BLOCK, NM, NZ)),
        ("tmp", f8, (NM, NZ)),
        ("squares", f8, (n_squares, NM, NZ)),
    ]


@kernel
def pair(m: np.void, q: np.ndarray, dq: np.ndarray) -> int:  # pragma: no cover - compiled
    """q_all = [q, q], v_all = [q̇, q̇] in record ``m``: the patient taken in the exoskeleton's state.

    Returns a :class:`~exo_ctrl._jit.Status` value: WRONG_LENGTH (nothing
    written) unless q and q̇ have 4 entries.
    """
    if q.shape[0] != 4 or dq.shape[0] != 4:
        return Status.WRONG_LENGTH.value
    q_all, v_all = m.q_all, m.v_all
    for i in range(4):
        q_all[i] = q_all[4 + i] = q[i]
        v_all[i] = v_all[4 + i] = dq[i]
    return Status.OK.value


@kernel
def gather(
    m: np.void, mass: np.ndarray, nle: np.ndarray, q: np.ndarray, dq: np.ndarray, split: bool | None
) -> None:  # pragma: no cover - compiled
    """Fill record ``m``'s linearisation from the Pinocchio results ``mass`` and ``nle``.

    ``q``, ``dq``: the measured state (the patient's taken equal).  ``mass``
    and ``nle``: CRBA (symmetric) and nonLinearEffects of the model of both
    bodies at (q_all, v_all); the mass matrices are its diagonal blocks;
    bias = nle + b q̇ + f_c tanh(q̇/ε) per body.  The patient's cuff
    Jacobians, (x, z) rows on their leg's two joints, from the cuff points'
    form p = P (cos θ, sin θ) + p₀ with link rotations θ = S q_all (patient
    points 4-7, rotations 4-7): ∂p/∂q = Σ_j (−P_j sin θ_j + P_{8+j} cos θ_j) S_j.
    ``split``: :attr:`CuffHorizonModel.split_switch` (None: split_cuffs' code not compiled).
    """
    losses, points, select = m.losses, m.points, m.select
    mass_e, mass_p, jac = m.mass_exo, m.mass_patient, m.jac
    bias_e, bias_p = m.bias_exo, m.bias_patient
    for i in range(4):
        for j in range(4):
            mass_e[i, j] = mass[i, j]
            mass_p[i, j] = mass[4 + i, 4 + j]
        sgn = np.tanh(dq[i] / FRICTION_SMOOTHING_RAD_S)
        bias_e[i] = nle[i] + losses[0, i] * dq[i] + losses[1, i] * sgn
        bias_p[i] = nle[4 + i] + losses[2, i] * dq[i] + losses[3, i] * sgn
    for c in range(4):  # cuff c = 2 leg + k, k: thigh 0, shank 1
        leg, k = c // 2, c % 2
        for col in range(2):
            joint = 4 + 2 * leg + col  # q_all index of the patient joint
            for axis in range(2):  # x, z
                row = 4 + c + 8 * axis  # row of P
                acc = 0.0
                for j in range(4, 8):
                    s = select[j, joint]
                    if s != 0.0:
                        theta = 0.0
                        for n in range(4):
                            theta += select[j, 4 + n] * q[n]
                        cos_t, sin_t = math.cos(theta), math.sin(theta)
                        acc += s * (points[row, 8 + j] * cos_t - points[row, j] * sin_t)
                jac[leg, 2 * k + axis, col] = acc
    if split is not None and m.split:
        split_gains(m, q)


@kernel
def predict(
    m: np.void, delta: np.ndarray, ddelta: np.ndarray, dist: np.ndarray, split: bool | None
) -> None:  # pragma: no cover - compiled
    """Fill ``m.A`` (8 P, 4) and ``m.b`` (8 P) from record ``m``'s linearisation (module docstring).

    ``delta`` δ [rad], ``ddelta`` δ̇ [rad/s], ``dist`` d [N·m]: the initial
    cuff state and the patient's held torque, (4,) each; ``split``: as :func:`gather`.
    """
    powers, a_out, b_out = m.powers, m.A, m.b
    me, mp, jac, he, hp = m.mass_exo, m.mass_patient, m.jac, m.bias_exo, m.bias_patient
    damp_e, damp_p = m.damp_e, m.damp_p
    stiff, damp_c, dt_block = m.stiffness, m.damping, m.block
    # As plain C arrays (``[:]``), the type of a slice of ``squares``: one
    # compiled version of mul_top and copy_top for every call (sv4: split cuffs).
    f, ge, gp, sv, sv_tmp, squares = m.f[:], m.ge[:], m.gp[:], m.sv[:], m.sv_tmp[:], m.squares
    sv4, sv4_tmp, shear = m.sv4[:], m.sv4_tmp[:], m.split
    n_pts = powers.shape[0]
    n_sq = squares.shape[0]  # squares e^{FΔ 2^k}, k < n_sq: the bit length of the largest power
    for r in range(a_out.shape[0]):
        b_out[r] = 0.0
        for c in range(4):
            a_out[r, c] = 0.0
    for leg in range(2):
        i0 = 2 * leg
        # 2x2 blocks: exo mass (with armature), patient mass, G = J^T J.
        m11, m12, m22 = me[i0, i0], me[i0, i0 + 1], me[i0 + 1, i0 + 1]
        p11, p12, p22 = mp[i0, i0], mp[i0, i0 + 1], mp[i0 + 1, i0 + 1]
        if split is not None and shear:  # G_K, G_C (split_cuffs)
            k11, k12, k22 = m.gk[leg, 0, 0], m.gk[leg, 0, 1], m.gk[leg, 1, 1]
            c11, c12, c22 = m.gc[leg, 0, 0], m.gc[leg, 0, 1], m.gc[leg, 1, 1]
        else:  # K G, C G
            g11 = g12 = g22 = 0.0
            for r in range(4):
                g11 += jac[leg, r, 0] * jac[leg, r, 0]
                g12 += jac[leg, r, 0] * jac[leg, r, 1]
                g22 += jac[leg, r, 1] * jac[leg, r, 1]
            k11, k12, k22 = stiff * g11, stiff * g12, stiff * g22
            c11, c12, c22 = damp_c * g11, damp_c * g12, damp_c * g22
        de = m11 * m22 - m12 * m12
        dp = p11 * p22 - p12 * p12
        ie11, ie12, ie22 = m22 / de, -m12 / de, m11 / de
        ip11, ip12, ip22 = p22 / dp, -p12 / dp, p11 / dp
        # Generalised forces on the exo per unit of each state/input column.
        # exo: tau - he - D u_e - G K delta - G C (u_e - u_p)
        # patient: -hp + d - Dp u_p + G K delta + G C (u_e - u_p)
        for r in range(2):
            for c in range(NZ):
                ge[r, c] = 0.0
                gp[r, c] = 0.0
        km = ((k11, k12), (k12, k22))
        cm = ((c11, c12), (c12, c22))
        for r in range(2):
            for c in range(2):
                gk = km[r][c]
                gc = cm[r][c]
                ge[r, c] = -gk
                ge[r, 2 + c] = -gc
                ge[r, 4 + c] = gc
                gp[r, c] = gk
                gp[r, 2 + c] = gc
                gp[r, 4 + c] = -gc
            ge[r, 2 + r] -= m.losses[0, i0 + r] if m.held[i0 + r] > 0.0 else damp_e[i0 + r]
            gp[r, 4 + r] -= damp_p[i0 + r]
            ge[r, 6 + r] = 1.0
            ge[r, 8] = -he[i0 + r]
            gp[r, 8] = -hp[i0 + r] + dist[i0 + r]
        # Rows 0-5 of F Δ (rows 6-8 are zero).
        for c in range(NZ):
            f[0, c] = 0.0
            f[1, c] = 0.0
            f[2, c] = (ie11 * ge[0, c] + ie12 * ge[1, c]) * dt_block
            f[3, c] = (ie12 * ge[0, c] + ie22 * ge[1, c]) * dt_block
            f[4, c] = (ip11 * gp[0, c] + ip12 * gp[1, c]) * dt_block
            f[5, c] = (ip12 * gp[0, c] + ip22 * gp[1, c]) * dt_block
        f[0, 2] = f[1, 3] = dt_block
        f[0, 4] = f[1, 5] = -dt_block
        expm_top(f, squares[0], m.x_powers[:], m.tmp[:])
        for k in range(1, n_sq):
            mul_top(squares[k - 1], squares[k - 1], 1.0, squares[k])
        # z0 = (delta, 0, -ddelta, tau, 1)
        for p in range(n_pts):
            # The s rows (s = K delta + C (u_e - u_p)) of e^{F Δ n}, n = Σ_k 2^k
            # over n's bits: S e^{F Δ 2^k0}, times the other squares in turn.
            n = powers[p]
            k = 0
            while (n >> k) & 1 == 0:
                k += 1
            sq = squares[k]
            if split is not None and shear:  # rows δ and δ̇ = u_e − u_p; f = −W_K δ − W_C δ̇
                for r in range(2):
                    for c in range(NZ):
                        sv4[r, c] = sq[r, c]
                        sv4[2 + r, c] = sq[2 + r, c] - sq[4 + r, c]
                power_rows(sv4, sv4_tmp, squares, n, k + 1)
                split_rows(m, leg, p, sv4, delta, ddelta)
                continue
            for r in range(2):
                for c in range(NZ):
                    sv[r, c] = stiff * sq[r, c] + damp_c * (sq[2 + r, c] - sq[4 + r, c])
            power_rows(sv, sv_tmp, squares, n, k + 1)
            for r in range(2):
                s_t0 = sv[r, 6]
                s_t1 = sv[r, 7]
                s_c = sv[r, 8]
                for c in range(2):
                    s_c += sv[r, c] * delta[i0 + c] - sv[r, 4 + c] * ddelta[i0 + c]
                # f = -J s
                for rr in range(4):
                    row = p * 8 + leg * 4 + rr
                    jj = jac[leg, rr, r]
                    a_out[row, i0] -= jj * s_t0
                    a_out[row, i0 + 1] -= jj * s_t1
                    b_out[row] -= jj * s_c


@kernel
def _pair(state: np.ndarray, q: np.ndarray, dq: np.ndarray) -> int:  # pragma: no cover - compiled
    return pair(state[0], q, dq)


@kernel
def _gather(state, mass, nle, q, dq, split) -> None:  # pragma: no cover - compiled
    gather(state[0], mass, nle, q, dq, split)


@kernel
def _predict(state, delta, ddelta, dist, split) -> None:  # pragma: no cover - compiled
    predict(state[0], delta, ddelta, dist, split)


class CuffHorizonModel:
    """Cuff forces at horizon points, affine in the held drive torques (module docstring).

    Args:
        exo: the exoskeleton model the controller believes in.
        patient: the patient model the controller believes in.
        motor: the drive (reflected rotor inertia, back-EMF damping).
        cuffs: the cuff model: normal stiffness K and damping C, and along
            the link k_u, C_u (default :meth:`CuffParams.isotropic`, the
            device's default model; split cuffs: :mod:`~exo_ctrl.control.qp.split_cuffs`).
        dt: control period [s], finite and > 0.
        horizon_ticks: the horizon points t_i = n_i Δt, increasing integers in
            [1, 1000].

    Attributes:
        record: the kernels' parameters, state and scratch (:func:`horizon_fields`);
            the arrays below are views of its fields.
        model: the Pinocchio model of both bodies (exo joints 0-3 with the
            rotors' reflected inertia, patient 4-7).
        data: its Pinocchio data.
        q_all: the joint angles of both bodies of the last :meth:`terms` [rad], (8,).
        v_all: their speeds [rad/s], (8,).
        A: ∂f/∂τ, (8 P, 4) [1/m]; row 8 p + 2 c + i is component i (x, z)
            of cuff c at horizon point p.
        b: forces at τ = 0, (8 P,) [N].
        jac: patient cuff Jacobians per leg, (2, 4, 2): rows thigh x, thigh z,
            shank x, shank z; columns hip, knee [m/rad].
        mass_exo: exoskeleton mass matrix with the rotors, (4, 4) [kg·m²].
        mass_patient: patient mass matrix, (4, 4) [kg·m²].
        bias_exo: h_e, exoskeleton bias torques at the measured state [N·m].
        bias_patient: h_p, patient bias torques at the measured state [N·m].
        gk, gc: G_K = Jᵀ𝒦J [N·m/rad] and G_C = Jᵀ𝒞J [N·m·s/rad] per leg, (2, 2, 2)
            (split cuffs only; :mod:`~exo_ctrl.control.qp.split_cuffs`).
        wk, wc: W_K = 𝒦J [N/rad] and W_C = 𝒞J [N·s/rad] per leg, (2, 4, 2)
            (split cuffs only).

    Raises:
        InvalidParameter: a bad dt or horizon.

    """

    def __init__(
        self,
        exo: BodyModel,
        patient: BodyModel,
        motor: MotorParams,
        cuffs: CuffParams | None = None,
        dt: float = 1e-3,
        horizon_ticks: tuple[int, ...] = DEFAULT_HORIZON_TICKS,
    ) -> None:
        cuffs = cuffs or CuffParams.isotropic()
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise InvalidParameter("dt", dt, "a finite control period > 0 s")
        try:
            ticks = tuple(int(t) for t in horizon_ticks)
        except (TypeError, ValueError):
            ticks = ()
        if not ticks or ticks[0] < 1 or ticks[-1] > 1000 or list(ticks) != sorted(set(ticks)):
            raise InvalidParameter(
                "horizon_ticks", horizon_ticks, "strictly increasing integers in [1, 1000] ticks"
            )
        block = math.gcd(*ticks)
        self.horizon_ticks = ticks
        self.horizon_s = tuple(t * dt for t in ticks)
        self.dt = float(dt)
        powers = [t // block for t in ticks]
        # Both bodies in one model (exo joints 0-3 with the rotors' reflected
        # inertia, patient 4-7); the patient's cuff points as in the plant.
        self.model = combined_model(exo, patient)
        rotor = np.full(4, motor.reflected_inertia_kgm2)
        self.model.armature = np.concatenate((rotor, np.zeros(4)))
        self.data = self.model.createData()
        cuff_set = CuffSet(exo, patient, cuffs)
        kt, kb, r = motor.torque_per_amp_Nm_per_A, motor.back_emf_V_per_rad_s, motor.resistance_ohm
        #: Back-EMF damping of a drive held at constant voltage, i_G k_m (i_G/k_E)/R [N·m·s/rad].
        self.back_emf_damping = kt * kb / r
        self.stiffness = float(cuffs.stiffness_N_per_m)
        self.damping = float(cuffs.damping_N_s_per_m)
        self.shear_stiffness = float(cuffs.shear_stiffness_N_per_m)
        self.shear_damping = float(cuffs.shear_damping_N_s_per_m)
        #: Normal and shear apart (split_cuffs), else the isotropic arithmetic; its
        #: compile-time switch (:func:`~exo_ctrl._jit.switch`), the kernels' ``split``.
        self.split = (self.shear_stiffness, self.shear_damping) != (self.stiffness, self.damping)
        self.split_switch = switch(self.split)
        self.record = record(horizon_fields(len(ticks), powers[-1].bit_length()))
        m = self.record[0]
        m["losses"] = np.stack((exo.damping, exo.friction, patient.damping, patient.friction))
        m["points"] = cuff_set.points
        m["select"] = cuff_set.select
        m["damp_e"] = self.back_emf_damping + exo.damping
        m["damp_p"] = patient.damping
        m["stiffness"], m["damping"], m["block"] = self.stiffness, self.damping, block * dt
        m["shear_stiffness"], m["shear_damping"] = self.shear_stiffness, self.shear_damping
        m["split"], m["along0"] = self.split, cuff_set.along0
        m["powers"] = powers
        view = self._view
        self.q_all, self.v_all = view("q_all"), view("v_all")
        self.A, self.b, self.jac = view("A"), view("b"), view("jac")
        self.mass_exo, self.mass_patient = view("mass_exo"), view("mass_patient")
        self.bias_exo, self.bias_patient = view("bias_exo"), view("bias_patient")
        self.gk, self.gc, self.wk, self.wc = view("gk"), view("gc"), view("wk"), view("wc")

    def _view(self, name: str) -> np.ndarray:
        return self.record[name][0]

    def terms(self, q: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """M and C q̇ + g of both bodies at (q, q, q̇, q̇): Pinocchio's CRBA and nonLinearEffects.

        The arrays Pinocchio returns (M symmetric), for :meth:`linearise`.

        Raises:
            InvalidParameter: q or dq without 4 entries.

        """
        q = np.asarray(q, dtype=float)
        dq = np.asarray(dq, dtype=float)
        if q.ndim != 1 or dq.ndim != 1 or _pair(self.record, q, dq):
            shapes = f"shapes {np.shape(q)} and {np.shape(dq)}"
            raise InvalidParameter("q and dq", shapes, "arrays of 4 joint values each")
        model, data = self.model, self.data
        return pin.crba(model, data, self.q_all), pin.nonLinearEffects(
            model, data, self.q_all, self.v_all
        )

    def linearise(self, q: np.ndarray, dq: np.ndarray) -> None:
        """Mass matrices, bias torques and cuff Jacobians at the measured state.

        Args:
            q: exoskeleton joint angles [rad] (the patient's are taken equal).
            dq: exoskeleton joint speeds [rad/s].

        Raises:
            InvalidParameter: q or dq without 4 entries.

        """
        mass, nle = self.terms(q, dq)
        _gather(self.record, mass, nle, self.q_all[:4], self.v_all[:4], self.split_switch)

    def predict(self, delta: np.ndarray, ddelta: np.ndarray, disturbance: np.ndarray) -> None:
        """Fill :attr:`A` and :attr:`b` from the state of the last :meth:`linearise`.

        Args:
            delta: δ = q_exo − q_patient [rad], (4,).
            ddelta: δ̇ [rad/s], (4,).
            disturbance: patient joint torque d, held over the horizon [N·m], (4,).

        """
        fours = _fours(delta=delta, ddelta=ddelta, disturbance=disturbance)
        _predict(self.record, *fours, self.split_switch)

    def update(
        self,
        q: np.ndarray,
        dq: np.ndarray,
        delta: np.ndarray,
        ddelta: np.ndarray,
        disturbance: np.ndarray,
    ) -> None:
        """:meth:`linearise` at (q, q̇), then :meth:`predict` from (δ, δ̇, d)."""
        self.linearise(q, dq)
        self.predict(delta, ddelta, disturbance)

    def forces(self, tau: np.ndarray) -> np.ndarray:
        """Predicted cuff forces A τ + b, (P, 4, 2) [N] (allocates)."""
        return (self.A @ np.asarray(tau, dtype=float) + self.b).reshape(-1, 4, 2)


def _fours(**values: object) -> list[np.ndarray]:
    """Each value as a float64 array of 4 entries (InvalidParameter naming one that is not)."""
    for name, value in values.items():
        if np.shape(np.asarray(value, dtype=float)) != (4,):
            raise InvalidParameter(name, value, "an array of shape (4,)")
    return [np.asarray(a, dtype=float) for a in values.values()]
