"""The supervisor's per-tick check of the readings, in one compiled call.

A still encoder against the drive's current (:func:`~exo_ctrl.safety.still.still_winding`,
row STILL, inputs of length 4 only; first, while the record holds the voltage
sent last tick), the plausibility monitors (:func:`~exo_ctrl.safety.plausibility.plausibility`:
drive model, encoder step, stuck torque sensor, command age; rows DRIVE …
AGE of the monitor record's ``excess``), the torque sensor's consistency
with the drive's current (:func:`~exo_ctrl.safety.consistency.consistency`,
row CONSIST, inputs of length 4 only) and then the limit monitor
(:func:`~exo_ctrl.safety.monitor.monitor`: its own rows, ``worst`` and
``passed`` over every row), as :class:`~exo_ctrl.safety.SafetySupervisor`
runs them each tick.  One call instead of four saves three dispatches (about
0.3 µs each plus the repeated arguments, :mod:`exo_ctrl.sim.tick`); the
arithmetic is the four kernels'.
"""

from __future__ import annotations

import numpy as np

from .. import _validate as v
from .._jit import Status, check, kernel
from .consistency import consistency
from .monitor import monitor
from .plausibility import plausibility
from .still import still_winding

__all__ = ["check_readings"]


@kernel
def check_readings(
    cuff_force: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray,
    tau: np.ndarray,
    current_A: np.ndarray,
    u_cmd: np.ndarray,
    age_s: float,
    t: float,
    checks: bool,
    plausible: np.ndarray,
    state: np.ndarray,
) -> int:  # pragma: no cover - compiled
    """The plausibility monitors (``checks``), then the limit monitor; the latter's status.

    With ``checks``, when q, q̇, τ and the currents are 4 each, the still
    encoder's check (:mod:`.still`) runs before the plausibility monitors and the
    torque-sensor consistency (:mod:`.consistency`) after them.

    Args:
        cuff_force: cuff forces (x, z), (4, 2) [N].
        q: joint angles, (4,) [rad].
        dq: joint speeds, (4,) [rad/s].
        tau: joint torque readings, (4,) [N·m].
        current_A: drive current readings, (4,) [A].
        u_cmd: the controller's command, (4,) [V].
        age_s: the command's age [s].
        t: time of the tick [s].
        checks: run the plausibility monitors.
        plausible: their record (:data:`~exo_ctrl.safety.plausibility.PLAUSIBILITY_FIELDS`).
        state: the monitor record (:data:`~exo_ctrl.safety.monitor.MONITOR_FIELDS`).

    Returns:
        The limit monitor's ``Status`` value: WRONG_LENGTH when an input is
        not of its length (the plausibility monitors, which do not read the
        cuff forces and currents, have run on the others if those are of length 4).

    """
    if checks:
        fours = q.shape[0] == dq.shape[0] == tau.shape[0] == current_A.shape[0] == 4
        if fours:
            still_winding(q, current_A, plausible, state)
        plausibility(q, dq, tau, u_cmd, age_s, plausible, state)
        if fours:
            consistency(q, dq, tau, current_A, plausible, state)
    return monitor(cuff_force, q, dq, tau, current_A, u_cmd, t, state)


def refuse_readings(status: int, f: object, *vectors: object) -> None:
    """Raise for :func:`check_readings`' ``status``, naming the input at fault.

    ``f`` the cuff forces, ``vectors`` the joint angles, speeds, torques, currents
    and the command, as :meth:`~exo_ctrl.safety.SafetySupervisor.step` was given them.
    """
    names = ("sensors_q", "sensors_dq", "sensors_tau", "current_A", "u_cmd")
    inputs = dict(zip(names, vectors, strict=True))
    if status == Status.WRONG_LENGTH and all(np.shape(x) == (4,) for x in vectors):
        v.refuse_shapes((4, 2), cuff_force=f)
    check(status, "SafetySupervisor.step", **inputs)
