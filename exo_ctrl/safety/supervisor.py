r"""Safety supervisor: limit monitors and a controlled stop.

The supervisor sits between the controller and the drives.  Every control
tick it checks what the device can measure — joint angles, speeds and torques
from the sensors, cuff forces (measured, or estimated from the joint torques),
drive currents — and the controller's command against :class:`SafetyLimits`
(:mod:`.limits`, :mod:`.monitor`) and the plausibility monitors (:mod:`.plausibility`;
the torque sensor against the current, :mod:`.consistency`) in one compiled call
(:mod:`.tick_check`), after the belt monitor with the belt (:mod:`.belt_monitor`).
While nothing is wrong it returns the controller's command unchanged (and allocates
no array).  Its state is one record, :attr:`record`, whose ``state`` field the log reads.

**Controlled stop.**  On the first violation, on a non-finite reading or at
the emergency-stop time, it stops the gait:

1. ``"stopping"``: the posture measured at the stop, q_h, is to be held.  The
   hold command is gravity compensation plus a PD on the posture,

   .. math::

       U_{hold} = \frac{R}{i_G k_m}\,\bigl(g_{exo}(q_h) + g_{patient}(q_h)\bigr)
                + k_p (q_h - q) - k_d \dot q,

   the first term being the motor model at zero speed (:meth:`MotorBank.voltage_for` with ω = 0)
   applied to the generalised gravity torques of both bodies at the hold posture (the patient's
   legs hang in the cuffs, so the drives carry them too; the patient's joint angles are taken
   equal to the exoskeleton's, as the computed-torque feedforward does).  The command is ramped
   linearly from the last normal command U_0 to the hold command over ``ramp_s``, U = U_0 + α
   (U_hold - U_0), α = (t - t_stop) / ramp_s, so the drive torque has no step (a volt across the
   0.1 Ω winding is 10 A, 170 N·m). U_0 still carries the back-EMF of the planned speed, so the
   joints coast on a little before the PD pulls them back (0.085 rad at most for the default
   e-stop at 0.5 s, back within 0.015 rad by the end of the ramp).
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

**Stop reaction** (``stop_reaction``; :mod:`.stop_reaction`).  The above is ``hold``.  ``yield``
ramps, over its own shorter ramp, to gravity compensation at the present posture with damping
injection instead (``"yielding"`` after the ramp, no posture held): an active patient moves the
legs with a bounded interaction force; a joint beyond its speed limit cuts the power, one out of
its range is braked alone, legs at rest end in the hold.  A hold or its ramp the patient pushes
against (a release would take a cuff past its limit, or in the ramp past what the stop found,
:mod:`.release`; on readings no plausibility monitor has doubted since the stop) yields at once.
The QP's departure stop (:meth:`~SafetySupervisor.request_stop`) yields with the cuff forces fed
back (:mod:`.yield_command`) until a plausibility monitor doubts a reading.

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
from collections.abc import Sequence
from typing import Any

import numpy as np

from .. import _validate as v
from ..model import JOINT_NAMES, BodyModel
from ..plant import MotorParams
from ..sensing import CurrentSensorParams, SensorParams, SensorReadings
from .belt_monitor import BELT, BeltMonitor, belt_monitor
from .limits import STATES, SafetyLimits, resolve_limits
from .monitor import LIMIT_GROUPS, channels, monitor_record
from .plausibility import plausibility_limits, plausibility_record
from .release import ReleaseBound
from .stop_reaction import (
    REST_SPEED_RAD_S,
    REST_TIME_S,
    YieldCommand,
    check_stop_reaction,
    hold_breach,
    reaction_at,
    yield_breach,
)
from .stop_reaction import yield_damping as _yield_damping
from .tick_check import check_readings, refuse_readings

__all__ = ["SafetySupervisor"]


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
        use_estimate: the cuff forces given to :meth:`step` are estimates (a string: their name).
        ramp_s: duration of the ramp [s] (0: switch at once; to a yield at most its ramp_s).
        hold_tolerance_rad: largest posture error during the hold [rad].
        hold_kp: hold PD proportional gain [V/rad] (default 100; tracking PD: 300).
        hold_kd: hold PD derivative gain [V·s/rad] (default 2; tracking PD: 5).
        event_interval_s: after the stop, a violation of the same channel is
            logged at most once per this interval [s].
        sensors: the sensors' parameters, for the plausibility monitors'
            thresholds (:mod:`exo_ctrl.safety.plausibility`; None: the defaults).
        current_sensor: the drives' current sensors' datasheet, for the
            consistency and still-encoder limits (None: the default driver's).
        plausibility_checks: run the plausibility monitors (:mod:`.plausibility`).
        compliant_drives: the joints are compliant (the torque sensors read
            a spring, :mod:`exo_ctrl.plant.compliance`): the rigid drive
            model's and the consistency checks are off, the others stay.
        belt: the belt monitor's readings (belt encoder, foot load cells,
            drive's report) and datasheet (:mod:`exo_ctrl.safety.belt_monitor`;
            None: no belt monitor).
        stop_reaction: ``"hold"`` or ``"yield"`` (:mod:`.stop_reaction`), or a
            schedule ((start time [s], reaction), ...) (the one in force at
            the stop acts; :func:`~exo_ctrl.safety.stop_reaction.stop_reaction_schedule`).
        yield_damping: the yield's joint damping d_y [N·m·s/rad], a number
            or 4 (None: :func:`~exo_ctrl.safety.stop_reaction.yield_damping`
            from the cuff limits, the lever arms and the speed limits).
        cuff_stiffness: the cuffs' stiffness the device believes [N/m], for
            when a pushed hold yields (:mod:`.release`; None: 8 N/mm).

    Attributes:
        state: ``"normal"``, ``"stopping"``, ``"holding"``, ``"power_cut"`` or ``"yielding"``.
        state_code: 0, 1, 2, 3, 4 (same order), for logging.
        record: the supervisor's record, a structured array of one element
            (:data:`exo_ctrl.safety.monitor.MONITOR_FIELDS`): the monitor's
            limits and last excesses, and the field ``state`` (float, equal
            to ``state_code``) for the log.
        events: the event dicts, in time order.
        stop_time_s: time of the stop [s] (None while normal).
        hold_posture_rad: the posture held, (4,) [rad] (NaN while normal).
        hold_voltage_gravity_V: gravity-compensation voltages of the hold, (4,) [V].
        q_lower, q_upper, speed_limit, current_limit, cuff_limit: the limits, (4,) each.

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
        use_estimate: bool | str = False,
        ramp_s: float = 0.2,
        hold_tolerance_rad: float = 0.1,
        hold_kp: float = 100.0,
        hold_kd: float = 2.0,
        event_interval_s: float = 0.5,
        sensors: SensorParams | None = None,
        plausibility_checks: bool = True,
        compliant_drives: bool = False,
        belt: BeltMonitor | None = None,
        stop_reaction: str | Sequence[tuple[float, str]] = "hold",
        yield_damping: float | Sequence[float] | None = None,
        cuff_stiffness: float | None = None,
        current_sensor: CurrentSensorParams | None = None,
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
        resolved = resolve_limits(limits, exo, patient, motor)
        self.q_lower, self.q_upper = resolved.q_lower, resolved.q_upper
        self.speed_limit = resolved.speed_limit
        self.current_limit = resolved.current_limit
        self.cuff_limit = resolved.cuff_limit
        if isinstance(stop_reaction, str):
            stop_reaction = ((0.0, stop_reaction),)
        #: The stop reaction's schedule ((start [s], reaction), ...).
        self.stop_reactions = tuple((float(t0), check_stop_reaction(r)) for t0, r in stop_reaction)
        if yield_damping is None:
            damping = _yield_damping(resolved, exo)
        else:
            damping = v.per_item("yield_damping", yield_damping, "N·m·s/rad", JOINT_NAMES)
        #: The yield's command (:class:`~exo_ctrl.safety.yield_command.YieldCommand`).
        self.yield_command = YieldCommand(exo, patient, motor, damping, self.speed_limit, self.dt)
        #: The cuff forces a release of the hold reaches (:mod:`.release`).
        self.release = ReleaseBound(exo, patient, motor, self.dt, cuff_stiffness)
        #: The reaction of the present stop ("" while normal).
        self.reaction = ""
        self._ramp_t0 = 0.0
        self._rest_ticks, self._doubt = 0, False
        self._rest_needed = max(round(REST_TIME_S / self.dt), 1)
        self._estop = math.inf if self.estop_at_s is None else self.estop_at_s
        self._request: tuple[dict[str, Any], str, np.ndarray | None] | None = None
        self._feedback: np.ndarray | None = None  # the stop's cuff bounds: force feedback
        self.record = monitor_record(resolved, self._estop)
        sensors = sensors if sensors is not None else SensorParams()
        #: The plausibility monitors' limits (4 groups, 4 joints) and state.
        self.plausibility_limits = plausibility_limits(
            motor, sensors, self.dt, self.speed_limit, current_sensor
        )
        self.plausibility_record = plausibility_record(motor, sensors, self.dt)
        #: Whether the plausibility monitors run (``plausibility_checks``).
        self.checks = bool(plausibility_checks)
        if compliant_drives:
            # A compliant joint's sensor reads the spring, τ_d − J_r θ̈ with the rotor's θ̈
            # unmeasured: the rigid drive model's residual carries J_r (θ̈ − q̈) of the rotor's
            # ~42 Hz mode (31 N·m on the default PD run): it, .consistency and .still are off.
            self.plausibility_limits[[0, 4, 5]] = np.finfo(float).max
        if self.checks:
            self.record["limit"][0][LIMIT_GROUPS:BELT] = self.plausibility_limits
        self._u_sent = self.plausibility_record["u_prev"][0]
        #: The belt monitor (None: no belt).
        self.belt = belt
        self._belt = None if belt is None else belt.args
        belt_limit = None if belt is None else belt.threshold_mps
        if belt_limit is not None:
            self.record["limit"][0][BELT, 0] = belt_limit
        self._channels = channels(
            resolved, use_estimate, self.record["limit"][0][LIMIT_GROUPS:BELT], belt_limit
        )
        self._passed = self.record["passed"]  # read once per tick
        self._u_start = np.zeros(4)
        self._u = np.zeros(4)
        self._e, self._w = np.zeros(4), np.zeros(4)
        self._last_logged: dict[str, float] = {}
        self.hold_posture_rad = np.full(4, np.nan)
        self.hold_voltage_gravity_V = np.zeros(4)
        self.stop_time_s: float | None = None
        self.state = "normal"
        self.state_code = 0
        self.events: list[dict[str, Any]] = []

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
        command_age_s: float = 0.0,
    ) -> np.ndarray:
        """Check the tick's readings; return the voltages to apply [V], (4,).

        One compiled call (:mod:`.tick_check`; with the belt, the belt monitor's before
        it); the rest only when the tick did not pass (the stop, :meth:`respond`).

        Args:
            k: control tick index.
            t: time of the tick [s].
            sensors: the sensor readings the controller saw.
            cuff_force: cuff forces on the exo (x, z), (4, 2) [N] (measured or estimated).
            current_A: drive currents, (4,) [A] (mean over the last step).
            u_cmd: the controller's voltage command, (4,) [V].
            command_age_s: the time since the command's readings [s] (0: this tick's).

        Returns:
            ``u_cmd`` while normal; else its own buffer (the stop command).

        Raises:
            InvalidParameter: an input of the wrong shape (named).

        """
        q, dq, tau = sensors.q, sensors.dq, sensors.tau
        f, current, u = cuff_force, current_A, u_cmd
        if not (
            type(q) is type(dq) is type(tau) is type(f) is type(current) is type(u) is np.ndarray
        ):
            q, dq, tau, current, u = v.arrays(
                (4,), sensors_q=q, sensors_dq=dq, sensors_tau=tau, current_A=current, u_cmd=u
            )
            f = v.array("cuff_force", f, (4, 2))
        rec = self.record
        if self._belt is not None:  # its own row; the plausibility monitors' are others
            belt_monitor(*self._belt, rec)
        status = check_readings(
            f, q, dq, tau, current, u, command_age_s, t, self.checks, self.plausibility_record, rec
        )
        if status:
            self.refuse(status, f, q, dq, tau, current, u)
        return u_cmd if self._passed[0] else self.respond(t, sensors, f, u_cmd)

    def respond(
        self, t: float, sensors: SensorReadings, cuff_force: np.ndarray, u_cmd: np.ndarray
    ) -> np.ndarray:
        """:meth:`step`'s answer to a tick whose check did not pass: the stop command [V], (4,)."""
        worst = float(self.record["worst"][0])
        if self.state_code == 0:
            self._start_stop(t, sensors, u_cmd, worst)
        elif not worst <= 0.0:
            self._log_violations(t)
        out = self._stop_command(t, sensors, cuff_force, clean=worst == worst)
        np.copyto(self._u_sent, out)  # what the drives get, for the drive model
        return out

    def request_stop(
        self, t: float, cause: dict[str, Any], reaction: str, limit_N: Any = None
    ) -> None:
        """Stop at this tick's check for ``cause``, once; yield feedback from ``limit_N`` [N]."""
        if self.state_code == 0 and self._request is None:
            limit = None if limit_N is None else np.asarray(limit_N, dtype=float)
            self._request = (cause, check_stop_reaction(reaction), limit)
            self._estop = min(self._estop, float(t))
            self.record["estop_s"] = self._estop

    refuse = staticmethod(refuse_readings)  # raise for the check's status, naming the input

    # ------------------------------------------------------------------ stop

    def _start_stop(
        self, t: float, sensors: SensorReadings, u_cmd: np.ndarray, worst: float
    ) -> None:
        if not worst <= 0.0:
            cause = self._log_violations(t)[0]
        elif self._request is not None:  # a stop asked for (request_stop)
            cause = self._event(t, "violation", **self._request[0])
        else:
            text = f"emergency stop at t = {t:.4f} s"
            cause = self._event(t, "estop", "time", float(t), float(self._estop), text)
        self.stop_time_s = self._ramp_t0 = float(t)
        self._doubt = False
        self.release.begin()
        asked = self._request
        self.reaction = reaction_at(self.stop_reactions, t) if asked is None else asked[1]
        self._feedback = None if asked is None else asked[2]
        q = np.asarray(sensors.q, dtype=float)
        finite = np.isfinite(q)
        self.hold_posture_rad = np.where(finite, q, self.record["q_last"][0])
        u = np.asarray(u_cmd, dtype=float)
        self._u_start[:] = np.where(np.isfinite(u), u, self.record["u_last"][0])
        if not np.all(np.isfinite(self.hold_posture_rad)):
            self._set_state(t, "power_cut", "no finite posture reading to hold")
            return
        self.hold_voltage_gravity_V = self._gravity_voltage(self.hold_posture_rad)
        if self.reaction == "yield":
            dq = np.asarray(sensors.dq, dtype=float)
            self.yield_command.start(self.hold_posture_rad, dq, self._feedback)
        why = f"controlled stop ({self.reaction}): {cause['message']}"
        self._set_state(t, "stopping", why)

    def _gravity_voltage(self, q: np.ndarray) -> np.ndarray:
        """U = R (g_exo(q) + g_patient(q)) / (i_G k_m): holding torque at zero speed [V]."""
        tau = self.yield_command.gravity(q)  # the device's models, as the yield's
        return self._motor.resistance_ohm * tau / self._motor.torque_per_amp_Nm_per_A

    def _stop_command(
        self, t: float, sensors: SensorReadings, f: np.ndarray, clean: bool
    ) -> np.ndarray:
        """The stop command [V]; f the cuff forces [N]; ``clean``: every reading is finite."""
        u, e, w = self._u, self._e, self._w
        if self.state_code == 3:
            u.fill(0.0)
            return u
        if self.reaction == "yield":
            return self._yield(t, sensors, f)
        np.subtract(self.hold_posture_rad, sensors.q, out=e)
        np.copyto(w, sensors.dq)
        if not clean:  # no PD on a joint whose reading is not finite
            e[~np.isfinite(e)] = 0.0
            w[~np.isfinite(w)] = 0.0
        if self.state_code == 2 and self._hold_failed(t, e, w):
            u.fill(0.0)
            return u
        self._doubt = self._doubt or bool(np.any(self.record["excess"][0][LIMIT_GROUPS:] > 0.0))
        ramp = self.state_code == 1  # pushed: module docstring
        pushed = self.release.pushed(f, self.hold_posture_rad, self.cuff_limit, ramp)
        # U_hold = U_g + k_p (q_h - q) - k_d q̇
        np.multiply(e, self.hold_kp, out=u)
        np.multiply(w, self.hold_kd, out=w)
        np.subtract(u, w, out=u)
        np.add(u, self.hold_voltage_gravity_V, out=u)
        if pushed and not self._doubt:  # yield at once (a ramp keeps part of the lock)
            self.reaction, self._rest_ticks = "yield", 0
            self.yield_command.start(np.asarray(sensors.q, dtype=float), sensors.dq, self._feedback)
            why = f"the patient pushes against the {'ramp to the ' * ramp}hold: yield at once"
            self._set_state(t, "yielding", why)
            return self._yield(t, sensors, f)
        if ramp:
            self._ramp(t, u, "holding")
        return u

    def _ramp(self, t: float, u: np.ndarray, then: str) -> None:
        """U_0 + α (U - U_0) in place, α = (t - t_0)/T (ramp_s, a yield's ≤ its own); ``then``."""
        elapsed = t - self._ramp_t0 + 1e-9 * self.dt  # rounding of t = k Δt
        ramp = min(self.ramp_s, self.yield_command.ramp_s if self.reaction == "yield" else math.inf)
        alpha = elapsed / ramp if ramp > 0.0 else 1.0
        if alpha >= 1.0:
            self._set_state(t, then, "ramp done")
        else:
            np.subtract(u, self._u_start, out=u)
            np.multiply(u, alpha, out=u)
            np.add(u, self._u_start, out=u)

    def _yield(self, t: float, sensors: SensorReadings, f: np.ndarray | None) -> np.ndarray:
        """The yield's command [V] (:mod:`.stop_reaction`); cuff forces f [N] fed back, trusted."""
        self._doubt = self._doubt or bool(np.any(self.record["excess"][0][LIMIT_GROUPS:] > 0.0))
        f = None if self._doubt else f
        u = self.yield_command.command(np.asarray(sensors.q, dtype=float), self._u, f)
        if self.state_code == 1:
            self._ramp(t, u, "yielding")
            return u
        q = self.yield_command.posture  # the last finite reading per joint
        dq = np.abs(np.asarray(sensors.dq, dtype=float))
        for braked in self.yield_command.brake_outside(q, self.q_lower, self.q_upper, u):
            self._event(t, "violation", *braked)  # out of its range: braked outward alone
        breach = yield_breach(dq, self.speed_limit)
        if breach is not None:
            self._event(t, "violation", *breach)
            self._set_state(t, "power_cut", "yield ended: drive voltages set to zero")
            u.fill(0.0)
            return u
        self._rest_ticks = self._rest_ticks + 1 if np.all(dq < REST_SPEED_RAD_S) else 0
        if self._rest_ticks >= self._rest_needed:  # the legs at rest: hold them there
            self.reaction = "hold"
            self._ramp_t0 = float(t)
            self.release.begin()
            self.hold_posture_rad = q.copy()
            self.hold_voltage_gravity_V = self._gravity_voltage(self.hold_posture_rad)
            self._u_start[:] = u
            self._set_state(t, "stopping", "legs at rest: ramp to the hold")
        return u

    def _hold_failed(self, t: float, e: np.ndarray, speed: np.ndarray) -> bool:
        if (breach := hold_breach(e, speed, self.hold_tolerance_rad, self.speed_limit)) is None:
            return False
        self._event(t, "violation", *breach)
        self._set_state(t, "power_cut", "hold failed: drive voltages set to zero")
        return True

    # ------------------------------------------------------------------ events

    def _log_violations(self, t: float) -> list[dict[str, Any]]:
        """Log the violated channels (after the stop: those not logged within the interval).

        Rate-limited per quantity (a non-finite angle violates both its bounds).
        """
        excess = self.record["excess"][0].ravel()
        logged: list[dict[str, Any]] = []
        for c in np.flatnonzero(~(excess <= 0.0)):
            quantity = self._channels[c].quantity
            last = self._last_logged.get(quantity, -math.inf)
            if last == t or (self.state_code != 0 and t - last < self.event_interval_s):
                continue
            self._last_logged[quantity] = t
            logged.append(self._violation_event(t, int(c), float(excess[c])))
        return logged

    def _violation_event(self, t: float, c: int, excess: float) -> dict[str, Any]:
        channel = self._channels[c]
        if channel.finite_only(excess):
            text = f"{channel.quantity} is not finite at t = {t:.4f} s"
            return self._event(t, "violation", channel.quantity, None, None, text)
        value, text = channel.describe(excess)
        return self._event(
            t, "violation", channel.quantity, value, channel.limit, f"{text} at t = {t:.4f} s"
        )

    def _event(
        self, t: float, kind: str, quantity: str, value: Any, limit: Any, message: str
    ) -> dict[str, Any]:
        event = {"t": float(t), "kind": kind, "quantity": quantity}
        event.update(value=value, limit=limit, message=message)
        self.events.append(event)
        return event

    def _set_state(self, t: float, state: str, why: str) -> None:
        old = self.state
        self.state = state
        self.state_code = STATES.index(state)
        self.record["state"] = self.state_code
        self._event(t, "state", "state", state, None, f"safety state {old} -> {state}: {why}")
