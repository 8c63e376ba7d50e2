r"""The departure stop: a QP that leaves its plan on the belt stops the walk first.

The QP holds its cuff bound by leaving the plan where the patient loads the
cuffs beyond it (:mod:`exo_ctrl.control.qp.margin`).  In free air (no belt)
a leg off its plan only tracks worse.  Over the belt it strikes the belt or
is dragged by it, a load outside every horizon the QP holds: with the
pelvis supported the feet walk on the moving belt, and with it fixed they
skim it (the default scenario's spastic patient at a 120 N bound on a
1.0 s, 0.4 m gait: the QP left the plan by 0.3 rad RMS and the feet's
strikes took a thigh cuff to 263 N).  Measured on ``tools/load_held.py``'s
supported points, safety off: a spastic or active patient whose own torques
the device cannot know before the run left the plan by 0.2–0.8 rad, and the
strikes that followed took the cuffs 10–45 % past their bound; stopped at
the first departure beyond 0.15 rad (an e-stop at that tick, the yield
reaction) every one of nine such points stayed within its bound
(docs/performance.md).

So with the feet over the belt and the QP's bound tightened, every control
tick compares the encoders' joint angles with the plan's row, and a knee's
folding beyond its plan by the time a stop takes hold,

.. math::

    d = \max\big(\max_j |e_j|,\ \max_{j\,\in\,\text{knees}} (e_j + T\,\dot e_j)\big),\qquad
    e = q - q^*,\ \dot e = \dot q - \dot q^*

(knee flexion positive),

against

.. math::

    δ = h_s / (l_1 + l_2)

beyond which the device stops the walk: the supervisor's controlled stop with the
``yield`` reaction (:mod:`.stop_reaction`: gravity compensation and damping,
so the patient's own torques move the legs against a bounded force; a hold
against them took the cuffs 29–57 % past the bound on two active points),
the harness locked and the belt run down as at any stop.  δ is the swing
foot's clearance over the leg's length: a hip departure δ moves the foot by
at most (l_1 + l_2) δ = h_s, the lift the plan gives it (h_s the gait's
``lift_height``, l_1 + l_2 the device's exoskeleton thigh and shank; 0.096
rad with the defaults).  The stop belongs to the bound's promise: it acts
with the safety supervisor off too (the supervisor then serves stops only,
as for an e-stop), and not when the bound is not tightened.

**The look-ahead T** (:func:`harness_arrest_s`).  A stance knee the QP lets
fold under its bound drops the pelvis, and the swing foot with it: the stop
locks the harness, but the brake (a spring–damper K, C at the height of the
lock, :mod:`exo_ctrl.plant.pelvis`) arrests the falling pelvis only after

.. math::

    T = \frac{\operatorname{atan2}(\sqrt{1-ζ^2},\ ζ)}{ω\sqrt{1-ζ^2}},\qquad
    ω = \sqrt{K/M},\ ζ = \frac{C}{2\sqrt{K M}}

(the first zero of the speed of a damped oscillator started at its rest
point with a speed; T = ln(s_1/s_2)/(s_1 − s_2), s_{1,2} = ω(ζ ± √(ζ²−1)), when
ζ > 1, and 1/ω at ζ = 1), M the mass the guide moves (the patient's body
mass, which the trainer's unloading is set from, and the exoskeleton's
links).  With the defaults T = 33–48 ms over 50–110 kg (the default
exoskeleton, 17 kg).  On the campaign (``tools/load_held.py --cuff-sensors
full``, seed 0) the present departure alone (T = 0) stopped point 118
(active, pelvis supported, bound 105 N) at 1.656 s with the stance knee
sinking at 0.9 rad/s and the pelvis falling at 0.25 m/s: the patient's swing
foot, 6 mm below the exoskeleton's sole (the knee 1.9 cm off), landed 6 ms
after the stop, the belt stopped the patient's shank and the exoskeleton's
knee, still extending at 2.2 rad/s, ran into it through the cuff (115.9 N,
+10.3 %, with the yield's force feedback, :mod:`.yield_command`; 137.0 N
without).  With T the same point stops in its first cycle (1.02 s) within
its bound (−0.7 %; docs/performance.md, the QP's cuff-force bound).  Only a
knee folding beyond its plan drops the hip: looking ahead on every joint in
either direction also stopped the ``clinic-spastic`` preset's own QP walk
(`--controller qp`, 30 % support) at 2.83 s, its swing knee held 0.08 rad
short of its plan by the reflex and the pelvis rising, a departure that
peaks at 0.083 rad, and 8 more of the 64 spastic walks of
``tools/touchdowns.py --controller qp`` (0.078–0.094 rad).  With the pelvis
fixed nothing falls: T = 0.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .. import _validate as v
from .._jit import kernel, preload
from ..model import JOINT_NAMES

__all__ = ["DepartureMonitor", "departure_limit_rad", "harness_arrest_s"]


def departure_limit_rad(lift_height_m: float, leg_length_m: float) -> float:
    """δ = h_s / (l_1 + l_2) [rad] (module docstring).

    Raises:
        InvalidParameter: a lift or a leg length not > 0.

    """
    lift = v.positive("lift_height", lift_height_m, "m")
    return lift / v.positive("leg length", leg_length_m, "m")


def harness_arrest_s(stiffness_N_per_m: float, damping_N_s_per_m: float, mass_kg: float) -> float:
    """T, the time the locked harness takes to arrest a falling pelvis [s] (module docstring).

    Args:
        stiffness_N_per_m: K of the harness's brake [N/m].
        damping_N_s_per_m: C of the harness's brake [N·s/m].
        mass_kg: M, the mass the guide moves [kg].

    Raises:
        InvalidParameter: K or M not > 0, C < 0.

    """
    k = v.positive("pelvis stop stiffness", stiffness_N_per_m, "N/m")
    c = v.non_negative("pelvis stop damping", damping_N_s_per_m, "N·s/m")
    m = v.positive("pelvis moving mass", mass_kg, "kg")
    omega = math.sqrt(k / m)
    zeta = c / (2.0 * math.sqrt(k * m))
    if zeta < 1.0:
        root = math.sqrt(1.0 - zeta * zeta)
        return math.atan2(root, zeta) / (omega * root)
    if zeta == 1.0:
        return 1.0 / omega
    root = math.sqrt(zeta * zeta - 1.0)
    s1, s2 = omega * (zeta + root), omega * (zeta - root)
    return math.log(s1 / s2) / (s1 - s2)


class DepartureMonitor:
    """The largest joint departure from the plan, and the knees' folding T ahead, against δ.

    (Module docstring.)

    Args:
        limit_rad: δ [rad].
        lookahead_s: T [s] (0: the present departure alone).

    Raises:
        InvalidParameter: a limit not > 0, a look-ahead < 0.

    """

    def __init__(self, limit_rad: float, lookahead_s: float = 0.0) -> None:
        self.limit_rad = v.positive("departure limit", limit_rad, "rad")
        self.lookahead_s = v.non_negative("departure look-ahead", lookahead_s, "s")
        self._out = np.zeros(2)  # d and |e| of the joint furthest off
        self._knee = np.array([name.endswith("_knee") for name in JOINT_NAMES])

    def preload(self, q: np.ndarray) -> None:
        """Load :func:`departure` for readings of ``q``'s type (before a timed run)."""
        preload(departure, q, q, q, q, self.lookahead_s, self._knee, self._out)

    def check(
        self, t: float, q: np.ndarray, dq: np.ndarray, q_plan: np.ndarray, dq_plan: np.ndarray
    ) -> dict[str, Any] | None:
        """The stop's cause at time t [s] when d > δ, else None.

        Args:
            t: the tick's time [s].
            q: the encoders' joint angles, (4,) [rad].
            dq: the joint speed readings, (4,) [rad/s].
            q_plan: the plan's row, (4,) [rad].
            dq_plan: the plan's speeds on that row, (4,) [rad/s].

        Returns:
            The supervisor's event fields (``quantity``, ``value`` the departure
            d, ``limit``, ``message``) of the joint furthest from its plan; None
            within δ.  A non-finite speed reading leaves the present departure
            alone; a non-finite angle is the supervisor's own violation.

        """
        out = self._out
        j = departure(q, dq, q_plan, dq_plan, self.lookahead_s, self._knee, out)
        if j < 0 or not out[0] > self.limit_rad:
            return None
        d, e = float(out[0]), float(out[1])
        name = JOINT_NAMES[j]
        ahead = (
            f", {d:.3f} rad within the harness's arrest ({1e3 * self.lookahead_s:.0f} ms)"
            if d > e
            else ""
        )
        return {
            "quantity": f"departure_{name}",
            "value": d,
            "limit": self.limit_rad,
            "message": (
                f"the {name} left the plan by {e:.3f} rad at t = {t:.4f} s{ahead} (limit "
                f"{self.limit_rad:.3f} rad, the swing foot's lift over the leg's length): the QP "
                "holds its cuff bound by leaving the plan, and on the belt a leg off its plan "
                "can strike it"
            ),
        }


@kernel
def departure(q, dq, q_plan, dq_plan, lookahead_s, knee, out):  # pragma: no cover - compiled
    """The joint furthest off its plan (module docstring), its d and |e| into ``out``.

    d_j = |e_j|, for a knee (``knee[j]``) max(|e_j|, e_j + T ė_j), its folding T ahead.
    Writes d and |e| of that joint into ``out`` (2,) and returns its index; −1
    when no angle reading is finite.  A joint whose angle is not finite is
    skipped; one whose speed is not finite counts |e_j| alone.
    """
    best = -1
    out[0] = -1.0
    out[1] = 0.0
    for j in range(4):
        e = q[j] - q_plan[j]
        if not math.isfinite(e):
            continue
        a = abs(e)
        d = a
        if knee[j]:
            ahead = e + lookahead_s * (dq[j] - dq_plan[j])
            if ahead > a:  # (a NaN speed: False)
                d = ahead
        if d > out[0]:
            best = j
            out[0] = d
            out[1] = a
    return best
