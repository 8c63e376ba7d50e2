r"""The swing leg's acceleration feedforward, blended in over its lift-off.

The paper's swing paths are C¹ (:mod:`exo_ctrl.plan.gait`): at lift-off (D)
the foot's planned acceleration relative to the hip jumps from the stance's
(zero) to the swing cubic's, ẍ = 2 k₂ forward and z̈ = 6 h_s / d² up at
once (d = T_sw/2: 11.7 and 6.7 m/s² for the default gait).  Computed
torque's feedforward, inverse dynamics on the plan, turns the jump into a
torque step: measured on the default run (pelvis fixed), the right hip's
drive torque went from 4 to 128 N·m in 4 ms while the sole was still
pressed into the belt.  The drive then throws the foot forward before it
has cleared the sole's compression, and the foot slides: 0.115 m/s of slip
at lift-off, against PD's 0.031 m/s (whose torque waits for an error to
build up).

So the foot's planned acceleration a* enters the feedforward through a
quintic blend in the time u since the leg's planned lift-off
(the plan's ``lift_off_s``, :meth:`~exo_ctrl.plan.gait.GaitPlan.since_lift_off`):

.. math::

    α(u) = S(u / T_b), \quad S(x) = 10x^3 - 15x^4 + 6x^5 \ (x \in [0, 1]),

    \ddot q_b = J^{-1} (α\, a^* - \dot J \dot q^*)
             = \ddot q_s + α (\ddot q^* - \ddot q_s), \quad
    \ddot q_s = -J^{-1} \dot J \dot q^*,

J the foot point's Jacobian at q* on the device's own leg geometry
(:mod:`exo_ctrl.model.leg_kernels`) and q̈_s the joint acceleration that
keeps the foot's planned velocity (the stance's, at the instant of lift-off).
The feedforward is the inverse dynamics at (q*, q̇*, q̈_b)
(:mod:`exo_ctrl.control.computed_torque`); the targets q*, q̇* are the plan's,
so the PD takes what the blend leaves out.  S has S' = S'' = 0 at both ends:
the feedforward torque is continuous across lift-off and joins the plan's own
at u = T_b.  Only what the device knows enters: its plan and its leg model.
A run blends with the belt on only (:func:`~exo_ctrl.sim.tracking.lift_off_blend_for`):
in free air no foot is loaded at lift-off, and the QP's hips, held in its
torque box where they pass zero speed, tracked worse with the blend there
(1.13/0.97 against 0.92/0.76 mrad; tests/control/qp/test_closed_loop.py).

**T_b** = :data:`LIFT_OFF_BLEND_S` = 10 ms (chosen; the paper has no such
term): a few times the milliseconds the foot takes to clear the sole's
compression, and below the PD position loop's time constant (1/65 rad/s ≈
15 ms, :class:`~exo_ctrl.control.base.PDGains`), so that the PD has little
to catch up.  Measured on the default scenario (pelvis fixed; worst slip,
then the RMS tracking error left hip, left knee, right hip, right knee
[mrad]), computed torque: T_b = 0: 0.115 m/s, 0.58/0.74/0.56/0.74; 10 ms:
0.015 m/s, 0.51/0.75/0.50/0.74; 20 ms: 0.015 m/s, 0.46/0.76/0.47/0.75
(PD: 0.031 m/s).  The QP, which holds the thigh cuffs at its 120 N bound
while the leg catches up: T_b = 0: 0.105 m/s, 0.77/0.76/0.62/0.73;
10 ms: 0.015 m/s, 0.85/0.77/0.67/0.74; 20 ms: 0.015 m/s,
0.97/0.78/0.80/0.75.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._jit import kernel
from ..model.leg_kernels import foot_bias, foot_point

__all__ = ["LIFT_OFF_BLEND_S", "blend_lift_off"]

#: T_b: the swing leg's acceleration feedforward is blended in over this
#: time after its planned lift-off [s] (module docstring).
LIFT_OFF_BLEND_S = 0.01


@kernel
def blend_lift_off(
    legs: Any,
    q: np.ndarray,
    dq: np.ndarray,
    ddq: np.ndarray,
    lift: np.ndarray,
    blend_s: float,
    out: np.ndarray,
) -> None:
    """q̈_b of the module docstring into ``out`` (4,) [rad/s²].

    Args:
        legs: a record with the device's leg geometry
            (:func:`~exo_ctrl.model.leg_kernels.legs_record`).
        q: q* [rad], (4,).
        dq: q̇* [rad/s], (4,).
        ddq: q̈* [rad/s²], (4,).
        lift: u, each leg's time since its planned lift-off [s], (2,)
            (+inf in stance: no blend).
        blend_s: T_b [s]; 0: ``out`` = q̈*.
        out: q̈_b [rad/s²], (4,).

    """
    g = legs[0]
    for j in range(4):
        out[j] = ddq[j]
    for leg in range(2):
        u = lift[leg]
        if not 0.0 <= u < blend_s:
            continue
        x = u / blend_s
        a = x * x * x * (10.0 - 15.0 * x + 6.0 * x * x)
        i = 2 * leg
        _, _, jx0, jx1, jz0, jz1 = foot_point(g, leg, q[i], q[i + 1])
        bx, bz = foot_bias(g, leg, q[i], q[i + 1], dq[i], dq[i + 1])
        det = jx0 * jz1 - jx1 * jz0
        s0 = (jx1 * bz - jz1 * bx) / det  # J q̈_s = −J̇ q̇
        s1 = (jz0 * bx - jx0 * bz) / det
        out[i] = s0 + a * (ddq[i] - s0)
        out[i + 1] = s1 + a * (ddq[i + 1] - s1)
