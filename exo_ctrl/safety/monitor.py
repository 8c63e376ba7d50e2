r"""The limit monitor: which channel exceeds its limit, and by how much.

Every control tick the monitor compares 28 channels with their limits, in
seven groups of four (cuffs in CUFF_NAMES order, joints in JOINT_NAMES
order), and writes each channel's excess e = value - limit:

=========  ===================  ====================================
group      excess e             unit of the value
=========  ===================  ====================================
CUFF       f_x² + f_z² - F²     N (e in N²; F the cuff force limit)
UPPER      q - q_upper          rad
LOWER      (-q) - (-q_lower)    rad (that is q_lower - q)
SPEED      |q̇| - q̇_max          rad/s
CURRENT    |i| - i_max          A
TORQUE     |τ| - DBL_MAX        N·m (finiteness only)
VOLTAGE    |U| - DBL_MAX        V (finiteness only, the command)
=========  ===================  ====================================

Six more groups, the plausibility monitors (drive model residual, encoder
step, torque sensor unchanged, command age; the torque sensor's consistency
with the drive's current, :mod:`exo_ctrl.safety.consistency`; a still encoder
against the drive's current, :mod:`exo_ctrl.safety.still`), are written into the rows after
these by :func:`exo_ctrl.safety.plausibility.plausibility` before this
kernel runs, and a last one, the belt's speed against the speed its forces
predict (one channel; :mod:`exo_ctrl.safety.belt_monitor`), with the belt; it counts them
in ``worst`` and ``passed`` like its own (56 channels in all).

A channel is violated when ``not e <= 0``: e > 0, or e NaN (a NaN reading),
or e = +inf (an infinite one).  The tick's ``worst`` is the sum of the
violated excesses (0 when all is well, > 0 or NaN if not).

The monitor's state is one record (:data:`MONITOR_FIELDS`); the kernel
:func:`monitor` reads the limits from it and writes the excesses, ``worst``
and ``passed`` into it.  ``passed`` (the tick is normal and nothing is
violated, so the controller's command goes to the drives unchanged) is what
the caller branches on; on such a tick the kernel also keeps the posture and
the command, the last good ones, for the controlled stop.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._jit import Status, kernel, record
from ..model import CUFF_NAMES, JOINT_NAMES
from .limits import ResolvedLimits

__all__ = [
    "CUFF",
    "CURRENT",
    "GROUPS",
    "LOWER",
    "MONITOR_FIELDS",
    "SPEED",
    "TORQUE",
    "UPPER",
    "VOLTAGE",
    "Channel",
    "channels",
    "monitor",
    "monitor_record",
]

#: Channel groups: the rows of the record's ``excess`` and ``limit``.  The
#: last seven (drive, jump, stuck, age, consistency, still; belt) are the plausibility
#: monitors' (:mod:`exo_ctrl.safety.plausibility`, :mod:`exo_ctrl.safety.consistency`,
#: :mod:`exo_ctrl.safety.still`) and the belt monitor's
#: (:mod:`exo_ctrl.safety.belt_monitor`), written before this kernel runs
#: (their limits +DBL_MAX, never violated, unless the supervisor sets them).
CUFF, UPPER, LOWER, SPEED, CURRENT, TORQUE, VOLTAGE = range(7)
#: The groups' names, in row order.
GROUPS = (
    "cuff", "upper", "lower", "speed", "current", "torque", "voltage",
    "drive", "jump", "stuck", "age", "consistency", "still", "belt",
)  # fmt: skip
#: Groups of the limit monitor itself (this kernel writes their excesses).
LIMIT_GROUPS = 7

#: The monitor's record (numpy dtype fields; one element, see :func:`_jit.record`).
MONITOR_FIELDS = [
    # Excess of each channel over its limit, (group, joint or cuff); see the table.
    ("excess", np.float64, (len(GROUPS), 4)),
    # Each channel's limit as the kernel subtracts it: F² [N²], q_upper,
    # -q_lower [rad], q̇_max [rad/s], i_max [A], DBL_MAX, DBL_MAX.
    ("limit", np.float64, (len(GROUPS), 4)),
    # Sum of the violated excesses this tick (0: none; > 0 or NaN: a violation).
    ("worst", np.float64),
    # This tick is normal and nothing is violated: the command passes unchanged.
    ("passed", np.bool_),
    # The supervisor's state code (0 normal, 1 stopping, 2 holding, 3 power
    # cut; exo_ctrl.safety.limits.STATES), kept by the supervisor.
    ("state", np.float64),
    # Emergency-stop time [s] (inf: none); from then on no tick is normal.
    ("estop_s", np.float64),
    # The posture [rad] and the command [V] of the last tick that passed.
    ("q_last", np.float64, (4,)),
    ("u_last", np.float64, (4,)),
]


def monitor_record(limits: ResolvedLimits, estop_s: float) -> np.ndarray:
    """A monitor record holding ``limits`` (state normal, no good tick yet).

    Args:
        limits: the resolved limits.
        estop_s: emergency-stop time [s] (``math.inf``: none).

    Returns:
        The record, a structured array of one element with :data:`MONITOR_FIELDS`.

    """
    state = record(MONITOR_FIELDS)
    big = np.finfo(float).max
    state["limit"][0] = np.stack(
        (
            limits.cuff_limit**2,
            limits.q_upper,
            -limits.q_lower,
            limits.speed_limit,
            limits.current_limit,
            np.full(4, big),
            np.full(4, big),
            *(np.full(4, big) for _ in GROUPS[LIMIT_GROUPS:]),
        )
    )
    state["estop_s"] = estop_s
    state["q_last"] = np.nan
    return state


@kernel
def monitor(
    cuff_force: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray,
    tau: np.ndarray,
    current_A: np.ndarray,
    u_cmd: np.ndarray,
    t: float,
    state: np.ndarray,
) -> int:
    """Compare the tick's readings with the limits (module docstring).

    Args:
        cuff_force: cuff forces (x, z), (4, 2) [N].
        q: joint angles, (4,) [rad].
        dq: joint speeds, (4,) [rad/s].
        tau: joint torque sensor readings, (4,) [N·m].
        current_A: drive currents, (4,) [A].
        u_cmd: the controller's voltage command, (4,) [V].
        t: time of the tick [s].
        state: the monitor record (:data:`MONITOR_FIELDS`).

    Returns:
        ``Status.WRONG_LENGTH`` (as its integer value; nothing written) when
        an input is not of length 4 (the cuff forces: not (4, 2));
        otherwise ``Status.OK``, with ``excess``, ``worst`` and ``passed``
        written (and ``q_last``, ``u_last`` when the tick passed).

    """
    if (
        q.shape[0] != 4
        or dq.shape[0] != 4
        or tau.shape[0] != 4
        or current_A.shape[0] != 4
        or u_cmd.shape[0] != 4
        or cuff_force.shape[0] != 4
        or cuff_force.shape[1] != 2
    ):
        return Status.WRONG_LENGTH.value
    s = state[0]
    e = s.excess
    lim = s.limit
    for i in range(4):
        fx = cuff_force[i, 0]
        fz = cuff_force[i, 1]
        e[CUFF, i] = fx * fx + fz * fz - lim[CUFF, i]
        e[UPPER, i] = q[i] - lim[UPPER, i]
        e[LOWER, i] = -q[i] - lim[LOWER, i]
        e[SPEED, i] = abs(dq[i]) - lim[SPEED, i]
        e[CURRENT, i] = abs(current_A[i]) - lim[CURRENT, i]
        e[TORQUE, i] = abs(tau[i]) - lim[TORQUE, i]
        e[VOLTAGE, i] = abs(u_cmd[i]) - lim[VOLTAGE, i]
    worst = 0.0
    for g in range(e.shape[0]):
        for i in range(4):
            x = e[g, i]
            if not x <= 0.0:
                worst += x  # a NaN stays NaN
    passed = s.state == 0.0 and t < s.estop_s and worst <= 0.0
    if passed:
        for i in range(4):
            s.q_last[i] = q[i]
            s.u_last[i] = u_cmd[i]
    s.worst = worst
    s.passed = passed
    return Status.OK.value


@dataclass(frozen=True)
class Channel:
    """One monitored channel, as events name it.

    Attributes:
        group: its group (:data:`CUFF` ... :data:`VOLTAGE`).
        quantity: its name (``"cuff force left_shank"``, ``"angle left_knee"``).
        unit: the unit of its value.
        limit: its limit as reported [unit]: the cuff force limit F (not
            F²), the lower angle limit (not negated); 0 for the finiteness
            channels (their limit is not reported).

    """

    group: int
    quantity: str
    unit: str
    limit: float

    def finite_only(self, excess: float) -> bool:
        """Whether the violation is a non-finite reading (no value to report)."""
        return self.group in (TORQUE, VOLTAGE) or not math.isfinite(excess)

    def describe(self, excess: float) -> tuple[float, str]:
        """The value that violated the limit, from its ``excess`` > 0, and a sentence.

        The value is ``sqrt(e + F²)`` for a cuff, ``q_lower - e`` for a lower
        angle limit, ``e + limit`` otherwise.
        """
        q, u, limit = self.quantity, self.unit, self.limit
        if self.group == CUFF:  # excess is |f|² - limit²
            value = math.sqrt(excess + limit * limit)
            return value, f"{q} {value:.4g} {u} > limit {limit:.4g} {u}"
        if self.group == UPPER:
            value = excess + limit
            return value, f"{q} {value:.4g} {u} > upper limit {limit:.4g} {u}"
        if self.group == LOWER:
            value = limit - excess
            return value, f"{q} {value:.4g} {u} < lower limit {limit:.4g} {u}"
        value = excess + limit
        return value, f"|{q}| {value:.4g} {u} > limit {limit:.4g} {u}"


def channels(
    limits: ResolvedLimits,
    use_estimate: bool | str,
    plausible: np.ndarray | None = None,
    belt_limit: float | None = None,
) -> tuple[Channel, ...]:
    """The 56 channels in the order of the record's ``excess`` flattened (group-major).

    Args:
        limits: the resolved limits (reported in the events).
        use_estimate: the cuff forces are estimates (``"estimated cuff force ..."``); a
            string: the cuff forces' name.
        plausible: the plausibility groups' limits, (6, 4)
            (:func:`~exo_ctrl.safety.plausibility.plausibility_limits`; None: DBL_MAX).
            The consistency group's value is |r| less its model bound
            (:mod:`~exo_ctrl.safety.consistency`); the still group's the mean
            current outside the still winding's band (:mod:`~exo_ctrl.safety.still`).
        belt_limit: the belt speed deviation's limit [m/s]
            (:mod:`~exo_ctrl.safety.belt_monitor`; None: DBL_MAX, no belt).
            Its group's one channel is ``"belt speed deviation"``; the
            other three are never written.

    """
    force = "estimated cuff force" if use_estimate else "cuff force"
    if isinstance(use_estimate, str):
        force = use_estimate
    zero = np.zeros(4)
    table = (
        (force, "N", limits.cuff_limit, CUFF_NAMES),
        ("angle", "rad", limits.q_upper, JOINT_NAMES),
        ("angle", "rad", limits.q_lower, JOINT_NAMES),
        ("speed", "rad/s", limits.speed_limit, JOINT_NAMES),
        ("current", "A", limits.current_limit, JOINT_NAMES),
        ("torque sensor", "N·m", zero, JOINT_NAMES),
        ("voltage command", "V", zero, JOINT_NAMES),
    )
    if plausible is None:
        plausible = np.full((6, 4), np.finfo(float).max)
    table += (
        ("drive model residual", "N·m", plausible[0], JOINT_NAMES),
        ("encoder step", "rad", plausible[1], JOINT_NAMES),
        ("equal torque readings", "", plausible[2], JOINT_NAMES),
        ("command age", "s", plausible[3], JOINT_NAMES),
        ("torque sensor vs current", "N·m", plausible[4], JOINT_NAMES),
        ("still encoder vs current", "A", plausible[5], JOINT_NAMES),
    )
    big = np.finfo(float).max
    belt = (big if belt_limit is None else float(belt_limit), big, big, big)
    table += (("belt speed deviation", "m/s", belt, ("", "unused 1", "unused 2", "unused 3")),)
    return tuple(
        Channel(g, f"{name} {label}".strip(), unit, float(lim[i]))
        for g, (name, unit, lim, labels) in enumerate(table)
        for i, label in enumerate(labels)
    )
