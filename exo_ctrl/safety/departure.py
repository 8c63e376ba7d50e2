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
tick compares the encoders' joint angles with the plan's row,
d = max_j |q_j − q*_j|, and beyond

.. math::

    δ = h_s / (l_1 + l_2)

the device stops the walk: the supervisor's controlled stop with the
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
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .. import _validate as v
from ..model import JOINT_NAMES

__all__ = ["DepartureMonitor", "departure_limit_rad"]


def departure_limit_rad(lift_height_m: float, leg_length_m: float) -> float:
    """δ = h_s / (l_1 + l_2) [rad] (module docstring).

    Raises:
        InvalidParameter: a lift or a leg length not > 0.

    """
    lift = v.positive("lift_height", lift_height_m, "m")
    return lift / v.positive("leg length", leg_length_m, "m")


class DepartureMonitor:
    """The largest joint departure from the plan against δ (module docstring).

    Args:
        limit_rad: δ [rad].

    Raises:
        InvalidParameter: a limit not > 0.

    """

    def __init__(self, limit_rad: float) -> None:
        self.limit_rad = v.positive("departure limit", limit_rad, "rad")
        self._d = np.zeros(4)

    def check(self, t: float, q: np.ndarray, q_plan: np.ndarray) -> dict[str, Any] | None:
        """The stop's cause at time t [s] when d > δ, else None.

        Args:
            t: the tick's time [s].
            q: the encoders' joint angles, (4,) [rad].
            q_plan: the plan's row, (4,) [rad].

        Returns:
            The supervisor's event fields (``quantity``, ``value``, ``limit``,
            ``message``) of the joint furthest from its plan; None within δ.

        """
        d = self._d
        np.subtract(q, q_plan, out=d)
        np.abs(d, out=d)
        j = int(np.argmax(d))
        if not d[j] > self.limit_rad:  # (a non-finite reading is the supervisor's)
            return None
        name = JOINT_NAMES[j]
        return {
            "quantity": f"departure_{name}",
            "value": float(d[j]),
            "limit": self.limit_rad,
            "message": (
                f"the {name} left the plan by {d[j]:.3f} rad at t = {t:.4f} s (limit "
                f"{self.limit_rad:.3f} rad, the swing foot's lift over the leg's length): the QP "
                "holds its cuff bound by leaving the plan, and on the belt a leg off its plan "
                "can strike it"
            ),
        }
