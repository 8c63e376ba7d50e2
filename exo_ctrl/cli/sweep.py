"""``exo-ctrl sweep``: parameter sweeps (the options and the runner are :mod:`exo_ctrl.sweep`'s).

Before the first run starts, every file the sweep writes beside ``--out``
(the table, its CSV, the journal and the report; the load diagrams go into
the same directory) is checked (:func:`exo_ctrl.sweep.command.check_sweep_outputs`).
"""

from __future__ import annotations

import argparse

from ..sweep import add_sweep_arguments, run_sweep_command

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``sweep`` subcommand."""
    p = sub.add_parser(
        "sweep",
        help="sweep gait, patient and device parameters: Parquet/CSV table, load plots, report",
    )
    add_sweep_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Run the sweep (:func:`~exo_ctrl.sweep.run_sweep_command`: outputs checked first)."""
    return run_sweep_command(args)
