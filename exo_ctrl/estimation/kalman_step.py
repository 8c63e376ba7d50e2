"""The compiled step of :class:`~exo_ctrl.estimation.kalman.CuffForceKalman`.

The prediction, covariance propagation and update of the filter on the
coupled exoskeleton–cuff–patient model, per leg, in place on the filter's
record; the model, the linearisation and the notation are
:mod:`exo_ctrl.estimation.kalman`'s module docstring.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import Status, kernel
from ..plant.cuffs import forces_of, isotropic_forces
from .kalman_cuff import add_model_error, add_to_state, cuff_sensor_update

__all__ = [
    "KALMAN_FIELDS",
    "cuff_jacobian",
    "force_std",
    "kalman_outputs",
    "kalman_step",
    "leg_covariance",
    "leg_model",
    "leg_update",
]


#: The filter's record (:class:`~exo_ctrl.estimation.kalman.CuffForceKalman`'s):
#: parameters, state, covariance, work rows, outputs.
KALMAN_FIELDS = [
    # Models' losses: damping [N·m·s/rad] and dry friction [N·m], exo then patient (8,).
    ("damping", np.float64, (8,)),
    ("friction", np.float64, (8,)),
    ("friction_smoothing", np.float64),
    ("torque_bias", np.float64, (4,)),
    # Step h [s]; noise variances: encoder σ_q² [rad²], exo torque, patient torque [N²m²],
    # random walk σ_d² [N²m²/s].
    ("h", np.float64),
    ("var_q", np.float64),
    ("var_exo", np.float64),
    ("var_patient", np.float64),
    ("var_rate", np.float64),
    # Cuff sensors (kalman_cuff): R = σ_e² of the normal and along axes [N²]; b's walk σ_r²
    # [1/s] and σ_0² [N²/s], its start ρ² [-] and σ_00² [N²], its decay e^(−h/T_b) per step;
    # the cuff model's error b and the sensors' biases β (normal, along) per cuff [N], β's
    # walk σ_w² [N²/s]; the joint torques' check (kalman_check): σ_τ² [N²m²], ε_τ² [-] and
    # (κ σ_τ)² [N²m²]; per leg the covariance B of (b, β) (thigh n, u, shank n, u; b then β).
    ("var_cuff", np.float64, (2,)),
    ("var_model_rate", np.float64),
    ("var_model_floor", np.float64),
    ("var_model_start", np.float64),
    ("var_model_start_floor", np.float64),
    ("model_decay", np.float64),
    ("model_error", np.float64, (4, 2)),
    ("sensor_bias", np.float64, (4, 2)),
    ("var_bias_rate", np.float64),
    ("var_torque_check", np.float64),
    ("var_check_rel", np.float64),
    ("var_check_blind", np.float64),
    ("bias_cov", np.float64, (2, 8, 8)),
    # The tare (kalman_cuff): its window in the filter's steps (settle, end), steps taken,
    # done, per axis the samples averaged and the offset estimate (mean reading − model) [N].
    ("tare_from", np.int64),
    ("tare_to", np.int64),
    ("steps", np.int64),
    ("tared", np.bool_),
    ("tare_n", np.int64, (4, 2)),
    ("offset", np.float64, (4, 2)),
    # Joint indices of each leg in (q_e, q_p): exo hip, knee, patient hip, knee.
    ("joints", np.int64, (2, 4)),
    # State: angles, speeds (exo 4, patient 4), d (4), covariance per leg, held torque.
    ("q", np.float64, (8,)),
    ("v", np.float64, (8,)),
    ("d", np.float64, (4,)),
    ("cov", np.float64, (2, 10, 10)),
    ("tau_hold", np.float64, (4,)),
    # Work: F and Q of the last prediction per leg, J_Δ (8 × 8), the step's midpoint.
    ("F", np.float64, (2, 10, 10)),
    ("Q", np.float64, (2, 10, 10)),
    ("jd", np.float64, (8, 8)),
    ("q_mid", np.float64, (8,)),
    ("work", np.float64, (10, 10)),
    # Per leg: M⁻¹, the cuffs' ∂τ/∂q and ∂τ/∂v − B (4 × 4), generalised forces, accelerations.
    ("minv", np.float64, (4, 4)),
    ("kq", np.float64, (4, 4)),
    ("kv", np.float64, (4, 4)),
    ("gen_force", np.float64, (4,)),
    ("acc", np.float64, (4,)),
    # Outputs (as the momentum observer's) and the along-link components [N].
    ("tau_ext", np.float64, (4,)),
    ("cuff_normal", np.float64, (4,)),
    ("cuff_force", np.float64, (4, 2)),
    ("cuff_along", np.float64, (4,)),
    # σ_c of each cuff force's estimate, from the covariance (kalman_step.force_std) [N].
    ("cuff_force_std", np.float64, (4,)),
    ("skipped", np.int64),
]


@kernel
def kalman_outputs(state, cuffs, split):
    """The device's cuff forces at the step's midpoint (q − ½ h v, v): f, n · f, u · f, J_eᵀ f.

    ``split``: the device's cuffs' switch (:attr:`~exo_ctrl.plant.cuffs.CuffSet.split_switch`).
    """
    st = state[0]
    cr = cuffs[0]
    for i in range(8):
        st.q_mid[i] = st.q[i] - 0.5 * st.h * st.v[i]
    if split is None:  # the device's cuffs isotropic: the split cuffs' code not compiled in
        isotropic_forces(cr, st.q_mid[:], st.v[:])
    else:
        forces_of(cr, st.q_mid[:], st.v[:])
    for c in range(4):
        fx, fz = cr.f[c], cr.f[4 + c]
        cc, sc = cr.cs[c], cr.cs[8 + c]
        ux = cr.along0[c, 0] * cc - cr.along0[c, 1] * sc
        uz = cr.along0[c, 1] * cc + cr.along0[c, 0] * sc
        st.cuff_force[c, 0] = fx
        st.cuff_force[c, 1] = fz
        st.cuff_normal[c] = -uz * fx + ux * fz
        st.cuff_along[c] = ux * fx + uz * fz
        st.tau_ext[c] = cr.tau[c]
    force_std(st, cr)


@kernel
def force_std(st, cr):
    """σ_c, the square root of the largest eigenvalue of cuff c's force covariance H_c P H_cᵀ.

    f_c = −𝒦_c J_c Δq − 𝒞_c J_c Δv to first order (J_c: rows c and 4 + c of
    J_Δ, the last prediction's; 𝒦_c = k_n n nᵀ + k_u u uᵀ, 𝒞_c likewise), so
    H_c (2 × 10, the leg's state) holds −𝒦_c J_c on the angles, −𝒞_c J_c on
    the speeds and zeros on d; P is the leg's posterior covariance [N].
    """
    for c in range(4):
        s = c // 2
        joints = st.joints[s]
        P = st.cov[s]
        cc, sc = cr.cs[c], cr.cs[8 + c]
        ux = cr.along0[c, 0] * cc - cr.along0[c, 1] * sc
        uz = cr.along0[c, 1] * cc + cr.along0[c, 0] * sc
        nx, nz = -uz, ux
        kxx = cr.k * nx * nx + cr.k_u * ux * ux
        kxz = cr.k * nx * nz + cr.k_u * ux * uz
        kzz = cr.k * nz * nz + cr.k_u * uz * uz
        cxx = cr.c * nx * nx + cr.c_u * ux * ux
        cxz = cr.c * nx * nz + cr.c_u * ux * uz
        czz = cr.c * nz * nz + cr.c_u * uz * uz
        hx = st.work[8]  # rows 8, 9 of the work matrix: H_c (the update is done with it)
        hz = st.work[9]
        for i in range(4):
            g = joints[i]
            jx, jz = st.jd[c, g], st.jd[4 + c, g]
            hx[i] = -(kxx * jx + kxz * jz)
            hz[i] = -(kxz * jx + kzz * jz)
            hx[4 + i] = -(cxx * jx + cxz * jz)
            hz[4 + i] = -(cxz * jx + czz * jz)
        sxx = sxz = szz = 0.0
        for i in range(8):
            px = pz = 0.0
            for j in range(8):
                px += P[i, j] * hx[j]
                pz += P[i, j] * hz[j]
            sxx += hx[i] * px
            sxz += hz[i] * px
            szz += hz[i] * pz
        mid = 0.5 * (sxx + szz)
        half = 0.5 * (sxx - szz)
        st.cuff_force_std[c] = math.sqrt(max(mid + math.sqrt(half * half + sxz * sxz), 0.0))


@kernel
def cuff_jacobian(cuffs, jd):
    """J_Δ = ∂(p_e − p_p)/∂q_all (rows x of the 4 cuffs, then z), after a force call."""
    cr = cuffs[0]
    for row in range(8):
        for i in range(8):
            jd[row, i] = 0.0
        for j in range(8):
            g = cr.dp[row, j] * cr.csr[j] + cr.dp[row, 8 + j] * cr.csr[8 + j]
            if g != 0.0:
                for i in range(8):
                    s = cr.select[j, i]
                    if s != 0.0:
                        jd[row, i] += g * s


@kernel
def kalman_step(state, cuffs, mass_e, nle_e, mass_p, nle_p, q_meas, tau_meas, split, cuff_meas):
    """One prediction and update of both legs in place (module docstring), then the outputs.

    ``mass_*``, ``nle_*``: M and n of the exoskeleton's link model and of the
    patient model at the last posterior; ``split``: as :func:`kalman_outputs`;
    ``cuff_meas``: the cuff sensors' readings record, fused after the
    encoders (:mod:`.kalman_cuff`), or None: no cuff sensors (not compiled in).
    Returns a :class:`Status` value: OK; WRONG_LENGTH (nothing done);
    NOT_FINITE when the state became non-finite (the caller restarts the filter).
    """
    if q_meas.shape[0] != 4 or tau_meas.shape[0] != 4:
        return Status.WRONG_LENGTH.value
    st = state[0]
    cr = cuffs[0]
    h = st.h
    # cuff forces and their generalised torques at the prior
    if split is None:
        isotropic_forces(cr, st.q[:], st.v[:])
    else:
        forces_of(cr, st.q[:], st.v[:])
    cuff_jacobian(cuffs, st.jd)
    minv, kq, kv, acc = st.minv, st.kq, st.kv, st.acc
    for s in range(2):
        joints = st.joints[s]
        leg_model(st, cr, s, mass_e, nle_e, mass_p, nle_p, tau_meas, minv, kq, kv, acc)
        leg_covariance(st, s, minv, kq, kv)
        for m in range(4):  # semi-implicit Euler of the nonlinear model
            g = joints[m]
            st.v[g] += h * acc[m]
            st.q[g] += h * st.v[g]
        if math.isfinite(q_meas[2 * s]) and math.isfinite(q_meas[2 * s + 1]):
            leg_update(st, s, q_meas)
        else:
            st.skipped += 1
    for i in range(8):
        if not (math.isfinite(st.q[i]) and math.isfinite(st.v[i])):
            return Status.NOT_FINITE.value
    if cuff_meas is not None:
        cuff_sensor_update(st, cr, cuff_meas, split)
        for i in range(8):
            if not (math.isfinite(st.q[i]) and math.isfinite(st.v[i])):
                return Status.NOT_FINITE.value
    kalman_outputs(state, cuffs, split)
    if cuff_meas is not None:
        add_model_error(st, cr)
    return Status.OK.value


@kernel
def leg_model(st, cr, s, mass_e, nle_e, mass_p, nle_p, tau_meas, minv, kq, kv, acc):
    """Leg s: M⁻¹ (4 × 4, block diagonal), the cuffs' ∂τ/∂q and ∂τ/∂v, the accelerations."""
    joints = st.joints[s]
    a, b = 2 * s, 2 * s + 1
    if math.isfinite(tau_meas[a]) and math.isfinite(tau_meas[b]):
        st.tau_hold[a] = tau_meas[a]
        st.tau_hold[b] = tau_meas[b]
    for i in range(4):
        for j in range(4):
            minv[i, j] = 0.0
            kq[i, j] = 0.0
            kv[i, j] = 0.0
    det_e = mass_e[a, a] * mass_e[b, b] - mass_e[a, b] * mass_e[b, a]
    det_p = mass_p[a, a] * mass_p[b, b] - mass_p[a, b] * mass_p[b, a]
    minv[0, 0], minv[0, 1] = mass_e[b, b] / det_e, -mass_e[a, b] / det_e
    minv[1, 0], minv[1, 1] = -mass_e[b, a] / det_e, mass_e[a, a] / det_e
    minv[2, 2], minv[2, 3] = mass_p[b, b] / det_p, -mass_p[a, b] / det_p
    minv[3, 2], minv[3, 3] = -mass_p[b, a] / det_p, mass_p[a, a] / det_p
    # −J_Δᵀ K_c J_Δ and −J_Δᵀ C_c J_Δ over the leg's two cuffs, links' frames held.
    for c in (a, b):
        cc, sc = cr.cs[c], cr.cs[8 + c]
        ux = cr.along0[c, 0] * cc - cr.along0[c, 1] * sc
        uz = cr.along0[c, 1] * cc + cr.along0[c, 0] * sc
        nx, nz = -uz, ux
        for i in range(4):
            gi = joints[i]
            ji_n = nx * st.jd[c, gi] + nz * st.jd[4 + c, gi]
            ji_u = ux * st.jd[c, gi] + uz * st.jd[4 + c, gi]
            for j in range(4):
                gj = joints[j]
                jj_n = nx * st.jd[c, gj] + nz * st.jd[4 + c, gj]
                jj_u = ux * st.jd[c, gj] + uz * st.jd[4 + c, gj]
                kq[i, j] -= cr.k * ji_n * jj_n + cr.k_u * ji_u * jj_u
                kv[i, j] -= cr.c * ji_n * jj_n + cr.c_u * ji_u * jj_u
    eps = st.friction_smoothing
    force = st.gen_force
    for m in range(4):
        g = joints[m]
        kv[m, m] -= st.damping[g]
        w = st.v[g]
        f = cr.tau[g] - st.damping[g] * w - st.friction[g] * math.tanh(w / eps)
        if m < 2:
            f += st.tau_hold[g] - st.torque_bias[g] - nle_e[g]
        else:
            f += st.d[g - 4] - nle_p[g - 4]
        force[m] = f
    for i in range(4):
        x = 0.0
        for j in range(4):
            x += minv[i, j] * force[j]
        acc[i] = x


@kernel
def leg_covariance(st, s, minv, kq, kv):
    """F and Q of leg s (module docstring), then P⁻ = F P Fᵀ + Q in place."""
    h = st.h
    F, Q, P, W = st.F[s], st.Q[s], st.cov[s], st.work
    for i in range(10):
        for j in range(10):
            F[i, j] = 1.0 if i == j else 0.0
            Q[i, j] = 0.0
    for i in range(4):
        for j in range(4):
            aq = 0.0
            av = 0.0
            for m in range(4):
                aq += minv[i, m] * kq[m, j]
                av += minv[i, m] * kv[m, j]
            F[4 + i, j] = h * aq
            F[4 + i, 4 + j] += h * av
            F[i, j] += h * h * aq
            F[i, 4 + j] = h * (F[4 + i, 4 + j])
        for j in range(2):
            F[4 + i, 8 + j] = h * minv[i, 2 + j]
            F[i, 8 + j] = h * h * minv[i, 2 + j]
    # Q = G Σ Gᵀ, G = [h² M⁻¹; h M⁻¹]; Σ = diag(var_exo, var_exo, var_patient, var_patient).
    for i in range(4):
        for j in range(4):
            x = 0.0
            for m in range(4):
                var = st.var_exo if m < 2 else st.var_patient
                x += minv[i, m] * var * minv[j, m]
            Q[i, j] = h**4 * x
            Q[i, 4 + j] = h**3 * x
            Q[4 + i, j] = h**3 * x
            Q[4 + i, 4 + j] = h * h * x
    Q[8, 8] = Q[9, 9] = h * st.var_rate
    # F's rows 0–3 are e_i + h (row 4 + i) and rows 8, 9 are e_8, e_9 (module
    # docstring), so only its rows 4–7, F_v, multiply: F P = [P_q + h F_v P;
    # F_v P; P_d], and likewise (F P) Fᵀ column-wise — 800 multiply-adds, not 1550.
    for i in range(4):  # W = F P
        for j in range(10):
            x = 0.0
            for m in range(10):
                x += F[4 + i, m] * P[m, j]
            W[4 + i, j] = x
    for j in range(10):
        for i in range(4):
            W[i, j] = P[i, j] + h * W[4 + i, j]
        W[8, j] = P[8, j]
        W[9, j] = P[9, j]
    for i in range(10):  # P = W Fᵀ + Q by rows, then its upper triangle mirrored
        for c in range(4):
            y = 0.0
            for m in range(10):
                y += W[i, m] * F[4 + c, m]
            P[i, c] = W[i, c] + h * y + Q[i, c]
            P[i, 4 + c] = y + Q[i, 4 + c]
        P[i, 8] = W[i, 8] + Q[i, 8]
        P[i, 9] = W[i, 9] + Q[i, 9]
    for i in range(10):
        for j in range(i + 1, 10):
            P[j, i] = P[i, j]


@kernel
def leg_update(st, s, q_meas):
    """The Kalman update of leg s with its two encoder angles (H = [I 0 0 0 0], R = σ_q² I)."""
    P, W = st.cov[s], st.work
    joints = st.joints[s]
    s00 = P[0, 0] + st.var_q
    s01 = P[0, 1]
    s11 = P[1, 1] + st.var_q
    det = s00 * s11 - s01 * s01
    i00, i01, i11 = s11 / det, -s01 / det, s00 / det
    y0 = q_meas[2 * s] - st.q[joints[0]]
    y1 = q_meas[2 * s + 1] - st.q[joints[1]]
    for i in range(10):  # gain K = P Hᵀ S⁻¹ in W[:, 0:2]
        W[i, 0] = P[i, 0] * i00 + P[i, 1] * i01
        W[i, 1] = P[i, 0] * i01 + P[i, 1] * i11
    for i in range(10):
        add_to_state(st, s, i, W[i, 0] * y0 + W[i, 1] * y1)
    for j in range(10):  # rows 0 and 1 of P (H P), kept before P changes
        W[j, 2] = P[0, j]
        W[j, 3] = P[1, j]
    for i in range(10):  # P = P − K H P, kept symmetric
        for j in range(i, 10):
            x = P[i, j] - W[i, 0] * W[j, 2] - W[i, 1] * W[j, 3]
            P[i, j] = x
            P[j, i] = x
