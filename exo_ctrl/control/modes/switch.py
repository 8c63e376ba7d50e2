r"""Bumpless switching between controllers: a session's segments behind the one interface.

A session (:mod:`exo_ctrl.sim.session`) runs its segments' controllers one
after another.  Segment i runs from tick K_i; at a switch the new
controller starts from the readings (its own state initialised from them:
the free command's speed filter from the measured speed, aan's support
table empty, path's phase from the clock) and the command is blended
linearly from the old controller's to the new one's over N_b ticks:

.. math::  U_k = (1 − λ_k)\,U^{old}_k + λ_k\,U^{new}_k,
           \qquad λ_k = \frac{k − K_i + 1}{N_b + 1},\quad K_i ≤ k < K_i + N_b,

both controllers running in the window (λ = 1 after it).  **The bound**:
as U_k − U_{k−1} = (1 − λ_k) ΔU^{old}_k + λ_k ΔU^{new}_k
+ (λ_k − λ_{k−1}) (U^{new}_{k−1} − U^{old}_{k−1}), the command's change over
one tick K_i ≤ k ≤ K_i + N_b is at most

.. math::  |U_k − U_{k−1}| ≤ \max(|ΔU^{old}_k|, |ΔU^{new}_k|)
           + \frac{g}{N_b + 1},

each controller's own change over the tick plus the gap g = |U^{new} − U^{old}|
(at tick k − 1; at K_i, where the new one has no tick before, the gap at
K_i and ΔU^{old} alone) shared over the window; the gap is at most 2 U_max
(both commands within the supply ±U_max), so a switch adds at most
2 U_max / (N_b + 1) per tick: 0.475 V with the default 24 V supply and
0.1 s at 1 kHz (N_b = 100), against the whole gap at once without blending
(tests/sim/test_session.py measures the gaps: 0.3 V tracking → aan, 3.6 V
aan → transparent with a weak active patient).  Each switch is an event
``{"t", "kind": "mode_switch", "message"}`` in :attr:`SwitchedController.events`.

A mode may tune the run's estimator (``transparent``: the Kalman filter's
σ_d, :meth:`~exo_ctrl.control.modes.InteractionController.tune_estimator`):
at each switch the new segment's controller's wish is applied, or the
filter's own σ_d restored (``estimator_torque_rate_Nm_per_sqrt_s``: None).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..._jit import kernel, record
from ...exceptions import InvalidParameter
from ...sensing.readings import SensorReadings
from ..base import COMMAND_FIELDS, CommandCounters

__all__ = ["SWITCH_FIELDS", "SwitchedController", "blend_command"]

#: The switcher's part of the record (after COMMAND_FIELDS): the segment
#: running, λ of the last tick, and the largest gap |U_new − U_old| seen
#: in a blend window [V].
SWITCH_FIELDS: list[tuple[Any, ...]] = [
    ("segment", np.int64),
    ("blend", np.float64),
    ("max_gap", np.float64),
]


class SwitchedController(CommandCounters):
    """Runs ``controllers[i]`` from tick ``starts[i]``, blending each switch (module docstring).

    Args:
        controllers: one controller per segment (each with ``command``).
        names: each segment's name in the events (its mode).
        starts: K_i, the first tick of each segment (K_0 = 0, increasing).
        blend_ticks: N_b ≥ 0, the blend window [ticks] (0: a hard switch).
        dt: the control period Δt [s] (for the events' times).

    Raises:
        InvalidParameter: no controller, starts not one per controller,
            not from 0 or not increasing, or a negative window.

    """

    def __init__(
        self,
        controllers: Sequence[Any],
        names: Sequence[str],
        starts: Sequence[int],
        blend_ticks: int,
        dt: float,
    ) -> None:
        if not controllers or len(names) != len(controllers):
            raise InvalidParameter("names", tuple(names), "one name per controller")
        if len(starts) != len(controllers):
            raise InvalidParameter(
                "starts", tuple(starts), f"one start tick per controller ({len(controllers)})"
            )
        if starts[0] != 0 or any(b <= a for a, b in itertools.pairwise(starts)):
            raise InvalidParameter("starts", tuple(starts), "increasing ticks from 0")
        if blend_ticks < 0:
            raise InvalidParameter("blend_ticks", blend_ticks, "an integer >= 0")
        self.controllers = list(controllers)
        self.names = list(names)
        self.starts = [int(s) for s in starts]
        self.blend_ticks = int(blend_ticks)
        self.dt = dt
        self.name = "session"
        self.record = record(COMMAND_FIELDS + SWITCH_FIELDS)
        self.events: list[dict[str, Any]] = []
        self._u = self.record["u_cmd"][0]
        self._seg = 0
        self._next = self.starts[1] if len(self.starts) > 1 else None
        self._estimator: object | None = None

    @property
    def segment(self) -> int:
        """The segment running."""
        return self._seg

    def tune_estimator(self, estimator: object) -> None:
        """Keep the run's estimator to tune at each switch; tune it for the first segment."""
        self._estimator = estimator
        self._tune()

    def _tune(self) -> None:
        """The running segment's σ_d into a Kalman filter (None: the filter's own)."""
        set_rate = getattr(self._estimator, "set_torque_rate", None)
        if set_rate is not None:
            ctrl = self.controllers[self._seg]
            set_rate(getattr(ctrl, "estimator_torque_rate_Nm_per_sqrt_s", None))

    def command(self, k: int, sensors: SensorReadings) -> np.ndarray:
        """Drive voltages [V] for tick k: a view of ``record["u_cmd"]``."""
        if self._next is not None and k >= self._next:
            self._switch(k)
        seg = self._seg
        new = self.controllers[seg].command(k, sensors)
        since = k - self.starts[seg]
        lam = 1.0
        old = new
        if seg > 0 and since < self.blend_ticks:
            old = self.controllers[seg - 1].command(k, sensors)
            lam = (since + 1) / (self.blend_ticks + 1)
        blend_command(self.record, old, new, lam)
        return self._u

    def _switch(self, k: int) -> None:
        """Start the next segment at tick k and log the event."""
        before = self.names[self._seg]
        self._seg += 1
        self.record["segment"] = self._seg
        after = self.names[self._seg]
        self._next = self.starts[self._seg + 1] if self._seg + 1 < len(self.starts) else None
        self._tune()
        t = k * self.dt
        self.events.append(
            {
                "t": t,
                "kind": "mode_switch",
                "message": f"segment {self._seg + 1}: {before} → {after} at t = {t:.4g} s "
                f"(blended over {self.blend_ticks * self.dt:g} s)",
            }
        )


@kernel
def blend_command(state, u_old, u_new, lam):  # pragma: no cover - compiled
    """U = (1 − λ) U_old + λ U_new into ``state[0].u_cmd`` [V]; tracks the largest gap."""
    s = state[0]
    s.blend = lam
    for j in range(4):
        if lam < 1.0:
            gap = abs(u_new[j] - u_old[j])
            if gap > s.max_gap:
                s.max_gap = gap
        s.u_cmd[j] = (1.0 - lam) * u_old[j] + lam * u_new[j]
