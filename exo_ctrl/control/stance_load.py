r"""The stance legs' load in the feedforward: the weight the body-weight support leaves.

With the pelvis on its vertical guide (:mod:`exo_ctrl.plant.pelvis`) the
stance legs carry what the support does not, and the planned motion alone
(RNEA on the fixed-base models) knows nothing of it.  The device knows what
it needs to: the support force F_s it applies, the body mass entered for the
patient and its own mass (so the moving mass M), and the plan.  For a plan
row (q*, q̇*, q̈*) of the exoskeleton:

- each foot point's height z_i relative to the hip, its rate and
  acceleration (the leg's closed form, :mod:`exo_ctrl.plant.contact`),
  z̈_i = J_z,i q̈* + J̇_z,i q̇*;
- the planned stance share of each foot from its height above the lower
  foot, d_i = z_i − min(z_L, z_R) (the plan puts a stance foot on the belt
  line, the lower one): w_i = max(0, 1 − d_i / b)², s_i = w_i / (w_L + w_R),
  with the band b = 1 cm, so the load passes from foot to foot as the swing
  foot comes down and the other lifts, continuously;
- the hip's planned vertical acceleration is that of the belt line seen from
  the hip with the stance foot fixed on the belt, a_h = −Σ s_i z̈_i, and the
  vertical balance of the moving mass gives the belt's total normal force
  F = max(0, M (g + a_h) − F_s) (the legs' own motion relative to the pelvis
  is left out: a feedforward, the PD corrects the rest);
- the torque the drives add: τ_load = −Σ s_i F J_z,iᵀ on each exoskeleton
  leg (the belt pushes the foot up with s_i F; the drives hold it).

This term joins computed torque's feedforward row
(:class:`~exo_ctrl.control.computed_torque.ComputedTorqueController`) with
a supported pelvis; with the pelvis fixed the row is unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from .. import _validate as v
from .._jit import kernel, record
from ..model import BodyModel
from ..model.leg_kernels import LEG_FIELDS, fill_legs, foot_bias, foot_point

__all__ = ["STANCE_LOAD_FIELDS", "StanceLoad", "stance_load_record", "stance_load_torque"]

#: b: a foot this far above the lower one carries no load in the plan [m].
STANCE_BAND_M = 0.01


@dataclass(frozen=True)
class StanceLoad:
    """What the device knows of the load on its stance legs (module docstring).

    Attributes:
        mass_kg: M, the mass the pelvis's guide moves as the device holds it
            (the body mass entered and its own) [kg].
        support_N: F_s, the support force it applies [N].
        gravity_mps2: g [m/s²].

    Raises:
        InvalidParameter: a mass not > 0, a support or gravity < 0.

    """

    mass_kg: float
    support_N: float
    gravity_mps2: float = 9.81

    def __post_init__(self) -> None:
        v.positive("stance load mass", self.mass_kg, "kg")
        v.non_negative("stance load support", self.support_N, "N")
        v.non_negative("stance load gravity", self.gravity_mps2, "m/s²")


#: Fields of the stance load's record: the leg geometry per leg (``l1``,
#: ``l2`` [m], ``s_h``, ``s_k``, ``phi1_0``, ``phi2_0`` [rad]); ``mass``
#: [kg], ``support`` [N], ``g`` [m/s²], ``band`` b [m]; outputs of the last
#: row: ``share`` s_i, ``force`` F [N], ``jz`` (2, 2) [m/rad].
STANCE_LOAD_FIELDS = [
    *LEG_FIELDS,
    *((name, np.float64) for name in ("mass", "support", "g", "band", "force")),
    ("share", np.float64, (2,)),
    ("jz", np.float64, (2, 2)),
]


def stance_load_record(load: StanceLoad, exo: BodyModel) -> np.ndarray:
    """The kernel's record for ``load`` on the legs of ``exo`` (the device's model)."""
    rec = record(STANCE_LOAD_FIELDS)
    r = rec[0]
    fill_legs(r, exo)
    r["mass"], r["support"], r["g"] = load.mass_kg, load.support_N, load.gravity_mps2
    r["band"] = STANCE_BAND_M
    return rec


@kernel
def stance_load_torque(
    load: Any, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, tau: np.ndarray
) -> None:
    """τ += τ_load of the plan row (q, q̇, q̈) (module docstring); ``load``: its record."""
    r = load[0]
    z = np.empty(2)
    zdd = np.empty(2)
    for leg in range(2):
        i = 2 * leg
        _, z[leg], _, _, r.jz[leg, 0], r.jz[leg, 1] = foot_point(r, leg, q[i], q[i + 1])
        bias = foot_bias(r, leg, q[i], q[i + 1], dq[i], dq[i + 1])[1]
        zdd[leg] = r.jz[leg, 0] * ddq[i] + r.jz[leg, 1] * ddq[i + 1] + bias
    low = min(z[0], z[1])
    total = 0.0
    for leg in range(2):
        w = 1.0 - (z[leg] - low) / r.band
        r.share[leg] = w * w if w > 0.0 else 0.0
        total += r.share[leg]
    acc = 0.0
    for leg in range(2):
        r.share[leg] /= total
        acc += r.share[leg] * zdd[leg]
    force = r.mass * (r.g - acc) - r.support
    r.force = force if force > 0.0 else 0.0
    for leg in range(2):
        f = r.share[leg] * r.force
        tau[2 * leg] -= f * r.jz[leg, 0]
        tau[2 * leg + 1] -= f * r.jz[leg, 1]
