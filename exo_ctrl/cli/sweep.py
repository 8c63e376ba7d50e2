"""``exo-ctrl sweep``: parameter sweeps (the options and the runner are :mod:`exo_ctrl.sweep`'s)."""

from __future__ import annotations

import argparse

from ..sweep import add_sweep_arguments, run_sweep_command

__all__ = ["register"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``sweep`` subcommand."""
    p = sub.add_parser(
        "sweep",
        help="sweep gait, patient and device parameters: Parquet/CSV table, load plots, report",
    )
    add_sweep_arguments(p)
    p.set_defaults(func=run_sweep_command)
