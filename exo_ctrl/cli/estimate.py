"""``exo-ctrl estimate``: cuff forces estimated from a recording's or a CSV log's readings."""

from __future__ import annotations

import argparse

from ..record import estimate_file, write_estimate_recording
from .common import write_json

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``estimate`` subcommand."""
    p = sub.add_parser(
        "estimate", help="estimate cuff forces from a recording's or a CSV log's sensor readings"
    )
    p.add_argument("file", metavar="RUN.rrd|LOG.csv", help="an exo_ctrl recording or a CSV log")
    p.add_argument(
        "--exo",
        default=None,
        metavar="URDF",
        help="exoskeleton URDF (default: the recording's, or urdf/exoskeleton.urdf)",
    )
    p.add_argument(
        "--gain",
        type=float,
        default=None,
        metavar="1/S",
        help="observer gain K_O [1/s] (default: the recording's, or 100)",
    )
    p.add_argument(
        "--out", default=None, metavar="EST.rrd", help="write the estimate as a recording"
    )
    p.add_argument("--summary", default=None, metavar="PATH.json", help="write the figures as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Estimate, write what was asked for, print peaks (and errors where the truth is known)."""
    estimate = estimate_file(args.file, exo=args.exo, gain_per_s=args.gain)
    summary = estimate.summary()
    if args.out:
        write_estimate_recording(estimate, args.out)
    if args.summary:
        write_json(args.summary, summary)
    print(
        f"estimated {summary['samples']} samples of {args.file} "
        f"(observer gain {summary['observer_gain_per_s']:g} 1/s)"
    )
    errors = summary.get("cuff_force_estimate_rms_error_N", {})
    rel = summary.get("cuff_force_estimate_rms_error_rel", {})
    print(
        f"{'cuff':<13}{'peak normal est [N]':>20}"
        + (f"{'rms err [N]':>13}{'rel':>8}" if errors else "")
    )
    for cuff, peak in summary["peak_cuff_normal_est_N"].items():
        line = f"{cuff:<13}{peak:>20.1f}"
        if errors:
            line += f"{errors[cuff]:>13.2f}{100 * rel[cuff]:>7.2f}%"
        print(line)
    if args.out:
        print(f"estimate recording: {args.out}")
    return 0
