"""Fault injection: one scheduled fault of a sensor, the control timing, a drive or a cuff.

A run's faults (``SimConfig.faults``, off by default) are injected by a
:class:`FaultInjector` that the tick (:class:`~exo_ctrl.sim.tick.Runner`)
consults at two points, outside the components it corrupts:

- after the sensors: it copies the readings into its own record and
  corrupts the copy (the estimator, the controller, the supervisor and the
  log all see the corrupted readings, as on the device);
- between the controller and the supervisor: it delays the command (a
  control period overrun) and reports the command's age; and at a drive or
  cuff fault's onset it sets that drive's ``fault`` flag in the drives'
  record (:data:`exo_ctrl.plant.drive.DRIVE_FAULTS`, honoured by
  ``step_drives``) or the cuff's ``slipped`` flag in the cuffs' record,
  or at a belt stop the belt's ``brake`` flag (:mod:`exo_ctrl.plant.belt`).

A run without faults builds no injector and its tick is unchanged.

**The faults** (:data:`FAULT_KINDS`; ``target`` a joint of JOINT_NAMES, or a
cuff of CUFF_NAMES for ``cuff_slip``; ``magnitude`` in the unit given):

=================  ============================================================
kind               what the device gets from the onset t_f for ``duration_s``
=================  ============================================================
encoder_freeze     the encoder stuck at its last value (no magnitude)
encoder_dropout    stale encoder value (the last one received), then fresh again
noise_burst        encoder noise of std ``magnitude`` [rad] added
torque_bias_step   the torque sensor offset by ``magnitude`` [N·m]
torque_drift       the torque sensor offset by ``magnitude`` (t - t_f) [N·m/s]
torque_saturation  the torque sensor clipped at ±``magnitude`` [N·m] (its rail)
nan_reading        every reading of the joint NaN (a corrupted frame)
control_overrun    every drive gets the command ``magnitude`` [s] late (whole ticks)
drive_open         the drive's phase open: no current, no torque
drive_short        the drive's winding shorted: U = 0 whatever the command
cuff_slip          the cuff slipped off: no force (stiffness and damping zero)
belt_stop          the treadmill belt stops (a jammed roller, the treadmill's own
                   e-stop): a brake of ``magnitude`` [N] (None: the belt drive's
                   force limit F_max) holds it at rest whatever the set speed;
                   with contact on only (the belt exists there)
=================  ============================================================

**Encoder faults and the speed.**  The device has no speed sensor: it
differentiates the encoder (:mod:`exo_ctrl.sensing.sensors`).  From an
encoder fault's onset on, that joint's speed reading is recomputed from the
corrupted angles by the same filter, v += α ((q_k - q_{k-1}) / Δt - v),
α = 1 - exp(-2π f_v Δt), so a frozen encoder reads a speed decaying to zero
and a stale one a spike when fresh values return.  A NaN frame is skipped by
the filter (the speed resumes from its last finite value).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import _validate as v
from .._jit import record
from ..exceptions import InvalidParameter
from ..model import CUFF_NAMES, JOINT_NAMES
from ..plant.drive import OPEN_PHASE, SHORTED
from ..sensing import SensorReadings

__all__ = ["BELT_STOP_NEEDS", "FAULT_KINDS", "INJECTABLE", "Fault", "FaultInjector", "faults_of"]

#: Every fault of the campaign (issue 19), in its order.
FAULT_KINDS = (
    "encoder_freeze",
    "encoder_dropout",
    "noise_burst",
    "torque_bias_step",
    "torque_drift",
    "torque_saturation",
    "nan_reading",
    "control_overrun",
    "drive_open",
    "drive_short",
    "cuff_slip",
    "belt_stop",
)

#: The faults the plant can take (all; ``belt_stop`` with contact on only).
INJECTABLE = FAULT_KINDS

_ENCODER = ("encoder_freeze", "encoder_dropout", "noise_burst")
_NEEDS_MAGNITUDE = ("noise_burst", "torque_bias_step", "torque_drift", "torque_saturation")
_UNITS = {
    "noise_burst": "rad",
    "torque_bias_step": "N·m",
    "torque_drift": "N·m/s",
    "torque_saturation": "N·m",
    "control_overrun": "s",
    "belt_stop": "N",
}

#: What a ``belt_stop`` needs (the message of its refusal without the belt).
BELT_STOP_NEEDS = "a fault of a part the run models: the belt exists with contact on only"

#: Fields of the injector's readings record (what :func:`~exo_ctrl.sim.log_rows.write_measured`
#: logs): ``q`` [rad], ``dq`` [rad/s], ``tau`` [N·m].
READING_FIELDS = [("q", np.float64, (4,)), ("dq", np.float64, (4,)), ("tau", np.float64, (4,))]


@dataclass(frozen=True)
class Fault:
    """One fault, injected at ``at_s`` for ``duration_s`` (module docstring's table).

    Attributes:
        kind: one of :data:`INJECTABLE`.
        at_s: onset [s] (the first control tick at or after it).
        target: a joint (JOINT_NAMES), a cuff (CUFF_NAMES) for ``cuff_slip``,
            ``""`` for ``control_overrun`` (every drive) and ``belt_stop``.
        magnitude: the kind's size in its unit (table); None for the kinds
            without one.  ``control_overrun``: the delay [s], at least one tick.
            ``belt_stop``: the brake's force limit [N] (None: the belt drive's).
        duration_s: how long it lasts [s] (None: to the end of the run).
        seed: seed of a noise burst's noise.

    Raises:
        InvalidParameter: an unknown or non-injectable kind, a bad target, a
            missing or bad magnitude, a negative time.

    """

    kind: str
    at_s: float
    target: str = ""
    magnitude: float | None = None
    duration_s: float | None = None
    seed: int = 0

    def __post_init__(self) -> None:
        v.one_of("fault kind", self.kind, INJECTABLE)
        object.__setattr__(self, "at_s", v.non_negative("fault at_s", self.at_s, "s"))
        names = CUFF_NAMES if self.kind == "cuff_slip" else JOINT_NAMES
        if self.kind in ("control_overrun", "belt_stop"):
            if self.target != "":
                what = "every drive" if self.kind == "control_overrun" else "the belt"
                raise InvalidParameter("fault target", self.target, f'"" ({what})')
        elif self.target not in names:
            raise InvalidParameter("fault target", self.target, f"one of {', '.join(names)}")
        if self.kind in _NEEDS_MAGNITUDE or self.kind == "control_overrun":
            if self.magnitude is None:
                raise InvalidParameter(
                    "fault magnitude", None, f"a number [{_UNITS[self.kind]}] for {self.kind}"
                )
            size = v.finite("fault magnitude", self.magnitude, _UNITS[self.kind])
            if self.kind in ("noise_burst", "torque_saturation", "control_overrun"):
                size = v.positive("fault magnitude", size, _UNITS[self.kind])
            object.__setattr__(self, "magnitude", size)
        elif self.magnitude is not None:
            if self.kind != "belt_stop":
                raise InvalidParameter("fault magnitude", self.magnitude, f"None for {self.kind}")
            brake = v.positive("fault magnitude", self.magnitude, "N")
            object.__setattr__(self, "magnitude", brake)
        if self.duration_s is not None:
            object.__setattr__(
                self, "duration_s", v.positive("fault duration_s", self.duration_s, "s")
            )
        if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)):
            raise InvalidParameter("fault seed", self.seed, "an integer >= 0")

    @property
    def label(self) -> str:
        """``kind`` and its target, for tables and events."""
        return f"{self.kind} {self.target}".strip()

    def describe(self) -> str:
        """One line: what is injected."""
        size = "" if self.magnitude is None else f" of {self.magnitude:g} {_UNITS[self.kind]}"
        how_long = "" if self.duration_s is None else f" for {self.duration_s:g} s"
        return f"{self.label}{size}{how_long}"

    def ticks(self, dt: float, n_ticks: int) -> tuple[int, int]:
        """The ticks [k_on, k_off) of the fault in a run of ``n_ticks`` ticks of Δt [s]."""
        k_on = math.ceil(self.at_s / dt - 1e-9)
        if self.duration_s is None:
            return k_on, max(n_ticks, k_on)
        return k_on, k_on + max(round(self.duration_s / dt), 1)


def faults_of(value: Any) -> tuple[Fault, ...]:
    """``SimConfig.faults`` as a tuple of :class:`Fault` (dicts, as a recording has them, accepted).

    Raises:
        InvalidParameter: not a sequence of faults, or a bad fault.

    """
    if isinstance(value, (Fault, dict, str)) or not isinstance(value, (tuple, list)):
        raise InvalidParameter("faults", value, "a tuple of Fault")
    out = []
    for f in value:
        if isinstance(f, dict):
            try:
                f = Fault(**f)
            except TypeError as exc:
                raise InvalidParameter("faults", f, f"the fields of Fault ({exc})") from None
        if not isinstance(f, Fault):
            raise InvalidParameter("faults", f, "a Fault")
        out.append(f)
    return tuple(out)


class FaultInjector:
    """Injects a run's faults at the tick's two injection points (module docstring).

    Args:
        faults: the faults.
        dt: control period Δt [s].
        n_ticks: ticks of the run.
        velocity_filter_hz: the sensors' speed filter cut-off f_v [Hz].
        motors: the plant's drives' record (its ``fault`` field is set).
        cuffs: the plant's cuffs' record (its ``slipped`` field is set).
        belt: the plant's belt record (its ``brake`` and ``f_brake`` fields
            are set; None: no belt, contact off).

    Attributes:
        readings: the corrupted readings the device sees (a new object; its
            arrays are views of :attr:`record`).
        record: the readings' record (:data:`READING_FIELDS`), for the log.
        events: the faults' onsets, one event dict each (kind ``"fault"``).

    """

    def __init__(
        self,
        faults: tuple[Fault, ...],
        dt: float,
        n_ticks: int,
        velocity_filter_hz: float,
        motors: np.ndarray | None,
        cuffs: np.ndarray,
        belt: np.ndarray | None = None,
    ) -> None:
        self.faults = faults
        self.dt = float(dt)
        self._alpha = 1.0 - math.exp(-2.0 * math.pi * velocity_filter_hz * self.dt)
        self.record = record(READING_FIELDS)
        r = self.record
        self.readings = SensorReadings(q=r["q"][0], dq=r["dq"][0], tau=r["tau"][0])
        self._motor_fault = None if motors is None else motors["fault"][0]
        self._slipped = cuffs["slipped"][0]
        self._belt = belt
        if belt is None and any(f.kind == "belt_stop" for f in faults):
            raise InvalidParameter("fault kind", "belt_stop", BELT_STOP_NEEDS)
        self._windows = [f.ticks(self.dt, n_ticks) for f in faults]
        self._index = [
            CUFF_NAMES.index(f.target)
            if f.kind == "cuff_slip"
            else (JOINT_NAMES.index(f.target) if f.target else -1)
            for f in faults
        ]
        self._noise = [
            np.random.default_rng(f.seed).standard_normal(k1 - k0) * f.magnitude
            if f.kind == "noise_burst"
            else None
            for f, (k0, k1) in zip(faults, self._windows, strict=True)
        ]
        self._held = np.zeros(len(faults))
        self._q_prev = np.full(4, np.nan)  # the last reading out, per joint
        self._v = np.zeros(4)  # the recomputed speed of an encoder-faulted joint
        self._own_speed = np.zeros(4, dtype=bool)
        self._history = np.zeros((8, 4))  # the last commands, by tick mod 8
        self._delays = [
            round(f.magnitude / self.dt) if f.kind == "control_overrun" else 0 for f in faults
        ]
        for d in self._delays:
            if d >= self._history.shape[0]:
                raise InvalidParameter(
                    "fault magnitude",
                    d * self.dt,
                    f"a control_overrun below {self._history.shape[0] * self.dt:g} s",
                )
        self.events: list[dict[str, Any]] = []

    def _active(self, i: int, k: int) -> bool:
        k0, k1 = self._windows[i]
        return k0 <= k < k1

    def readings_at(self, k: int, raw: SensorReadings) -> SensorReadings:
        """The readings of tick ``k`` as the faulted device gets them."""
        out = self.readings
        q, dq, tau = out.q, out.dq, out.tau
        np.copyto(q, raw.q)
        np.copyto(dq, raw.dq)
        np.copyto(tau, raw.tau)
        out.cuff_force_est = raw.cuff_force_est
        nan_joints = []
        for i, f in enumerate(self.faults):
            j = self._index[i]
            k0, k1 = self._windows[i]
            if k == k0:
                self._onset(i, k)
            elif k == k1 and f.duration_s is not None:
                self._set_plant_flag(i, 0.0)
            if not self._active(i, k):
                continue
            kind = f.kind
            if kind in ("encoder_freeze", "encoder_dropout"):
                if k == k0:
                    self._held[i] = self._q_prev[j] if math.isfinite(self._q_prev[j]) else q[j]
                q[j] = self._held[i]
            elif kind == "noise_burst":
                q[j] += self._noise[i][k - k0]
            elif kind == "torque_bias_step":
                tau[j] += f.magnitude
            elif kind == "torque_drift":
                tau[j] += f.magnitude * (k - k0) * self.dt
            elif kind == "torque_saturation":
                tau[j] = min(max(tau[j], -f.magnitude), f.magnitude)
            elif kind == "nan_reading":
                nan_joints.append(j)
        for i, f in enumerate(self.faults):
            if f.kind in _ENCODER and k >= self._windows[i][0]:
                self._own_speed[self._index[i]] = True
        for j in range(4):
            if self._own_speed[j]:
                v_j = self._v[j] + self._alpha * ((q[j] - self._q_prev[j]) / self.dt - self._v[j])
                self._v[j] = v_j
                dq[j] = v_j
            else:
                self._v[j] = dq[j]
            self._q_prev[j] = q[j]
        for j in nan_joints:
            q[j] = dq[j] = tau[j] = math.nan
        return out

    def command_at(self, k: int, u: np.ndarray) -> tuple[np.ndarray, float]:
        """The command the drives get at tick ``k`` and its age [s] (0: this tick's)."""
        n = self._history.shape[0]
        self._history[k % n] = u
        for i, d in enumerate(self._delays):
            if d and self._active(i, k):
                return self._history[(k - d) % n], d * self.dt
        return u, 0.0

    def _set_plant_flag(self, i: int, value: float) -> None:
        """Set (the fault's code) or clear (0) a drive or cuff fault's flag in the plant."""
        f, j = self.faults[i], self._index[i]
        if f.kind in ("drive_open", "drive_short") and self._motor_fault is not None:
            code = OPEN_PHASE if f.kind == "drive_open" else SHORTED
            self._motor_fault[j] = code if value else 0.0
        elif f.kind == "cuff_slip":
            self._slipped[j] = 1.0 if value else 0.0
        elif f.kind == "belt_stop" and self._belt is not None:
            b = self._belt
            if value:
                b["f_brake"] = b["f_max"][0] if f.magnitude is None else f.magnitude
            b["brake"] = 1.0 if value else 0.0

    def _onset(self, i: int, k: int) -> None:
        f = self.faults[i]
        self._set_plant_flag(i, 1.0)
        t = k * self.dt
        self.events.append(
            {
                "t": t,
                "kind": "fault",
                "quantity": f.label,
                "value": f.magnitude,
                "limit": None,
                "message": f"fault injected: {f.describe()} at t = {t:.4f} s",
            }
        )
