r"""The Kalman filter's update with the instrumented cuffs' readings.

With cuff force sensors (:mod:`exo_ctrl.sensing.cuff_load`) the filter of
:mod:`.kalman` fuses, after the encoders' update of each tick, every fresh
sample of every measured axis as a scalar measurement of its leg's state
x = (q_e, q_p, v_e, v_p, d) ∈ ℝ¹⁰.  The model's part of the measured
component of cuff c on axis a (a the link's normal n, or its direction u) is

    aᵀ f_c(q − ½ h v, v),

the device's cuff force at the step's midpoint, as the filter's outputs
(:func:`~exo_ctrl.estimation.kalman_step.kalman_outputs`) and the sensor's
truth (the plant's force over its last step).  Linearised (J_c: rows c and
4 + c of J_Δ, the prediction's; 𝒦_c aᵀ = k_a aᵀ and likewise 𝒞_c for the
link-frame axes a ∈ {n, u}, k_n = ``k``, k_u = ``k_u``):

    h = [−k_a aᵀ J_c,  (½ h k_a − c_a) aᵀ J_c,  0 0],

(the ½ h k_a from the midpoint q − ½ h v), and the components are taken
one after another (a sequential update, exact for independent noises).

**The cuff model's error and the sensors' biases.**  The filter's cuffs
are the device's model (the published ones by default); the true cuffs are
not.  With the two patient angles per leg as the only free positions, the
model's four force components of a leg lie on a two-dimensional family,
which the true forces leave: no state x reproduces them.  So each measured
axis carries a model-error force b_ca [N], added to the model's force in
the outputs (f_c + b_n n + b_u u).  The sensor adds its bias β_ca (its
offset and drift, :mod:`exo_ctrl.sensing.cuff_load`), which the filter
carries too, as the datasheet describes it: a random walk of intensity σ_w
(``drift_N_per_sqrt_s``) from N(0, σ_b²) (``offset_std_N``).  The reading is

    z = aᵀ f_c(q − ½ h v, v) + b_ca + β_ca + e,   e ~ N(0, σ_e²),

so R = σ_e² (the offset and the drift are states now).  Per leg the
measured axes' (b, β) ∈ ℝ⁸ (b of the thigh's n, u and the shank's n, u,
then β likewise; an axis the set does not read keeps b = β = 0 and no
variance) has a covariance B of its own, decoupled from x (its
cross-covariance with x is dropped, as a Schmidt filter drops a nuisance
state's).  One scalar update takes x, b and β with the same innovation
(g = e_b + e_β, the reading's view of (b, β)):

    ẑ = aᵀ f_c + h δx + b + β,   y = z − ẑ,   S = h P hᵀ + gᵀ B g + σ_e²,
    x ← x + P hᵀ y / S,   (b, β) ← (b, β) + B g y / S,
    P ← P − P hᵀ h P / S,   B ← B − B g gᵀ B / S,

δx the leg's change since the forces were evaluated (so ẑ follows the
earlier components' corrections to first order), P and B kept symmetric by
writing their upper triangles to both halves.

*What tells b from β.*  The readings see b + β only: the split needs more.

1. **The joint torques** (:mod:`.kalman_check`).  The encoders' update of
   the exoskeleton's dynamics (τ_s an input) holds x where the model's
   forces give the torques the exoskeleton's joints see, Σ_c J_e,cᵀ f_c,
   so the model's error in what a joint sees is nil: per leg and
   exoskeleton joint j, after each fresh sample's updates,

       0 = Σ_(c,a read) g_jca b_ca + ε_j,   g_jca = aᵀ J_e,c e_j,
       ε_j ~ N(0, σ_τ² + ε_τ² τ_j² + h_jᵀ P h_j),

   J_e,c e_j the exoskeleton joint's column of rows c and 4 + c of J_Δ
   (the prediction's), τ_j = Σ_(c,a) g_jca aᵀ f_c the model's cuff torque
   at the joint (a model's error grows with its load), h_j = Σ_(c,a) g_jca
   h_ca the joint's view of f on x (x's own uncertainty of it).  The knee
   sees the shank's normal force; the hip the thigh's normal, the shank's
   normal and its along force, through levers that turn with the knee
   (:mod:`.cuff_geometry`).  So over the gait's changing posture the
   readings fix b + β, the check G b and constant β on those axes become
   observable.  A joint that also sees an axis the set does not read (the
   hip with ``normal`` sensors: the shank's along force) checks nothing:
   that axis's model error, which no b carries, would pass into β.  The
   rule: the joint checks when Σ_(c,a unread) g_jca² (ρ² (aᵀ f_c)² + σ_00²)
   ≤ (κ σ_τ)², κ = :data:`CHECK_BLIND`.
2. **The model's force.**  No joint sees the thigh's along force (it
   passes through the hip's axis: g = 0 at every posture), so there b and β
   are told apart by their priors alone.  The cuff model's error scales
   with its force (a stiffness off by a fraction puts the force off by that
   fraction; the patient's cuffs scatter ±2 × 20 %,
   :mod:`exo_ctrl.plant.cuff_scatter`), so b is sized by the model's force
   f_ca = aᵀ f_c: its initial variance, at the first fused sample,
   ρ² f_ca² + σ_00², and between ticks an Ornstein–Uhlenbeck process,

       b ← e^(−h/T_b) b,   B_bb ← e^(−h/T_b) B_bb e^(−h/T_b) + (σ_r² f_ca² + σ_0²) h,

   (the rows and columns of b scaled, B's β block grows by σ_w² h, β is
   held).  On the default gait the thigh's along force is under 1 N, so
   b's std there stays a fraction of σ_b and a constant reading goes to β;
   on a thigh's or shank's normal force (some 50 N) b moves at some
   30 N/√s, as fast as the gait's model error, and the check (1) separates.

An axis the set does not read keeps b = 0: its component is the model's
(moved only through x).  A reading that is not finite (an axis the set does
not read, a failed sensor) is skipped; a held sample (``fresh`` false) is
not used again.

**The tare.**  On request (``tare_s`` > 0; off by default,
:mod:`exo_ctrl.sensing.cuff_load` says why) the device zeroes its sensors
while it stands at the start, with the cuffs strapped on: over the window of the filter's steps
(t_s, t_s + T_t], t_s = :data:`TARE_SETTLE_S` (its start's transient) and
T_t the sensors' ``tare_s``, it takes no update but averages, per measured
axis, each fresh sample less the model's component at the same point,

    ô_ca = mean(z − aᵀ f_c(q − ½ h v, v)),

and from the first fresh sample after the window on updates with z − ô_ca
(until then b = β = 0, b's prior is not yet set and σ_c is the joint
torques' own); β then carries what the tare left of the offset.  The
filter there runs on the encoders and the joint torques alone, so ô carries
the standing estimate's error: the joint torques fix the shank's normal
force, and the standing model the thigh's along force, to well under 0.1 N;
the hip torque's split between the thigh's normal and the shank's along
force comes from the cuff model and is off by up to about 0.9 N on the
default run.

**Limits.**  b and β are not in the model's dynamics and (b, β) is
decoupled from x, so the check takes x's estimate of what a joint sees as
right within its noise; a model whose error is slow in what the joints see
(ε_j is taken white per sample) leaves a share of it in β.  With ``normal``
sensors the hip does not check (rule above): the thigh's normal offset stays
in b (as without β) and the shank's along force is the model's.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel, leaf
from ..plant.cuffs import forces_of, isotropic_forces
from ..sensing.cuff_load import CuffSensorParams
from .kalman_check import bias_update, downdate, gain, torque_check

__all__ = [
    "INITIAL_MODEL_ERROR_N",
    "TARE_SETTLE_S",
    "add_model_error",
    "add_to_state",
    "cuff_sensor_update",
    "set_cuff_noise",
]

#: The filter's settling after its start, before the tare's window opens [s]
#: (chosen: the estimate's error on the default run falls from some 8 N over
#: the first 10 ms to its standing level of about 0.8 N within 50 ms).
TARE_SETTLE_S = 0.05

#: σ_r, the intensity of b's random walk per newton of the model's force
#: [1/√s] (chosen: 0.6, some 30 N/√s on the default gait's 50 N thigh force,
#: the intensity the constant walk had before the bias states).
MODEL_ERROR_REL_RATE_PER_SQRT_S = 0.6

#: σ_0, the floor of b's walk [N/√s] (chosen: the sensors' drift's 0.05:
#: b may move on a force the model holds at zero only as fast as β).
MODEL_ERROR_FLOOR_N_PER_SQRT_S = 0.05

#: ρ, b's initial std per newton of the model's force at the first fused
#: sample [-] (chosen: 0.5, against the cuffs' scatter of ±2 × 20 %).
INITIAL_MODEL_ERROR_REL = 0.5

#: σ_00, the floor of b's initial std [N] (chosen: 0.2 N, a fifth of σ_b,
#: so a force the model holds at zero leaves a constant reading to β).
INITIAL_MODEL_ERROR_N = 0.2

#: T_b, b's correlation time [s] (chosen: 10 s, the longest of 1, 3 and 10 s,
#: with which the ``normal`` set's thighs, where β cannot be told from b,
#: matched the constant walk to 0.01 %; it bounds b's std on a zero force).
MODEL_ERROR_TIME_S = 10.0

#: σ_τ, the joint torques' check's std per fresh sample [N·m] (chosen with
#: ε_τ: the worst cuff's full-vector error over the default run, sensor seed
#: 6, a cuff-scatter seed, the knee 2 cm off and point 113 of
#: tools/load_held.py; 0.2–2 N·m alone tried).
TORQUE_CHECK_NM = 0.3

#: ε_τ, the check's std per newton-metre of the model's cuff torque at the
#: joint [-] (chosen: 0.04 of 0.02 and 0.04, as σ_τ).
TORQUE_CHECK_REL = 0.04

#: κ, the largest std of the unread axes' model error a joint may see and
#: still check b, in σ_τ [-] (chosen: 0.1; the knee sees the shank's along
#: force through some 2e-4 m of rounding, 0.002 N·m, the hip through 0.43 m).
CHECK_BLIND = 0.1


def set_cuff_noise(state: np.ndarray, params: CuffSensorParams) -> None:
    """Set R = σ_e², b's and β's noises, β's prior, the torques' check and the tare's window.

    ``state``: the filter's record, its step h already set; ``params``: the cuff sensors.
    """
    h = float(state["h"][0])
    state["var_cuff"] = params.noise_std_N**2
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


@kernel
def cuff_sensor_update(st, cr, meas, split):
    """The sequential scalar updates with the cuffs' fresh readings (module docstring).

    ``st``: the filter's record (element); ``cr``: the device's cuff record
    (element); ``meas``: the readings' record
    (:data:`~exo_ctrl.sensing.cuff_load.CUFF_READING_FIELDS`); ``split``: the
    device's cuffs' switch, as :func:`~exo_ctrl.estimation.kalman_step.kalman_outputs`.
    Uses rows 0–4 of ``st.work`` (and :func:`~.kalman_check.torque_check` rows 4–6).
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
            S = gain(P, hrow, ph, 10, S)
            y = (z - zhat) / S
            bias_update(st, s, B, pg, y, S)
            for i in range(10):
                d = ph[i] * y
                dx[i] += d
                add_to_state(st, s, i, d)
            downdate(P, ph, S, 10)
    if not taring:
        torque_check(st, cr, m.axes)


@kernel
def add_model_error(st, cr):
    """Add b to the outputs of :func:`~.kalman_step.kalman_outputs`: f_c + b_n n + b_u u.

    ``st``, ``cr``: the filter's and the device's cuff records (elements),
    after the outputs (``cr.cs`` at the step's midpoint).  ``tau_ext`` stays
    the model's J_eᵀ f; β, the sensors', is not added.  σ_c
    (``cuff_force_std``) becomes √(σ_c² + λ_c), λ_c the largest eigenvalue
    of cuff c's 2 × 2 block of B's b (in the link's frame; b is independent
    of x, so the force's covariance is the sum of H P Hᵀ and that block
    turned into x, z, whose largest eigenvalue is at most the sum of theirs).
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
