r"""Cuff forces over a horizon, affine in the drive torques held over it.

The cuffs are springs (K = 8 N/mm) with the patient's leg on them: modes of
5–12 Hz, slow against the 1 ms tick, so a force bound must look ahead over
about half a cuff period.  Per leg (hip, knee; the legs do not couple), with
δ = q_exo − q_patient the patient's lag behind the exoskeleton, J the
patient's cuff Jacobians (rows thigh x, z, shank x, z; 4×2), G = JᵀJ, and
the cuffs isotropic spring–dampers with the joint axes aligned (as fitted),
the cuff forces on the exoskeleton are, to first order in δ,

.. math::

    f = -J s, \qquad s = K δ + C \dot δ \quad [\text{N·m per m², joint space}].

The drive's voltage U(τ) = R τ/(i_G k_m) + i_G ω₀/k_E is held over the
horizon (move blocking), so the joint torque is τ − D (q̇ − ω₀) with the
back-EMF damping D = i_G k_m (i_G/k_E)/R ≈ 330 N·m·s/rad.  Linearised at
the measured (q, ω₀), with u_e = q̇_e − ω₀, u_p = q̇_p − ω₀:

.. math::

    \dot δ = u_e - u_p, \\
    M_e' \dot u_e = τ - h_e - (D + b_e) u_e - G (K δ + C (u_e - u_p)), \\
    M_p \dot u_p = -h_p + d - b_p u_p + G (K δ + C (u_e - u_p)),

M_e' = M_e + i_G² J_rotor, h the Coriolis, gravity, damping and friction
torques at the measured state, b the URDF joint damping, d the patient's own
joint torque (held; estimated by :class:`CuffStateObserver`).  With
z = (δ, u_e, u_p, τ, 1) this is ż = F z (9×9 per leg), so z(t) = e^{Ft} z(0),
z(0) = (δ̂, 0, −δ̂̇, τ, 1), and s(t_i) — hence f(t_i) = A_i τ + b_i — is
affine in τ.  F's rows 6–8 are zero (τ and 1 are held), so e^{Ft} =
[[E₁₁, E₁₂], [0, I]], as is every product of such matrices: only their rows
0–5 are formed.  e^{FΔ} (Δ = gcd of the horizon points) is computed by
scaling and squaring a degree-10 Taylor polynomial (evaluated
Paterson–Stockmeyer: X, X², X³, then Horner in X³), and squared on to
e^{FΔ 2^k}; the point nΔ (default 5, 10, 20, 30, 40 ms: half the slowest
cuff period; n = 1, 2, 4, 6, 8) needs only the two rows S of s = S z, which
are S e^{FΔ 2^{k₀}} times the squares of n's other binary digits.  All in
one compiled kernel (:func:`exo_ctrl._jit.kernel`).

Accuracy (tests/test_qp.py): against the plant (nonlinear, elastic cuffs,
drive current dynamics) stepped 40 ms with the voltage held, given the true
δ, δ̇: ≤ 4.6 N on forces up to 155 N.  Neglected: the drive's electrical
time constant (0.7 ms), the change of M, h, J over 40 ms, the speed
dependence of the Coriolis and friction torques, the cuff's nonlinearity in δ.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from ..._jit import kernel
from ...exceptions import InvalidParameter
from ...model.body import FRICTION_SMOOTHING_RAD_S, BodyModel, combined_model
from ...plant.cuffs import CuffParams, CuffSet
from ...plant.motor import MotorParams

__all__ = ["DEFAULT_HORIZON_TICKS", "CuffHorizonModel", "CuffStateObserver"]

#: Default horizon points, in control ticks after the present one.
DEFAULT_HORIZON_TICKS = (5, 10, 20, 30, 40)
_TAYLOR_ORDER = 10
#: The Taylor polynomial is evaluated Paterson–Stockmeyer in blocks of this
#: many terms: X, X², X³ formed, then Horner in X³ (5 products for degree 10,
#: against 9 for Horner in X).
_PS_BLOCK = 3
#: z = (δ, u_e, u_p, τ, 1) has _NZ entries of which the first _NM move (τ and
#: 1 are held): F's rows 6–8 are zero, e^{Ft}'s are [0 | I], and the kernels
#: store and compute only rows 0–5 of every matrix.
_NZ = 9
_NM = 6
#: Slots of :func:`_predict`'s scratch array, (_W_SQUARES + bits of the largest
#: power, 6, 9): F Δ; the generalised forces per column of z (rows 0–1 exo,
#: 2–3 patient); the s rows of a power (rows 0–1, rows 2–3 scratch);
#: :func:`_expm`'s scratch; e^{FΔ 2^k}, k = 0, 1, ...
_W_F = 0
_W_G = 1
_W_S = 2
_W_EXPM = 3
_W_SQUARES = _W_EXPM + _PS_BLOCK + 1


@kernel
def _mul_top(a, b, beta, out):  # pragma: no cover - compiled
    """Write the first rows of a b to ``out`` (as many as it has); b's rows 6–8 are β [0 | I].

    a: rows of 9 columns (rows 0–5 of a 9×9 matrix of the block form, or
    combinations of them); b: rows 0–5 of a 9×9 matrix; out must overlap
    neither.  out = a[:, :6] b[:6] + β a[:, 6:] (added to columns 6–8), each
    entry summed over k in order; the six a[i, k] are held in registers and
    the loop over j is independent (it vectorises).
    """
    for i in range(out.shape[0]):
        a0, a1, a2, a3, a4, a5 = a[i, 0], a[i, 1], a[i, 2], a[i, 3], a[i, 4], a[i, 5]
        for j in range(_NM):
            out[i, j] = (
                a0 * b[0, j] + a1 * b[1, j] + a2 * b[2, j] + a3 * b[3, j] + a4 * b[4, j]
            ) + a5 * b[5, j]
        for j in range(_NM, _NZ):
            out[i, j] = (
                (a0 * b[0, j] + a1 * b[1, j] + a2 * b[2, j] + a3 * b[3, j] + a4 * b[4, j])
                + a5 * b[5, j]
            ) + beta * a[i, j]


@kernel
def _copy(src, dst):  # pragma: no cover - compiled
    for i in range(src.shape[0]):
        for j in range(src.shape[1]):
            dst[i, j] = src[i, j]


@kernel
def _expm(f, out, work):  # pragma: no cover - compiled
    """exp(F) by scaling and squaring a degree-10 Taylor polynomial (F small after scaling).

    F is 9×9 with rows 6–8 zero: ``f`` holds its rows 0–5, (6, 9), and
    ``out`` gets those of exp(F), whose rows 6–8 are [0 | I].  With
    X = F/2^s, ‖X‖∞ ≤ 1/4, T(X) = Σ_{k≤10} X^k/k! = B_0 + X³ (B_1 + X³ (B_2 +
    X³ B_3)), B_j = Σ_{i<3} X^i/(3j+i)!; then squared s times.
    ``work``: (_PS_BLOCK + 1, 6, 9) scratch.
    """
    norm = 0.0
    for i in range(_NM):
        row = 0.0
        for j in range(_NZ):
            row += abs(f[i, j])
        norm = max(norm, row)
    s = 0
    while norm > 0.25 and s < 40:
        norm *= 0.5
        s += 1
    scale = 0.5**s
    q = _PS_BLOCK
    tmp = work[q]
    # work[k] = X^(k+1) (rows 6-8 zero: the product's β is 0)
    for i in range(_NM):
        for j in range(_NZ):
            work[0, i, j] = scale * f[i, j]
    for k in range(1, q):
        _mul_top(work[0], work[k - 1], 0.0, work[k])
    top = _TAYLOR_ORDER // q
    # Horner in X^q over the blocks B_j, top one first; the running
    # polynomial's rows 6-8 are beta [0 | I] (beta = 1/(jq)!).
    beta = 0.0
    for jb in range(top, -1, -1):
        c = 1.0
        for k in range(2, jb * q + 1):
            c /= k
        if jb == top:
            for i in range(_NM):
                for j in range(_NZ):
                    out[i, j] = 0.0
        else:
            _mul_top(work[q - 1], out, beta, tmp)
            _copy(tmp, out)
        beta = c
        for i in range(_NM):
            out[i, i] += c
        for k in range(1, q):
            if jb * q + k > _TAYLOR_ORDER:
                break
            c /= jb * q + k
            xk = work[k - 1]
            for i in range(_NM):
                for j in range(_NZ):
                    out[i, j] += c * xk[i, j]
    for _ in range(s):
        _mul_top(out, out, 1.0, tmp)
        _copy(tmp, out)


@kernel
def _predict(
    me,
    mp,
    jac,
    he,
    hp,
    damp_e,
    damp_p,
    stiff,
    damp_c,
    dt_block,
    powers,
    delta,
    ddelta,
    dist,
    a_out,
    b_out,
    work,
):  # pragma: no cover - compiled
    """Fill a_out (P*8, 4) and b_out (P*8) -- see module docstring.

    ``work``: (_W_SQUARES + bit length of powers[-1], 6, 9) scratch.
    """
    n_pts = powers.shape[0]
    n_sq = 0  # squares e^{FΔ 2^k}, k < n_sq, needed for the largest power
    while powers[n_pts - 1] >> n_sq > 0:
        n_sq += 1
    for r in range(a_out.shape[0]):
        b_out[r] = 0.0
        for c in range(4):
            a_out[r, c] = 0.0
    f = work[_W_F]
    ge = work[_W_G, 0:2]
    gp = work[_W_G, 2:4]
    sv = work[_W_S, 0:2]
    sv_tmp = work[_W_S, 2:4]
    for leg in range(2):
        i0 = 2 * leg
        # 2x2 blocks: exo mass (with armature), patient mass, G = J^T J.
        m11, m12, m22 = me[i0, i0], me[i0, i0 + 1], me[i0 + 1, i0 + 1]
        p11, p12, p22 = mp[i0, i0], mp[i0, i0 + 1], mp[i0 + 1, i0 + 1]
        g11 = g12 = g22 = 0.0
        for r in range(4):
            g11 += jac[leg, r, 0] * jac[leg, r, 0]
            g12 += jac[leg, r, 0] * jac[leg, r, 1]
            g22 += jac[leg, r, 1] * jac[leg, r, 1]
        de = m11 * m22 - m12 * m12
        dp = p11 * p22 - p12 * p12
        ie11, ie12, ie22 = m22 / de, -m12 / de, m11 / de
        ip11, ip12, ip22 = p22 / dp, -p12 / dp, p11 / dp
        # Generalised forces on the exo per unit of each state/input column.
        # exo: tau - he - D u_e - G K delta - G C (u_e - u_p)
        # patient: -hp + d - Dp u_p + G K delta + G C (u_e - u_p)
        for r in range(2):
            for c in range(_NZ):
                ge[r, c] = 0.0
                gp[r, c] = 0.0
        gm = ((g11, g12), (g12, g22))
        for r in range(2):
            for c in range(2):
                gk = stiff * gm[r][c]
                gc = damp_c * gm[r][c]
                ge[r, c] = -gk
                ge[r, 2 + c] = -gc
                ge[r, 4 + c] = gc
                gp[r, c] = gk
                gp[r, 2 + c] = gc
                gp[r, 4 + c] = -gc
            ge[r, 2 + r] -= damp_e[i0 + r]
            gp[r, 4 + r] -= damp_p[i0 + r]
            ge[r, 6 + r] = 1.0
            ge[r, 8] = -he[i0 + r]
            gp[r, 8] = -hp[i0 + r] + dist[i0 + r]
        # Rows 0-5 of F Δ (rows 6-8 are zero).
        for c in range(_NZ):
            f[0, c] = 0.0
            f[1, c] = 0.0
            f[2, c] = (ie11 * ge[0, c] + ie12 * ge[1, c]) * dt_block
            f[3, c] = (ie12 * ge[0, c] + ie22 * ge[1, c]) * dt_block
            f[4, c] = (ip11 * gp[0, c] + ip12 * gp[1, c]) * dt_block
            f[5, c] = (ip12 * gp[0, c] + ip22 * gp[1, c]) * dt_block
        f[0, 2] = f[1, 3] = dt_block
        f[0, 4] = f[1, 5] = -dt_block
        _expm(f, work[_W_SQUARES], work[_W_EXPM:_W_SQUARES])
        for k in range(1, n_sq):
            sq = work[_W_SQUARES + k - 1]
            _mul_top(sq, sq, 1.0, work[_W_SQUARES + k])
        # z0 = (delta, 0, -ddelta, tau, 1)
        for p in range(n_pts):
            # The s rows (s = K delta + C (u_e - u_p)) of e^{F Δ n}, n = Σ_k 2^k
            # over n's bits: S e^{F Δ 2^k0}, times the other squares in turn.
            n = powers[p]
            k = 0
            while (n >> k) & 1 == 0:
                k += 1
            sq = work[_W_SQUARES + k]
            for r in range(2):
                for c in range(_NZ):
                    sv[r, c] = stiff * sq[r, c] + damp_c * (sq[2 + r, c] - sq[4 + r, c])
            k += 1
            while n >> k > 0:
                if (n >> k) & 1 == 1:
                    _mul_top(sv, work[_W_SQUARES + k], 1.0, sv_tmp)
                    _copy(sv_tmp, sv)
                k += 1
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
def _observe(
    mp,
    hp,
    jac,
    force,
    omega,
    stiff,
    damp_c,
    a_delta,
    a_dist,
    h,
    delta,
    ddelta,
    vp_prev,
    dist,
    first,
):  # pragma: no cover - compiled
    """One observer tick per leg (CuffStateObserver docstring).

    ``first``: (1,), 1 before the first tick, set to 0 by it.  Returns False
    (and nothing done) if an entry of ``force`` is not finite.
    """
    for c in range(4):
        if not (math.isfinite(force[c, 0]) and math.isfinite(force[c, 1])):
            return False
    for leg in range(2):
        i0 = 2 * leg
        g11 = g12 = g22 = 0.0
        r1 = r2 = 0.0
        for r in range(4):
            j0, j1 = jac[leg, r, 0], jac[leg, r, 1]
            g11 += j0 * j0
            g12 += j0 * j1
            g22 += j1 * j1
            fr = force[2 * leg + r // 2, r % 2]
            r1 += j0 * fr
            r2 += j1 * fr
        dg = g11 * g22 - g12 * g12
        # s = -G⁻¹ Jᵀ f̂
        s1 = -(g22 * r1 - g12 * r2) / dg
        s2 = -(g11 * r2 - g12 * r1) / dg
        delta[i0] += a_delta * (s1 / stiff - delta[i0])
        delta[i0 + 1] += a_delta * (s2 / stiff - delta[i0 + 1])
        dd1 = (s1 - stiff * delta[i0]) / damp_c
        dd2 = (s2 - stiff * delta[i0 + 1]) / damp_c
        ddelta[i0], ddelta[i0 + 1] = dd1, dd2
        vp1, vp2 = omega[i0] - dd1, omega[i0 + 1] - dd2
        if first[0] == 0.0:
            a1 = (vp1 - vp_prev[i0]) / h
            a2 = (vp2 - vp_prev[i0 + 1]) / h
            e1 = mp[i0, i0] * a1 + mp[i0, i0 + 1] * a2 + hp[i0] - (g11 * s1 + g12 * s2)
            e2 = mp[i0, i0 + 1] * a1 + mp[i0 + 1, i0 + 1] * a2 + hp[i0 + 1] - (g12 * s1 + g22 * s2)
            dist[i0] += a_dist * (e1 - dist[i0])
            dist[i0 + 1] += a_dist * (e2 - dist[i0 + 1])
        vp_prev[i0], vp_prev[i0 + 1] = vp1, vp2
    first[0] = 0.0
    return True


@kernel
def _pair(q, dq, q_all, v_all):  # pragma: no cover - compiled
    """q_all = [q, q], v_all = [q̇, q̇]: the patient taken in the exoskeleton's state.

    Returns False (nothing written) unless q and q̇ have 4 entries.
    """
    if q.shape[0] != 4 or dq.shape[0] != 4:
        return False
    for i in range(4):
        q_all[i] = q_all[4 + i] = q[i]
        v_all[i] = v_all[4 + i] = dq[i]
    return True


@kernel
def _gather(mass, nle, q, dq, losses, points, select, mass_e, mass_p, bias_e, bias_p, jac):
    """Fill what :meth:`CuffHorizonModel.linearise` keeps from the Pinocchio calls.

    ``q``, ``dq``: the measured state (the patient's taken equal).  ``mass``
    and ``nle``: CRBA and nonLinearEffects of the model of both bodies
    (q_all = [q, q]); the mass matrices are its diagonal blocks; bias
    = nle + b q̇ + f_c tanh(q̇/ε) per body (``losses`` rows b_e, f_e, b_p,
    f_p).  The patient's cuff Jacobians, (x, z) rows on their leg's two
    joints, from the cuff points' form p = P (cos θ, sin θ) + p₀ with link
    rotations θ = S q_all (``points`` = P, ``select`` = S of
    :class:`~exo_ctrl.plant.cuffs.CuffSet`; patient points 4-7, rotations 4-7):
    ∂p/∂q = Σ_j (−P_j sin θ_j + P_{8+j} cos θ_j) S_j.
    """
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
                        for m in range(4):
                            theta += select[j, 4 + m] * q[m]
                        cos_t, sin_t = math.cos(theta), math.sin(theta)
                        acc += s * (points[row, 8 + j] * cos_t - points[row, j] * sin_t)
                jac[leg, 2 * k + axis, col] = acc


class CuffHorizonModel:
    """Cuff forces at horizon points, affine in the held drive torques (module docstring).

    Args:
        exo: the exoskeleton model the controller believes in.
        patient: the patient model the controller believes in.
        motor: the drive (reflected rotor inertia, back-EMF damping).
        cuffs: the cuffs' stiffness K and damping C (default: CuffParams()).
        dt: control period [s], finite and > 0.
        horizon_ticks: the horizon points t_i = n_i Δt, increasing integers in
            [1, 1000].

    Attributes:
        A: ∂f/∂τ, (8 P, 4) [1/m]; row 8 p + 2 c + i is component i (x, z)
            of cuff c at horizon point p.
        b: forces at τ = 0, (8 P,) [N].
        jac: patient cuff Jacobians per leg, (2, 4, 2): rows thigh x, thigh z,
            shank x, shank z; columns hip, knee [m/rad].
        mass_patient: patient mass matrix (upper triangle valid), (4, 4).
        bias_patient: h_p, patient bias torques at the measured state [N·m].

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
        cuffs = cuffs or CuffParams()
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
        self._powers = np.array([t // block for t in ticks], dtype=np.int64)
        self._block = block * dt
        self.dt = float(dt)
        # Both bodies in one model (exo joints 0-3 with the rotors' reflected
        # inertia, patient 4-7); the patient's cuff points as in the plant.
        self._model = combined_model(exo, patient)
        rotor = np.full(4, motor.reflected_inertia_kgm2)
        self._model.armature = np.concatenate((rotor, np.zeros(4)))
        self._data = self._model.createData()
        self._q_all = np.zeros(8)
        self._v_all = np.zeros(8)
        cuff_set = CuffSet(exo, patient, cuffs)
        self._points = np.ascontiguousarray(cuff_set.kernel_points)
        self._select = np.ascontiguousarray(cuff_set.kernel_matrices[:8, :8])
        kt, kb, r = motor.torque_per_amp_Nm_per_A, motor.back_emf_V_per_rad_s, motor.resistance_ohm
        #: Back-EMF damping of a drive held at constant voltage, i_G k_m (i_G/k_E)/R [N·m·s/rad].
        self.back_emf_damping = kt * kb / r
        self._damp_e = self.back_emf_damping + exo.damping
        self._damp_p = patient.damping.copy()
        self._b_e, self._f_e = exo.damping.copy(), exo.friction.copy()
        self._b_p, self._f_p = patient.damping.copy(), patient.friction.copy()
        self._losses = np.stack((self._b_e, self._f_e, self._b_p, self._f_p))
        self.stiffness = float(cuffs.stiffness_N_per_m)
        self.damping = float(cuffs.damping_N_s_per_m)
        n = len(ticks)
        self.A = np.zeros((8 * n, 4))
        self.b = np.zeros(8 * n)
        self.jac = np.zeros((2, 4, 2))
        self.mass_exo = np.zeros((4, 4))
        self.mass_patient = np.zeros((4, 4))
        self.bias_exo = np.zeros(4)
        self.bias_patient = np.zeros(4)
        n_squares = int(self._powers[-1]).bit_length()
        self._work = np.zeros((_W_SQUARES + n_squares, _NM, _NZ))

    def linearise(self, q: np.ndarray, dq: np.ndarray) -> None:
        """Mass matrices, bias torques and cuff Jacobians at the measured state.

        Args:
            q: exoskeleton joint angles [rad] (the patient's are taken equal).
            dq: exoskeleton joint speeds [rad/s].

        Raises:
            InvalidParameter: q or dq without 4 entries.

        """
        mass, nle = self.terms(q, dq)
        _gather(
            mass,
            nle,
            q,
            dq,
            self._losses,
            self._points,
            self._select,
            self.mass_exo,
            self.mass_patient,
            self.bias_exo,
            self.bias_patient,
            self.jac,
        )

    def terms(self, q: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The Pinocchio part of :meth:`linearise`: M and C q̇ + g of both bodies at (q, q, q̇, q̇).

        Arrays of Pinocchio's data (:attr:`data_terms` views the same
        memory), overwritten by the next call.

        Raises:
            InvalidParameter: q or dq without 4 entries.

        """
        q_all, v_all = self._q_all, self._v_all
        if not _pair(q, dq, q_all, v_all):
            shapes = f"shapes {np.shape(q)} and {np.shape(dq)}"
            raise InvalidParameter("q and dq", shapes, "arrays of 4 joint values each")
        model, data = self._model, self._data
        return pin.crba(model, data, q_all), pin.nonLinearEffects(model, data, q_all, v_all)

    @property
    def data_terms(self) -> tuple[np.ndarray, np.ndarray]:
        """Views of where :meth:`terms` leaves M (C-ordered: M is symmetric) and C q̇ + g."""
        return self._data.M.T, self._data.nle

    def predict(self, delta: np.ndarray, ddelta: np.ndarray, disturbance: np.ndarray) -> None:
        """Fill :attr:`A` and :attr:`b` from the state of the last :meth:`linearise`.

        Args:
            delta: δ = q_exo − q_patient [rad], (4,).
            ddelta: δ̇ [rad/s], (4,).
            disturbance: patient joint torque d, held over the horizon [N·m], (4,).

        """
        _predict(
            self.mass_exo,
            self.mass_patient,
            self.jac,
            self.bias_exo,
            self.bias_patient,
            self._damp_e,
            self._damp_p,
            self.stiffness,
            self.damping,
            self._block,
            self._powers,
            delta,
            ddelta,
            disturbance,
            self.A,
            self.b,
            self._work,
        )

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


class CuffStateObserver:
    """Cuff deflection δ, its rate δ̇ and the patient's torque d from the force estimate.

    Per leg, with s = −G⁻¹ Jᵀ f̂ the joint-space cuff load (module docstring):
    the deflection obeys C δ̇ = s − K δ exactly (isotropic spring–damper), so

    - δ̂ is s/K through a first-order filter of time constant C/K (12.5 ms
      with the defaults), discretised exactly (zero-order hold of s);
    - δ̇̂ = (s − K δ̂)/C, and the patient's joint speed v̂_p = q̇ − δ̇̂;
    - d̂, the patient's own joint torque, from the patient's equation
      M_p v̇_p + h_p = G s + d: the residual M_p Δv̂_p/Δt + h_p − G s through
      a first-order filter of bandwidth ``disturbance_bandwidth_per_s``.

    Args:
        stiffness: K [N/m].
        damping: C [N·s/m], > 0.
        dt: control period [s].
        disturbance_bandwidth_per_s: bandwidth of the d̂ filter [1/s], ≥ 0
            (0: d̂ = 0).

    Raises:
        InvalidParameter: a value outside its range.

    """

    def __init__(
        self,
        stiffness: float,
        damping: float,
        dt: float = 1e-3,
        disturbance_bandwidth_per_s: float = 30.0,
    ) -> None:
        from ... import _validate as v

        k = v.positive("cuff stiffness", stiffness, "N/m")
        c = v.positive("cuff damping", damping, "N·s/m")
        h = v.positive("dt", dt, "s")
        bw = v.non_negative("disturbance_bandwidth", disturbance_bandwidth_per_s, "1/s")
        self.stiffness, self.damping, self.dt = k, c, h
        self._a_delta = -math.expm1(-h * k / c)
        self._a_dist = -math.expm1(-h * bw)
        self.delta = np.zeros(4)
        self.ddelta = np.zeros(4)
        self.disturbance = np.zeros(4)
        self._vp = np.zeros(4)
        #: 1 until the first update (no speed difference yet), then 0.
        self.first = np.ones(1)

    def reset(self) -> None:
        """Forget the state (cuffs taken as just fitted: δ = 0, d = 0)."""
        self.delta.fill(0.0)
        self.ddelta.fill(0.0)
        self.disturbance.fill(0.0)
        self.first[0] = 1.0

    def update(self, model: CuffHorizonModel, force_est: np.ndarray, omega: np.ndarray) -> bool:
        """One tick: f̂ (4, 2) [N] and q̇ [rad/s], with ``model`` linearised at this tick.

        Returns False, and leaves the observer as it was, if f̂ is not finite.
        """
        return _observe(
            model.mass_patient,
            model.bias_patient,
            model.jac,
            force_est,
            omega,
            self.stiffness,
            self.damping,
            self._a_delta,
            self._a_dist,
            self.dt,
            self.delta,
            self.ddelta,
            self._vp,
            self.disturbance,
            self.first,
        )
