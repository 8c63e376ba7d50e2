"""Plausibility of a sensor log against the device it claims to come from.

A log in the wrong units reads as numbers all the same: angles in degrees
are 57 times too large (``estimate`` reported 870 N at 100 rad against a
range of motion of [-0.05, 2.09] rad), times in hours make every step 3600
times too short, a gap in ``t`` makes one step huge.  :func:`implausibility`
finds the first sample far outside what the exoskeleton's URDF allows:

- a time step: the median step outside [:data:`MIN_STEP_S`,
  :data:`MAX_STEP_S`], or one step over :data:`STEP_RATIO` times the median;
- an angle more than :data:`ANGLE_MARGIN_RAD` beyond the joint's range;
- a speed (the log's ``*_dq``, else the angles' differences) over
  :data:`SPEED_FACTOR` times the joint's speed limit.

The margins are generous: a real log passes with room to spare, a log in the
wrong unit does not.
"""

from __future__ import annotations

import numpy as np

from ..model import JOINT_NAMES, BodyModel

__all__ = [
    "ANGLE_MARGIN_RAD",
    "MAX_STEP_S",
    "MIN_STEP_S",
    "SPEED_FACTOR",
    "STEP_RATIO",
    "implausibility",
]

#: How far beyond the URDF's range of motion an angle may read [rad] (about 29°).
ANGLE_MARGIN_RAD = 0.5
#: How many times the URDF's speed limit a joint speed may read.
SPEED_FACTOR = 3.0
#: How many times the median time step one step may last.
STEP_RATIO = 10.0
#: The shortest and longest median time steps a log may have [s] (100 kHz, 1 Hz).
MIN_STEP_S = 1e-5
MAX_STEP_S = 1.0


def implausibility(
    t: np.ndarray, q: np.ndarray, dq: np.ndarray | None, exo: BodyModel
) -> tuple[int | None, str, str] | None:
    """The first implausible sample of a log, or None.

    Args:
        t: times [s], (N,), strictly increasing.
        q: joint angles [rad], (N, 4), in :data:`JOINT_NAMES` order.
        dq: joint speeds [rad/s], (N, 4), or None (then the angles' differences).
        exo: the exoskeleton (its URDF's range of motion and speed limits).

    Returns:
        (row index from 0, or None for the log as a whole; column name; what
        is wrong with the value and the limit it breaks), or None when the
        log is plausible.

    """
    steps = np.diff(t)
    if steps.size:
        median = float(np.median(steps))
        if not MIN_STEP_S <= median <= MAX_STEP_S:
            return (
                None,
                "t",
                f"the median time step is {median:.4g} s, outside [{MIN_STEP_S:g}, "
                f"{MAX_STEP_S:g}] s (times in another unit?)",
            )
        far = np.flatnonzero(steps > STEP_RATIO * median)
        if far.size:
            k = int(far[0]) + 1
            return (
                k,
                "t",
                f"t = {t[k]:.6g} s comes {steps[k - 1]:.4g} s after the sample before, over "
                f"{STEP_RATIO:g} times the median step {median:.4g} s (a gap in the log?)",
            )
    lower, upper = exo.position_limits
    lo, hi = lower - ANGLE_MARGIN_RAD, upper + ANGLE_MARGIN_RAD
    bad = (q < lo) | (q > hi)
    if bad.any():
        k, j = (int(x) for x in np.argwhere(bad)[0])
        return (
            k,
            f"{JOINT_NAMES[j]}_q",
            f"{q[k, j]:.4g} rad is far outside the range of motion [{lower[j]:.4g}, "
            f"{upper[j]:.4g}] rad of {exo.source} (more than {ANGLE_MARGIN_RAD:g} rad beyond; "
            "angles in degrees?)",
        )
    speed = dq if dq is not None else np.diff(q, axis=0) / steps[:, None]
    column = "_dq" if dq is not None else "_q (its differences)"
    limit = SPEED_FACTOR * exo.velocity_limit
    bad = np.abs(speed) > limit
    if bad.any():
        k, j = (int(x) for x in np.argwhere(bad)[0])
        k_row = k if dq is not None else k + 1
        return (
            k_row,
            f"{JOINT_NAMES[j]}{column}",
            f"a speed of {speed[k, j]:.4g} rad/s is over {SPEED_FACTOR:g} times the speed limit "
            f"{exo.velocity_limit[j]:.4g} rad/s of {exo.source}",
        )
    return None
