"""The QP controller: CT + PD distributed under drive limits and predicted cuff-force bounds."""

from .controller import (
    POLYGON_SIDES,
    SCREENED_ROWS,
    QPController,
    TorqueQP,
    polygon_rows,
)
from .prediction import (
    DEFAULT_HORIZON_TICKS,
    CuffHorizonModel,
    CuffStateObserver,
)

__all__ = [
    "DEFAULT_HORIZON_TICKS",
    "POLYGON_SIDES",
    "SCREENED_ROWS",
    "CuffHorizonModel",
    "CuffStateObserver",
    "QPController",
    "TorqueQP",
    "polygon_rows",
]
