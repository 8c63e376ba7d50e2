r"""The stop reactions: ``hold`` the posture, or ``yield`` to the patient.

The supervisor (:mod:`.supervisor`) stops the gait on a violation.  How it
stops is its *stop reaction*:

- ``hold``: ramp to gravity compensation plus a stiff PD on the posture at
  the stop (the supervisor's module docstring).  Right when the device is in
  charge and the patient passive: the legs stay where they were.  Against an
  ACTIVE patient who keeps walking it is a position lock: the campaign
  (``tools/faults.py --mode transparent --stop-reaction hold``) measured
  263 N on a thigh cuff and 160 N on a shank cuff after the stop (ISO/TS
  15066: 220 N, 130 N).  A hold the patient pushes against yields at once,
  while a release still keeps every cuff within its limit (:mod:`.release`).
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
  uncompensated: no force feedback, the torque sensors may be the fault; after
  the QP's departure stop, which no sensor caused, fed back: :mod:`.yield_command`),
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

**The ramp** (:attr:`YieldCommand.ramp_s`).  The ramp from the last
command U_0 holds part of U_0, and a held voltage is a speed command: the
drive's back-EMF pulls the joint toward its speed at the stop ω_0 with
(1 − α) D (ω − ω_0), D = i_G k_m (i_G/k_E)/R = 208 N·m·s/rad.  A patient
in charge leaves ω_0 at up to q̈_p (:data:`PATIENT_ACCELERATION_RAD_S2`),
so over a ramp of T_y that torque peaks at D q̈_p T_y / 4 (t = T_y/2); kept
within the damping's share of the cuff budget, d_y ω_max = σ F_lim r:

.. math::  T_y = \min_j \frac{4\, d_{y,j}\, ω_{max,j}}{D\, q̈_p},

11 ms with the defaults (the knees; 16 ms at the hips), against the
hold's 0.2 s.  Measured on the transparent campaign (tools/faults.py
--mode transparent, seeds 0–3, every fault; the transparent law of the
time): the worst thigh/shank forces after the stop 196/198 N with the
0.2 s ramp, 143/173 N with 50 ms, 139/140 N with 20 ms, 137/110 N with
11 ms, 158/86 N switching at once; with 0.2 s a slipped cuff's free leg
was driven on at its hip's speed at the stop, 237 N on the thigh cuff.
The per-tick step of the command is |U_y − U_0| Δt / T_y.

*From a hold* the yield starts at once, with no ramp.  The premise above is
a held speed command; the hold's command is a position lock, U_g +
k_p (q_h − q) − k_d q̇ recomputed every tick (the default k_p = 300 V/rad is
K_p = k_p i_G k_m / R = 13.5 kN·m/rad at the joint), and the patient who
pushes against it has the joints at rest (ω_0 ≈ 0).  The (1 − α) of it a
ramp keeps goes on holding the limb that loads the cuff, so the force goes
on rising at its rate ḟ for about T_y/2 more: in tests/safety/test_hold_pushed.py,
yielding on the force over its limit, the shank's true force peaked at
144 N with T_y = 11 ms against 137 N switched at once (limit 130 N).  The
step the switch makes in the drive torque is the hold's reaction to the
cuff force, released; the cuff's spring keeps the force continuous while
it accelerates the exoskeleton's link after the limb.  The rest of that
overshoot was the trigger's (:mod:`.release`): yielding while a release
still keeps the cuffs within their limits, the worst true forces from the
switch on are 152 N (thigh) and 116 N (shank).  (Measured on the patient model
before its reflex damping acted at once; on the model since, a patient
with 2.5× the default reflex stiffness keeps pushing the released limb,
past the limits: tests/safety/test_hold_pushed.py.)

**The patient's feet on the belt** (``ContactParams.patient_feet`` with the
pelvis supported, :meth:`YieldCommand.stand`).  At a stop the harness
locks the pelvis and the patient stands on the stopped belt: a leg whose
foot is down stands on it, a leg in the air sinks onto it against d_y, and
a patient who carries their own legs is not lifted against their own
torques.  So the yield (and the hold it ends in) compensates the
exoskeleton's gravity alone.  Measured on the QP's departure stop
(:mod:`.departure`, ``tools/load_held.py --cuff-sensors full``, points 2,
7 and 54: active patients walking on against the stopped device): the
thigh cuffs at 119–126 N with the patient's legs compensated too (bounds
109–112 N), 60–104 N without; scaling each leg's compensation by the
share of its weight the shoes' load cells read on the belt left them at
119–125 N (the legs in the air are the active patient's own to carry).
And after an e-stop with the yield (``--preset clinic-bws`` on its former
1.2 s gait, CT, the patient's feet on, stops at 0.9, 1.5 and 2.1 s) the largest cuff force
after the stop: 42–45 N passive, 58–66 N spastic, 114–129 N active, against
57–60, 71–83 and 147–150 N with the patient's legs compensated too.

**The speed \hat ω**: the encoder's difference (q_k − q_{k−1})/Δt through a
first-order filter of :data:`SPEED_FILTER_HZ` = 150 Hz (as the interaction
modes' back-EMF compensation, :class:`~exo_ctrl.control.modes.ModeParams`),
started at the stop from the sensors' speed reading.  The sensors' own
30 Hz speed lags 5 ms: compensating the back-EMF with it leaves
D × 5 ms ≈ 1.0 kg·m² of felt inertia per joint (the knee's own
exoskeleton inertia is about 0.5 kg·m² plus 0.29 kg·m² of rotor); 150 Hz
leaves 0.2 kg·m².  It is clipped to ± the joint's speed limit (beyond it
the power is cut anyway).

**When the yield ends.**  (a) A joint beyond its speed limit (the
supervisor's limit), checked from the end of the ramp on: power cut (the
short-circuit brake above).  A joint outside its range of motion, checked
likewise, is braked alone and only outward: the short-circuit brake's
damping D on its outward speed (:meth:`YieldCommand.brake_outside`), so it
goes no further out than its yield torque over D allows and comes back
freely; the patient segments it carries are no longer carried (their mass
dropped from the yield's patient model until the next stop: an attached
patient joint cannot leave its range, so beyond it the leg is taken as
off the exoskeleton, and pushing less is the safe side if it is not); the
others keep yielding.  A shank cuff slipped off in ``transparent`` lets
the free exoskeleton knee swing out of its range 0.6–1.7 s after the slip
(tools/faults.py, seeds 0–7).  Cutting every drive then locked the leg
against the walking patient (thigh cuff 244–431 N over the seeds that
stopped); braking the knee outward alone still left the yield lifting
the straight exoskeleton leg with the weight of a patient shank it no
longer carried (247 N, seed 6); with that weight dropped, 56–144 N.
(b) The legs at rest:
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

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..estimation.cuff_geometry import CuffGeometry
from ..exceptions import InvalidParameter
from ..model import JOINT_NAMES, BodyModel
from .limits import ResolvedLimits
from .yield_command import (
    PATIENT_ACCELERATION_RAD_S2,
    SPEED_FILTER_HZ,
    YIELD_FORCE_SHARE,
    YieldCommand,
)

__all__ = [
    "PATIENT_ACCELERATION_RAD_S2",
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
    speed: np.ndarray, speed_limit: np.ndarray
) -> tuple[str, float, float, str] | None:
    """The speed limit that ends the yield, as (quantity, value, limit, message); None: none.

    Args:
        speed: joint speed magnitudes |q̇| [rad/s], (4,).
        speed_limit: the speed limits [rad/s], (4,).

    The first joint beyond its limit.  (A joint outside its range of motion
    does not end the yield: :meth:`YieldCommand.brake_outside` brakes it alone.)

    """
    for j in range(4):
        if speed[j] > speed_limit[j]:
            v, lim, name = float(speed[j]), float(speed_limit[j]), JOINT_NAMES[j]
            return f"yield speed {name}", v, lim, f"yield ended: {name} at {v:.4g} rad/s > {lim:g}"
    return None


def yield_damping(limits: ResolvedLimits, exo: BodyModel) -> np.ndarray:
    """d_y per joint, σ F_lim r / ω_max [N·m·s/rad], (4,) JOINT_NAMES order (module docstring)."""
    arms = CuffGeometry.from_body(exo).joint_arms()  # the lever arms of the device's model
    return YIELD_FORCE_SHARE * limits.cuff_limit * arms / limits.speed_limit
