"""Interaction modes (issue 18): guidance, transparent and assist-as-needed controllers.

- :mod:`~exo_ctrl.control.modes.params`: the modes' names and parameters.
- :mod:`~exo_ctrl.control.modes.controller`: the modes behind the controller
  interface, one compiled kernel per tick.
"""

from .controller import MODE_FIELDS, InteractionController, mode_command
from .params import MODES, ModeParams

__all__ = ["MODES", "MODE_FIELDS", "InteractionController", "ModeParams", "mode_command"]
