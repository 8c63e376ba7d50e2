r"""The Kalman filter's update with the instrumented cuffs' readings.

With cuff force sensors (:mod:`exo_ctrl.sensing.cuff_load`) the filter of
:mod:`.kalman` fuses, after the encoders' update of each tick, every fresh
sample of every measured axis as a scalar measurement of its leg's state
x = (q_e, q_p, v_e, v_p, d) ∈ ℝ¹⁰.  The measured component of cuff c on
axis a (a the link's normal n, or its direction u) is

    z = aᵀ f_c(q − ½ h v, v) + e,   e ~ N(0, R_a),

the device's cuff force at the step's midpoint, as the filter's outputs
(:func:`~exo_ctrl.estimation.kalman_step.kalman_outputs`) and the sensor's
truth (the plant's force over its last step).  Linearised (J_c: rows c and
4 + c of J_Δ, the prediction's; 𝒦_c aᵀ = k_a aᵀ and likewise 𝒞_c for the
link-frame axes a ∈ {n, u}, k_n = ``k``, k_u = ``k_u``):

    h = [−k_a aᵀ J_c,  (½ h k_a − c_a) aᵀ J_c,  0 0],

(the ½ h k_a from the midpoint q − ½ h v), and the components are taken
one after another (a sequential update, exact for independent noises).

**The cuff model's error.**  The filter's cuffs are the device's model
(isotropic 8 N/mm by default); the true cuffs are not.  With the two
patient angles per leg as the only free positions, the model's four force
components of a leg lie on a two-dimensional family, which the true forces
leave: no state x reproduces them, and the update alone moved the estimate
by under 2 % of the force on the default run (the filter trusts its model:
σ_c ≈ 0.5 N).  So each measured axis carries a model-error force b_ca [N],
a random walk of intensity σ_m (:data:`MODEL_ERROR_RATE_N_PER_SQRT_S`),
added to the model's force in the outputs (f_c + b_n n + b_u u), with its
own variance p_ca, decoupled from x (its cross-covariance with x is
dropped, as a Schmidt filter drops a nuisance state's).  One scalar update
takes both, with the same innovation:

    ẑ = aᵀ f_c + h δx + b,   S = h P hᵀ + p + R_a,
    x ← x + P hᵀ (z − ẑ) / S,   b ← b + p (z − ẑ) / S,
    P ← P − P hᵀ h P / S,   p ← p − p² / S,

δx the leg's change since the forces were evaluated (so ẑ follows the
earlier components' corrections to first order), P kept symmetric by
writing its upper triangle to both halves; between samples p grows by
σ_m² h a tick and b is held.  An axis the set does not read keeps b = 0:
its component is the model's (moved only through x).  A reading that is not finite
(an axis the set does not read, a failed sensor) is skipped; a held
sample (``fresh`` false) is not used again.

**The tare.**  A sensor's offset b_s (:mod:`exo_ctrl.sensing.cuff_load`)
reads as force; the filter cannot tell them apart from the readings alone.
On request (``tare_s`` > 0; off by default, :mod:`exo_ctrl.sensing.cuff_load`
says why) the device zeroes its sensors while it stands at the start, with
the cuffs strapped on: over the window of the filter's steps
(t_s, t_s + T_t], t_s = :data:`TARE_SETTLE_S` (its start's transient) and
T_t the sensors' ``tare_s``, it takes no update but averages, per measured
axis, each fresh sample less the model's component at the same point,

    ô_ca = mean(z − aᵀ f_c(q − ½ h v, v)),

and from the first fresh sample after the window on updates with z − ô_ca
(until then b stays 0 and σ_c is the joint torques' own).  The filter there runs on the
encoders and the joint torques alone, so ô carries the standing estimate's
error: the joint torques fix the shank's normal force, and the standing
model the thigh's along force, to well under 0.1 N; the hip torque's split
between the thigh's normal and the shank's along force comes from the cuff
model and is off by up to about 0.9 N on the default run.  A run that walks
from its first tick (no ramp-in) tares on the moving model, whose error is
of the same size (docs/performance.md).

R_a (``var_cuff``, :class:`~exo_ctrl.estimation.kalman.CuffForceKalman`)
is the sensor's white noise plus what the filter does not model: the
offset left after the tare and the drift over a session, as if white,
R = σ_e² + σ_b² + σ_w² T_R with T_R = :data:`DRIFT_HORIZON_S` (σ_b, the
offset's own spread, as a bound on the tare's residual).  Their errors are
slow, so the estimate carries them.

**Limits.**  b is added to the outputs, not to the model's dynamics, so
the joint torques never check it: a ``normal`` set leaves the shank's
along force to the models (the hip torque's split is not revisited), and
the tare's residual passes into the estimate.  Putting b and the offsets
into the dynamics (a state per measured axis in the leg's model, J_eᵀ and
−J_pᵀ of its force) would let the changing posture of the gait separate
them; the tare does without.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel, leaf
from ..plant.cuffs import forces_of, isotropic_forces
from ..sensing.cuff_load import CuffSensorParams

__all__ = [
    "DRIFT_HORIZON_S",
    "INITIAL_MODEL_ERROR_N",
    "MODEL_ERROR_RATE_N_PER_SQRT_S",
    "TARE_SETTLE_S",
    "add_model_error",
    "add_to_state",
    "cuff_sensor_update",
    "cuff_variance",
    "set_cuff_noise",
]

#: T_R, the time over which R counts the sensor's drift [s] (chosen: a
#: minute, the length of a session's bout between two zeroings).
DRIFT_HORIZON_S = 60.0

#: The filter's settling after its start, before the tare's window opens [s]
#: (chosen: the estimate's error on the default run falls from some 8 N over
#: the first 10 ms to its standing level of about 0.8 N within 50 ms).
TARE_SETTLE_S = 0.05

#: σ_m, the random walk's intensity of the cuff model's error b [N/√s]
#: (chosen: on the default CT run with ``full`` sensors, by the worst
#: cuff's full-vector error, the best of 10, 30 and 100 with the default
#: offsets and of 30, 100, 300 and 1000 with the offsets at zero).
MODEL_ERROR_RATE_N_PER_SQRT_S = 30.0

#: The weight c_R of the offset and the drift in R (module docstring): 0, β carries them.
SLOW_IN_R = 0.0

#: σ_τ, the std of the joint torques' check of b per fresh sample [N·m] (module docstring).
TORQUE_CHECK_NM = 0.3

#: σ_r, the relative intensity of b's random walk [1/√s] (module docstring).
MODEL_ERROR_REL_RATE_PER_SQRT_S = 0.6

#: σ_0, the floor of b's random walk's intensity [N/√s] (module docstring).
MODEL_ERROR_FLOOR_N_PER_SQRT_S = 0.05

#: ρ, b's initial std relative to the model's force at the first fused sample [-].
INITIAL_MODEL_ERROR_REL = 0.5

#: T_b, b's correlation time [s] (module docstring).
MODEL_ERROR_TIME_S = 10.0

#: ε_τ, the std of the joint torques' check relative to the model's cuff torque at the joint [-].
TORQUE_CHECK_REL = 0.04

#: The largest std of the unread axes' model error a joint may see and still check b, as a
#: fraction of σ_τ [-] (module docstring).
CHECK_BLIND = 0.1

#: The initial std of b [N] (chosen: twice the model's RMS error on the
#: default gait without cuff sensors, some 15 N).
INITIAL_MODEL_ERROR_N = 0.2


def set_cuff_noise(state: np.ndarray, params: CuffSensorParams) -> None:
    """Set R (:func:`cuff_variance`), σ_m², σ_w², the (b, β) start and the tare's window.

    ``state``: the filter's record, its step h already set; ``params``: the cuff sensors.
    """
    h = float(state["h"][0])
    state["var_cuff"] = cuff_variance(
        params.noise_std_N, params.offset_std_N, params.drift_N_per_sqrt_s
    )
    state["var_model_rate"] = MODEL_ERROR_REL_RATE_PER_SQRT_S**2
    state["var_model_floor"] = MODEL_ERROR_FLOOR_N_PER_SQRT_S**2
    state["var_model_start"] = INITIAL_MODEL_ERROR_REL**2
    state["var_model_start_floor"] = INITIAL_MODEL_ERROR_N**2
    state["model_decay"] = math.exp(-h / MODEL_ERROR_TIME_S)
    state["var_bias_rate"] = params.drift_N_per_sqrt_s**2
    state["var_torque_check"] = TORQUE_CHECK_NM**2
    state["var_check_rel"] = TORQUE_CHECK_REL**2
    state["var_check_blind"] = (CHECK_BLIND * TORQUE_CHECK_NM) ** 2
    state["model_error"] = 0.0
    state["sensor_bias"] = 0.0
    cov = np.zeros((8, 8))
    for k in range(2):
        for a in range(params.axes):
            cov[4 + 2 * k + a, 4 + 2 * k + a] = params.offset_std_N**2
    state["bias_cov"][0] = cov
    start = round(TARE_SETTLE_S / h) if params.tared else 0
    state["tare_from"] = start
    state["tare_to"] = start + round(params.tare_s / h)
    state["steps"] = 0
    state["tared"] = False
    state["tare_n"] = 0
    state["offset"] = 0.0


def cuff_variance(noise_std_N: float, offset_std_N: float, drift_N_per_sqrt_s: float) -> float:
    """R = σ_e² + c_R (σ_b² + σ_w² T_R) [N²] (module docstring)."""
    slow = offset_std_N**2 + drift_N_per_sqrt_s**2 * DRIFT_HORIZON_S
    return noise_std_N**2 + SLOW_IN_R * slow


@leaf
def add_to_state(st, s, i, dx):
    """Add ``dx`` to component i of leg s's state (q_e, q_p: 0–3; v_e, v_p: 4–7; d: 8, 9).

    Every update of the filter (the encoders', :func:`~.kalman_step.leg_update`, and the
    cuff sensors' here) moves the state through it.
    """
    joints = st.joints[s]
    if i < 4:
        st.q[joints[i]] += dx
    elif i < 8:
        st.v[joints[i - 4]] += dx
    else:
        st.d[2 * s + i - 8] += dx


@leaf
def add_to_bias(st, s, i, d):
    """Add ``d`` to entry i of leg s's (b, β): i < 4 b of cuff 2 s + i // 2, axis i % 2; else β."""
    if i < 4:
        st.model_error[2 * s + i // 2, i % 2] += d
    else:
        st.sensor_bias[2 * s + (i - 4) // 2, i % 2] += d


@kernel
def cuff_sensor_update(st, cr, meas, split):
    """The sequential scalar updates with the cuffs' fresh readings (module docstring).

    ``st``: the filter's record (element); ``cr``: the device's cuff record
    (element); ``meas``: the readings' record
    (:data:`~exo_ctrl.sensing.cuff_load.CUFF_READING_FIELDS`); ``split``: the
    device's cuffs' switch, as :func:`~exo_ctrl.estimation.kalman_step.kalman_outputs`.
    Uses rows 0–5 of ``st.work``.
    """
    m = meas[0]
    h = st.h
    st.steps += 1
    first = False
    if not st.tared and m.fresh and st.steps > st.tare_to:
        st.tared = True  # the window closed: this sample is the first one fused
        first = True
    taring = not st.tared
    if not taring:
        decay = st.model_decay
        for s in range(2):
            B = st.bias_cov[s]
            for k in range(2):
                c = 2 * s + k
                for a in range(m.axes):
                    i = 2 * k + a
                    f = st.cuff_normal[c] if a == 0 else st.cuff_along[c]
                    f -= st.model_error[c, a]  # the model's own, at the last outputs
                    st.model_error[c, a] *= decay
                    for j in range(8):
                        B[i, j] *= decay
                        B[j, i] *= decay
                    var = (st.var_model_rate * f * f + st.var_model_floor) * h
                    if first:
                        var += st.var_model_start * f * f + st.var_model_start_floor
                    B[i, i] += var
                    B[4 + i, 4 + i] += st.var_bias_rate * h
    if not m.fresh or (taring and st.steps <= st.tare_from):
        return
    for i in range(8):
        st.q_mid[i] = st.q[i] - 0.5 * h * st.v[i]
    if split is None:
        isotropic_forces(cr, st.q_mid[:], st.v[:])
    else:
        forces_of(cr, st.q_mid[:], st.v[:])
    W = st.work
    for i in range(10):
        W[2, i] = 0.0
        W[3, i] = 0.0
    hrow, ph, pg = W[0], W[1], W[4]
    for c in range(4):
        s = c // 2
        joints = st.joints[s]
        P = st.cov[s]
        B = st.bias_cov[s]
        dx = W[2 + s]
        cc, sc = cr.cs[c], cr.cs[8 + c]
        ux = cr.along0[c, 0] * cc - cr.along0[c, 1] * sc
        uz = cr.along0[c, 1] * cc + cr.along0[c, 0] * sc
        for a in range(m.axes):
            z = m.reading[c, a]
            if not math.isfinite(z):
                continue
            if a == 0:
                ax, az, k, damp = -uz, ux, cr.k, cr.c
            else:
                ax, az, k, damp = ux, uz, cr.k_u, cr.c_u
            if taring:  # the running mean of reading − model, no update
                n = st.tare_n[c, a] + 1
                st.offset[c, a] += (z - ax * cr.f[c] - az * cr.f[4 + c] - st.offset[c, a]) / n
                st.tare_n[c, a] = n
                continue
            z -= st.offset[c, a]
            for i in range(4):
                g = joints[i]
                jn = ax * st.jd[c, g] + az * st.jd[4 + c, g]
                hrow[i] = -k * jn
                hrow[4 + i] = (0.5 * h * k - damp) * jn
            hrow[8] = 0.0
            hrow[9] = 0.0
            zhat = ax * cr.f[c] + az * cr.f[4 + c] + st.model_error[c, a] + st.sensor_bias[c, a]
            for i in range(10):
                zhat += hrow[i] * dx[i]
            ib = 2 * (c - 2 * s) + a
            for i in range(8):  # B g, g = e_b + e_β
                pg[i] = B[i, ib] + B[i, 4 + ib]
            S = st.var_cuff[a] + pg[ib] + pg[4 + ib]
            for i in range(10):
                x = 0.0
                for j in range(10):
                    x += P[i, j] * hrow[j]
                ph[i] = x
                S += hrow[i] * x
            y = (z - zhat) / S
            for i in range(8):
                add_to_bias(st, s, i, pg[i] * y)
            for i in range(8):
                for j in range(i, 8):
                    x = B[i, j] - pg[i] * pg[j] / S
                    B[i, j] = x
                    B[j, i] = x
            for i in range(10):
                d = ph[i] * y
                dx[i] += d
                add_to_state(st, s, i, d)
            for i in range(10):
                for j in range(i, 10):
                    x = P[i, j] - ph[i] * ph[j] / S
                    P[i, j] = x
                    P[j, i] = x
    if not taring:
        torque_check(st, cr, m.axes)


@kernel
def torque_check(st, cr, axes):
    """The joint torques' check of b: 0 = G_j b + ε per exoskeleton joint j (module docstring).

    ``cr.cs`` and ``st.jd`` as :func:`cuff_sensor_update` left them.  Uses rows 4, 5 of ``st.work``.
    """
    pg, gr, hx = st.work[4], st.work[5], st.work[6]
    h = st.h
    for s in range(2):
        joints = st.joints[s]
        B = st.bias_cov[s]
        P = st.cov[s]
        for j in range(2):
            g = joints[j]
            for i in range(8):
                gr[i] = 0.0
            for i in range(10):
                hx[i] = 0.0
            y = 0.0
            seen = 0.0  # the model's cuff torque at the joint
            unread = 0.0  # the variance of the unread axes' model error the joint sees
            for k in range(2):
                c = 2 * s + k
                cc, sc = cr.cs[c], cr.cs[8 + c]
                ux = cr.along0[c, 0] * cc - cr.along0[c, 1] * sc
                uz = cr.along0[c, 1] * cc + cr.along0[c, 0] * sc
                for a in range(2):
                    ax, az = (-uz, ux) if a == 0 else (ux, uz)
                    x = ax * st.jd[c, g] + az * st.jd[4 + c, g]
                    k_a, c_a = (cr.k, cr.c) if a == 0 else (cr.k_u, cr.c_u)
                    for i in range(4):  # the joint's view of the model's force, on x
                        jn = ax * st.jd[c, joints[i]] + az * st.jd[4 + c, joints[i]]
                        hx[i] -= x * k_a * jn
                        hx[4 + i] += x * (0.5 * h * k_a - c_a) * jn
                    f = ax * cr.f[c] + az * cr.f[4 + c]
                    seen += x * f
                    if a < axes:
                        gr[2 * k + a] = x
                        y -= x * st.model_error[c, a]
                    else:
                        unread += x * x * (st.var_model_start * f * f + st.var_model_start_floor)
            if unread > st.var_check_blind:
                continue  # the joint sees an unread axis's model error, which b does not carry
            S = st.var_torque_check + st.var_check_rel * seen * seen
            for i in range(8):  # x's uncertainty of that view: hxᵀ P hx (d's entries are 0)
                x = 0.0
                for n in range(8):
                    x += P[i, n] * hx[n]
                S += hx[i] * x
            for i in range(8):
                x = 0.0
                for n in range(8):
                    x += B[i, n] * gr[n]
                pg[i] = x
                S += gr[i] * x
            y /= S
            for i in range(8):
                add_to_bias(st, s, i, pg[i] * y)
            for i in range(8):
                for n in range(i, 8):
                    x = B[i, n] - pg[i] * pg[n] / S
                    B[i, n] = x
                    B[n, i] = x


@kernel
def add_model_error(st, cr, meas):
    """Add b to the outputs of :func:`~.kalman_step.kalman_outputs`: f_c + b_n n + b_u u.

    ``st``, ``cr``: the filter's and the device's cuff records (elements),
    after the outputs (``cr.cs`` at the step's midpoint); ``meas``: the
    readings' record (its ``axes``).  ``tau_ext`` stays the model's J_eᵀ f.
    σ_c (``cuff_force_std``) becomes √(σ_c² + λ_c), λ_c the largest
    eigenvalue of cuff c's 2 × 2 block of b's covariance (in the link's
    frame; b is independent of x, so the force's covariance is the sum of
    H P Hᵀ and that block turned into x, z, whose largest eigenvalue is at
    most the sum of theirs).
    """
    if not st.tared:
        return  # the tare: no update yet, b = 0, σ_c the joint torques' own
    for c in range(4):
        s = c // 2
        i = 2 * (c - 2 * s)
        B = st.bias_cov[s]
        mid = 0.5 * (B[i, i] + B[i + 1, i + 1])
        half = 0.5 * (B[i, i] - B[i + 1, i + 1])
        extra = mid + math.sqrt(half * half + B[i, i + 1] ** 2)
        st.cuff_force_std[c] = math.sqrt(st.cuff_force_std[c] ** 2 + max(extra, 0.0))
        cc, sc = cr.cs[c], cr.cs[8 + c]
        ux = cr.along0[c, 0] * cc - cr.along0[c, 1] * sc
        uz = cr.along0[c, 1] * cc + cr.along0[c, 0] * sc
        bn, bu = st.model_error[c, 0], st.model_error[c, 1]
        st.cuff_force[c, 0] += -uz * bn + ux * bu
        st.cuff_force[c, 1] += ux * bn + uz * bu
        st.cuff_normal[c] += bn
        st.cuff_along[c] += bu
