"""The sagittal leg's foot point in closed form, for compiled kernels.

With a leg's absolute angles (:class:`~exo_ctrl.model.geometry.LegGeometry`)
φ1 = φ1₀ + s_h q_hip and φ2 = φ2₀ + s_h q_hip + s_k q_knee, the foot point
relative to the hip joint and its Jacobian rows ∂p/∂(q_hip, q_knee) are

    p = l1 (cos φ1, sin φ1) + l2 (cos φ2, sin φ2),
    J_x = [−s_h (l1 sin φ1 + l2 sin φ2), −s_k l2 sin φ2],
    J_z = [ s_h (l1 cos φ1 + l2 cos φ2),  s_k l2 cos φ2],

and the velocity-product term of its acceleration, p̈ = J q̈ + J̇ q̇ with
J̇ q̇ = −l1 ω1² (cos φ1, sin φ1) − l2 ω2² (cos φ2, sin φ2), ω1 = s_h q̇_hip,
ω2 = s_h q̇_hip + s_k q̇_knee.

Kernels that need a body's legs keep their geometry in a record with the
fields :data:`LEG_FIELDS` (per leg: left, right), filled by :func:`fill_legs`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._jit import kernel, leaf, record
from .loader import BodyModel
from .names import SIDES

__all__ = ["LEG_FIELDS", "feet_torque", "fill_legs", "foot_bias", "foot_point", "legs_record"]

#: A record's leg geometry, per leg (left, right): ``l1``, ``l2`` [m],
#: ``s_h``, ``s_k`` [-], ``phi1_0``, ``phi2_0`` [rad].
LEG_FIELDS = [(name, np.float64, (2,)) for name in ("l1", "l2", "s_h", "s_k", "phi1_0", "phi2_0")]


def fill_legs(rec: Any, body: BodyModel) -> None:
    """Write ``body``'s leg geometry into a record element ``rec`` with :data:`LEG_FIELDS`."""
    for i, side in enumerate(SIDES):
        leg = body.legs[side]
        rec["l1"][i], rec["l2"][i] = leg.thigh_length, leg.shank_length
        rec["s_h"][i], rec["s_k"][i] = leg.sign_hip, leg.sign_knee
        rec["phi1_0"][i], rec["phi2_0"][i] = leg.phi1_zero, leg.phi2_zero


def legs_record(body: BodyModel) -> np.ndarray:
    """A record of :data:`LEG_FIELDS` alone, filled with ``body``'s legs.

    Python's argument to :func:`foot_point` and :func:`foot_bias`: kernels
    inline them whatever record holds the legs, but a call from Python
    compiles them for the record's type, so Python always passes this one
    (one signature per kernel, :mod:`exo_ctrl._jit`).
    """
    legs = record(LEG_FIELDS)
    fill_legs(legs[0], body)
    return legs


@leaf
def foot_point(g: Any, leg: int, q_hip: float, q_knee: float) -> tuple:
    """(x, z, J_x hip, J_x knee, J_z hip, J_z knee) of leg ``leg``'s foot relative to its hip.

    ``g``: a record (element) with :data:`LEG_FIELDS`; angles [rad]; [m], [m/rad].
    """
    sh, sk = g.s_h[leg], g.s_k[leg]
    a1 = g.phi1_0[leg] + sh * q_hip
    a2 = g.phi2_0[leg] + sh * q_hip + sk * q_knee
    c1, s1, c2, s2 = np.cos(a1), np.sin(a1), np.cos(a2), np.sin(a2)
    l1, l2 = g.l1[leg], g.l2[leg]
    return (
        l1 * c1 + l2 * c2,
        l1 * s1 + l2 * s2,
        -sh * (l1 * s1 + l2 * s2),
        -sk * l2 * s2,
        sh * (l1 * c1 + l2 * c2),
        sk * l2 * c2,
    )


@leaf
def foot_bias(g: Any, leg: int, q_hip: float, q_knee: float, dq_hip: float, dq_knee: float):
    """J̇ q̇ of leg ``leg``'s foot point, (x, z) [m/s²] (module docstring)."""
    sh, sk = g.s_h[leg], g.s_k[leg]
    a1 = g.phi1_0[leg] + sh * q_hip
    a2 = g.phi2_0[leg] + sh * q_hip + sk * q_knee
    w1 = sh * dq_hip
    w2 = w1 + sk * dq_knee
    l1, l2 = g.l1[leg], g.l2[leg]
    return (
        -l1 * w1 * w1 * np.cos(a1) - l2 * w2 * w2 * np.cos(a2),
        -l1 * w1 * w1 * np.sin(a1) - l2 * w2 * w2 * np.sin(a2),
    )


@kernel
def feet_torque(g: Any, q: np.ndarray, force: np.ndarray, out: np.ndarray) -> None:
    """τ = J_xᵀ F_x + J_zᵀ F_z of a force (x, z) on each foot point, (4,) [N·m].

    ``g``: a record with :data:`LEG_FIELDS` (:func:`legs_record`); ``q``:
    joint angles [rad], (4,) in JOINT_NAMES order; ``force``: (2, 2) [N],
    per leg (left, right) its x and z components.
    """
    r = g[0]
    for leg in range(2):
        i = 2 * leg
        _, _, jx0, jx1, jz0, jz1 = foot_point(r, leg, q[i], q[i + 1])
        fx, fz = force[leg, 0], force[leg, 1]
        out[i] = jx0 * fx + jz0 * fz
        out[i + 1] = jx1 * fx + jz1 * fz
