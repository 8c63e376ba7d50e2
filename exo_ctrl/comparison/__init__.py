"""Runs side by side: one table of their summaries' figures and one figure of a gait cycle.

- :mod:`.runs`: :func:`compare`, a scenario run once per controller.
- :mod:`.recordings`: :func:`~.recordings.compare_recordings`, existing
  recordings read back (imported on its own: it imports the recorder, and
  so rerun, which ``import exo_ctrl`` does not).
- :mod:`.table`: :class:`CompareTable` and its rows, every figure the
  run's own summary's (:data:`FIGURES`); CSV, JSON and Markdown.
- :mod:`.cycle`: the one gait cycle drawn, kept while a run goes.
- :mod:`.differences`: the configuration keys runs differ in, and the refusal.
- :mod:`.plot`: ``compare.png`` (matplotlib).
"""

from .cycle import CycleKeeper, cycle_ticks, trace_from_history
from .differences import COMPARED, check_same, config_differences, flatten
from .plot import cycle_figure, require_matplotlib, write_compare_png
from .runs import compare, controller_list, run_config
from .table import FIGURES, CompareRow, CompareTable, CycleTrace, Figure, Keyed, row_from

__all__ = [
    "COMPARED",
    "FIGURES",
    "CompareRow",
    "CompareTable",
    "CycleKeeper",
    "CycleTrace",
    "Figure",
    "Keyed",
    "check_same",
    "compare",
    "config_differences",
    "controller_list",
    "cycle_figure",
    "cycle_ticks",
    "flatten",
    "require_matplotlib",
    "row_from",
    "run_config",
    "trace_from_history",
    "write_compare_png",
]
