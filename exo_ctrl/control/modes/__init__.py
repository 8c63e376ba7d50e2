"""Interaction modes (issue 18): guidance, transparent and assist-as-needed controllers.

- :mod:`~exo_ctrl.control.modes.params`: the modes' names and parameters.
- :mod:`~exo_ctrl.control.modes.controller`: the modes behind the controller
  interface, one compiled kernel per tick.
- :mod:`~exo_ctrl.control.modes.path`: path control with free timing (a
  tunnel around the planned foot path).
"""

from .controller import MODE_FIELDS, InteractionController, mode_command
from .params import FORCE_GAINS, FORCE_LEADS, MODES, ModeParams
from .path import PATH_FIELDS, PathController, PathParams, path_command

__all__ = [
    "FORCE_GAINS",
    "FORCE_LEADS",
    "MODES",
    "MODE_FIELDS",
    "PATH_FIELDS",
    "InteractionController",
    "ModeParams",
    "PathController",
    "PathParams",
    "mode_command",
    "path_command",
]
