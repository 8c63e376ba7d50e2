r"""What the device knows of its patient's true cuffs, for the QP's margin (e_cuffs).

:class:`CuffKnowledge` names it: the published cuffs the true ones scatter
around, the spread the device assumes, the cuff sensors it carries and
whether it tares them; :func:`unobserved` is the projector onto the
components those sensors do not measure, :func:`link_normals` the
exoskeleton links' normals it is built from.  How e_cuffs follows from
them: :mod:`~exo_ctrl.control.qp.margin`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ... import _validate as v
from ...exceptions import InvalidParameter
from ...plant.cuff_scatter import DEFAULT_SPREAD, CuffScatter, checked_spread
from ...plant.cuffs import CuffParams
from .prediction import CuffHorizonModel

__all__ = ["SENSOR_SETS", "CuffKnowledge", "link_normals", "unobserved"]

#: The cuff sensor sets (:mod:`exo_ctrl.sensing.cuff_load`): none, a load cell
#: per cuff measuring its normal force, a 2-axis sensor per cuff.
SENSOR_SETS = ("none", "normal", "full")


@dataclass(frozen=True)
class CuffKnowledge:
    """What the device knows of its patient's true cuffs, for e_cuffs (module docstring).

    Attributes:
        published: the cuffs the true ones scatter around (the published
            split stiffness by default; ``SimConfig.cuffs``).
        spread_rel: s, the spread the device assumes for a patient's cuffs
            [-], in [0, MAX_SPREAD] (default: the literature's,
            :data:`~exo_ctrl.plant.cuff_scatter.DEFAULT_SPREAD`; 0: the true
            cuffs are ``published`` exactly).
        sensors: the cuff sensors the device carries, one of :data:`SENSOR_SETS`.
        tare: whether the device tares them at the standing start
            (``CuffSensorParams.tare_s`` > 0).

    Raises:
        InvalidParameter: cuffs that are not a CuffParams, a spread outside
            [0, MAX_SPREAD], an unknown sensor set.

    """

    published: CuffParams = field(default_factory=CuffParams)
    spread_rel: float = DEFAULT_SPREAD
    sensors: str = "none"
    tare: bool = False

    def __post_init__(self) -> None:
        if not isinstance(self.tare, bool):
            raise InvalidParameter("cuff knowledge tare", self.tare, "True or False")
        if not isinstance(self.published, CuffParams):
            raise InvalidParameter("cuff knowledge published", self.published, "a CuffParams")
        spread = checked_spread("cuff knowledge spread_rel", self.spread_rel)
        v.one_of("cuff knowledge sensors", self.sensors, SENSOR_SETS)
        object.__setattr__(self, "spread_rel", spread)

    def true_cuffs(self) -> list[CuffParams]:
        """The plausible true cuffs e_cuffs is taken over (none with untared 2-axis sensors)."""
        if self.sensors == "full" and not self.tare:
            return []
        if self.spread_rel == 0.0:
            return [self.published]
        return list(CuffScatter(spread_rel=self.spread_rel).extremes(self.published))


def link_normals(model: CuffHorizonModel, q: np.ndarray) -> np.ndarray:
    """n_c, the unit normal of each cuff's exoskeleton link at ``q``, (4, 2) (x, z).

    u = R(θ_c) u₀, θ_c = S_c · q, n = u turned by +90° (as
    :func:`~exo_ctrl.control.qp.split_cuffs.split_gains`).
    """
    m = model.record[0]
    theta = m["select"][:4, :4] @ q
    ct, st = np.cos(theta), np.sin(theta)
    u0 = m["along0"]
    ux = u0[:, 0] * ct - u0[:, 1] * st
    uz = u0[:, 1] * ct + u0[:, 0] * st
    return np.stack((-uz, ux), axis=1)


def unobserved(normals: np.ndarray, sensors: str) -> np.ndarray:
    """U, the projector onto the cuff-force components a leg's sensors do not measure, (4, 4).

    Rows and columns thigh x, z, shank x, z (module docstring, e_cuffs).

    Args:
        normals: the leg's two cuffs' link normals n_c, (2, 2) (:func:`link_normals`).
        sensors: one of :data:`SENSOR_SETS`: ``"none"`` I, ``"normal"``
            I − n_c n_cᵀ per cuff, ``"full"`` 0.

    """
    if sensors == "full":
        return np.zeros((4, 4))
    out = np.eye(4)
    if sensors == "normal":
        for k in range(2):
            out[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] -= np.outer(normals[k], normals[k])
    return out
