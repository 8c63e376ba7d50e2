"""``exo-ctrl estimate``: cuff forces estimated from a recording's or a CSV log's readings."""

from __future__ import annotations

import argparse

from .._io import is_special
from ..estimation import ESTIMATORS
from ..record import estimate_file, write_estimate_recording
from ..record.export import estimate_table, table_suffix, write_table
from .common import add_accept_implausible, check_outputs, write_json

#: The files ``--out`` writes, by suffix: a rerun recording or a table.
OUT_SUFFIXES = (".rrd", ".csv", ".parquet")

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``estimate`` subcommand."""
    p = sub.add_parser(
        "estimate", help="estimate cuff forces from a recording's or a CSV log's sensor readings"
    )
    p.add_argument(
        "file",
        metavar="RUN.rrd|LOG.csv",
        help="an exo_ctrl recording (.rrd) or a CSV log (.csv) file",
    )
    p.add_argument(
        "--exo",
        default=None,
        metavar="URDF",
        help="exoskeleton URDF (default: the recording's, or urdf/exoskeleton.urdf)",
    )
    p.add_argument(
        "--estimator",
        choices=ESTIMATORS,
        default=None,
        help="momentum (the momentum observer on the exoskeleton's model) or kalman (the "
        "Kalman filter on the coupled exoskeleton-cuff-patient model, rebuilt from the "
        "recording's device models) (default: the recording's run's; momentum for a CSV log)",
    )
    p.add_argument(
        "--gain",
        type=float,
        default=None,
        metavar="1/S",
        help="the momentum observer's gain K_O [1/s] (default: the recording's, or 100)",
    )
    p.add_argument(
        "--allow-other-exo",
        action="store_true",
        help="estimate a recording with an --exo other than the one it was recorded with "
        "(default: refused)",
    )
    add_accept_implausible(p)
    p.add_argument(
        "--out",
        default=None,
        metavar="EST.rrd|EST.csv|EST.parquet",
        help="write the per-sample estimate to this file, by its suffix: a rerun recording "
        "(also a device or a FIFO), "
        "or a table with t [s] and one column per cuff, joint and axis, named as exo-ctrl "
        "export names them (left_thigh_cuff_normal_est_N) (default: none)",
    )
    p.add_argument(
        "--summary",
        default=None,
        metavar="PATH.json",
        help="write the figures to this JSON file (default: none)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Estimate, write what was asked for, print peaks (and errors where the truth is known).

    The output paths (and ``--out``'s suffix) are checked before the input is read.
    """
    # a special file (a device, a FIFO) has no suffix to go by: it takes the recording
    to_recording = bool(args.out) and (is_special(args.out) or args.out.lower().endswith(".rrd"))
    if args.out and not to_recording:
        table_suffix(args.out, "--out", OUT_SUFFIXES)
    check_outputs(args, {"the input file": args.file}, out="--out", summary="--summary")
    estimate = estimate_file(
        args.file,
        exo=args.exo,
        gain_per_s=args.gain,
        allow_other_exo=args.allow_other_exo,
        estimator=args.estimator,
        accept_implausible=args.accept_implausible,
    )
    summary = estimate.summary()
    if to_recording:
        write_estimate_recording(estimate, args.out)
    elif args.out:
        write_table(estimate_table(estimate.series), args.out)
    if args.summary:
        write_json(args.summary, summary)
    gain = summary["observer_gain_per_s"]
    how = (
        "the Kalman filter on the device's models"
        if gain is None
        else f"the momentum observer, gain {gain:g} 1/s"
    )
    print(f"estimated {summary['samples']} samples of {args.file} ({how})")
    print(estimate.table())
    if args.out:
        print(f"estimate written: {args.out}")
    return 0
