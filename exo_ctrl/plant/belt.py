"""The treadmill belt: a body with its own speed, driven by a speed controller.

The belt's surface moves backwards (-x) at the belt speed v_b [m/s] (v_b > 0
when walking forwards).  Belt, rollers and the drive motor's rotor reflected
to the belt surface are one equivalent mass m_b [kg]; the drive is a PI
speed controller with a force limit at the belt surface,

    F_d = clip(m_b a_set + K_p e + K_i ∫e dt, ±F_max),   e = v_set - v_b,
    m_b dv_b/dt = F_d + Σ F_t,

where F_t is the friction force of the belt on each foot in x (a foot that
holds back against the belt feels F_t < 0 and slows the belt).  The integral
stops while the force is at its limit (no wind-up).  The set speed v_set is
the session's command (the plan's σ(t) v_f, :mod:`exo_ctrl.plan.ramp`), set
per control tick with its rate a_set (the feedforward m_b a_set: without it
the PI follows the 1.2 s ramp-in 3.6 cm/s late and overshoots by as much
after it, a slip the feet would see).  A real treadmill's drive follows a
commanded speed profile the same way (a profile generator with acceleration
feedforward).  The belt's position x_b = ∫v_b dt is what the roller's
encoder counts (:mod:`exo_ctrl.sensing.belt_encoder`).

**Parameters** (chosen for a rehabilitation treadmill of the class under
gait trainers, e.g. a 0.5 m × 1.5 m deck with a 2–3 kW drive; no source
gives them, so each is an estimate, checked against measured belts below,
and configurable):

- ``mass_kg = 20``: a rubber belt of about 0.5 m × 3.2 m × 3 mm (≈ 6 kg),
  two hollow steel rollers of ≈ 4 kg (their rotary inertia m r² / r² ≈ m at
  the surface, ≈ 8 kg) and the motor's rotor through the belt transmission
  (≈ 6 kg equivalent): the O(10–30 kg) of this class.
- ``bandwidth_hz = 30``: ω_c = 2π f_c; K_p = m_b ω_c (3770 N·s/m) and
  K_i = m_b ω_c² / 4 (1.78e5 N/m).  The closed loop m_b s² + K_p s + K_i = 0
  then has a double pole at s = -ω_c / 2 (critically damped, time constant
  2 / ω_c = 10.6 ms): a friction force stepping to F dips the belt by
  v(t) = (F / m_b) t e^{-ω_c t / 2}, at most 0.736 F / (m_b ω_c) at
  t = 2 / ω_c, and the controller returns it within about 50 ms.  Its
  static stiffness against a constant load is infinite (the integral);
  with ``integral=False`` (P only) a load F slows it by F / K_p.
  The check: measured treadmill belts run at 98–103 % of their set speed on
  average and dip by more than 5 % in the stance of running only (four
  treadmills, 1–4.5 m/s; Willwacher et al. 2021).  Walking's braking ground
  force, about 0.2 body weights (157 N at 80 kg; Winter 2009), dips this
  belt by 0.031 m/s, 3 % at 1 m/s.  The speed controller of a
  vector-controlled drive with an encoder closes at tens of hertz; a 2 Hz
  loop would let the same force dip the belt by 0.46 m/s, and under 30–50 %
  body-weight support at 0.37 m/s the feet would move it by −12 … +19 %.
- ``force_limit_N = 1000``: the drive's torque limit at the belt surface
  (a 2.5 kW drive delivers 1000 N at 2.5 m/s).

**The brake** (a fault, :mod:`exo_ctrl.sim.faults`' ``belt_stop``: a jammed
roller, or the treadmill's own emergency stop).  While the record's
``brake`` flag is set, the speed controller is out and a brake of force
limit F_br (``f_brake`` [N], by default the drive's F_max) holds the belt
surface at rest whatever the set speed: it applies the force that brings
the belt to rest within the step, F = -m_b v_b / h, clipped to ±F_br.  While
the clip binds the belt decelerates at (F_br + Σ F_t) / m_b (F_br / m_b =
50 m/s² with the defaults and no foot on it: 0.58 m/s stops in 12 ms); once
it is at rest it stays there (static friction of the brake): the feet's
friction impulses are solved against a fixed belt, and the brake takes up
their force as long as it stays within F_br (else the belt slips at the
limit).  The integral is frozen while braked.

**The drive's report** ``f_motor`` [N]: the force the treadmill's drive
reports applying, as its controller does (a device reading, e.g. for the
belt monitor, :mod:`exo_ctrl.safety.belt_monitor`): F_d while it runs, 0
while the brake has the speed controller out (the brake's force is not the
drive's, and no reading of it exists).

Integration, step h: the force is taken at the start of the step (explicit;
K_p h / m_b = ω_c h = 0.19 at 1 ms, far inside the bound 2), the friction
impulses of the feet over the step are added with the belt's inertia in the
foot-contact solve (:mod:`exo_ctrl.plant.contact`).

References:
    Willwacher S, Oberländer KD, Mai P, et al. (2021). A new method for
    measuring treadmill belt velocity fluctuations: effects of treadmill
    type, body mass and locomotion speed. Sci Rep 11:2244.
    Winter DA (2009). Biomechanics and Motor Control of Human Movement, 4th
    ed., Wiley, Appendix A (normal gait: ground reaction forces).

"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import _validate as v
from .._jit import kernel, record

__all__ = [
    "BELT_FIELDS",
    "BeltParams",
    "belt_commit",
    "belt_drive",
    "belt_response",
    "brake_holds",
]


@dataclass(frozen=True)
class BeltParams:
    """The treadmill belt and its speed controller (module docstring).

    Attributes:
        height_m: the belt's top below the exoskeleton's hip joint [m]; None:
            the plan's hip height H_s.
        mass_kg: m_b, belt + rollers + rotor as an equivalent mass [kg].
        bandwidth_hz: f_c of the speed controller [Hz]; K_p = m_b ω_c,
            K_i = m_b ω_c² / 4.
        force_limit_N: F_max, the drive's force limit at the belt surface [N].
        integral: use the integral term (False: P only).
        stop_decel_mps2: the treadmill's controlled stop when the device
            stops the gait: its set speed falls at this rate to rest [m/s²]
            (chosen: 3 m/s²; a stance foot the device holds at a stop travels
            with the belt v² / (2a) as it runs down, 5.6 cm from the default
            0.58 m/s, 17 cm at 1 m/s², more than a held leg follows within
            the hold's 0.1 rad; the default 0.58 m/s stops in 0.19 s).

    Raises:
        InvalidParameter: a height, mass, bandwidth, force limit or stop
            deceleration that is not a finite number > 0.

    """

    height_m: float | None = None
    mass_kg: float = 20.0
    bandwidth_hz: float = 30.0
    force_limit_N: float = 1000.0
    integral: bool = True
    stop_decel_mps2: float = 3.0

    def __post_init__(self) -> None:
        if self.height_m is not None:
            object.__setattr__(self, "height_m", v.positive("belt height", self.height_m, "m"))
        object.__setattr__(self, "mass_kg", v.positive("belt mass", self.mass_kg, "kg"))
        bw = v.positive("belt speed bandwidth", self.bandwidth_hz, "Hz")
        object.__setattr__(self, "bandwidth_hz", bw)
        f = v.positive("belt force limit", self.force_limit_N, "N")
        object.__setattr__(self, "force_limit_N", f)
        decel = v.positive("belt stop deceleration", self.stop_decel_mps2, "m/s²")
        object.__setattr__(self, "stop_decel_mps2", decel)

    @property
    def gains(self) -> tuple[float, float]:
        """(K_p [N·s/m], K_i [N/m]) of the speed controller."""
        w = 2.0 * math.pi * self.bandwidth_hz
        return self.mass_kg * w, (self.mass_kg * w * w / 4.0 if self.integral else 0.0)

    def into(self, belt: Any) -> None:
        """Write the parameters into a record of :data:`BELT_FIELDS` (``belt = rec[0]``)."""
        kp, ki = self.gains
        belt["mass"] = self.mass_kg
        belt["kp"], belt["ki"] = kp, ki
        belt["f_max"] = self.force_limit_N
        belt["f_brake"] = self.force_limit_N

    def new_record(self) -> np.ndarray:
        """A record of :data:`BELT_FIELDS` with these parameters, the belt at rest."""
        r = record(BELT_FIELDS)
        self.into(r[0])
        return r


#: Fields of the belt's record.  Parameters: ``mass`` m_b [kg], ``kp`` [N·s/m],
#: ``ki`` [N/m], ``f_max`` [N].  State: ``v`` belt speed v_b [m/s], ``x``
#: belt travel [m], ``integral`` ∫e dt [m].  Input: ``v_set`` [m/s] and
#: ``a_set`` its rate [m/s²].  Work of
#: the step: ``f_drive`` F_d [N], ``v_free`` v_b + h F_d / m_b [m/s],
#: ``v_next``, ``integral_next``: the state at the end of the step;
#: ``f_feet`` Σ F_t over the last step [N].  The brake (a fault): ``brake``
#: its flag (0 off), ``f_brake`` F_br [N]; of the step, ``f_stop`` the
#: brake's force before the feet [N], ``held`` 1 while it holds the belt at
#: rest, ``inv_m`` the belt's 1/m_b in the feet's friction solve [1/kg] (0
#: while held: a fixed belt).  ``f_motor``: the drive's report of its force
#: [N] (F_d; 0 while braked).
BELT_FIELDS = [
    *((name, np.float64) for name in ("mass", "kp", "ki", "f_max", "v", "x", "integral")),
    *(
        (name, np.float64)
        for name in ("v_set", "a_set", "f_drive", "v_free", "v_next", "integral_next")
    ),
    ("f_feet", np.float64),
    *((name, np.float64) for name in ("brake", "f_brake", "f_stop", "held", "inv_m")),
    ("f_motor", np.float64),
]


@kernel
def belt_drive(b: Any, h: float) -> None:
    """The drive force of the step and the belt speed without the feet (``b``: a belt record)."""
    e = b.v_set - b.v
    integral = b.integral + e * h
    f = b.mass * b.a_set + b.kp * e + b.ki * integral
    if f > b.f_max:
        f = b.f_max
        integral = b.integral  # no wind-up at the limit
    elif f < -b.f_max:
        f = -b.f_max
        integral = b.integral
    b.f_drive = f
    b.f_motor = f
    b.integral_next = integral
    b.v_free = b.v + h * f / b.mass
    b.v_next = b.v_free
    b.f_feet = 0.0
    b.held = 0.0
    b.inv_m = 1.0 / b.mass
    if b.brake != 0.0:
        _brake(b, h)


@kernel
def _brake(b: Any, h: float) -> None:
    """The braked belt's step (module docstring): F = clip(-m_b v_b / h, ±F_br), the PI out."""
    f = -b.mass * b.v / h
    b.integral_next = b.integral
    b.f_motor = 0.0  # the drive is out
    if abs(f) <= b.f_brake:
        b.f_stop = f
        b.f_drive = f
        b.v_free = 0.0
        b.v_next = 0.0
        b.held = 1.0  # at rest: the feet push against a fixed belt
        b.inv_m = 0.0
        return
    f = b.f_brake if f > 0.0 else -b.f_brake
    b.f_stop = f
    b.f_drive = f
    b.v_free = b.v + h * f / b.mass
    b.v_next = b.v_free


@kernel
def belt_commit(b: Any, h: float) -> None:
    """End of step: v_b, x_b and the integral take their new values (trapezoidal x_b)."""
    b.x += 0.5 * h * (b.v + b.v_next)
    b.v = b.v_next
    b.integral = b.integral_next


@kernel
def belt_response(
    belt: np.ndarray, v_set: float, load_N: np.ndarray, h: float, speed: np.ndarray
) -> None:
    """Step the belt record ``belt`` under a foot load, without feet (a check of the drive).

    Each step k: the set speed ``v_set`` [m/s] (rate 0), the feet's friction
    force on the belt ``load_N[k]`` [N] (the F_t of the module docstring: < 0
    holds the belt back), step ``h`` [s]; the speed at the end of each step
    into ``speed`` [m/s] (as long as ``load_N``).
    """
    b = belt[0]
    b.v_set = v_set
    b.a_set = 0.0
    for k in range(load_N.shape[0]):
        belt_drive(b, h)
        if b.held != 0.0 and brake_holds(b, load_N[k], h):
            b.v_next = 0.0
        else:
            b.v_next = b.v_free + h * load_N[k] / b.mass
        b.f_feet = load_N[k]
        belt_commit(b, h)
        speed[k] = b.v


@kernel
def brake_holds(b: Any, f_feet: float, h: float) -> bool:
    """Whether the brake holding the belt at rest also takes up the feet's force ``f_feet`` [N].

    Yes when |f_stop - f_feet| ≤ F_br (``f_drive`` becomes that force); no:
    the brake slips at its limit, ``f_drive`` = ±F_br, ``v_free`` the
    speed it leaves without the feet and ``inv_m`` = 1/m_b (the belt moves).
    """
    f = b.f_stop - f_feet
    if abs(f) <= b.f_brake:
        b.f_drive = f
        b.inv_m = 0.0
        return True
    f = b.f_brake if f > 0.0 else -b.f_brake
    b.f_drive = f
    b.v_free = b.v + h * f / b.mass
    b.inv_m = 1.0 / b.mass
    return False
