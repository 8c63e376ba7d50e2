"""Parameter sweeps over many runs, on a process pool or a Dask cluster.

- :mod:`~exo_ctrl.sweep.parameters`: the sweepable parameters and ``--param``.
- :mod:`~exo_ctrl.sweep.spec`: the points of a sweep, each resolved to a run with a stable id.
- :mod:`~exo_ctrl.sweep.outputs`: a run's output columns and the files of a sweep.
- :mod:`~exo_ctrl.sweep.journal`: the journal of finished runs, and resuming.
- :mod:`~exo_ctrl.sweep.run`: running the points on an Executor.
- :mod:`~exo_ctrl.sweep.report`: the table, the text report, the load diagrams.
- :mod:`~exo_ctrl.sweep.command`: the ``exo-ctrl sweep`` command.
"""

from ..exceptions import MissingDependency, SweepError
from .command import add_sweep_arguments, run_sweep_command
from .outputs import OUTPUT_COLUMNS, SweepPaths
from .parameters import PARAMETERS, ParamInfo, parameter_names, parse_param
from .report import write_plots, write_report
from .run import SweepInterrupted, config_for, run_point, run_sweep
from .spec import SweepSpec, SweepTask, base_values, resolved_run, run_id_of

__all__ = [
    "OUTPUT_COLUMNS",
    "PARAMETERS",
    "MissingDependency",
    "ParamInfo",
    "SweepError",
    "SweepInterrupted",
    "SweepPaths",
    "SweepSpec",
    "SweepTask",
    "add_sweep_arguments",
    "base_values",
    "config_for",
    "parameter_names",
    "parse_param",
    "resolved_run",
    "run_id_of",
    "run_point",
    "run_sweep",
    "run_sweep_command",
    "write_plots",
    "write_report",
]
