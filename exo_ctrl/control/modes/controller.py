r"""Interaction modes: guidance, transparent and assist-as-needed, behind the one interface.

Each mode is a :class:`~exo_ctrl.control.base.TickController` (plan and sensor
readings in, drive voltages out) built on the device's own models (the
exoskeleton URDF it holds, the drive's datasheet): never the plant's.  All
three share the **free command**, the voltage that makes the exoskeleton
carry itself and follow the patient's push:

.. math::

    τ_{free} = n(q, \dot q) + b\,\dot q + f_c \tanh(\dot q / ε) + K_f\,\hat τ_{int} + F(φ),
    \qquad U_{free} = \frac{R\,τ_{free}}{k_t\,η^{s}} + \frac{i_G}{k_E}\dot q,

- n(q, q̇): the exoskeleton's gravity, Coriolis and centrifugal torques
  (Pinocchio's ``nonLinearEffects`` on the device's exoskeleton model, in
  place); b, f_c: its URDF joint
  damping and friction (ε: :data:`~exo_ctrl.model.FRICTION_SMOOTHING_RAD_S`);
- the drive's own dynamics: its back-EMF (i_G / k_E) q̇ (208 N·m·s/rad of
  damping with the default drive if left alone), q̇ here the encoder's
  difference through a first-order filter of ``speed_filter_hz`` (150 Hz:
  the sensors' 30 Hz speed lags 5 ms, and 208 N·m·s/rad × 5 ms is an
  inertia of 1.1 kg·m² the patient would feel), and its
  gearbox efficiency η^s, s = sign(τ) tanh(q̇ / ω_η), as
  :meth:`~exo_ctrl.plant.motor.MotorBank.voltage_for`;
- inertia: by force feedback on the ESTIMATED interaction torque
  τ̂_int = Σ J_cᵀ f̂_c (``readings.cuff_force_est`` through the cuff lever
  arms of the device's exoskeleton model, :class:`~exo_ctrl.estimation.cuff_geometry.CuffGeometry`):
  with M q̈ = τ_int + K_f τ_int the patient feels the exoskeleton's
  inertia (links and reflected rotor inertia) divided by 1 + K_f, and the
  interaction force falls by that factor (no acceleration is measured);
- F(φ): the assist-as-needed support (``aan`` only).

The modes (``mode`` of :class:`~exo_ctrl.control.modes.params.ModeParams`):

- ``transparent`` (patient-in-charge): U = U_free with F = 0, K_f per
  joint for the run's estimator (:data:`~exo_ctrl.control.modes.params.FORCE_GAINS`:
  hip 14, knee 10 with the Kalman filter; 10 with the momentum observer);
  the force feedback acts on τ̂_int with a lead, τ̂_int + λ T_L r, r the
  rate of τ̂_int (its difference through a first-order low-pass of
  ``force_lead_filter_hz``), λ rising from 0 to 1 over
  ``force_lead_ramp_s`` from the mode's start, T_L the estimate's lag
  (:data:`~exo_ctrl.control.modes.params.FORCE_LEADS`: 15 ms with the
  Kalman filter, none with the observer); and the Kalman filter's σ_d is
  raised to 30 N·m/√s while it runs (:meth:`InteractionController.tune_estimator`):
  the patient in charge changes their torques at the gait's rate (the
  measurements: :class:`~exo_ctrl.control.modes.params.ModeParams`).
- ``guidance`` G ∈ [0, 1]: U = G U_track + (1 − G) U_free, U_track the
  tracking controller's command (PD, CT or QP).  In torque,
  τ = G (k_t/R)(k_p e + k_d ė − (i_G/k_E) q̇) + (1 − G) τ_free (+ G τ_ff for
  CT): the tracking impedance, its back-EMF damping included, scaled by G
  around the plan, and the free share by 1 − G.  G = 1 gives U_track
  exactly (1·U + 0·U_free: bit-equal), G = 0 gives the free command
  (transparent's law with guidance's own K_f, 10, and the filter's own σ_d).
  For 0 < G < 1 the force feedback acts on τ̂_int through a first-order
  low-pass of ``force_filter_hz`` (ω_f = 100 rad/s by default),
  K_f ω_f/(s + ω_f) τ̂_int: the loop's bandwidth is the mode's own, not
  the estimator's (below).
- ``aan`` (assist-as-needed, Emken et al. 2007): U = U_soft + U_free with
  K_f = 0, U_soft a soft PD on the plan (``aan_kp``, ``aan_kd``) and the
  support F(φ) per phase bin of the plan's gait period, learned cycle by
  cycle from the tracking error e = q* − q:

  .. math::  F_{k+1}(φ) = f\,F_k(φ) + g\,\bar e_k(φ),\qquad 0 ≤ f < 1,

  ē_k(φ) the mean error over the bin's ticks in cycle k; a bin is updated
  when the plan leaves it, and the support a tick applies is its bin's
  from the cycles before.  Support rises while the patient fails to follow
  and fades by f per cycle (time constant −1/ln f cycles) once the error is
  gone.  Outside the gait's periodic rows (the ramps) the support is zero
  and nothing is learned.

**Why guidance filters its force feedback.**  The lag of a first-order
filter turns part of the rendered spring into damping: (1 + K' ω_f/(s +
ω_f))⁻¹ ≈ (1 + s/ω_f)/(1 + K'), K' = (1 − G) K_f, below (1 + K') ω_f.  The
momentum observer has that lag built in (100 rad/s), the Kalman filter
does not; with the filter the two estimators give the same guidance forces
(second by second within 10 % + 2 N).  Fed the Kalman estimate unfiltered,
the loop stays bounded too (healthy active patient, 1.0 s, 0.30 m, at G =
0.25: the 8th second's RMS cuff force 1.07× the 2nd's, the same phase of
the patient's 6 s beat with the plan); it grew (2.4×, at 5–6 Hz) only
while the patient model's reflex damping acted 60 ms late
(:mod:`exo_ctrl.plant.patient_active`).  Transparent mode has no spring
for the lag to damp, only the rendered inertia, which the lag turns into
negative damping, so it is left unfiltered.
``tests/control/test_guidance_force_loop.py``.

All per-tick arithmetic is one compiled kernel (:func:`mode_command`),
plus one Pinocchio call (gravity) and, for guidance and aan, the tracking
controller's own compiled tick.

Reference:
    Emken JL, Benitez R, Reinkensmeyer DJ (2007). Human-robot cooperative
    movement training: learning a novel sensory motor transformation during
    walking with robotic assistance-as-needed. J NeuroEng Rehabil 4:8.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin

from ..._jit import check, kernel, record
from ...estimation.cuff_geometry import GEOMETRY_FIELDS, CuffGeometry
from ...exceptions import InvalidParameter
from ...model import FRICTION_SMOOTHING_RAD_S, BodyModel
from ...plan.kinematics import JointTrajectory
from ...plan.rows import plan_row
from ...plant.drive import MotorParams
from ...plant.motor import drive_model, steady_voltage
from ...sensing.readings import SensorReadings
from ..base import COMMAND_FIELDS, CommandCounters, PDGains
from ..pd import PDController
from .params import ModeParams

__all__ = ["MODE_FIELDS", "InteractionController", "mode_command"]

_CODES = {"guidance": 1, "transparent": 2, "aan": 3}

#: The modes' part of the record (after COMMAND_FIELDS): the mode code, G,
#: K_f; the drive model (R/k_t [Ω·A/(N·m)], i_G/k_E [V·s/rad], ln η,
#: ω_η [rad/s]); the exoskeleton's damping [N·m·s/rad] and friction [N·m];
#: the cuff geometry; the plan's row rule; aan's f, g [N·m/rad], its bin of
#: the last tick, error sum and count in it, completed cycles and support
#: level (RMS of F over the table [N·m]); what the last tick computed:
#: τ̂_int, τ_free, the support applied [N·m], U_free [V]; guidance's force
#: loop low-pass: its step weight 1 − exp(−ω_f Δt) (1: none) and its output
#: (transparent: with the lead) [N·m]; transparent's lead: on (any T_L > 0),
#: T_L per joint [s], the rate filter's step weight, τ̂_int of the last tick
#: [N·m] and its filtered rate [N·m/s], ticks since the start and the ramp's
#: length [ticks].
MODE_FIELDS: list[tuple[Any, ...]] = [
    ("mode", np.int64),
    ("guidance", np.float64),
    ("force_gain", np.float64, (4,)),
    ("drive", np.float64, (4,)),
    ("damping", np.float64, (4,)),
    ("friction", np.float64, (4,)),
    *GEOMETRY_FIELDS,
    ("lead", np.int64),
    ("period", np.int64),
    ("tail", np.int64),
    ("forget", np.float64),
    ("learn", np.float64, (4,)),
    ("bin", np.int64),
    ("err_sum", np.float64, (4,)),
    ("err_count", np.int64),
    ("cycles", np.int64),
    ("support_rms", np.float64),
    ("tau_int_est", np.float64, (4,)),
    ("tau_free", np.float64, (4,)),
    ("tau_support", np.float64, (4,)),
    ("u_free", np.float64, (4,)),
    ("speed_alpha", np.float64),
    ("dt", np.float64),
    ("q_prev", np.float64, (4,)),
    ("speed", np.float64, (4,)),
    ("started", np.int64),
    ("force_alpha", np.float64),
    ("tau_int_lp", np.float64, (4,)),
    ("force_lead_on", np.int64),
    ("force_lead_s", np.float64, (4,)),
    ("force_lead_alpha", np.float64),
    ("tau_int_prev", np.float64, (4,)),
    ("tau_int_rate", np.float64, (4,)),
    ("force_lead_ticks", np.int64),
    ("force_lead_ramp", np.int64),
]


class InteractionController(CommandCounters):
    """An interaction mode (module docstring) behind the controller interface.

    Args:
        mode: ``"guidance"``, ``"transparent"`` or ``"aan"``.
        params: the modes' parameters.
        plan: the joint plan (its rows as the tracking controller's).
        exo: the exoskeleton model the DEVICE holds.
        motor: the drive the device believes in.
        tracking: the tracking controller (guidance: blended with; None for
            the others).
        dt: the control period Δt [s] (the torque loop's integration step).
        estimator: the run's live cuff-force estimator, ``"kalman"`` or
            ``"momentum"`` (the default force gains depend on it:
            :meth:`ModeParams.force_gain_for`).

    Attributes:
        record: COMMAND_FIELDS and :data:`MODE_FIELDS`.
        support: aan's support table F, (bins, 4) [N·m] (zero for the others).
        support_history: aan's support level (RMS of F [N·m]) after each cycle.
        estimator_torque_rate_Nm_per_sqrt_s: the Kalman filter's σ_d this
            mode runs with [N·m/√s] (``transparent``:
            ``params.estimator_torque_rate_Nm_per_sqrt_s``), or None (the
            filter's own); :meth:`tune_estimator` applies it.

    """

    def __init__(
        self,
        mode: str,
        params: ModeParams,
        plan: JointTrajectory,
        exo: BodyModel,
        motor: MotorParams,
        tracking: PDController | None = None,
        dt: float = 1e-3,
        estimator: str = "kalman",
    ) -> None:
        self.name = mode
        self.plan = plan
        self.params = params
        if mode == "aan":
            tracking = PDController(plan, PDGains(kp=params.aan_kp, kd=params.aan_kd))
        self._tracking = tracking
        self.record = rec = record(COMMAND_FIELDS + MODE_FIELDS)
        s = rec[0]
        s["mode"] = _CODES[mode]
        s["guidance"] = params.guidance if mode == "guidance" else 0.0
        s["force_gain"] = 0.0 if mode == "aan" else params.force_gain_for(mode, estimator)
        self.estimator_torque_rate_Nm_per_sqrt_s = params.torque_rate_for(mode)
        s["drive"] = drive_model(motor)
        s["damping"], s["friction"] = exo.damping, exo.friction
        CuffGeometry.from_body(exo).fill(rec)
        s["lead"], s["period"], s["tail"] = plan.row_rule
        s["forget"] = params.aan_forgetting
        s["learn"] = params.aan_gain
        s["bin"] = -1
        s["dt"] = dt
        s["speed_alpha"] = 1.0 - math.exp(-2.0 * math.pi * params.speed_filter_hz * dt)
        s["force_alpha"] = 1.0
        if mode == "guidance" and 0.0 < params.guidance < 1.0:
            s["force_alpha"] = 1.0 - math.exp(-2.0 * math.pi * params.force_filter_hz * dt)
        if mode == "transparent":
            s["force_lead_s"] = params.force_lead_for(mode, estimator)
            s["force_lead_on"] = int(np.any(s["force_lead_s"] > 0.0))
            w_lead = 2.0 * math.pi * params.force_lead_filter_hz
            s["force_lead_alpha"] = 1.0 - math.exp(-w_lead * dt)
            s["force_lead_ramp"] = max(1, round(params.force_lead_ramp_s / dt))
        self.support = np.zeros((params.aan_bins if mode == "aan" else 1, 4))
        self.support_history: list[float] = []
        self._m = pin.Model(exo.model)
        self._d = self._m.createData()
        self._q_des = plan.q
        self._zero = np.zeros(4)
        self._u = rec["u_cmd"][0]
        self._aan = mode == "aan"
        if tracking is not None and hasattr(tracking, "refresh_row"):
            self.refresh_row = tracking.refresh_row

    def tune_estimator(self, estimator: object) -> None:
        """Give the run's estimator this mode's tuning: a Kalman filter's σ_d (transparent).

        The filter's :meth:`~exo_ctrl.estimation.kalman.CuffForceKalman.set_torque_rate`
        with :attr:`estimator_torque_rate_Nm_per_sqrt_s`; nothing for the
        other modes or an estimator without the term (the momentum observer).
        """
        set_rate = getattr(estimator, "set_torque_rate", None)
        if set_rate is not None and self.estimator_torque_rate_Nm_per_sqrt_s is not None:
            set_rate(self.estimator_torque_rate_Nm_per_sqrt_s)

    def command(self, k: int, sensors: SensorReadings) -> np.ndarray:
        """Drive voltages [V] for tick k: a view of ``record["u_cmd"]``.

        A non-finite angle or speed reading (a sensor fault) commands NaN volts
        and leaves the mode's state (filters, aan's table) as it was: the safety supervisor,
        which checks the readings, replaces the command and stops the device,
        as it does PD's NaN command (tools/faults.py's ``nan_reading``).

        Raises:
            InvalidParameter: readings not of 4 joint values or a cuff-force
                estimate not (4, 2), or a tick beyond the plan.

        """
        q, dq, force = sensors.q, sensors.dq, sensors.cuff_force_est
        if force is None:
            raise InvalidParameter(
                "sensors.cuff_force_est", None, "the estimated cuff forces, (4, 2) [N]"
            )
        u_track = self._zero
        if self._tracking is not None:
            u_track = self._tracking.command(k, sensors)
        g = pin.nonLinearEffects(self._m, self._d, q, dq)
        status = mode_command(
            self.record,
            k,
            u_track,
            g,
            q,
            dq,
            force,
            self.support,
            self._q_des,
        )
        if status:
            check(
                status,
                f"{type(self).__name__}.command",
                shapes={"cuff_force_est": (4, 2)},
                sensors_q=q,
                sensors_dq=dq,
                cuff_force_est=force,
            )
        if self._aan and self.record["cycles"][0] > len(self.support_history):
            self.support_history.append(float(self.record["support_rms"][0]))
        return self._u


@kernel
def _cross(rx, rz, fx, fz):  # pragma: no cover - compiled
    """R × f in the x–z plane (positive from +x towards +z)."""
    return rx * fz - rz * fx


@kernel
def mode_command(state, k, u_track, g, q, dq, f_est, support, q_des):  # pragma: no cover
    """One tick of a mode (module docstring) into ``state[0].u_cmd`` [V]; returns a status.

    ``u_track``: the tracking (guidance) or soft PD (aan) command [V];
    ``g``: the exoskeleton's gravity and velocity torques at (q, q̇) [N·m]; ``f_est``: the
    estimated cuff forces on the exoskeleton (4, 2) [N]; ``support``: aan's
    table F (bins, 4) [N·m], updated in place; ``q_des``: the plan's angles.
    """
    if q.shape[0] != 4 or dq.shape[0] != 4 or u_track.shape[0] != 4:
        return 1
    if f_est.shape[0] != 4 or f_est.shape[1] != 2:
        return 1
    s = state[0]
    for j in range(4):  # a sensor fault: NaN volts, the state kept; the supervisor stops
        if not (np.isfinite(q[j]) and np.isfinite(dq[j])):
            for i in range(4):
                s.u_cmd[i] = np.nan
            return 0
    # The joint speed for the drive's back-EMF: the encoder's difference through
    # a faster first-order filter than the sensors' (less lag, more noise).
    for j in range(4):
        if s.started == 0:
            s.speed[j] = dq[j]
        else:
            raw = (q[j] - s.q_prev[j]) / s.dt
            s.speed[j] += s.speed_alpha * (raw - s.speed[j])
        s.q_prev[j] = q[j]
    # τ̂_int = Σ J_cᵀ f̂_c per leg.
    for leg in range(2):
        sh, sk = s.sign_hip[leg], s.sign_knee[leg]
        turn = sh * q[2 * leg]
        pt = s.thigh_dir0[leg] + turn
        pk = s.knee_dir0[leg] + turn
        ps = s.shank_dir0[leg] + turn + sk * q[2 * leg + 1]
        a, l1, c = s.thigh_arm[leg], s.knee_arm[leg], s.shank_arm[leg]
        ftx, ftz = f_est[2 * leg, 0], f_est[2 * leg, 1]
        fsx, fsz = f_est[2 * leg + 1, 0], f_est[2 * leg + 1, 1]
        rsx, rsz = c * np.cos(ps), c * np.sin(ps)
        knee = _cross(rsx, rsz, fsx, fsz)
        hip = _cross(a * np.cos(pt), a * np.sin(pt), ftx, ftz) + _cross(
            l1 * np.cos(pk) + rsx, l1 * np.sin(pk) + rsz, fsx, fsz
        )
        s.tau_int_est[2 * leg] = sh * hip
        s.tau_int_est[2 * leg + 1] = sk * knee
    # The torque fed back: τ̂ with transparent's lead, τ̂ + λ T_L r (r: τ̂'s difference
    # low-passed; λ: 0 → 1 from the start), then the force loop's low-pass (weight 1: none).
    ramp = min(1.0, s.force_lead_ticks / s.force_lead_ramp) if s.force_lead_on else 0.0
    s.force_lead_ticks += s.force_lead_on
    for j in range(4):
        x = s.tau_int_est[j]
        if s.force_lead_on:
            if s.started != 0:
                raw = (x - s.tau_int_prev[j]) / s.dt
                s.tau_int_rate[j] += s.force_lead_alpha * (raw - s.tau_int_rate[j])
            s.tau_int_prev[j] = x
            x = x + ramp * s.force_lead_s[j] * s.tau_int_rate[j]
        if s.started == 0:
            s.tau_int_lp[j] = x
        else:
            s.tau_int_lp[j] += s.force_alpha * (x - s.tau_int_lp[j])
    s.started = 1
    # aan: the support of this tick's phase bin, and learning from its error.
    b = -1
    if s.mode == 3 and s.period > 0:
        row = plan_row(k, s.lead, s.period, s.tail)
        if s.lead <= row < s.lead + s.period:
            b = (row - s.lead) * support.shape[0] // s.period
        if b != s.bin:
            if s.bin >= 0 and s.err_count > 0:
                for j in range(4):
                    mean = s.err_sum[j] / s.err_count
                    support[s.bin, j] = s.forget * support[s.bin, j] + s.learn[j] * mean
                if b < s.bin:  # back to the cycle's start: one more cycle learned
                    total = 0.0
                    for i in range(support.shape[0]):
                        for j in range(4):
                            total += support[i, j] * support[i, j]
                    s.support_rms = np.sqrt(total / (4 * support.shape[0]))
                    s.cycles += 1
            s.bin = b
            s.err_count = 0
            for j in range(4):
                s.err_sum[j] = 0.0
        if b >= 0:
            s.err_count += 1
            for j in range(4):
                s.err_sum[j] += q_des[row, j] - q[j]
    dr = s.drive[:]  # a plain array: steady_voltage has one signature (exo_ctrl/_jit.py)
    blend = s.guidance
    for j in range(4):
        w = s.speed[j]
        sup = support[b, j] if b >= 0 else 0.0
        s.tau_support[j] = sup
        tau = (
            g[j]
            + s.damping[j] * w
            + s.friction[j] * np.tanh(w / FRICTION_SMOOTHING_RAD_S)
            + s.force_gain[j] * s.tau_int_lp[j]
            + sup
        )
        s.tau_free[j] = tau
        u_free = steady_voltage(tau, w, dr)
        s.u_free[j] = u_free
        if s.mode == 3:
            s.u_cmd[j] = u_track[j] + u_free
        else:
            s.u_cmd[j] = blend * u_track[j] + (1.0 - blend) * u_free
    return 0
