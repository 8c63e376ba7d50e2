"""``exo-ctrl export``: a recording's time series as a CSV or Parquet table."""

from __future__ import annotations

import argparse

from ..record.export import export_recording, parse_signals, table_suffix
from .common import check_outputs

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``export`` subcommand."""
    p = sub.add_parser(
        "export",
        help="write a recording's time series to a CSV or Parquet table",
        description="Write a recording's time series as a table: a column t [s] (tick × Δt), "
        "then one column per scalar component of each signal, named with the joint, cuff or "
        "foot, the signal, the axis and the unit (left_knee_q_rad, left_thigh_cuff_force_x_N).",
    )
    p.add_argument("file", metavar="RUN.rrd", help="an exo_ctrl recording")
    p.add_argument(
        "--out",
        required=True,
        metavar="FILE.csv|FILE.parquet",
        help="the table to write; its suffix chooses the format",
    )
    p.add_argument(
        "--signals",
        default=None,
        metavar="a,b,...",
        help="the signals to export, by their log-schema names (q, q_des, cuff_force, ...), "
        "in this order (default: every signal)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Check the options and the output, read the recording, write the table.

    Bad ``--signals`` or ``--out`` is refused before the recording is read.
    """
    table_suffix(args.out)
    parse_signals(args.signals)
    check_outputs(args, {"the input file": args.file}, out="--out")
    table = export_recording(args.file, args.out, args.signals)
    print(f"{args.out}: {table.num_rows} rows, {table.num_columns} columns (t [s] first)")
    return 0
