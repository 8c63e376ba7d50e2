r"""Exercises other than the gait: the calibration swing that identification needs.

``calibration`` swings both legs in the air about a flexed rest posture, from
rest to rest, for the run's duration T (at least :data:`MIN_CALIBRATION_S`).
Each joint j follows

    q_j(t) = c_j + e(t) Σ_k a_jk sin(2π f_jk t + φ_jk),

with the envelope e(t) = S(t / T_r) S((T - t) / T_r) (S the quintic
smoothstep of :mod:`exo_ctrl.plan.ramp`, T_r = :data:`ENVELOPE_S`): e, ė and
ë vanish at both ends, so the plan starts and ends at rest and is C².

The sum holds a slow large swing and a fast small one per joint
(:data:`CALIBRATION_SINES`): the slow one moves the legs through postures
far apart (the gravity terms: the first moments m c), the fast one
accelerates them (the inertia terms: I about the joint).  The frequencies
differ between hip and knee and are not multiples of each other, so that the
columns of the regressor stay apart (:mod:`exo_ctrl.estimation.identification`
reports the condition number: 6.7 on the default 6 s run, columns
normalised).  All frequencies stay well below the cuffs' natural frequency
(about 8 Hz for the shank on 8 N/mm), where exoskeleton and patient move as
one: with a fast sine at 1.7-2.3 Hz the cuffs' dynamics added 10 % to the
apparent shank inertia; at 0.8-1.05 Hz they add about 4 % (the default
patient).  No motion of the fixed-hip legs separates a segment's mass from
its ratios (:mod:`exo_ctrl.estimation.excitation`).
The right leg runs half a slow period behind the left, so the two legs do
not swing in phase.

Chosen values, not from the paper: the rest posture hip 0.75 rad, knee
1.6 rad (flexion positive) and the amplitudes keep the joints within
[0.30, 1.24] rad (hip) and [1.28, 1.92] rad (knee), the feet at least
7.8 cm above the belt line of the default 0.90 m hip height (at least
:data:`BELT_CLEARANCE_M` is required) and the hip gravity torque of a
thigh near horizontal away (a rest posture at 1.3 rad took the hip drive to
148 of its 150 N·m).  On the default 6 s run (default patient, CT): peak
planned speed 1.6 rad/s, within the default drive's 5.18 rad/s no-load
speed; peak sensor torque 99 N·m (left hip); peak cuff force 84 N.
"""

from __future__ import annotations

import math

import numpy as np

from .. import _validate as v
from ..exceptions import InvalidParameter
from ..model import SIDES, BodyModel
from .kinematics import JointTrajectory, check_range, forward_kinematics
from .ramp import smoothstep

__all__ = [
    "BELT_CLEARANCE_M",
    "CALIBRATION_DURATION_S",
    "CALIBRATION_REST_RAD",
    "CALIBRATION_SINES",
    "ENVELOPE_S",
    "EXERCISES",
    "MIN_CALIBRATION_S",
    "calibration_plan",
]

#: The exercises a run can do (``SimConfig.exercise``).
EXERCISES = ("gait", "calibration")

#: The calibration's rest posture (hip, knee) [rad], flexion positive.
CALIBRATION_REST_RAD = (0.75, 1.6)

#: Per joint (hip, knee): the (amplitude [rad], frequency [Hz]) of each sine.
CALIBRATION_SINES = (
    ((0.40, 0.25), (0.12, 0.8)),
    ((0.35, 0.35), (0.10, 1.05)),
)

#: T_r, the envelope's rise and fall time [s].
ENVELOPE_S = 0.5

#: Shortest calibration run [s]: the rise, the fall and most of a slow period between.
MIN_CALIBRATION_S = 3.0

#: The calibration's length when none is given [s] (``exo-ctrl simulate``).
CALIBRATION_DURATION_S = 6.0

#: Smallest height of a foot above the belt line during the calibration [m].
BELT_CLEARANCE_M = 0.05


def _envelope(t: np.ndarray, duration: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """e, ė, ë of the module docstring at ``t`` [s]."""
    a, da, dda = smoothstep(t / ENVELOPE_S)
    b, db, ddb = smoothstep((duration - t) / ENVELOPE_S)
    da, dda = da / ENVELOPE_S, dda / ENVELOPE_S**2
    db, ddb = -db / ENVELOPE_S, ddb / ENVELOPE_S**2
    return a * b, da * b + a * db, dda * b + 2.0 * da * db + a * ddb


def calibration_plan(
    body: BodyModel, t: np.ndarray, duration_s: float, hip_height_m: float
) -> JointTrajectory:
    """The calibration swing (module docstring) of ``body`` at times ``t`` [s].

    Args:
        body: the exoskeleton model (its ranges of motion and leg lengths).
        t: the sample times [s], within [0, ``duration_s``].
        duration_s: T, the exercise's length [s], at least :data:`MIN_CALIBRATION_S`.
        hip_height_m: the hips' height above the belt [m] (the feet stay
            :data:`BELT_CLEARANCE_M` above it).

    Raises:
        InvalidParameter: a duration shorter than :data:`MIN_CALIBRATION_S`;
            a joint leaving its range of motion, or a foot coming closer
            than :data:`BELT_CLEARANCE_M` to the belt, for this body.

    """
    duration = v.positive("duration", duration_s, "s")
    if duration < MIN_CALIBRATION_S:
        raise InvalidParameter(
            "duration",
            duration_s,
            f">= {MIN_CALIBRATION_S:g} s for the calibration exercise",
            f"the swing rises and falls over {ENVELOPE_S:g} s each with its slow swing between",
        )
    t = np.asarray(t, dtype=float)
    e, de, dde = _envelope(t, duration)
    n = t.size
    q, dq, ddq = np.empty((n, 4)), np.empty((n, 4)), np.empty((n, 4))
    slow = CALIBRATION_SINES[0][0][1]
    for s, side in enumerate(SIDES):
        lag = 0.0 if side == "left" else 0.5 / slow
        for k, (rest, sines) in enumerate(
            zip(CALIBRATION_REST_RAD, CALIBRATION_SINES, strict=True)
        ):
            x, dx, ddx = np.zeros(n), np.zeros(n), np.zeros(n)
            for amplitude, freq in sines:
                w = 2.0 * math.pi * freq
                arg = w * (t - lag)
                x += amplitude * np.sin(arg)
                dx += amplitude * w * np.cos(arg)
                ddx -= amplitude * w * w * np.sin(arg)
            j = 2 * s + k
            q[:, j] = rest + e * x
            dq[:, j] = de * x + e * dx
            ddq[:, j] = dde * x + 2.0 * de * dx + e * ddx
    check_range(body, t, q, "calibration")
    phi = np.empty((n, 4))
    feet = np.empty((n, 2, 2))
    feet_vel = np.empty((n, 2, 2))
    for s, side in enumerate(SIDES):
        leg = body.legs[side]
        l1, l2 = leg.thigh_length, leg.shank_length
        p1, p2 = leg.joint_to_absolute(q[:, 2 * s], q[:, 2 * s + 1])
        d1 = leg.sign_hip * dq[:, 2 * s]
        d2 = d1 + leg.sign_knee * dq[:, 2 * s + 1]
        phi[:, 2 * s], phi[:, 2 * s + 1] = p1, p2
        feet[:, s, 0], feet[:, s, 1] = forward_kinematics(p1, p2, l1, l2)
        feet_vel[:, s, 0] = -l1 * np.sin(p1) * d1 - l2 * np.sin(p2) * d2
        feet_vel[:, s, 1] = l1 * np.cos(p1) * d1 + l2 * np.cos(p2) * d2
        low = int(np.argmin(feet[:, s, 1]))
        if feet[low, s, 1] < -hip_height_m + BELT_CLEARANCE_M:
            raise InvalidParameter(
                f"{side} foot height on the calibration",
                round(float(feet[low, s, 1] + hip_height_m), 4),
                f">= {BELT_CLEARANCE_M:g} m above the belt",
                f"m, at t = {t[low]:.4g} s with the hips {hip_height_m:g} m above it",
            )
    return JointTrajectory(t=t, q=q, dq=dq, ddq=ddq, phi=phi, foot_pos=feet, foot_vel=feet_vel)
