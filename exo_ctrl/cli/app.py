"""The ``exo-ctrl`` command.

Every subcommand validates its input through the library; an
:class:`~exo_ctrl.exceptions.ExoCtrlError` becomes a one-line message on
stderr and exit code 2, never a traceback.  Files are written atomically.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
from collections.abc import Sequence

import numpy as np

from .. import _validate as v
from .._io import atomic_write
from ..control import PDGains
from ..exceptions import ExoCtrlError
from ..model.body import JOINT_NAMES, load_body, load_exo
from ..plan.gait import GaitParams, GaitPlan
from ..plan.kinematics import plan_joints
from ..plant.patient import PATIENT_TORQUES
from ..sim.loop import CONTROLLERS, SimConfig, simulate

__all__ = ["GAIT_CSV_HEADER", "main"]

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


# --------------------------------------------------------------------------- options


def add_gait_options(parser: argparse.ArgumentParser) -> None:
    """The gait parameter options shared by the subcommands (defaults: GaitParams)."""
    d = GaitParams()
    g = parser.add_argument_group("gait (paper §III)")
    g.add_argument(
        "--step-length",
        type=float,
        default=d.step_length,
        metavar="S",
        help=f"step length s [m] (default {d.step_length})",
    )
    g.add_argument(
        "--lift-height",
        type=float,
        default=d.lift_height,
        metavar="H",
        help=f"foot lift h_s [m] (default {d.lift_height})",
    )
    g.add_argument(
        "--hip-height",
        type=float,
        default=d.hip_height,
        metavar="HS",
        help=f"hip height above the belt H_s [m] (default {d.hip_height})",
    )
    g.add_argument(
        "--shape-coeff",
        type=float,
        default=d.shape_coeff,
        metavar="KV",
        help=f"shape coefficient k_v = v_f / v_b (default {d.shape_coeff})",
    )
    g.add_argument(
        "--period",
        type=float,
        default=d.period,
        metavar="T",
        help=f"gait period T_s [s] (default {d.period})",
    )
    g.add_argument(
        "--duty-factor",
        type=float,
        default=d.duty_factor,
        metavar="B",
        help=f"stance fraction β of the period (default {d.duty_factor})",
    )
    g.add_argument(
        "--exo",
        default=None,
        metavar="URDF",
        help="exoskeleton URDF (default: urdf/exoskeleton.urdf)",
    )


def gait_params_from(args: argparse.Namespace) -> GaitParams:
    """GaitParams from the parsed gait options."""
    return GaitParams(
        step_length=args.step_length,
        lift_height=args.lift_height,
        hip_height=args.hip_height,
        shape_coeff=args.shape_coeff,
        period=args.period,
        duty_factor=args.duty_factor,
    )


# --------------------------------------------------------------------------- gait


def _cmd_gait(args: argparse.Namespace) -> int:
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


# --------------------------------------------------------------------------- urdf


def _cmd_urdf(args: argparse.Namespace) -> int:
    from ..model.urdfgen import BodyParams, write_urdf

    base = BodyParams.exo_default() if args.kind == "exo" else BodyParams.patient_default()
    changes = {
        name: getattr(args, name)
        for name in (
            "thigh_length",
            "shank_length",
            "thigh_mass",
            "shank_mass",
            "thigh_cuff",
            "shank_cuff",
        )
        if getattr(args, name) is not None
    }
    # A cuff not given keeps its place as a fraction of its link.
    for seg in ("thigh", "shank"):
        length = changes.get(f"{seg}_length")
        if length is not None and f"{seg}_cuff" not in changes:
            changes[f"{seg}_cuff"] = (
                getattr(base, f"{seg}_cuff") / getattr(base, f"{seg}_length") * length
            )
    params = base.replace(**changes)
    path = write_urdf(params, args.out)
    body = load_body(path, name=args.kind)
    print(
        f"wrote {path}: {args.kind}, legs {body.legs['left'].thigh_length:g} m + "
        f"{body.legs['left'].shank_length:g} m, moving mass {body.mass:.4g} kg"
    )
    return 0


# --------------------------------------------------------------------------- simulate


def _sim_config(args: argparse.Namespace) -> SimConfig:
    gait = gait_params_from(args)
    if args.cycles is not None:
        duration = v.positive("cycles", args.cycles) * gait.period
    else:
        duration = args.duration if args.duration is not None else 2 * gait.period
    gains = PDGains(
        kp=args.kp if args.kp is not None else PDGains().kp,
        kd=args.kd if args.kd is not None else PDGains().kd,
    )
    return SimConfig(
        gait=gait,
        exo=args.exo,
        patient=args.patient,
        controller=args.controller,
        gains=gains,
        duration_s=duration,
        control_rate_hz=args.rate,
        plant_substeps=args.substeps,
        patient_torque=args.patient_torque,
        safety=not args.no_safety,
        safety_use_estimate=args.safety_estimate,
        estop_at_s=args.estop_at,
        cuff_force_limit_N=args.cuff_force_limit,
    )


def _cmd_simulate(args: argparse.Namespace) -> int:
    config = _sim_config(args)
    observers = []
    if not args.no_record:
        from ..record.recorder import RerunRecorder

        observers.append(RerunRecorder(args.out, spawn=args.spawn))
    result = simulate(config, observers=observers, progress=True, keep_history=False)
    summary = result.summary()
    if args.summary:
        with atomic_write(args.summary) as handle:
            json.dump(summary, handle, indent=2)
            handle.write("\n")
    print(format_summary(summary))
    if not args.no_record:
        print(f"recording: {args.out} (view offline: rerun {args.out})")
    if result.status == "interrupted":
        return 130
    if result.status != "completed":
        print(f"exo-ctrl simulate: error: {result.error}", file=sys.stderr)
        return 1
    return 0


def format_summary(summary: dict) -> str:
    """The summary as a plain-text table."""
    lines = [
        f"controller {summary['controller']}, {summary['status']}: "
        f"{summary['duration_s']:.3f} s simulated in {summary['wall_time_s']:.2f} s "
        f"(real-time factor {summary['real_time_factor']:.1f}), "
        f"belt speed {summary['belt_speed_mps']:.3f} m/s",
        f"{'joint':<12}{'rms err [mrad]':>15}{'max err [mrad]':>15}{'peak τ [N·m]':>13}"
        f"{'peak I [A]':>11}{'peak U [V]':>11}",
    ]
    for j in JOINT_NAMES:
        lines.append(
            f"{j:<12}{1e3 * summary['rms_tracking_error_rad'][j]:>15.3f}"
            f"{1e3 * summary['max_tracking_error_rad'][j]:>15.3f}"
            f"{summary['peak_drive_torque_Nm'][j]:>13.1f}"
            f"{summary['peak_motor_current_A'][j]:>11.2f}{summary['peak_motor_voltage_V'][j]:>11.2f}"
        )
    cuffs = ", ".join(f"{c} {f:.1f}" for c, f in summary["peak_cuff_force_N"].items())
    lines.append(f"peak cuff force [N]: {cuffs}")
    for event in summary["safety_events"][:5]:
        lines.append(f"safety: {event['message']}")
    if summary["safety_state"] != "normal":
        lines.append(f"safety supervisor ended in state {summary['safety_state']!r}")
    return "\n".join(lines)


# --------------------------------------------------------------------------- estimate


def _cmd_estimate(args: argparse.Namespace) -> int:
    from ..estimation.offline import estimate_file, write_estimate_recording

    estimate = estimate_file(args.file, exo=args.exo, gain_per_s=args.gain)
    summary = estimate.summary()
    if args.out:
        write_estimate_recording(estimate, args.out)
    if args.summary:
        with atomic_write(args.summary) as handle:
            json.dump(summary, handle, indent=2)
            handle.write("\n")
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


# --------------------------------------------------------------------------- main


class _Parser(argparse.ArgumentParser):
    """argparse with exit code 2 and a one-line message on bad usage."""

    def error(self, message: str) -> None:
        self.exit(2, f"{self.prog}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``exo-ctrl``."""
    parser = _Parser(prog="exo-ctrl", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

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
    p.set_defaults(func=_cmd_gait)

    p = sub.add_parser("urdf", help="generate an exoskeleton or patient URDF")
    p.add_argument("--kind", choices=("exo", "patient"), required=True)
    for name, unit in (
        ("thigh-length", "m"),
        ("shank-length", "m"),
        ("thigh-mass", "kg"),
        ("shank-mass", "kg"),
        ("thigh-cuff", "m"),
        ("shank-cuff", "m"),
    ):
        p.add_argument(
            f"--{name}",
            type=float,
            default=None,
            metavar=unit.upper(),
            help=f"{name.replace('-', ' ')} [{unit}] (default: paper Table I; a cuff "
            "not given keeps its fraction of a changed link length)",
        )
    p.add_argument("--out", required=True, metavar="PATH", help="output URDF file")
    p.set_defaults(func=_cmd_urdf)

    p = sub.add_parser("simulate", help="run the closed loop and write a rerun recording")
    add_gait_options(p)
    p.add_argument(
        "--patient",
        default=None,
        metavar="URDF|human",
        help="patient URDF, or 'human' for example-robot-data's model (default: urdf/patient.urdf)",
    )
    p.add_argument(
        "--controller",
        choices=CONTROLLERS,
        default="pd",
        help="pd (paper), ct (computed torque + PD) or qp (CT + PD through a QP under drive "
        "limits and cuff-force bounds) (default pd)",
    )
    span = p.add_mutually_exclusive_group()
    span.add_argument(
        "--cycles",
        type=float,
        default=None,
        metavar="N",
        help="gait cycles to run; 0.5 = one step (default 2)",
    )
    span.add_argument(
        "--duration", type=float, default=None, metavar="SEC", help="simulated time [s]"
    )
    p.add_argument(
        "--rate", type=float, default=1000.0, metavar="HZ", help="control rate [Hz] (default 1000)"
    )
    p.add_argument(
        "--substeps",
        type=int,
        default=1,
        metavar="N",
        help="plant steps per control tick (default 1)",
    )
    p.add_argument(
        "--kp",
        type=float,
        default=None,
        metavar="V/RAD",
        help=f"PD proportional gain, all joints (default {PDGains().kp[0]:g})",
    )
    p.add_argument(
        "--kd",
        type=float,
        default=None,
        metavar="V.S/RAD",
        help=f"PD derivative gain, all joints (default {PDGains().kd[0]:g})",
    )
    p.add_argument(
        "--cuff-force-limit",
        type=float,
        default=SimConfig().cuff_force_limit_N,
        metavar="N",
        help="the qp controller's bound on each cuff's predicted force [N] (default "
        f"{SimConfig().cuff_force_limit_N:g}: ISO/TS 15066 lower leg 130 N with a margin)",
    )
    p.add_argument(
        "--patient-torque",
        choices=PATIENT_TORQUES,
        default="none",
        help="patient joint torques: none (paper §VI) or spastic (default none)",
    )
    p.add_argument(
        "--no-safety",
        action="store_true",
        help="run without the safety supervisor (an --estop-at still acts)",
    )
    p.add_argument(
        "--safety-estimate",
        action="store_true",
        help="the supervisor watches the estimated cuff forces, as on the device",
    )
    p.add_argument(
        "--estop-at",
        type=float,
        default=None,
        metavar="SEC",
        help="emergency stop at this time [s]",
    )
    p.add_argument("--summary", default=None, metavar="PATH.json", help="write the summary as JSON")
    p.add_argument(
        "--out",
        default="exo_run.rrd",
        metavar="PATH.rrd",
        help="rerun recording (default exo_run.rrd)",
    )
    p.add_argument("--no-record", action="store_true", help="do not write a recording")
    p.add_argument("--spawn", action="store_true", help="also open a rerun viewer if one can start")
    p.set_defaults(func=_cmd_simulate)

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
    p.set_defaults(func=_cmd_estimate)

    from ..sweep.sweep import add_sweep_arguments, run_sweep_command

    p = sub.add_parser(
        "sweep",
        help="sweep gait, patient and device parameters: Parquet/CSV table, load plots, report",
    )
    add_sweep_arguments(p)
    p.set_defaults(func=run_sweep_command)

    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``exo-ctrl``; returns the exit code (0 success, 2 bad input, 130 interrupted)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except ExoCtrlError as exc:
        print(f"exo-ctrl {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"exo-ctrl {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"exo-ctrl {args.command}: interrupted", file=sys.stderr)
        return 130
