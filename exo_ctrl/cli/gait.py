"""``exo-ctrl gait``: the planned foot and joint motion as CSV."""

from __future__ import annotations

import argparse
import csv

import numpy as np

from .. import _validate as v
from .._io import atomic_write
from ..model import JOINT_NAMES, load_exo
from ..plan import PLAN_BYTES_PER_SAMPLE, GaitParams, GaitPlan, plan_joints
from .common import add_gait_options, check_outputs, gait_params_from

__all__ = ["GAIT_BYTES_PER_SAMPLE", "GAIT_CSV_HEADER", "register", "run"]

#: Default sample rate of the CSV [Hz].
DEFAULT_RATE_HZ = 100.0

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

#: Memory the command takes per sample [bytes]: the time (8 B), the plan
#: (:data:`~exo_ctrl.plan.PLAN_BYTES_PER_SAMPLE`) and the table of the CSV's
#: columns (8 B each); the rows are formatted one at a time as they are written.
GAIT_BYTES_PER_SAMPLE = 8 + PLAN_BYTES_PER_SAMPLE + 8 * len(GAIT_CSV_HEADER)


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``gait`` subcommand."""
    p = sub.add_parser("gait", help="write the planned foot and joint motion as CSV")
    add_gait_options(p)
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="SEC",
        help=f"time span [s] (default: one period, {GaitParams().period:g} s at the default "
        "period); duration × rate is capped at "
        f"{v.max_items(GAIT_BYTES_PER_SAMPLE):,} samples (1 GiB of memory)",
    )
    p.add_argument(
        "--rate",
        type=float,
        default=DEFAULT_RATE_HZ,
        metavar="HZ",
        help=f"sample rate [Hz] (default {DEFAULT_RATE_HZ:g})",
    )
    p.add_argument("--csv", required=True, metavar="PATH", help="output CSV file")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Sample the plan at t = k / rate over the duration and write the CSV atomically."""
    check_outputs(args, csv="--csv")
    params = gait_params_from(args)
    duration = v.positive(
        "duration", args.duration if args.duration is not None else params.period, "s"
    )
    rate = v.positive("rate", args.rate, "Hz")
    n = int(np.floor(duration * rate + 1e-9)) + 1
    _check_size(args, duration, rate, n)
    exo = load_exo(getattr(args, "exo", None))
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
        writer.writerows([f"{x:.10g}" for x in row] for row in rows)
    print(
        f"wrote {n} samples over {duration:g} s to {args.csv} "
        f"(belt speed {params.belt_speed:.4g} m/s, top-of-swing speed "
        f"{params.swing_top_speed:.4g} m/s)"
    )
    return 0


def _check_size(args: argparse.Namespace, duration: float, rate: float, n: int) -> None:
    """Refuse ``n`` samples beyond the memory cap, naming the time span or the rate.

    The one named is the one further above its default (relative to the
    default period, 1.2 s, and rate, 100 Hz); the limit given keeps the other.

    Raises:
        InvalidParameter: ``n × GAIT_BYTES_PER_SAMPLE`` beyond
            :data:`~exo_ctrl._validate.MAX_ALLOCATION_BYTES`.

    """
    most = v.max_items(GAIT_BYTES_PER_SAMPLE) - 1  # intervals: samples - 1
    note = ""
    if rate / DEFAULT_RATE_HZ > duration / GaitParams().period:
        name, value, limit = (
            "rate",
            args.rate,
            f"at most {most / duration:.4g} Hz over {duration:g} s",
        )
    else:
        name = "duration" if args.duration is not None else "period"
        value = args.duration if args.duration is not None else duration
        limit = f"at most {most / rate:.4g} s at {rate:g} Hz"
        if args.duration is None:
            note = "the duration defaults to one period"
    v.allocation(name, value, n, GAIT_BYTES_PER_SAMPLE, limit=limit, note=note)
