"""The QP controller's fallbacks: the safe command of a tick the QP could not answer.

:class:`QPFallbacks` is a part of
:class:`~exo_ctrl.control.qp.controller.QPController` (its module docstring,
"Fallback", states the order); every fallback tick is counted in
``record["failures"]`` with its reason as the status.
"""

from __future__ import annotations

import numpy as np

from .tick import volts

__all__ = ["QPFallbacks"]


class QPFallbacks:
    """The fallbacks of :class:`~exo_ctrl.control.qp.controller.QPController`.

    Uses the controller's ``record``, ``torque``, ``torque_cmd``,
    ``torque_lo``, ``torque_hi``, ``_u`` and ``_u_max``.
    """

    record: np.ndarray
    torque: np.ndarray
    torque_cmd: np.ndarray
    torque_lo: np.ndarray
    torque_hi: np.ndarray
    _u: np.ndarray
    _u_max: float
    _status_text: str

    def _fail(self, why: str) -> None:
        """Count a fallback tick, with ``why`` as its status."""
        rec = self.record
        rec["failures"] += 1
        rec["active_constraints"] = 0
        rec["solved"] = False
        self._status_text = why

    def _fallback(self, omega: np.ndarray, why: str) -> np.ndarray:
        """The safe command of the controller's module docstring, counted in ``failures``."""
        u_ct = self.record["u_ct"][0]
        if not (np.isfinite(u_ct).all() and np.isfinite(omega).all()):
            return self._zero_volts(f"non-finite reading or command ({why})")
        lo, hi = self.torque_lo, self.torque_hi
        empty = lo > hi
        if empty.any():
            np.clip(self.torque_cmd, np.minimum(lo, hi), hi, out=self.torque)
            self.torque[empty] = 0.0
            joints = ", ".join(str(j) for j in np.flatnonzero(empty))
            self._fail(f"fallback: empty torque box at joint(s) {joints} ({why})")
            volts(self.record, omega)
            return np.clip(self._u, -self._u_max, self._u_max, out=self._u)
        np.clip(self.torque_cmd, lo, hi, out=self.torque)
        self._fail(f"fallback: τ_cmd clipped to the torque box ({why})")
        volts(self.record, omega)
        return self._u

    def _zero_volts(self, why: str) -> np.ndarray:
        """Zero volts on every joint (a non-finite reading or command), counted."""
        self._fail(f"fallback: zero volts ({why})")
        self.record["solve_time_us"] = 0.0
        self._u.fill(0.0)
        self.torque.fill(0.0)
        return self._u
