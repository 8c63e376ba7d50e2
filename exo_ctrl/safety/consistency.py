r"""Torque-sensor consistency: the joint torque sensor against the drive's current and the encoder.

The drift of a joint torque sensor is the fault that matters most where the
device follows its torque sensors: in ``transparent`` mode the controller
drives the estimated interaction torque to zero, so a sensor that reads δ
too much makes the drive push the patient with about δ (about δ/0.45 m at
a shank cuff, δ/0.39 m at a thigh cuff).  The device measures the same
torque a second way.  Between the motor and the link the rotor is the
only body (the torque sensor sits between the gearbox and the link,
:mod:`exo_ctrl.plant.plant`), so with the drive's current reading I (the
driver's mean over the last tick, :mod:`exo_ctrl.sensing.current_sensor`)
and the datasheet (:class:`~exo_ctrl.plant.MotorParams` as the device holds
it, never the plant's drive):

.. math::

    J_{eff}\,\ddot q = η^{s}\, i_G k_m\, I - τ_s,\qquad
    J_{eff} = i_G^2 J_{rotor} + \tfrac12 D\,Δt,\quad D = \frac{i_G k_m\, i_G}{k_E\,R},

η^s the gearbox efficiency (s = sign(I) tanh(ω/ω_η), :mod:`exo_ctrl.plant.drive`),
τ_s the torque reading.  The ½ D Δt is the readings' timing: the current
reading is the tick's mean, the torque reading its end, and over the tick
the back-EMF current changes by (i_G/k_E) q̈ Δt / R, whose mean lags its
end by half the tick (fitted on the default runs without it: 0.099 of
the predicted 0.104 kg·m²).  The device's own generalised-momentum
observer (:mod:`exo_ctrl.estimation.observer`) uses its URDF dynamics and
τ_s; run on the current-based torque instead, the two observers' external
torques differ by exactly this relation (the links' dynamics cancel), so
the check is the momentum observer of the rotor, with no acceleration:

.. math::

    z_k = z_{k-1} + Δt\,(τ_{m,k} - τ_{s,k} + r_{k-1}),\qquad
    r_k = K\,(J_{eff}\,ω_k - z_k),

τ_m = η^s i_G k_m I, ω_k = (q_k − q_{k−1})/Δt the encoder's own
difference (the mean speed over the tick the current was averaged over),
K = :data:`OBSERVER_GAIN_PER_S`.  For a sensor that reads τ_s + δ(t),
r → K/(s + K) δ: the offset through a first-order lag of 1/K = 33 ms.

**Threshold**: |r| is compared with B_k + T (the channel's value is
|r| − B_k, its limit T).

- T = :data:`NOISE_SIGMAS` σ_r, the readings' white noise through the
  observer (:func:`consistency_threshold`): the encoder's noise and
  quantisation σ_q² + Δq²/12 through the impulse response of r to q (K
  J_eff / Δt times the second difference), the current's (σ_I² +
  ΔI²/12) (i_G k_m/η)² and the torque sensor's σ_τ² + Δτ²/12, each
  through the lag, (KΔt)²/(1 − (1 − KΔt)²).  Default sensors: 0.41 N·m
  (encoder) and 0.04 N·m (current and torque), T = 2.5 N·m.
- B_k, the datasheet's uncertainty, through the same lag (so that a
  step of the torque does not outrun its bound): ε |τ_m|, ε =
  :data:`TORQUE_MODEL_TOLERANCE` = 10 % on i_G k_m η (a choice: the
  catalogue gives η as 70–85 % over load and temperature, so a device
  that takes η from its datasheet, or calibrates it at one load, is
  within about ±10 %; the torque constant's and the current sensor's gain
  errors are a few per cent more), plus the gear factor's span over the
  speed's uncertainty, |η^{s(ω+δω)} − η^{s(ω−δω)}| i_G k_m |I| with δω
  = 6 σ_ω (σ_ω = √2 σ_q,eff / Δt, 0.21 rad/s by default): near a speed
  reversal the gearbox passes from η to 1/η, and the encoder's speed
  cannot say exactly when.

On the default runs (PD, CT, QP; tracking; guidance, transparent, aan
and path with the active patient; the belt; body-weight support) |r| − B
peaks at 1.2 N·m, 1.3 N·m over 12 s of the active patient in each mode,
within T (tests/safety/test_consistency.py).

**Persistence.**  A channel is violated after :data:`PERSIST_TICKS` = 3
ticks in a row beyond B + T.  A joint-sensor frame that arrives a tick
late (held while the current reading is fresh) puts K J_eff ω̂ (12 N·m
per rad/s) into r for exactly two ticks, beyond T at gait speeds: the
sensors' own sample grid does that once in a default run, at 7.984 s
(its next sample time accumulates rounding past the tick's), which a
single tick's excess would turn into a stop of every run longer than 8 s.

**Detection.**  A drift at ρ [N·m/s] from a residual r_0 (|r_0| ≤ B + T
while healthy) makes r ≥ ρ (t − 1/K) − |r_0| (the lag's response to a
ramp), so it is detected by

.. math::  t_d ≤ \frac{2 (B + T)}{ρ} + \frac{1}{K} + (P - 1)\,Δt

(:func:`detection_bound_s`): 0.17–0.21 s for the campaign's 100 N·m/s in
transparent mode (B ≤ 4–6 N·m before the detection), which caught it
after 55–90 ms, the offset then 6–9 N·m.  A bias step b beyond B + T +
|r_0| is detected within −ln(1 − 2(B + T)/b)/K + (P − 1) Δt.

**What it leaves out.**  With compliant joints (:mod:`exo_ctrl.plant.compliance`)
the rotor is a body of its own behind a spring and the sensor reads the
spring: the relation holds for the rotor's acceleration, which the link
encoder does not see (|r| − B reached 3.4, 4.8 and 7.2 N·m against T =
2.5 N·m on the default PD, CT and transparent runs); the supervisor then
turns this check off as it does the drive model's.  The timing terms are
modelled for one reading of each sensor per tick at Δt ≤ 1 ms; the check
tripped on healthy default runs with the joint sensors read at 250 Hz
(the torque reading held while the current is fresh: 2.50 over 2.48
N·m), at Δt = 10 ms (1.52 over its T of 1.29 N·m) and at 2.5 ms with
three plant steps per tick (1.69 over 1.47 N·m), so it is off (its limit
DBL_MAX, :func:`consistency_limit`) in those cases; and with a noise-free
encoder and torque sensor, where T (0.20 N·m, the current sensor's noise
alone) is below what the model leaves out (|r| − B up to 0.44 N·m in
transparent mode).  The current sensor's noise is that of the drives'
current sensors (:class:`~exo_ctrl.sensing.CurrentSensorParams`, their
datasheet, which the supervisor is given: ``current_sensor``).  A joint
whose readings are not all finite is skipped and restarted from its next
finite reading (the limit monitor flags it).
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel
from ..plant import MotorParams
from ..sensing import CurrentSensorParams, SensorParams

__all__ = [
    "CONSIST",
    "CONSISTENCY_FIELDS",
    "NOISE_SIGMAS",
    "OBSERVER_GAIN_PER_S",
    "PERSIST_TICKS",
    "TORQUE_MODEL_TOLERANCE",
    "consistency",
    "consistency_limit",
    "consistency_threshold",
    "detection_bound_s",
    "gear_efficiency",
    "init_consistency",
]

#: The monitor record's row of the consistency group (after the four plausibility rows).
CONSIST = 11

#: The rotor observer's gain K [1/s]: the drift's lag 1/K = 33 ms, the
#: encoder's noise K J_eff σ_ω ≈ 0.4 N·m std (module docstring).
OBSERVER_GAIN_PER_S = 30.0

#: ε: the relative uncertainty of the drive torque i_G k_m η I (module docstring).
TORQUE_MODEL_TOLERANCE = 0.10

#: Standard deviations of the white-noise part of r in the limit T.
NOISE_SIGMAS = 6.0

#: Ticks in a row |r| must exceed B + T (module docstring, "Persistence").
PERSIST_TICKS = 3

#: The consistency check's part of the plausibility record (fields prefixed
#: ``c_``): ``c_gain`` K [1/s], ``c_step`` 1 − exp(−K Δt) of the bound's
#: lag, ``c_jeff`` J_eff [kg·m²], ``c_dw`` δω [rad/s], ``c_eps`` ε; per
#: joint ``c_q`` the last angle reading [rad], ``c_z`` z [N·m·s], ``c_r`` r
#: [N·m], ``c_bound`` B [N·m], ``c_width`` and ``c_torque`` the lagged
#: gear-span and |τ_m| terms [N·m], ``c_fresh`` (1: restart the joint at
#: its next finite reading), ``c_count`` ticks in a row beyond B + T.
CONSISTENCY_FIELDS = [
    *((name, np.float64) for name in ("c_gain", "c_step", "c_jeff", "c_dw", "c_eps")),
    *(
        (name, np.float64, (4,))
        for name in ("c_q", "c_z", "c_r", "c_bound", "c_width", "c_torque", "c_fresh", "c_count")
    ),
]


def _effective_inertia(motor: MotorParams, dt: float) -> float:
    """J_eff = i_G² J_rotor + ½ D Δt [kg·m²] (module docstring)."""
    damping = motor.torque_per_amp_Nm_per_A * motor.back_emf_V_per_rad_s / motor.resistance_ohm
    return motor.reflected_inertia_kgm2 + 0.5 * damping * dt


def _encoder_std(sensors: SensorParams) -> float:
    """σ_q,eff = √(σ_q² + Δq²/12) [rad]: the encoder's noise and quantisation."""
    return math.hypot(sensors.encoder_noise_std_rad, sensors.encoder_resolution_rad / math.sqrt(12))


def consistency_threshold(
    motor: MotorParams,
    sensors: SensorParams,
    dt: float,
    current: CurrentSensorParams | None = None,
) -> float:
    """T = NOISE_SIGMAS σ_r: the white-noise part of r [N·m] (module docstring).

    Args:
        motor: the drive's datasheet.
        sensors: the joint sensors' parameters (read every tick).
        dt: control period Δt [s].
        current: the current sensors' parameters (None: the default driver's).

    """
    current = current if current is not None else CurrentSensorParams()
    gain, jeff = OBSERVER_GAIN_PER_S, _effective_inertia(motor, dt)
    a = 1.0 - gain * dt
    # r's response to a unit encoder reading at tick 0: c (δ_0 − 2 δ_1 + δ_2) into
    # r_k = a r_{k−1} + in_k, then a^k; Σ h² in closed form for the geometric tail.
    c = gain * jeff / dt
    h0, h1 = c, a * c - 2.0 * c
    h2 = a * h1 + c
    var_q = h0 * h0 + h1 * h1 + h2 * h2 / (1.0 - a * a)
    var = var_q * _encoder_std(sensors) ** 2
    current_var = current.noise_std_A**2 + current.resolution_A**2 / 12.0
    torque_var = sensors.torque_noise_std_Nm**2 + sensors.torque_resolution_Nm**2 / 12.0
    kt_max = motor.torque_per_amp_Nm_per_A / motor.gear_efficiency  # braking: 1/η
    var += (gain * dt) ** 2 / (1.0 - a * a) * (current_var * kt_max**2 + torque_var)
    return NOISE_SIGMAS * math.sqrt(var)


def consistency_limit(
    motor: MotorParams,
    sensors: SensorParams,
    dt: float,
    current: CurrentSensorParams | None = None,
) -> np.ndarray:
    """The group's limit row, (4,) [N·m]: T, or DBL_MAX (off) where the check does not hold.

    Off: Δt > 1 ms, joint sensors read slower than every tick, or an
    ideal encoder and torque sensor (module docstring, "What it leaves out").
    """
    off = np.full(4, np.finfo(float).max)
    slow = sensors.sample_rate_hz is not None and sensors.sample_rate_hz * dt < 1.0 - 1e-9
    quiet = _encoder_std(sensors) == 0.0 and sensors.torque_noise_std_Nm == 0.0
    if dt > 1e-3 * (1.0 + 1e-9) or slow or quiet:
        return off
    return np.full(4, consistency_threshold(motor, sensors, dt, current))


def detection_bound_s(
    rate_Nm_s: float, bound_Nm: float, threshold_Nm: float, dt: float = 1e-3
) -> float:
    """t_d ≤ 2 (B + T)/ρ + 1/K + (P − 1) Δt: the latest detection of a drift of ρ [N·m/s] [s].

    Args:
        rate_Nm_s: the drift's rate ρ [N·m/s] (> 0).
        bound_Nm: the largest model bound B over the detection [N·m].
        threshold_Nm: the limit T [N·m].
        dt: control period Δt [s] (P = :data:`PERSIST_TICKS`).

    """
    persist = (PERSIST_TICKS - 1) * dt
    return 2.0 * (bound_Nm + threshold_Nm) / rate_Nm_s + 1.0 / OBSERVER_GAIN_PER_S + persist


def init_consistency(
    state: np.ndarray, motor: MotorParams, sensors: SensorParams, dt: float
) -> None:
    """Fill the check's constants into the record ``state`` (not started: every joint fresh)."""
    s = state[0]
    s["c_gain"] = OBSERVER_GAIN_PER_S
    s["c_step"] = -math.expm1(-OBSERVER_GAIN_PER_S * dt)
    s["c_jeff"] = _effective_inertia(motor, dt)
    s["c_dw"] = NOISE_SIGMAS * math.sqrt(2.0) * _encoder_std(sensors) / dt
    s["c_eps"] = TORQUE_MODEL_TOLERANCE
    s["c_fresh"] = 1.0


@kernel
def gear_efficiency(lneta: float, inv_w: float, current: float, omega: float) -> float:
    """η^s, s = sign(I) tanh(ω/ω_η) (:mod:`exo_ctrl.plant.drive`)."""
    th = math.tanh(omega * inv_w)
    s = th if current > 0.0 else (-th if current < 0.0 else 0.0)
    return math.exp(s * lneta)


@kernel
def consistency(q, dq, tau, current, state, mon):  # pragma: no cover - compiled
    """One tick of the check (module docstring): row CONSIST of ``mon``'s ``excess``.

    Args:
        q: joint angle readings, (4,) [rad].
        dq: joint speed readings, (4,) [rad/s] (a joint's start only).
        tau: joint torque readings, (4,) [N·m].
        current: drive current readings, (4,) [A].
        state: the plausibility record (its ``c_`` fields, and ``dt``,
            ``kt``, ``lneta``, ``inv_w_eta``).
        mon: the monitor record: excess = |r| − B − T (T its limit row CONSIST).

    The caller checks the lengths (all 4).  A joint whose readings are not
    all finite gets excess 0 and restarts at its next finite reading, its
    previous angle taken as if it had moved at its speed reading.

    """
    s = state[0]
    m = mon[0]
    e, lim = m.excess, m.limit
    dt = s.dt
    for j in range(4):
        qj, tj, ij = q[j], tau[j], current[j]
        if not (math.isfinite(qj) and math.isfinite(tj) and math.isfinite(ij)):
            e[CONSIST, j] = 0.0
            s.c_fresh[j] = 1.0
            continue
        if s.c_fresh[j] != 0.0:
            w0 = dq[j] if math.isfinite(dq[j]) else 0.0
            s.c_q[j] = qj - w0 * dt
            s.c_z[j] = s.c_jeff * w0
            s.c_r[j] = s.c_width[j] = s.c_torque[j] = s.c_count[j] = 0.0
            s.c_fresh[j] = 0.0
        w = (qj - s.c_q[j]) / dt
        s.c_q[j] = qj
        torque = gear_efficiency(s.lneta, s.inv_w_eta, ij, w) * s.kt * ij
        span = abs(
            gear_efficiency(s.lneta, s.inv_w_eta, ij, w + s.c_dw)
            - gear_efficiency(s.lneta, s.inv_w_eta, ij, w - s.c_dw)
        )
        s.c_z[j] += dt * (torque - tj + s.c_r[j])
        r = s.c_gain * (s.c_jeff * w - s.c_z[j])
        s.c_r[j] = r
        s.c_width[j] += s.c_step * (span * s.kt * abs(ij) - s.c_width[j])
        s.c_torque[j] += s.c_step * (abs(torque) - s.c_torque[j])
        bound = s.c_width[j] + s.c_eps * s.c_torque[j]
        s.c_bound[j] = bound
        excess = abs(r) - bound - lim[CONSIST, j]
        s.c_count[j] = s.c_count[j] + 1.0 if excess > 0.0 else 0.0
        e[CONSIST, j] = excess if s.c_count[j] >= PERSIST_TICKS else min(excess, -1e-12)
