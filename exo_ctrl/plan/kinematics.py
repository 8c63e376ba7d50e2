"""Closed-form kinematics of a two-link leg in the sagittal plane.

Positions are of the foot point relative to the hip joint, x forward and
z up [m].  Angles are the paper's absolute link angles, measured from +x
towards +z [rad]: φ1 of the thigh (hip → knee), φ2 of the shank
(knee → foot).  Forward kinematics (paper §II):

    x = l1 cos φ1 + l2 cos φ2,   z = l1 sin φ1 + l2 sin φ2.

Inverse kinematics, knee forward (paper §II), with r² = x² + z²:

    φ1 = atan2(z, x) + arccos((l1² - l2² + r²) / (2 l1 r)),
    φ2 = φ1 - (π - arccos((l1² + l2² - r²) / (2 l1 l2))).

The paper writes arctan(z/x) with a branch for x ≤ 0 that jumps at x = 0
(the top of the swing); atan2 is the same function without the jump.  Its
φ2 = φ1 + π + γ is the same angle as the one above, modulo 2π.

Rates go through the leg Jacobian J = ∂(x, z)/∂(φ1, φ2):
ẋ = J φ̇ and ẍ = J φ̈ + J̇ φ̇, solved in closed form (det J = l1 l2 sin(φ2 - φ1)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import _validate as v
from ..exceptions import InvalidParameter, UnreachableFootTarget
from ..model import JOINT_NAMES, SIDES, BodyModel
from .gait import GaitPlan
from .ramp import RampedGait
from .rows import NO_TAIL, fill_rows, plan_row

__all__ = [
    "PLAN_BYTES_PER_SAMPLE",
    "JointTrajectory",
    "forward_kinematics",
    "inverse_kinematics",
    "joint_accelerations",
    "joint_rates",
    "plan_joints",
]


def forward_kinematics(
    phi1: np.ndarray, phi2: np.ndarray, l1: float, l2: float
) -> tuple[np.ndarray, np.ndarray]:
    """Foot position (x, z) relative to the hip [m] from absolute angles [rad]."""
    return l1 * np.cos(phi1) + l2 * np.cos(phi2), l1 * np.sin(phi1) + l2 * np.sin(phi2)


def inverse_kinematics(
    x: np.ndarray | float, z: np.ndarray | float, l1: float, l2: float
) -> tuple[np.ndarray, np.ndarray]:
    """Absolute angles (φ1, φ2) [rad] putting the foot at (x, z) [m], knee forward.

    Raises:
        UnreachableFootTarget: a point is closer than |l1 - l2| or farther
            than l1 + l2 from the hip.

    """
    x = np.asarray(x, dtype=float)
    z = np.asarray(z, dtype=float)
    r2 = x * x + z * z
    r = np.sqrt(r2)
    bad = (r > l1 + l2) | (r < abs(l1 - l2)) | (r == 0.0) | ~np.isfinite(r)
    if np.any(bad):
        i = np.flatnonzero(np.atleast_1d(bad))[0]
        px, pz = np.atleast_1d(x)[i], np.atleast_1d(z)[i]
        raise UnreachableFootTarget((float(px), float(pz)), (abs(l1 - l2), l1 + l2))
    cos_a = np.clip((l1 * l1 - l2 * l2 + r2) / (2.0 * l1 * r), -1.0, 1.0)
    cos_g = np.clip((l1 * l1 + l2 * l2 - r2) / (2.0 * l1 * l2), -1.0, 1.0)
    phi1 = np.arctan2(z, x) + np.arccos(cos_a)
    phi2 = phi1 - (np.pi - np.arccos(cos_g))
    return phi1, phi2


def joint_rates(
    phi1: np.ndarray, phi2: np.ndarray, l1: float, l2: float, dx: np.ndarray, dz: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Absolute angle rates (φ̇1, φ̇2) [rad/s] from the foot velocity (ẋ, ż) [m/s].

    Solves J φ̇ = ẋ with J = [[-l1 sin φ1, -l2 sin φ2], [l1 cos φ1, l2 cos φ2]].
    """
    s1, c1, s2, c2 = np.sin(phi1), np.cos(phi1), np.sin(phi2), np.cos(phi2)
    det = l1 * l2 * (c1 * s2 - s1 * c2)
    dphi1 = (l2 * c2 * dx + l2 * s2 * dz) / det
    dphi2 = (-l1 * c1 * dx - l1 * s1 * dz) / det
    return dphi1, dphi2


def joint_accelerations(
    phi1: np.ndarray,
    phi2: np.ndarray,
    dphi1: np.ndarray,
    dphi2: np.ndarray,
    l1: float,
    l2: float,
    ddx: np.ndarray,
    ddz: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Absolute angle accelerations [rad/s²] from the foot acceleration [m/s²].

    Solves J φ̈ = ẍ - J̇ φ̇, with
    J̇ φ̇ = (-l1 cos φ1 φ̇1² - l2 cos φ2 φ̇2², -l1 sin φ1 φ̇1² - l2 sin φ2 φ̇2²).
    """
    jdx = -l1 * np.cos(phi1) * dphi1**2 - l2 * np.cos(phi2) * dphi2**2
    jdz = -l1 * np.sin(phi1) * dphi1**2 - l2 * np.sin(phi2) * dphi2**2
    return joint_rates(phi1, phi2, l1, l2, ddx - jdx, ddz - jdz)


#: Memory :func:`plan_joints` takes per sample time at its peak [bytes], the
#: time array itself not counted: the result (q, q̇, q̈, φ: 16 numbers; foot
#: position and velocity: 8) and the temporaries of the foot paths and the
#: inverse kinematics.  Measured 370-380 B (tests/plan/test_kinematics.py
#: checks the bound).
PLAN_BYTES_PER_SAMPLE = 400


@dataclass(frozen=True)
class JointTrajectory:
    """Planned joint motion sampled at times ``t``.

    Joint arrays have shape (N, 4), columns in :data:`~exo_ctrl.model.JOINT_NAMES`
    order; ``phi`` has shape (N, 4): left φ1, left φ2, right φ1, right φ2.

    Attributes:
        t: sample times [s].
        q: joint angles [rad].
        dq: joint speeds [rad/s].
        ddq: joint accelerations [rad/s²].
        phi: the paper's absolute link angles [rad].
        foot_pos: foot positions relative to the hips, (N, 2 legs, x/z) [m].
        foot_vel: foot velocities, (N, 2, 2) [m/s].
        period_ticks: when set, the rows hold the ramp-in ticks, one period
            of a periodic plan and the ramp-out ticks, sampled at the control
            ticks (:mod:`exo_ctrl.plan.rows`); None: row k is tick k.
        lead_ticks: L, the ramp-in ticks before the period (with a period).
        tail_tick: K, the first tick of the ramp-out rows (with a period;
            None: no ramp-out).
        hip: (N, 3): the hip's planned rise above H_s and its rates, ΔH [m],
            ΔḢ [m/s], ΔḦ [m/s²] (:meth:`~exo_ctrl.plan.gait.GaitPlan.hip`,
            ramped); None: the hip does not move (``pelvis_excursion`` 0).
        lift_off_s: (N, 2): each leg's time since its planned lift-off while
            it swings, +inf in stance [s]
            (:meth:`~exo_ctrl.plan.gait.GaitPlan.since_lift_off`); None: the
            plan has no lift-offs (a calibration motion, an exercise).

    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    phi: np.ndarray
    foot_pos: np.ndarray
    foot_vel: np.ndarray
    period_ticks: int | None = None
    lead_ticks: int = 0
    tail_tick: int | None = None
    hip: np.ndarray | None = None
    lift_off_s: np.ndarray | None = None

    @property
    def row_rule(self) -> tuple[int, int, int]:
        """(L, P, K) of :func:`~exo_ctrl.plan.rows.plan_row` (P = 0: row k is tick k)."""
        tail = NO_TAIL if self.tail_tick is None else int(self.tail_tick)
        return int(self.lead_ticks), int(self.period_ticks or 0), tail

    def row(self, k: int) -> int:
        """The row of tick ``k`` (:func:`~exo_ctrl.plan.rows.plan_row`)."""
        return int(plan_row(int(k), *self.row_rule))

    def rows(self, start: int, n: int) -> np.ndarray:
        """The rows of ticks ``start`` … ``start + n - 1``, (n,) int64."""
        out = np.empty(n, dtype=np.int64)
        fill_rows(int(start), out, *self.row_rule)
        return out


def plan_joints(plan: GaitPlan | RampedGait, body: BodyModel, t: np.ndarray) -> JointTrajectory:
    """Joint-space plan of ``body`` following ``plan`` (a gait, or a ramped one) at times ``t`` [s].

    The foot path is checked against each leg's reach, and the resulting
    joint angles against the URDF's ranges of motion.

    Raises:
        UnreachableFootTarget: the path leaves a leg's workspace.
        InvalidParameter: a planned joint angle leaves its range of motion,
            or ``t`` so long that the plan would take more than
            :data:`~exo_ctrl._validate.MAX_ALLOCATION_BYTES`
            (:data:`PLAN_BYTES_PER_SAMPLE` per sample).

    """
    t = np.asarray(t, dtype=float)
    n = t.shape[0]
    v.allocation(
        "t",
        t.shape,
        n,
        PLAN_BYTES_PER_SAMPLE,
        what="plan samples",
        limit="shorter",
    )
    feet = plan.feet(t)
    q = np.empty((n, 4))
    dq = np.empty((n, 4))
    ddq = np.empty((n, 4))
    phi = np.empty((n, 4))
    for s, side in enumerate(SIDES):
        leg = body.legs[side]
        l1, l2 = leg.thigh_length, leg.shank_length
        plan.check_reach(l1, l2, side)
        (x, z), (dx, dz), (ddx, ddz) = feet.pos[:, s].T, feet.vel[:, s].T, feet.acc[:, s].T
        p1, p2 = inverse_kinematics(x, z, l1, l2)
        d1, d2 = joint_rates(p1, p2, l1, l2, dx, dz)
        a1, a2 = joint_accelerations(p1, p2, d1, d2, l1, l2, ddx, ddz)
        cols = slice(2 * s, 2 * s + 2)
        phi[:, cols] = np.column_stack((p1, p2))
        q[:, cols] = np.column_stack(leg.absolute_to_joint(p1, p2))
        dq[:, cols] = np.column_stack(leg.rates_to_joint(d1, d2))
        ddq[:, cols] = np.column_stack(leg.rates_to_joint(a1, a2))
    check_range(body, t, q, "plan")
    hip = np.column_stack(plan.hip(t)) if plan.params.pelvis_excursion > 0.0 else None
    return JointTrajectory(
        t=t,
        q=q,
        dq=dq,
        ddq=ddq,
        phi=phi,
        foot_pos=feet.pos,
        foot_vel=feet.vel,
        hip=hip,
        lift_off_s=plan.since_lift_off(t),
    )


def check_range(body: BodyModel, t: np.ndarray, q: np.ndarray, what: str) -> None:
    """Refuse a planned joint angle outside the body's URDF range of motion.

    Args:
        body: the body whose ``<limit lower upper>`` apply.
        t: sample times [s], (N,).
        q: planned joint angles [rad], (N, 4).
        what: the motion's name in the message (``"plan"``, ``"calibration"``).

    Raises:
        InvalidParameter: the joint and sample furthest beyond its range.

    """
    lower, upper = body.position_limits
    for j, name in enumerate(JOINT_NAMES):
        out = np.flatnonzero((q[:, j] < lower[j]) | (q[:, j] > upper[j]))
        if out.size:
            i = out[np.argmax(np.maximum(lower[j] - q[out, j], q[out, j] - upper[j]))]
            raise InvalidParameter(
                f"{name} angle on the {what}",
                round(float(q[i, j]), 4),
                f"within the range of motion [{lower[j]:.4g}, {upper[j]:.4g}] rad of {body.source}",
                f"at t = {t[i]:.4g} s",
            )
