r"""Plausibility monitors: do the readings agree with each other, the drive model, the clock.

The limit monitor (:mod:`.monitor`) asks whether a reading is beyond its
limit; these ask whether the readings can be true.  They use only what the
device knows: the sensor readings, the voltage the supervisor sent the
drives last tick, the drive's model (:class:`~exo_ctrl.plant.MotorParams`,
its datasheet), the sensors' parameters and the command's age.  Four
channel groups, one channel per joint, their excesses written into the
monitor record's rows :data:`DRIVE` … :data:`AGE` (the limit monitor then
counts them with its own), and a fifth, the torque sensor against the
drive's current reading and the encoder (:mod:`.consistency`, row
:data:`~.consistency.CONSIST`; its state is this record's ``c_`` fields,
its limit this module's fifth row; :mod:`.tick_check` runs it), and a
sixth, a still encoder against the drive's current (:mod:`.still`, row
:data:`~.still.STILL`; its state the ``st_`` fields, its limit the sixth row):

**Drive model residual** (:data:`DRIVE`, N·m).  A drive with the voltage U
across it at the joint speed ω carries I = (U - i_G ω / k_E) / R (the
current follows with L/R ≈ 0.7 ms; the monitor steps it exactly as
:mod:`exo_ctrl.plant.motor` does, Ī below) and puts τ = η^s i_G k_m I on the
joint; the torque sensor reads τ_s = τ - i_G² J_rotor q̈.  The speed reading
is the encoder's difference through the first-order filter F of cut-off f_v
(:mod:`exo_ctrl.sensing.sensors`), so the voltage and the torque reading are
put through the same F, and the relation holds between the filtered
signals (it is linear in U, ω and τ):

.. math::

    r = F[τ_s] + i_G^2 J_{rotor}\,\frac{Δ\hat ω}{Δt}
        - η^{s} i_G k_m\,\mathrm{clip}\Bigl(\frac{F[U] - (i_G/k_E)\,\hat ω}{R}, ±I_{max}\Bigr),

(Ī in place of the clipped quotient: the tick's mean current of the exact
step driven by it), with \hat ω the speed reading, U the voltage applied over the last tick
(clipped to the supply) and s = sign(I) tanh(\hat ω / ω_η).  A frozen or stale
encoder (\hat ω → 0 while the joint moves), a drive that loses its torque (an
open phase: τ_s ≈ 0) or brakes (a short: U = 0 whatever is sent), a torque
sensor offset, drift or clipped all make |r| large.

*Threshold* :data:`DRIVE_RESIDUAL_NM` = 30 N·m.  What the model leaves out,
on the joint the speed error multiplies by the drive's back-EMF damping
D = i_G k_m (i_G / k_E) / R = 208 N·m·s/rad (default drive): the speed
filter's noise (0.005 rad/s std: 1.0 N·m std, 6 σ = 6 N·m); the half-tick
between the speed the drive saw and the reading (q̈ Δt / 2 ≤ 0.015 rad/s at
the gait's 30 rad/s²: 3 N·m); what remains of the current's lag (stepped
exactly, but driven by the filtered U)
(the PD's dU/dt ≤ 50 V/s: 0.035 V, 7 N·m); the rotor term's noise (the
speed noise over Δt times i_G² J_rotor = 0.29 kg·m²: 1.5 N·m std, 6 σ =
9 N·m) — 25 N·m together, 30 N·m with the torque sensor's filtered noise
and the efficiency's smoothing.  The default runs (PD, CT, QP, spastic)
peak at 7-17 N·m (tests/safety/test_plausibility.py).  While the model's
current (filtered or not) is at the driver's limit I_max, and for three
filter time constants after, the residual is not evaluated: the clip is not
linear, so filtering before and after it disagree (a blind spot of the
check, as during the legacy drive's saturated start).  A torque sensor
offset below 30 N·m (8 % of a 360 N·m range) is not detected by it.

**Encoder step** (:data:`JUMP`, rad).  Between two ticks the reading can
change by at most q̇_max Δt plus two quantisation steps and the noise of
two readings: limit q̇_max Δt + 2 Δq + 8 √2 σ_q (6.3e-3 rad with the
defaults).  A reading that steps further means the joint moved faster than
its speed limit or the reading is wrong (noise, a stale value that
refreshes).

**Torque sensor unchanged** (:data:`STUCK`, ticks).  With noise σ_τ =
0.2 N·m and a step of 0.01 N·m two successive readings are equal with
probability about Δτ / (2 √π σ_τ) ≈ 1.4 %; :data:`STUCK_READINGS` = 10
equal readings in a row happen by chance with probability 0.014⁹ ≈ 2e-17
per tick.  So the sensor is taken as stuck (a clipped rail, a frozen
converter) after 10 equal readings.  Off for a noise-free sensor
(``torque_noise_std_Nm = 0``: its reading may stay equal legitimately);
counted in samples when the sensors are read slower than the control rate.

**Command age** (:data:`AGE`, s).  Every command must be the one computed
from this tick's readings: its age, the time since those readings, is 0 on
time and at least one period Δt when the control task overran.  The limit
is half a period, between the two; the simulated clock has no jitter (set
it from the measured jitter on hardware).
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import Status, kernel, record
from ..plant import MotorParams
from ..plant.drive import EFFICIENCY_SMOOTHING_RAD_S
from ..sensing import CurrentSensorParams, SensorParams
from .consistency import CONSISTENCY_FIELDS, consistency_limit, gear_efficiency, init_consistency
from .still import STILL_FIELDS, init_still, still_limit

__all__ = [
    "AGE",
    "DRIVE",
    "DRIVE_RESIDUAL_NM",
    "JUMP",
    "PLAUSIBILITY_FIELDS",
    "STUCK",
    "STUCK_READINGS",
    "plausibility",
    "plausibility_limits",
    "plausibility_record",
]

#: The monitor record's rows of the plausibility groups (after the limit monitor's seven).
DRIVE, JUMP, STUCK, AGE = 7, 8, 9, 10

#: Largest drive model residual |r| of a healthy drive and sensors [N·m] (module docstring).
DRIVE_RESIDUAL_NM = 30.0

#: Equal torque readings in a row taken as a stuck sensor (module docstring).
STUCK_READINGS = 10

#: The plausibility monitors' state (numpy dtype fields; one element).  Drive
#: model: ``alpha`` the speed filter's α, ``dt`` Δt [s], ``kt`` i_G k_m
#: [N·m/A], ``kb`` i_G/k_E [V·s/rad], ``inv_r`` 1/R [1/Ω], ``i_max`` [A],
#: ``u_max`` [V], ``lneta`` ln η, ``inv_w_eta`` 1/ω_η [s/rad], ``j_rotor``
#: i_G² J_rotor [kg·m²]; state per joint: ``u_prev`` the voltage sent last
#: tick [V], ``u_f``, ``tau_f`` F[U] [V] and F[τ_s] [N·m], ``w_prev`` the last
#: speed reading [rad/s], ``q_prev`` the last angle [rad], ``tau_prev`` the last
#: torque reading [N·m], ``stuck`` equal torque readings in a row, ``residual``
#: r [N·m] (the last tick's); ``started``.
PLAUSIBILITY_FIELDS = [
    *(
        (name, np.float64)
        for name in (
            "alpha",
            "dt",
            "kt",
            "kb",
            "inv_r",
            "i_max",
            "u_max",
            "lneta",
            "inv_w_eta",
            "j_rotor",
            "eps",
            "phi",
            "settle",
        )
    ),
    *(
        (name, np.float64, (4,))
        for name in (
            "u_prev",
            "u_f",
            "tau_f",
            "w_prev",
            "q_prev",
            "tau_prev",
            "stuck",
            "residual",
            "i_m",
            "blind",
        )
    ),
    ("started", np.bool_),
    *CONSISTENCY_FIELDS,  # the torque-sensor consistency check's (.consistency)
    *STILL_FIELDS,  # the still encoder against the current (.still)
]


def plausibility_limits(
    motor: MotorParams,
    sensors: SensorParams,
    dt: float,
    speed_limit: np.ndarray,
    current: CurrentSensorParams | None = None,
) -> np.ndarray:
    """The limits of the six groups, (6 groups, 4 joints), in the monitor record's units.

    Args:
        motor: the drive (datasheet).
        sensors: the sensors' parameters.
        dt: control period Δt [s].
        speed_limit: the joint speed limits q̇_max [rad/s], (4,).
        current: the drives' current sensors (their datasheet; None: the default driver's).

    Returns:
        Rows DRIVE [N·m], JUMP [rad], STUCK [readings], AGE [s] (module docstring),
        the torque-sensor consistency's CONSIST [N·m] (:mod:`.consistency`) and
        the still encoder's STILL [A] (:mod:`.still`).
        The drive residual's limit is :data:`DRIVE_RESIDUAL_NM` at Δt ≤ 1 ms and
        grows ∝ Δt beyond (the half-tick speed offset and the plant's implicit
        step grow with it): 300 N·m at 100 Hz, beyond any drive's torque, so
        the check is in effect off at such coarse rates.

    """
    jump = (
        np.asarray(speed_limit, dtype=float) * dt
        + 2.0 * sensors.encoder_resolution_rad
        + 8.0 * math.sqrt(2.0) * sensors.encoder_noise_std_rad
    )
    stuck = math.inf
    if sensors.torque_noise_std_Nm > 0.0:
        period = dt if sensors.sample_rate_hz is None else max(1.0 / sensors.sample_rate_hz, dt)
        stuck = STUCK_READINGS * math.ceil(period / dt - 1e-9)
    big = np.finfo(float).max
    return np.stack(
        (
            np.full(4, DRIVE_RESIDUAL_NM * max(dt / 1e-3, 1.0)),
            jump,
            np.full(4, min(stuck, big)),
            np.full(4, 0.5 * dt),
            consistency_limit(motor, sensors, dt, current),
            still_limit(motor, sensors, dt, current),
        )
    )


def plausibility_record(motor: MotorParams, sensors: SensorParams, dt: float) -> np.ndarray:
    """The monitors' record for a drive, sensors and control period (not started)."""
    state = record(PLAUSIBILITY_FIELDS)
    s = state[0]
    s["alpha"] = 1.0 - math.exp(-2.0 * math.pi * sensors.velocity_filter_hz * dt)
    if sensors.velocity == "true":
        s["alpha"] = 1.0  # the speed is not filtered: neither are U and τ
    s["dt"] = dt
    s["kt"] = motor.torque_per_amp_Nm_per_A
    s["kb"] = motor.back_emf_V_per_rad_s
    s["inv_r"] = 1.0 / motor.resistance_ohm
    s["i_max"] = motor.current_limit_A
    s["u_max"] = motor.supply_voltage_V
    s["lneta"] = motor.log_efficiency
    s["inv_w_eta"] = 1.0 / EFFICIENCY_SMOOTHING_RAD_S
    s["j_rotor"] = motor.reflected_inertia_kgm2
    x = dt / motor.electrical_time_constant_s
    s["eps"] = math.exp(-x)
    s["phi"] = -math.expm1(-x) / x
    # Three time constants of the filter F (95 % settled), in ticks, at least one.
    s["settle"] = max(math.ceil(3.0 / (2.0 * math.pi * sensors.velocity_filter_hz * dt)), 1)
    init_consistency(state, motor, sensors, dt)
    init_still(state, motor, sensors, dt)
    return state


@kernel
def plausibility(q, dq, tau, u_cmd, age_s, state, mon):
    """One tick of the plausibility monitors (module docstring).

    Args:
        q: joint angle readings, (4,) [rad].
        dq: joint speed readings, (4,) [rad/s].
        tau: joint torque readings, (4,) [N·m].
        u_cmd: the command of this tick, (4,) [V] (kept as the voltage sent,
            unless the supervisor replaces it: :attr:`u_prev` is then overwritten).
        age_s: the command's age [s].
        state: the record of :data:`PLAUSIBILITY_FIELDS`.
        mon: the monitor record (:data:`~exo_ctrl.safety.monitor.MONITOR_FIELDS`):
            rows DRIVE … AGE of ``excess`` are written, from its ``limit`` rows.

    Returns:
        ``Status.WRONG_LENGTH`` (nothing written) when an input is not of
        length 4, else ``Status.OK``.  A joint whose readings are not all
        finite is skipped (its excesses 0; the limit monitor flags it) and
        its state kept.

    """
    if q.shape[0] != 4 or dq.shape[0] != 4 or tau.shape[0] != 4 or u_cmd.shape[0] != 4:
        return Status.WRONG_LENGTH.value
    s = state[0]
    m = mon[0]
    e, lim = m.excess, m.limit
    a = s.alpha
    for j in range(4):
        e[AGE, j] = age_s - lim[AGE, j]
        u = min(max(s.u_prev[j], -s.u_max), s.u_max)  # sent last tick, applied since
        if math.isfinite(u_cmd[j]):
            s.u_prev[j] = u_cmd[j]
        qj, wj, tj = q[j], dq[j], tau[j]
        if not (math.isfinite(qj) and math.isfinite(wj) and math.isfinite(tj)):
            e[DRIVE, j] = e[JUMP, j] = e[STUCK, j] = 0.0
            continue
        if not s.started:
            g = gear_efficiency(s.lneta, s.inv_w_eta, tj, wj)
            s.i_m[j] = tj / (g * s.kt)
            s.u_f[j] = s.i_m[j] / s.inv_r + s.kb * wj  # r = 0 to start
            s.tau_f[j] = tj
            s.w_prev[j] = wj
            s.q_prev[j] = qj
            s.tau_prev[j] = math.nan
            s.residual[j] = 0.0
            e[DRIVE, j] = e[JUMP, j] = e[STUCK, j] = -1.0
            continue
        s.u_f[j] += a * (u - s.u_f[j])
        s.tau_f[j] += a * (tj - s.tau_f[j])
        acc = (wj - s.w_prev[j]) / s.dt
        # The current's exact step (exo_ctrl.plant.motor) driven by the filtered voltage.
        i_inf = (s.u_f[j] - s.kb * wj) * s.inv_r
        i_raw = (u - s.kb * wj) * s.inv_r
        if abs(i_raw) >= s.i_max or abs(i_inf) >= s.i_max:
            s.blind[j] = s.settle  # the driver may hold the current: not linear
        d0 = s.i_m[j] - i_inf
        i_m = min(max(i_inf + d0 * s.phi, -s.i_max), s.i_max)
        s.i_m[j] = min(max(i_inf + d0 * s.eps, -s.i_max), s.i_max)
        g = gear_efficiency(s.lneta, s.inv_w_eta, i_m, wj)
        r = s.tau_f[j] + s.j_rotor * acc - g * s.kt * i_m
        s.residual[j] = r
        if s.blind[j] > 0.0:
            s.blind[j] -= 1.0
            e[DRIVE, j] = -1.0
        else:
            e[DRIVE, j] = abs(r) - lim[DRIVE, j]
        e[JUMP, j] = abs(qj - s.q_prev[j]) - lim[JUMP, j]
        s.stuck[j] = s.stuck[j] + 1.0 if tj == s.tau_prev[j] else 0.0
        e[STUCK, j] = s.stuck[j] - lim[STUCK, j]
        s.w_prev[j] = wj
        s.q_prev[j] = qj
        s.tau_prev[j] = tj
    s.started = True
    return Status.OK.value
