"""``exo-ctrl gait``: the planned foot and joint motion as CSV."""

from __future__ import annotations

import argparse
import csv

import numpy as np

from .. import _validate as v
from .._io import atomic_write
from ..model import JOINT_NAMES, load_exo
from ..plan import GaitPlan, plan_joints
from .common import add_gait_options, gait_params_from

__all__ = ["GAIT_CSV_HEADER", "register", "run"]

#: Columns of the gait CSV: t [s], the feet relative to their hips [m] and
#: their speeds [m/s], the link angles φ1, φ2 of each leg [rad] and the joint
#: angles [rad] in JOINT_NAMES order.
GAIT_CSV_HEADER = (
    "t",
    "left_foot_x",
    "left_foot_z",
    "right_foot_x",
    "right_foot_z",
    "left_foot_vx",
    "left_foot_vz",
    "right_foot_vx",
    "right_foot_vz",
    "left_phi1",
    "left_phi2",
    "right_phi1",
    "right_phi2",
    *JOINT_NAMES,
)


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``gait`` subcommand."""
    p = sub.add_parser("gait", help="write the planned foot and joint motion as CSV")
    add_gait_options(p)
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="SEC",
        help="time span [s] (default: one period)",
    )
    p.add_argument(
        "--rate", type=float, default=100.0, metavar="HZ", help="sample rate [Hz] (default 100)"
    )
    p.add_argument("--csv", required=True, metavar="PATH", help="output CSV file")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Sample the plan at t = k / rate over the duration and write the CSV atomically."""
    params = gait_params_from(args)
    exo = load_exo(args.exo)
    duration = v.positive(
        "duration", args.duration if args.duration is not None else params.period, "s"
    )
    rate = v.positive("rate", args.rate, "Hz")
    n = int(np.floor(duration * rate + 1e-9)) + 1
    t = np.arange(n) / rate
    joints = plan_joints(GaitPlan(params), exo, t)
    rows = np.column_stack(
        (
            t,
            joints.foot_pos.reshape(n, 4),
            joints.foot_vel.reshape(n, 4),
            joints.phi,
            joints.q,
        )
    )
    with atomic_write(args.csv) as handle:
        writer = csv.writer(handle)
        writer.writerow(GAIT_CSV_HEADER)
        writer.writerows([[f"{x:.10g}" for x in row] for row in rows])
    print(
        f"wrote {n} samples over {duration:g} s to {args.csv} "
        f"(belt speed {params.belt_speed:.4g} m/s, top-of-swing speed "
        f"{params.swing_top_speed:.4g} m/s)"
    )
    return 0
