"""The ``exo-ctrl`` command, one module per subcommand.

- :mod:`~exo_ctrl.cli.app`: the parser and :func:`main` (the entry point).
- :mod:`~exo_ctrl.cli.common`: the shared gait options, the summary as text,
  the parser class.
- :mod:`~exo_ctrl.cli.gait`, :mod:`~exo_ctrl.cli.urdf`,
  :mod:`~exo_ctrl.cli.simulate`, :mod:`~exo_ctrl.cli.estimate`,
  :mod:`~exo_ctrl.cli.sweep`: the subcommands.
"""

from .app import build_parser, main
from .common import format_summary
from .gait import GAIT_CSV_HEADER

__all__ = ["GAIT_CSV_HEADER", "build_parser", "format_summary", "main"]
