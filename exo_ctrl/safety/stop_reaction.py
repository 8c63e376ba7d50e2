r"""The stop reactions: ``hold`` the posture, or ``yield`` to the patient.

The supervisor (:mod:`.supervisor`) stops the gait on a violation.  How it
stops is its *stop reaction*:

- ``hold``: ramp to gravity compensation plus a stiff PD on the posture at
  the stop (the supervisor's module docstring).  Right when the device is in
  charge and the patient passive: the legs stay where they were.  Against an
  ACTIVE patient who keeps walking it is a position lock: the campaign
  (``tools/faults.py --mode transparent --stop-reaction hold``) measured
  263 N on a thigh cuff and 160 N on a shank cuff after the stop (ISO/TS
  15066: 220 N, 130 N).
- ``yield``: ramp (as the hold's ramp: U = U_0 + α (U_y − U_0), α = (t −
  t_stop)/ramp_s, no step) to a command that carries the device's own
  models and injects joint damping, and nothing else:

  .. math::

      τ_y = g_{exo}(q) + g_{patient}(q) - d_y\,\hat\omega,\qquad
      U_y = \frac{R\,τ_y}{i_G k_m\,η^{s}} + \frac{i_G}{k_E}\,\hat\omega,

  g the generalised gravity of the device's exoskeleton and nominal patient
  models at the PRESENT posture (the readings of this tick, as the hold's
  gravity term at the hold posture), \hat ω the joint speed, η^s the
  gearbox efficiency (s = sign(τ) tanh(ω/ω_η); :func:`~exo_ctrl.plant.motor.steady_voltage`).
  The last term compensates the drive's back-EMF: left alone, a drive at a
  fixed voltage is a viscous brake of D = i_G k_m (i_G/k_E)/R =
  208 N·m·s/rad (default drive), 30-40 times :data:`d_y` below; the power
  cut (0 V) is exactly that brake.  So the patient moves the legs against
  the exoskeleton's inertia (links and the reflected rotor inertia,
  uncompensated: no force feedback, the torque sensors may be the fault),
  its URDF friction and damping, and d_y; the device no longer drives.

**The damping d_y** (:func:`yield_damping`).  Chosen from the cuff-force
budget at the fastest speed the yield allows: the supervisor cuts the power
when a joint exceeds its speed limit ω_max, so within the yield |ω| ≤ ω_max,
and the damping's cuff force there is at most a share σ of the cuff's limit,

.. math::  d_{y,j} = σ\,F_{lim,c}\,r_c / ω_{max,j},

with c the cuff the joint's torque loads at the shortest lever r_c (hip:
the thigh cuff, r = hip → thigh cuff; knee: the shank cuff, r = knee →
shank cuff; from the device's exoskeleton model).  σ = :data:`YIELD_FORCE_SHARE`
= 0.5 leaves the other half of the limit to what the yield does not
remove, the exoskeleton's inertia the patient accelerates: a healthy active
patient walking a free exoskeleton without force feedback (``transparent``
with K_f = 0, the supervisor off) loads the thigh and shank cuffs to 90 N
and 58 N at most, 41 % and 45 % of 220 N and 130 N.  With the default
URDFs, ISO limits and the 6 rad/s speed limit: d_y = 0.5·220·0.39/6 =
7.2 N·m·s/rad at the hips and 0.5·130·0.45/6 = 4.9 N·m·s/rad at the knees;
at the patient's own peak speeds (2.3 rad/s hip, 3.1 rad/s knee) the
damping costs 42 N and 34 N at the cuffs.  Lower bound, why not 0: d_y
is what brings a passive (or weakened) leg to rest after the stop (time
constant M/d_y: about 1 s at a hip, exoskeleton and patient; a passive
patient stopped mid-gait came to rest in 1.9 s, tests/safety/test_stop_reaction.py) and
bounds the drift speed under the nominal models' gravity error Δτ_g to
Δτ_g/d_y.

**The speed \hat ω**: the encoder's difference (q_k − q_{k−1})/Δt through a
first-order filter of :data:`SPEED_FILTER_HZ` = 150 Hz (as the interaction
modes' back-EMF compensation, :class:`~exo_ctrl.control.modes.ModeParams`),
started at the stop from the sensors' speed reading.  The sensors' own
30 Hz speed lags 5 ms: compensating the back-EMF with it leaves
D × 5 ms ≈ 1.0 kg·m² of felt inertia per joint (the knee's own
exoskeleton inertia is about 0.5 kg·m² plus 0.29 kg·m² of rotor); 150 Hz
leaves 0.2 kg·m².  It is clipped to ± the joint's speed limit (beyond it
the power is cut anyway).

**When the yield ends.**  (a) A joint beyond its speed limit or outside its
range of motion (the supervisor's limits), checked from the end of the
ramp on: power cut (the short-circuit brake above). (b) The legs at rest:
every joint's speed reading below :data:`REST_SPEED_RAD_S` for
:data:`REST_TIME_S`: the supervisor ramps to the hold at the posture of
that tick (from the yield's command, over the same ramp), and holds as
the ``hold`` reaction does.  A walking patient never has all four joints
that slow for that long (each joint's speed crosses zero, not all
together), so an active patient keeps the yield; a passive leg, gravity
compensated and damped, comes to rest and is held.

**The default per mode** (:func:`default_stop_reaction`): ``hold`` in
``tracking`` and in ``guidance`` with G = 1 (bit-equal to tracking): the
device is in charge and the patient may be passive (a passive patient's
legs would drift under the nominal model's gravity error while yielding);
``yield`` where the patient is in charge or shares it — ``transparent``,
``path`` (the patient sets the pace), ``guidance`` with G < 1 (the device
is partly free, so the patient is expected to walk) and ``aan`` (the
support is learned because the patient is expected to walk, however
weakly; the yield still carries the legs' modelled weight).  With a
session the segment running at the stop decides.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from ..estimation.cuff_geometry import CuffGeometry
from ..exceptions import InvalidParameter
from ..model import JOINT_NAMES, BodyModel
from ..plant import MotorParams
from ..plant.motor import drive_model, steady_voltage
from .limits import ResolvedLimits

__all__ = [
    "REST_SPEED_RAD_S",
    "REST_TIME_S",
    "SPEED_FILTER_HZ",
    "STOP_REACTIONS",
    "YIELD_FORCE_SHARE",
    "YieldCommand",
    "check_stop_reaction",
    "default_stop_reaction",
    "hold_breach",
    "reaction_at",
    "stop_reaction_schedule",
    "yield_breach",
    "yield_damping",
]

#: The stop reactions (``--stop-reaction``, ``SimConfig.stop_reaction``).
STOP_REACTIONS = ("hold", "yield")

#: Share σ of a cuff's force limit the yield's damping may take at the
#: joint's speed limit (module docstring).
YIELD_FORCE_SHARE = 0.5

#: Cut-off of the yield's speed filter on the encoder difference [Hz].
SPEED_FILTER_HZ = 150.0

#: The legs are at rest when every joint's speed reading stays below this
#: [rad/s] (ten times the default speed reading's noise, 0.005 rad/s) ...
REST_SPEED_RAD_S = 0.05
#: ... for this long [s]; the yield then ends in the hold.
REST_TIME_S = 0.2


def check_stop_reaction(value: object, name: str = "stop_reaction") -> str:
    """``value`` if it is one of :data:`STOP_REACTIONS`, else :class:`InvalidParameter`."""
    if not isinstance(value, str) or value not in STOP_REACTIONS:
        raise InvalidParameter(name, value, f"one of {', '.join(STOP_REACTIONS)}")
    return value


def default_stop_reaction(mode: str, guidance: float = 1.0) -> str:
    """The stop reaction a mode gets by default (module docstring).

    Args:
        mode: the interaction mode (:data:`~exo_ctrl.control.modes.MODES`).
        guidance: G of ``guidance`` [-] (ignored otherwise).

    """
    if mode == "tracking" or (mode == "guidance" and guidance >= 1.0):
        return "hold"
    return "yield"


def stop_reaction_schedule(
    setting: str | None, mode: str, guidance: float, session: Any = None
) -> tuple[tuple[float, str], ...]:
    """The stop reaction over the run: ((start time [s], reaction), ...), times rising from 0.

    Args:
        setting: the reaction asked for (None: by mode, :func:`default_stop_reaction`).
        mode: the run's mode.
        guidance: the run's G.
        session: the session (its segments' modes and G decide; None: ``mode``).

    """
    if setting is not None:
        return ((0.0, check_stop_reaction(setting)),)
    if session is None:
        return ((0.0, default_stop_reaction(mode, guidance)),)
    out = []
    for start, seg in zip(session.starts_s, session.segments, strict=True):
        g = dict(seg.params).get("guidance", guidance)
        out.append((float(start), default_stop_reaction(seg.mode, g)))
    return tuple(out)


def reaction_at(schedule: Sequence[tuple[float, str]], t: float) -> str:
    """The reaction of ``schedule`` in force at time t [s] (the last one started by t)."""
    reaction = schedule[0][1]
    for start, what in schedule:
        if start <= t + 1e-12:
            reaction = what
    return reaction


def hold_breach(
    error: np.ndarray, speed: np.ndarray, tolerance: float, speed_limit: np.ndarray
) -> tuple[str, float, float, str] | None:
    """Whether the hold failed, as (quantity, value, limit, message); None: it holds.

    Args:
        error: the posture error q_h - q [rad], (4,).
        speed: joint speeds [rad/s], (4,).
        tolerance: the largest posture error [rad].
        speed_limit: the speed limits [rad/s], (4,).

    The largest posture error beyond the tolerance first, then the fastest
    joint beyond its speed limit.

    """
    err = np.abs(error)
    fast = np.abs(speed) - speed_limit
    i = int(np.argmax(err))
    if err[i] > tolerance:
        joint = JOINT_NAMES[i]
        return (
            f"hold posture error {joint}",
            float(err[i]),
            tolerance,
            f"hold failed: {joint} is {err[i]:.4g} rad from the hold posture "
            f"(tolerance {tolerance:g} rad)",
        )
    i = int(np.argmax(fast))
    if not fast[i] > 0.0:
        return None
    joint = JOINT_NAMES[i]
    return (
        f"hold speed {joint}",
        float(abs(speed[i])),
        float(speed_limit[i]),
        f"hold failed: {joint} moves at {abs(speed[i]):.4g} rad/s (limit {speed_limit[i]:g} rad/s)",
    )


def yield_breach(
    q: np.ndarray,
    speed: np.ndarray,
    q_lower: np.ndarray,
    q_upper: np.ndarray,
    speed_limit: np.ndarray,
) -> tuple[str, float, float, str] | None:
    """The first limit the yield breaks, as (quantity, value, limit, message); None: none.

    Args:
        q: joint angles [rad], (4,).
        speed: joint speed magnitudes |q̇| [rad/s], (4,).
        q_lower: the range of motion's lower ends [rad], (4,).
        q_upper: its upper ends [rad], (4,).
        speed_limit: the speed limits [rad/s], (4,).

    The speed first (the first joint beyond), then the range.

    """
    for j in range(4):
        if speed[j] > speed_limit[j]:
            v, lim, name = float(speed[j]), float(speed_limit[j]), JOINT_NAMES[j]
            return f"yield speed {name}", v, lim, f"yield ended: {name} at {v:.4g} rad/s > {lim:g}"
    for j in range(4):
        lim = q_upper[j] if q[j] > q_upper[j] else (q_lower[j] if q[j] < q_lower[j] else None)
        if lim is not None:
            v, name = float(q[j]), JOINT_NAMES[j]
            return (
                f"yield angle {name}",
                v,
                float(lim),
                f"yield ended: {name} at {v:.4g} rad, outside [{q_lower[j]:.4g}, {q_upper[j]:.4g}]",
            )
    return None


def yield_damping(limits: ResolvedLimits, exo: BodyModel) -> np.ndarray:
    """d_y per joint, σ F_lim r / ω_max [N·m·s/rad], (4,) JOINT_NAMES order (module docstring)."""
    geo = CuffGeometry.from_body(exo)  # the lever arms of the device's model
    arms = np.array([geo.thigh_arm[0], geo.shank_arm[0], geo.thigh_arm[1], geo.shank_arm[1]])
    return YIELD_FORCE_SHARE * limits.cuff_limit * arms / limits.speed_limit


class YieldCommand:
    """The yield's command U_y (module docstring), on the device's models.

    Args:
        exo: the exoskeleton model the device holds.
        patient: the nominal patient model (None: the exoskeleton alone).
        motor: the drive's datasheet.
        damping: d_y per joint [N·m·s/rad], (4,).
        speed_limit: ω_max per joint [rad/s], (4,) (the speed estimate's clip).
        dt: control period Δt [s].

    Attributes:
        speed: the filtered speed ω̂ [rad/s], (4,).
        torque: the last τ_y [N·m], (4,).

    """

    def __init__(
        self,
        exo: BodyModel,
        patient: BodyModel | None,
        motor: MotorParams,
        damping: np.ndarray,
        speed_limit: np.ndarray,
        dt: float,
    ) -> None:
        self.damping = np.array(damping, dtype=float)
        if self.damping.shape != (4,) or not np.all(np.isfinite(self.damping)):
            raise InvalidParameter("yield_damping", damping, "4 finite numbers >= 0 [N·m·s/rad]")
        if np.any(self.damping < 0.0):
            raise InvalidParameter("yield_damping", damping, "4 finite numbers >= 0 [N·m·s/rad]")
        self._bodies = []
        for body in (exo, patient):
            if body is not None:
                model = pin.Model(body.model)
                self._bodies.append((model, model.createData(), body, np.zeros(model.nq)))
        self._drive = drive_model(motor)
        self._limit = np.array(speed_limit, dtype=float)
        self._dt = dt
        self._alpha = 1.0 - math.exp(-2.0 * math.pi * SPEED_FILTER_HZ * dt)
        self.speed = np.zeros(4)
        self.torque = np.zeros(4)
        self._q_prev = np.zeros(4)

    def start(self, q: np.ndarray, dq: np.ndarray) -> None:
        """Start the speed filter at the stop: ω̂ from the speed reading, q_{k−1} = q."""
        self.speed[:] = np.where(np.isfinite(dq), dq, 0.0)
        np.clip(self.speed, -self._limit, self._limit, out=self.speed)
        self._q_prev[:] = q

    @property
    def posture(self) -> np.ndarray:
        """The last finite angle reading per joint [rad], (4,) (a view, do not modify)."""
        return self._q_prev

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """g_exo(q) + g_patient(q), the device's models [N·m], (4,) JOINT_NAMES order."""
        tau = np.zeros(4)
        for model, data, body, qm in self._bodies:
            qm[body.q_index] = q
            tau += pin.computeGeneralizedGravity(model, data, qm)[body.q_index]
        return tau

    def command(self, q: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Advance ω̂ by this tick's reading q [rad] and write U_y into ``out`` [V].

        A joint whose reading is not finite keeps its last speed and posture.
        """
        ok = np.isfinite(q)
        diff = np.where(ok, (q - self._q_prev) / self._dt, self.speed)
        self.speed += self._alpha * (diff - self.speed)
        np.clip(self.speed, -self._limit, self._limit, out=self.speed)
        self._q_prev[ok] = q[ok]
        tau = self.gravity(self._q_prev)
        tau -= self.damping * self.speed
        self.torque[:] = tau
        for j in range(4):
            out[j] = steady_voltage(tau[j], self.speed[j], self._drive)
        return out
