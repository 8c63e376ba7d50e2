"""The paper's PD voltage controller (§V)."""

from __future__ import annotations

from typing import Any, NoReturn

import numpy as np

from .. import _validate as v
from .._jit import Status, check, kernel, record
from ..exceptions import InvalidParameter
from ..plan.kinematics import JointTrajectory
from ..plan.rows import plan_row
from ..sensing.readings import SensorReadings
from .base import COMMAND_FIELDS, CommandCounters, PDGains

__all__ = ["PD_FIELDS", "PDController", "pd_command", "pd_law"]

#: The PD law's part of a controller's record (after :data:`~exo_ctrl.control.base.COMMAND_FIELDS`):
#: the gains k_p [V/rad] and k_d [V·s/rad]; the plan's row rule
#: (:func:`~exo_ctrl.plan.rows.plan_row`: ramp-in ticks ``lead``, ``period`` in
#: rows, 0: row k is tick k, first ramp-out tick ``tail``); the plan row of the
#: last tick.
PD_FIELDS: list[tuple[Any, ...]] = [
    ("kp", np.float64, (4,)),
    ("kd", np.float64, (4,)),
    ("lead", np.int64),
    ("period", np.int64),
    ("tail", np.int64),
    ("row", np.int64),
]


class PDController(CommandCounters):
    """U = k_p (q* - q) + k_d (q̇* - q̇) per drive [V].

    Args:
        plan: joint targets at the control ticks: row k for tick k, or the
            row of :func:`~exo_ctrl.plan.rows.plan_row` for a plan holding
            its ramps and one period.
        gains: the PD gains.

    Attributes:
        record: the controller's state (:data:`~exo_ctrl.control.base.COMMAND_FIELDS`
            and :data:`PD_FIELDS`); ``u_cmd`` is the last command.

    """

    name = "pd"

    def __init__(self, plan: JointTrajectory, gains: PDGains | None = None) -> None:
        self.plan = plan
        self.gains = gains or PDGains()
        self.record = record(self._fields())
        s = self.record[0]
        s["kp"] = self.gains.kp
        s["kd"] = self.gains.kd
        s["lead"], s["period"], s["tail"] = plan.row_rule
        self._q_des, self._dq_des = plan.q, plan.dq
        #: The feedforward voltage per plan row [V]: one zero row for the plain PD.
        self._u_ff = np.zeros((1, 4))
        self._u = self.record["u_cmd"][0]

    def _fields(self) -> list[tuple[Any, ...]]:
        """The dtype fields of :attr:`record` (a subclass adds its own)."""
        return COMMAND_FIELDS + PD_FIELDS

    def command(self, k: int, sensors: SensorReadings) -> np.ndarray:
        """PD (+ feedforward) voltages [V] for tick k: a view of ``record["u_cmd"]``.

        Raises:
            InvalidParameter: readings not of 4 joint values, or a tick beyond
                the plan.

        """
        q, dq = sensors.q, sensors.dq
        if not (type(q) is type(dq) is np.ndarray):
            q, dq = v.arrays((4,), sensors_q=q, sensors_dq=dq)
        status = pd_command(self.record, self._q_des, self._dq_des, self._u_ff, k, q, dq)
        if status:
            self.refuse(status, k, q, dq)
        return self._u

    def command_arguments(self) -> tuple[np.ndarray, ...]:
        """:func:`pd_command`'s arguments before the tick and the readings, for a fused tick.

        (:mod:`exo_ctrl.sim.fused`; the command is then ``record["u_cmd"][0]``.)
        """
        return self.record, self._q_des, self._dq_des, self._u_ff

    def refuse(self, status: int, k: int, q: np.ndarray, dq: np.ndarray) -> NoReturn:
        """Raise for a tick :func:`pd_law` refused (its docstring)."""
        rows = self._q_des.shape[0]
        row = self.plan.row(k)
        if not 0 <= row < rows:
            raise InvalidParameter("k", k, f"a control tick on the plan's {rows} rows")
        check(status, f"{type(self).__name__}.command", sensors_q=q, sensors_dq=dq)
        raise AssertionError(f"unreachable: status {status!r}")  # pragma: no cover

    @property
    def last_row(self) -> int:
        """The plan row of the last tick."""
        return int(self.record["row"][0])


@kernel
def pd_law(
    kp: np.ndarray,
    kd: np.ndarray,
    lead: int,
    period: int,
    tail: int,
    q_des: np.ndarray,
    dq_des: np.ndarray,
    u_ff: np.ndarray,
    k: int,
    q: np.ndarray,
    dq: np.ndarray,
    out: np.ndarray,
) -> tuple[int, int]:  # pragma: no cover - compiled
    """Write k_p (q*[r] - q) + k_d (q̇*[r] - q̇) + U_ff[r] [V] to ``out``, r: tick k's plan row.

    r = :func:`~exo_ctrl.plan.rows.plan_row` (k, ``lead``, ``period``,
    ``tail``): k for a period of 0, else k mod ``period`` after the ``lead``
    ramp-in rows, then the ramp-out rows from tick ``tail``.  ``u_ff``: the
    feedforward voltage per plan row, or one row for every tick (row r mod
    its length).  Returns (status, r), the status a
    :class:`~exo_ctrl._jit.Status` value: WRONG_LENGTH (nothing written)
    unless q and q̇ have 4 entries and r is a row of the plan.
    """
    if q.shape[0] != 4 or dq.shape[0] != 4:
        return Status.WRONG_LENGTH.value, 0
    row = plan_row(k, lead, period, tail)
    if row < 0 or row >= q_des.shape[0]:
        return Status.WRONG_LENGTH.value, 0
    ff = u_ff[row % u_ff.shape[0]]
    for j in range(4):
        out[j] = (kp[j] * (q_des[row, j] - q[j]) + kd[j] * (dq_des[row, j] - dq[j])) + ff[j]
    return Status.OK.value, row


@kernel
def pd_command(
    state: np.ndarray,
    q_des: np.ndarray,
    dq_des: np.ndarray,
    u_ff: np.ndarray,
    k: int,
    q: np.ndarray,
    dq: np.ndarray,
) -> int:  # pragma: no cover - compiled
    """A PD or CT tick: :func:`pd_law` into ``state[0].u_cmd``, its row; returns its status."""
    s = state[0]
    status, row = pd_law(
        s.kp, s.kd, s.lead, s.period, s.tail, q_des, dq_des, u_ff, k, q, dq, s.u_cmd
    )
    if status == Status.OK.value:
        s.row = row
    return status
