"""The QP controller: CT + PD distributed under drive limits and predicted cuff-force bounds.

- :mod:`~exo_ctrl.control.qp.controller`: :class:`QPController`.
- :mod:`~exo_ctrl.control.qp.tick`: its record and compiled per-tick kernels.
- :mod:`~exo_ctrl.control.qp.torque_box`: the drive torques reachable at a speed.
- :mod:`~exo_ctrl.control.qp.prediction`: :class:`CuffHorizonModel`, the cuff
  forces over a horizon, affine in the held torques.
- :mod:`~exo_ctrl.control.qp.expm`: the matrix exponential it needs.
- :mod:`~exo_ctrl.control.qp.observer`: :class:`CuffStateObserver`, the cuff
  state from the force estimate.
- :mod:`~exo_ctrl.control.qp.screening`: the octagon rows, the clip test, the
  screening of rows for proxsuite.
- :mod:`~exo_ctrl.control.qp.margin`: :func:`bound_margin`, what the
  device does not know, by which each cuff's bound is tightened;
  :mod:`~exo_ctrl.control.qp.cuff_knowledge`: :class:`CuffKnowledge`, what
  it knows of the patient's true cuffs.
- :mod:`~exo_ctrl.control.qp.workspace`: :class:`TorqueQP`, the persistent
  proxsuite workspace, its checks and its fallback.
"""

from .controller import CONTROLLER_EPS_ABS, NO_BOUND, SLACK_WEIGHT, QPController
from .cuff_knowledge import CuffKnowledge
from .margin import BoundMargin, bound_margin, contact_warning, departure_warning
from .observer import CuffStateObserver
from .prediction import DEFAULT_HORIZON_TICKS, CuffHorizonModel
from .screening import POLYGON_SIDES, SCREEN_ROUNDS, SCREENED_ROWS, polygon_rows
from .workspace import ACTIVE_TOL, FEASIBILITY_TOL, TorqueQP

__all__ = [
    "ACTIVE_TOL",
    "CONTROLLER_EPS_ABS",
    "DEFAULT_HORIZON_TICKS",
    "FEASIBILITY_TOL",
    "NO_BOUND",
    "POLYGON_SIDES",
    "SCREENED_ROWS",
    "SCREEN_ROUNDS",
    "SLACK_WEIGHT",
    "BoundMargin",
    "CuffHorizonModel",
    "CuffKnowledge",
    "CuffStateObserver",
    "QPController",
    "TorqueQP",
    "bound_margin",
    "contact_warning",
    "departure_warning",
    "polygon_rows",
]
