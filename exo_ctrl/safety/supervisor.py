r"""Safety supervisor: limit monitors and a controlled stop.

The supervisor sits between the controller and the drives.  Every control
tick it checks what the device can measure — joint angles, speeds and torques
from the sensors, cuff forces (measured, or estimated from the joint torques),
drive currents — and the controller's command against :class:`SafetyLimits`.
While nothing is wrong it returns the controller's command unchanged (and
allocates nothing).

**Controlled stop.**  On the first violation, on a non-finite reading or at
the emergency-stop time, it stops the gait:

1. ``"stopping"``: the posture measured at the stop, q_h, is to be held.  The
   hold command is gravity compensation plus a PD on the posture,

   .. math::

       U_{hold} = \frac{R}{i_G k_m}\,\bigl(g_{exo}(q_h) + g_{patient}(q_h)\bigr)
                + k_p (q_h - q) - k_d \dot q,

   the first term being the motor model at zero speed
   (:meth:`MotorBank.voltage_for` with ω = 0) applied to the generalised
   gravity torques of both bodies at the hold posture (the patient's legs
   hang in the cuffs, so the drives carry them too; the patient's joint
   angles are taken equal to the exoskeleton's, as the computed-torque
   feedforward does).  The command is ramped linearly from the last normal
   command U_0 to the hold command over ``ramp_s``,
   U = U_0 + α (U_hold - U_0), α = (t - t_stop) / ramp_s, so the drive
   torque has no step (a volt across the 0.1 Ω winding is 10 A, 170 N·m).
   U_0 still carries the back-EMF of the planned speed, so the joints coast
   on a little before the PD pulls them back (0.085 rad at most for the
   default e-stop at 0.5 s, back within 0.015 rad by the end of the ramp).
2. ``"holding"``: U = U_hold.  The hold has failed if a joint leaves the
   posture by more than ``hold_tolerance_rad`` or moves faster than its
   speed limit (checked from the end of the ramp on); then
3. ``"power_cut"``: U = 0.  Zero volts across the motor terminals
   short-circuits the winding through the driver bridge, so the back-EMF
   drives a braking current: the drive becomes a viscous brake of
   D = i_G k_m (i_G / k_E) / R ≈ 330 N·m·s/rad per joint with the default
   drive, and the legs sink slowly under gravity (τ_g / D: below 0.1 rad/s
   in the default scenario once the motion at the cut has died out, within
   about 0.1 s) instead of falling.  (A driver that opens its bridge would
   give no braking; not modelled.)

Every violation and every state change is an event dict
``{"t", "kind", "quantity", "value", "limit", "message"}`` in
:attr:`SafetySupervisor.events` (kind ``"violation"``, ``"estop"`` or
``"state"``).  Only the first violation starts the stop; later ones are
logged at most once per ``event_interval_s`` per monitored quantity.

**Non-finite readings** never reach the drives: a NaN or infinity in the
sensors, the cuff forces, the currents or the command is a violation; the
hold posture is the last finite reading of each joint, and while readings
stay non-finite the PD acts only on the joints whose readings are finite
(the others get gravity compensation alone).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from .. import _validate as v
from .._jit import kernel
from ..exceptions import InvalidParameter
from ..model.body import CUFF_NAMES, JOINT_NAMES, BodyModel
from ..plant.motor import MotorParams
from ..sensing.readings import SensorReadings

__all__ = ["STATES", "SafetyLimits", "SafetySupervisor"]

#: Supervisor states; the index is :attr:`SafetySupervisor.state_code`.
STATES = ("normal", "stopping", "holding", "power_cut")

#: ISO/TS 15066:2016 Annex A, Table A.2, maximum permissible quasi-static
#: contact force for the body regions "thighs and knees" (220 N) and "lower
#: legs" (130 N), per cuff in CUFF_NAMES order [N].
ISO_TS_15066_CUFF_FORCE_N = (220.0, 130.0, 220.0, 130.0)

#: Default current monitor threshold as a multiple of the driver's current limit.
CURRENT_LIMIT_FACTOR = 1.1


@dataclass(frozen=True)
class SafetyLimits:
    """What the supervisor allows.  Every field has a default with its source.

    Attributes:
        cuff_force_N: maximum permissible force per cuff (magnitude of the
            sagittal force), CUFF_NAMES order (thigh, shank, thigh, shank)
            [N].  Default: ISO/TS 15066:2016 Annex A, Table A.2, quasi-static
            contact, "thighs and knees" 220 N, "lower legs" 130 N.
        cuff_force_factor: derating applied to ``cuff_force_N`` [-], in
            (0, 1].  Default 1.0 (not derated), a choice: the ISO values are
            pain-onset thresholds for clamping by a small contact surface,
            whereas a cuff spreads its load over a strap of ~100 cm², so the
            pressure, the other half of the ISO criterion, stays far below its
            limit; and the default passive run already needs 107 N on the
            shank cuffs (CT; 97 N with PD), so the ×0.5 often used for
            continuous contact (65 N) would stop every default run.  At ×1.0
            the passive runs keep a 20 % margin and the default spastic
            patient (≈ 180 N) is stopped.  Lower it for a stricter policy.
        rom_margin_rad: the joint range allowed is the intersection of the
            exoskeleton's and the patient's URDF ``<limit lower upper>``,
            shrunk by this margin at both ends [rad].  Default 0.05 (≈ 3°),
            a choice: room to stop before the mechanical end stop.
        position_lower_rad: explicit lower joint limits, JOINT_NAMES order
            [rad] (None: from the URDFs as above).
        position_upper_rad: explicit upper joint limits [rad] (None: URDFs).
        speed_limit_rad_s: joint speed limit [rad/s], a number or 4 (None:
            the smaller of the exoskeleton's and the patient's URDF
            ``<limit velocity>``, 6 rad/s with the default URDFs).
        current_limit_A: drive current monitor threshold [A] (None:
            ``CURRENT_LIMIT_FACTOR`` = 1.1 × the driver's current limit
            ``MotorParams.current_limit_A``).  The driver clips the current
            at its limit, so in simulation this monitor trips only when set
            below that limit (e.g. a motor's thermal rating); on hardware it
            catches a failed current loop (the 10 % allows the overshoot of a
            healthy current loop).

    Non-finite readings are always a violation (no setting).

    Raises:
        InvalidParameter: a value is not finite, not positive where a limit
            must be, has the wrong length, or a lower limit is not below the
            upper one.

    """

    cuff_force_N: tuple[float, ...] | float = ISO_TS_15066_CUFF_FORCE_N
    cuff_force_factor: float = 1.0
    rom_margin_rad: float = 0.05
    position_lower_rad: tuple[float, ...] | None = None
    position_upper_rad: tuple[float, ...] | None = None
    speed_limit_rad_s: tuple[float, ...] | float | None = None
    current_limit_A: float | None = None

    def __post_init__(self) -> None:
        force = v.per_item("cuff_force_N", self.cuff_force_N, "N", CUFF_NAMES, what="cuff")
        for cuff, f in zip(CUFF_NAMES, force, strict=True):
            v.positive(f"cuff_force_N[{cuff}]", f, "N")
        object.__setattr__(self, "cuff_force_N", force)
        factor = v.positive("cuff_force_factor", self.cuff_force_factor)
        if factor > 1.0:
            raise InvalidParameter("cuff_force_factor", self.cuff_force_factor, "in (0, 1]")
        v.non_negative("rom_margin_rad", self.rom_margin_rad, "rad")
        for name in ("position_lower_rad", "position_upper_rad"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, v.per_item(name, value, "rad", JOINT_NAMES))
        lo, hi = self.position_lower_rad, self.position_upper_rad
        if lo is not None and hi is not None:
            for joint, a, b in zip(JOINT_NAMES, lo, hi, strict=True):
                if not a < b:
                    raise InvalidParameter(
                        f"position_upper_rad[{joint}]", b, f"> position_lower_rad ({a:g} rad)"
                    )
        if self.speed_limit_rad_s is not None:
            speed = v.per_item("speed_limit_rad_s", self.speed_limit_rad_s, "rad/s", JOINT_NAMES)
            for joint, s in zip(JOINT_NAMES, speed, strict=True):
                v.positive(f"speed_limit_rad_s[{joint}]", s, "rad/s")
            object.__setattr__(self, "speed_limit_rad_s", speed)
        if self.current_limit_A is not None:
            v.positive("current_limit_A", self.current_limit_A, "A")

    @property
    def cuff_limit_N(self) -> np.ndarray:
        """Effective cuff force limits ``cuff_force_N × cuff_force_factor`` [N], (4,)."""
        return np.array(self.cuff_force_N) * self.cuff_force_factor


# Channels of the per-tick excess vector (value - limit; > 0 or NaN is a violation).
# Groups of 4: cuff force, upper angle, lower angle, speed, current, torque
# sensor, voltage command.
_N_CHANNELS = 28
# The monitor kernel's buffer: the excess of the channels, then the last
# normal tick's posture and command, then the channels' limits.
_W_Q_LAST, _W_U_LAST, _W_LIMIT = 28, 32, 36


class SafetySupervisor:
    """Monitors the limits and performs the controlled stop (module docstring).

    Args:
        limits: the limits.
        exo: the exoskeleton model (limits and gravity).
        patient: the patient model (limits and gravity; None: exoskeleton only).
        motor: the drive as configured (``plant.motor_params``; its current
            limit and the motor model for the hold voltage).
        dt: control period [s].
        estop_at_s: emergency-stop time [s] (None: no e-stop).
        use_estimate: the cuff forces given to :meth:`step` are estimates
            (only changes the event wording).
        ramp_s: duration of the ramp to the hold command [s] (0: switch at once).
        hold_tolerance_rad: largest posture error during the hold [rad].
        hold_kp: hold PD proportional gain [V/rad] (default: the PD gain, 100).
        hold_kd: hold PD derivative gain [V·s/rad] (default: the PD gain, 2).
        event_interval_s: after the stop, a violation of the same channel is
            logged at most once per this interval [s].

    Attributes:
        state: ``"normal"``, ``"stopping"``, ``"holding"`` or ``"power_cut"``.
        state_code: 0, 1, 2, 3 (same order), for logging.
        events: the event dicts, in time order.
        stop_time_s: time of the stop [s] (None while normal).
        hold_posture_rad: the posture held, (4,) [rad] (NaN while normal).
        hold_voltage_gravity_V: gravity-compensation voltages of the hold, (4,) [V].
        q_lower, q_upper, speed_limit, current_limit, cuff_limit: the
            resolved limits, (4,) each [rad, rad, rad/s, A, N].

    Raises:
        InvalidParameter: a bad argument (named in the message).

    """

    def __init__(
        self,
        limits: SafetyLimits,
        exo: BodyModel,
        patient: BodyModel | None,
        motor: MotorParams,
        dt: float,
        estop_at_s: float | None = None,
        use_estimate: bool = False,
        ramp_s: float = 0.2,
        hold_tolerance_rad: float = 0.1,
        hold_kp: float = 100.0,
        hold_kd: float = 2.0,
        event_interval_s: float = 0.5,
    ) -> None:
        self.dt = v.positive("dt", dt, "s")
        self.estop_at_s = (
            None if estop_at_s is None else v.non_negative("estop_at_s", estop_at_s, "s")
        )
        self.ramp_s = v.non_negative("ramp_s", ramp_s, "s")
        self.hold_tolerance_rad = v.positive("hold_tolerance_rad", hold_tolerance_rad, "rad")
        self.hold_kp = v.non_negative("hold_kp", hold_kp, "V/rad")
        self.hold_kd = v.non_negative("hold_kd", hold_kd, "V·s/rad")
        self.event_interval_s = v.non_negative("event_interval_s", event_interval_s, "s")
        self.limits = limits
        self.use_estimate = bool(use_estimate)
        self._motor = motor
        self._bodies = [(pin.Model(b.model), b) for b in (exo, patient) if b is not None]
        self._resolve_limits(limits, exo, patient, motor)
        self._estop = math.inf if self.estop_at_s is None else self.estop_at_s
        # The monitor kernel's buffer: the excess of every channel over its
        # limit, the last normal tick's posture and command, and the limit of
        # every channel as the kernel subtracts it (lower - q = (-q) - (-lower)).
        self._work = np.zeros(_W_LIMIT + _N_CHANNELS)
        self._excess = self._work[:_N_CHANNELS]
        self._q_last = self._work[_W_Q_LAST : _W_Q_LAST + 4]
        self._u_last = self._work[_W_U_LAST : _W_U_LAST + 4]
        self._q_last[:] = np.nan
        big = np.finfo(float).max
        self._limit = self._work[_W_LIMIT:]
        self._limit[:] = np.concatenate(
            (
                self._cuff_limit_sq,
                self.q_upper,
                -self.q_lower,
                self.speed_limit,
                self.current_limit,
                np.full(4, big),
                np.full(4, big),
            )
        )
        self._u_start = np.zeros(4)
        self._u = np.zeros(4)
        self._e = np.zeros(4)
        self._w = np.zeros(4)
        self._last_logged: dict[str, float] = {}
        self.hold_posture_rad = np.full(4, np.nan)
        self.hold_voltage_gravity_V = np.zeros(4)
        self.stop_time_s: float | None = None
        self.state = "normal"
        self.state_code = 0
        self.events: list[dict[str, Any]] = []

    # ------------------------------------------------------------------ set-up

    def _resolve_limits(
        self, limits: SafetyLimits, exo: BodyModel, patient: BodyModel | None, motor: MotorParams
    ) -> None:
        bodies = [b for b in (exo, patient) if b is not None]
        lo = np.max([b.position_limits[0] for b in bodies], axis=0) + limits.rom_margin_rad
        hi = np.min([b.position_limits[1] for b in bodies], axis=0) - limits.rom_margin_rad
        if limits.position_lower_rad is not None:
            lo = np.array(limits.position_lower_rad)
        if limits.position_upper_rad is not None:
            hi = np.array(limits.position_upper_rad)
        for joint, a, b in zip(JOINT_NAMES, lo, hi, strict=True):
            if not a < b:
                if limits.position_upper_rad is not None:
                    name, value = "position_upper_rad", limits.position_upper_rad
                elif limits.position_lower_rad is not None:
                    name, value = "position_lower_rad", limits.position_lower_rad
                else:
                    name, value = "rom_margin_rad", limits.rom_margin_rad
                raise InvalidParameter(
                    name,
                    value,
                    f"such that {joint} keeps a range (lower {a:g} rad, upper {b:g} rad)",
                )
        self.q_lower, self.q_upper = lo, hi
        if limits.speed_limit_rad_s is None:
            self.speed_limit = np.min([b.velocity_limit for b in bodies], axis=0)
        else:
            self.speed_limit = np.array(limits.speed_limit_rad_s)
        i_lim = limits.current_limit_A
        if i_lim is None:
            i_lim = CURRENT_LIMIT_FACTOR * motor.current_limit_A
        self.current_limit = np.full(4, float(i_lim))
        self.cuff_limit = limits.cuff_limit_N
        self._cuff_limit_sq = self.cuff_limit**2
        force = "estimated cuff force" if self.use_estimate else "cuff force"
        self._channels: list[tuple[str, str, np.ndarray]] = []  # (quantity, unit, limits)
        for group, unit, lim in (
            (force, "N", self.cuff_limit),
            ("angle", "rad", self.q_upper),
            ("angle", "rad", self.q_lower),
            ("speed", "rad/s", self.speed_limit),
            ("current", "A", self.current_limit),
            ("torque sensor", "N·m", np.zeros(4)),
            ("voltage command", "V", np.zeros(4)),
        ):
            names = CUFF_NAMES if group == force else JOINT_NAMES
            for i, name in enumerate(names):
                self._channels.append((f"{group} {name}", unit, lim[i : i + 1]))

    # ------------------------------------------------------------------ per tick

    def normal_at(self, t: float) -> bool:
        """Whether the supervisor is in its normal state at time t [s] (no stop, e-stop not due)."""
        return self.state_code == 0 and t < self._estop

    def step(
        self,
        k: int,
        t: float,
        sensors: SensorReadings,
        cuff_force: np.ndarray,
        current_A: np.ndarray,
        u_cmd: np.ndarray,
    ) -> np.ndarray:
        """Check the tick's readings; return the voltages to apply [V], (4,).

        Args:
            k: control tick index.
            t: time of the tick [s].
            sensors: the sensor readings the controller saw.
            cuff_force: cuff forces on the exoskeleton (x, z), (4, 2) [N]
                (measured or estimated, see ``use_estimate``).
            current_A: drive currents, (4,) [A] (mean over the last step).
            u_cmd: the controller's voltage command, (4,) [V].

        Returns:
            ``u_cmd`` itself while normal; otherwise the supervisor's own
            buffer (the stop command), overwritten by the next call.

        """
        del k
        normal = self.normal_at(t)
        q, dq, tau = sensors.q, sensors.dq, sensors.tau
        f, current, u = cuff_force, current_A, u_cmd
        if not (
            type(q) is type(dq) is type(tau) is type(f) is type(current) is type(u) is np.ndarray
        ):
            q, dq, tau, current, u = v.arrays(
                (4,), sensors_q=q, sensors_dq=dq, sensors_tau=tau, current_A=current, u_cmd=u
            )
            f = v.array("cuff_force", f, (4, 2))
        worst = _monitor_kernel(f, q, dq, tau, current, u, normal, self._work)
        if worst < 0.0:
            v.refuse_shapes(
                (4,), sensors_q=q, sensors_dq=dq, sensors_tau=tau, current_A=current, u_cmd=u
            )
            v.refuse_shapes((4, 2), cuff_force=f)
        if normal and worst <= 0.0:
            return u_cmd
        if self.state_code == 0:
            self._start_stop(t, sensors, u_cmd, worst)
        elif not worst <= 0.0:
            self._log_violations(t)
        return self._stop_command(t, sensors, clean=worst == worst)

    # ------------------------------------------------------------------ stop

    def _start_stop(
        self, t: float, sensors: SensorReadings, u_cmd: np.ndarray, worst: float
    ) -> None:
        if not worst <= 0.0:
            cause = self._log_violations(t)[0]
        else:
            cause = self._event(
                t,
                "estop",
                "time",
                float(t),
                float(self._estop),
                f"emergency stop at t = {t:.4f} s",
            )
        self.stop_time_s = float(t)
        q = np.asarray(sensors.q, dtype=float)
        finite = np.isfinite(q)
        self.hold_posture_rad = np.where(finite, q, self._q_last)
        u = np.asarray(u_cmd, dtype=float)
        self._u_start[:] = np.where(np.isfinite(u), u, self._u_last)
        if not np.all(np.isfinite(self.hold_posture_rad)):
            self._set_state(t, "power_cut", "no finite posture reading to hold")
            return
        self.hold_voltage_gravity_V = self._gravity_voltage(self.hold_posture_rad)
        self._set_state(t, "stopping", f"controlled stop: {cause['message']}")

    def _gravity_voltage(self, q: np.ndarray) -> np.ndarray:
        """U = R (g_exo(q) + g_patient(q)) / (i_G k_m): holding torque at zero speed [V]."""
        tau = np.zeros(4)
        for model, body in self._bodies:
            data = model.createData()
            g = pin.computeGeneralizedGravity(model, data, body.to_model_q(q))
            tau += g[body.q_index]
        return self._motor.resistance_ohm * tau / self._motor.torque_per_amp_Nm_per_A

    def _stop_command(self, t: float, sensors: SensorReadings, clean: bool) -> np.ndarray:
        """The stop command [V]; ``clean``: every reading of the tick is finite."""
        u, e, w = self._u, self._e, self._w
        if self.state_code == 3:
            u.fill(0.0)
            return u
        np.subtract(self.hold_posture_rad, sensors.q, out=e)
        np.copyto(w, sensors.dq)
        if not clean:  # no PD on a joint whose reading is not finite
            e[~np.isfinite(e)] = 0.0
            w[~np.isfinite(w)] = 0.0
        if self.state_code == 2 and self._hold_failed(t, e, w):
            u.fill(0.0)
            return u
        # U_hold = U_g + k_p (q_h - q) - k_d q̇
        np.multiply(e, self.hold_kp, out=u)
        np.multiply(w, self.hold_kd, out=w)
        np.subtract(u, w, out=u)
        np.add(u, self.hold_voltage_gravity_V, out=u)
        if self.state_code == 1:
            elapsed = t - self.stop_time_s + 1e-9 * self.dt  # rounding of t = k Δt
            alpha = elapsed / self.ramp_s if self.ramp_s > 0.0 else 1.0
            if alpha >= 1.0:
                self._set_state(t, "holding", "ramp done")
            else:  # U = U_0 + α (U_hold - U_0)
                np.subtract(u, self._u_start, out=u)
                np.multiply(u, alpha, out=u)
                np.add(u, self._u_start, out=u)
        return u

    def _hold_failed(self, t: float, e: np.ndarray, speed: np.ndarray) -> bool:
        err = np.abs(e)
        fast = np.abs(speed) - self.speed_limit
        i = int(np.argmax(err))
        if err[i] > self.hold_tolerance_rad:
            joint = JOINT_NAMES[i]
            self._event(
                t,
                "violation",
                f"hold posture error {joint}",
                float(err[i]),
                self.hold_tolerance_rad,
                f"hold failed: {joint} is {err[i]:.4g} rad from the hold posture "
                f"(tolerance {self.hold_tolerance_rad:g} rad)",
            )
        else:
            i = int(np.argmax(fast))
            if not fast[i] > 0.0:
                return False
            joint = JOINT_NAMES[i]
            self._event(
                t,
                "violation",
                f"hold speed {joint}",
                float(abs(speed[i])),
                float(self.speed_limit[i]),
                f"hold failed: {joint} moves at {abs(speed[i]):.4g} rad/s "
                f"(limit {self.speed_limit[i]:g} rad/s)",
            )
        self._set_state(t, "power_cut", "hold failed: drive voltages set to zero")
        return True

    # ------------------------------------------------------------------ events

    def _log_violations(self, t: float) -> list[dict[str, Any]]:
        """Log the violated channels (after the stop: those not logged within the interval).

        Rate-limited per quantity (a non-finite angle violates both its bounds).
        """
        logged: list[dict[str, Any]] = []
        for c in np.flatnonzero(~(self._excess <= 0.0)):
            quantity = self._channels[c][0]
            last = self._last_logged.get(quantity, -math.inf)
            if last == t or (self.state_code != 0 and t - last < self.event_interval_s):
                continue
            self._last_logged[quantity] = t
            logged.append(self._violation_event(t, int(c)))
        return logged

    def _violation_event(self, t: float, c: int) -> dict[str, Any]:
        quantity, unit, lim = self._channels[c]
        limit = float(lim[0])
        excess = float(self._excess[c])
        group = c // 4
        if group >= 5 or not math.isfinite(excess):  # 5, 6: finiteness channels
            return self._event(
                t,
                "violation",
                quantity,
                None,
                None,
                f"{quantity} is not finite at t = {t:.4f} s",
            )
        if group == 0:  # cuff: excess is |f|² - limit²
            value = math.sqrt(excess + limit * limit)
            text = f"{quantity} {value:.4g} {unit} > limit {limit:.4g} {unit}"
        elif group == 1:
            value = excess + limit
            text = f"{quantity} {value:.4g} {unit} > upper limit {limit:.4g} {unit}"
        elif group == 2:
            value = limit - excess
            text = f"{quantity} {value:.4g} {unit} < lower limit {limit:.4g} {unit}"
        else:
            value = excess + limit
            text = f"|{quantity}| {value:.4g} {unit} > limit {limit:.4g} {unit}"
        return self._event(t, "violation", quantity, value, limit, f"{text} at t = {t:.4f} s")

    def _event(
        self,
        t: float,
        kind: str,
        quantity: str,
        value: Any,
        limit: Any,
        message: str,
    ) -> dict[str, Any]:
        event = {
            "t": float(t),
            "kind": kind,
            "quantity": quantity,
            "value": value,
            "limit": limit,
            "message": message,
        }
        self.events.append(event)
        return event

    def _set_state(self, t: float, state: str, why: str) -> None:
        old = self.state
        self.state = state
        self.state_code = STATES.index(state)
        self._event(t, "state", "state", state, None, f"safety state {old} -> {state}: {why}")


@kernel
def _monitor_kernel(cuff_force, q, dq, tau, current_A, u_cmd, normal, w):
    """Excess of every channel over its limit into w[:28]; the sum of the positive ones.

    Channels (groups of 4): cuff |f|² - limit², q - upper, lower - q, |q̇| -
    limit, |i| - limit, and the finiteness channels |τ| - DBL_MAX, |U| -
    DBL_MAX (<= 0, or +inf / NaN for an infinity / a NaN).  The sum is 0 when
    all is well, > 0 or NaN if not.  When it is 0 and ``normal``, the posture
    and command are kept in w (the last good tick's).  The limits are read
    from w (lower angle limits negated).  Returns -1 (and nothing done) when
    an input is not of length 4 (the cuff forces: not (4, 2)).
    """
    if (
        q.shape[0] != 4
        or dq.shape[0] != 4
        or tau.shape[0] != 4
        or current_A.shape[0] != 4
        or u_cmd.shape[0] != 4
        or cuff_force.shape[0] != 4
        or cuff_force.shape[1] != 2
    ):
        return -1.0
    for i in range(4):
        fx = cuff_force[i, 0]
        fz = cuff_force[i, 1]
        w[i] = fx * fx + fz * fz - w[_W_LIMIT + i]
        w[4 + i] = q[i] - w[_W_LIMIT + 4 + i]
        w[8 + i] = -q[i] - w[_W_LIMIT + 8 + i]
        w[12 + i] = abs(dq[i]) - w[_W_LIMIT + 12 + i]
        w[16 + i] = abs(current_A[i]) - w[_W_LIMIT + 16 + i]
        w[20 + i] = abs(tau[i]) - w[_W_LIMIT + 20 + i]
        w[24 + i] = abs(u_cmd[i]) - w[_W_LIMIT + 24 + i]
    worst = 0.0
    for c in range(28):
        e = w[c]
        if not e <= 0.0:
            worst += e  # a NaN stays NaN
    if normal and worst <= 0.0:
        for i in range(4):
            w[_W_Q_LAST + i] = q[i]
            w[_W_U_LAST + i] = u_cmd[i]
    return worst
