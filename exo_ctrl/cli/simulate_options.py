"""``exo-ctrl simulate``'s long options: every setting of a run as a flag.

These predate scenario files.  They stay accepted (and are listed in
docs/cli.md) but hidden from ``--help``: a scenario file and ``--set
section.key=value`` reach every setting.  :func:`flag_settings` turns the
flags a user gave into scenario settings: the SimConfig they build
(:func:`flags_config`, the free-air defaults of ``SimConfig()`` underneath)
compared with the one the flags' defaults build; what differs is set.
"""

from __future__ import annotations

import argparse

from .. import _validate as v
from ..control import PDGains
from ..estimation import ESTIMATORS
from ..exceptions import InvalidParameter
from ..model import SEXES
from ..plan import EXERCISES, GaitParams
from ..plan.exercise import CALIBRATION_DURATION_S
from ..plant import (
    MAX_MISALIGNMENT_M,
    MOTOR_PRESETS,
    CompliantJoint,
    CuffParams,
    Misalignment,
    motor_preset,
)
from ..plant.patient_active import PATIENT_KINDS
from ..sim import SimConfig
from ..sim.belief import Belief
from ..sim.config import CUFF_FITS, MAX_DURATION_S
from .common import (
    add_gait_options,
    gait_params_from,
)
from .modes_options import add_mode_options, mode_config_from
from .treadmill_options import add_treadmill_options, treadmill_config_from

__all__ = ["add_run_options", "flags_config"]


def add_run_options(p: argparse.ArgumentParser) -> None:
    """The long options of ``simulate`` (each a setting of the run)."""
    add_gait_options(p)
    p.add_argument(
        "--patient",
        default=None,
        metavar="URDF|human",
        help="patient URDF file, or 'human' for example-robot-data's model "
        "(default: urdf/patient.urdf)",
    )
    p.add_argument(
        "--exercise",
        choices=EXERCISES,
        default="gait",
        help="gait, or calibration: the legs swing in the air from rest to rest for "
        f"identification (exo-ctrl identify; default {CALIBRATION_DURATION_S:g} s) (default gait)",
    )
    p.add_argument(
        "--ramp-in",
        type=float,
        default=None,
        metavar="SEC",
        help="the start: standing at rest, then step length and belt speed rising smoothly "
        "(C2) into the gait over this time [s]; 0 starts on the gait at full speed "
        f"(default: one gait period, {GaitParams().period:g} s at the default period)",
    )
    p.add_argument(
        "--ramp-out",
        type=float,
        default=0.0,
        metavar="SEC",
        help="the end: from the gait back to standing over the run's last SEC seconds [s] "
        "(default 0: none)",
    )
    p.add_argument(
        "--cuff-fit",
        choices=CUFF_FITS,
        default="equilibrium",
        help="the cuffs at the start: equilibrium (the patient settled into them at rest) or "
        "slack (fitted in the exoskeleton's posture: the patient drops into them) "
        "(default equilibrium)",
    )
    for joint in ("hip", "knee"):
        p.add_argument(
            f"--misalignment-{joint}",
            default="0,0",
            metavar="DX,DZ",
            help=f"the true patient's {joint} axis offset from the exoskeleton's, forward and up "
            f"with the legs straight [m], each within ±{MAX_MISALIGNMENT_M:g} (truth only: the "
            "device's models stay aligned; default 0,0)",
        )
    p.add_argument(
        "--rate", type=float, default=1000.0, metavar="HZ", help="control rate [Hz] (default 1000)"
    )
    p.add_argument(
        "--substeps",
        type=int,
        default=1,
        metavar="N",
        help="plant steps per control tick, no unit (default 1)",
    )
    p.add_argument(
        "--motor",
        choices=MOTOR_PRESETS,
        default="default",
        help="the drives: default (an energy-consistent brushless motor with the paper's "
        "winding, a 120:1 harmonic drive of 85 %% efficiency, 24 V, 30 A) or paper-printed "
        "(Table I as printed, k_m = 0.35 N·m/A with k_E = 25.9 rad/(V·s), ratio 50, 10 A: "
        "not energy-consistent, warns; its own default gains kp 100, kd 2) (default default)",
    )
    p.add_argument(
        "--joint-stiffness",
        type=float,
        default=0.0,
        metavar="NM_PER_RAD",
        help="joint compliance: a torsional spring between each drive's rotor and its link "
        f"[N·m/rad], e.g. {CompliantJoint().stiffness_Nm_per_rad:g} for a size-20-25 harmonic "
        "drive; the encoders then measure the link and the torque sensors the spring "
        "(default 0: a rigid drive)",
    )
    p.add_argument(
        "--joint-damping",
        type=float,
        default=CompliantJoint().damping_Nm_s_per_rad,
        metavar="NM_S_PER_RAD",
        help="the joint spring's damping [N·m·s/rad], with --joint-stiffness "
        f"(default {CompliantJoint().damping_Nm_s_per_rad:g})",
    )
    add_treadmill_options(p)
    p.add_argument(
        "--kp",
        type=float,
        default=None,
        metavar="V/RAD",
        help=f"PD proportional gain [V/rad], all joints (default {PDGains().kp[0]:g})",
    )
    p.add_argument(
        "--kd",
        type=float,
        default=None,
        metavar="V.S/RAD",
        help=f"PD derivative gain [V·s/rad], all joints (default {PDGains().kd[0]:g})",
    )
    p.add_argument(
        "--cuff-force-limit",
        type=float,
        default=SimConfig().cuff_force_limit_N,
        metavar="N",
        help="the qp controller's bound on each cuff's predicted force [N] (default "
        f"{SimConfig().cuff_force_limit_N:g}: ISO/TS 15066 lower leg 130 N with a margin)",
    )
    device = p.add_argument_group(
        "what the device believes (the controller's, estimator's and supervisor's models; "
        "the plant simulates --exo and --patient)"
    )
    device.add_argument(
        "--controller-patient",
        default="nominal",
        metavar="nominal|truth|URDF",
        help="the patient model the device holds: nominal (the measured leg lengths with de "
        "Leva's segment tables for the patient's stature and mass), truth (the --patient URDF "
        "itself: the ideal comparison) or a URDF file, e.g. the identified patient that "
        "exo-ctrl identify --out wrote (default nominal)",
    )
    device.add_argument(
        "--controller-exo",
        default=None,
        metavar="URDF",
        help="the exoskeleton model the device holds (default: the --exo URDF)",
    )
    device.add_argument(
        "--controller-cuffs",
        choices=("isotropic", "split"),
        default="isotropic",
        help="the cuff model the QP and the kalman estimator hold: isotropic (the cuffs' "
        "nominal 8 N/mm and 100 N·s/m in every direction) or split (the published normal and "
        "shear stiffness of the cuff-tissue interface, the truth's default, "
        "exo_ctrl/plant/cuffs.py) (default isotropic)",
    )
    device.add_argument(
        "--patient-height",
        type=float,
        default=None,
        metavar="M",
        help="the patient's stature for the nominal model [m] (default: the paper's 1.75 m, "
        "for the default patient only)",
    )
    device.add_argument(
        "--patient-mass",
        type=float,
        default=None,
        metavar="KG",
        help="the patient's body mass for the nominal model [kg] (default: the paper's 80 kg, "
        "for the default patient only)",
    )
    device.add_argument(
        "--patient-sex",
        choices=SEXES,
        default="male",
        help="which of de Leva's tables the nominal model takes (default male)",
    )
    device.add_argument(
        "--estimator",
        choices=ESTIMATORS,
        default="kalman",
        help="the live cuff-force estimator: kalman (a Kalman filter on the coupled "
        "exoskeleton-cuff-patient model with the device's patient and cuff models) or "
        "momentum (the momentum observer on the exoskeleton's model) (default kalman)",
    )
    p.add_argument(
        "--patient-torque",
        choices=PATIENT_KINDS,
        default="none",
        help="patient joint torques: none (paper §VI), spastic, or active (their own gait "
        "with a delay and a strength: the active patient options) (default none)",
    )
    add_mode_options(p)
    p.add_argument(
        "--no-safety",
        action="store_true",
        help="run without the safety supervisor (an --estop-at still acts)",
    )
    p.add_argument(
        "--safety-force",
        choices=("estimate", "truth"),
        default="estimate",
        help="the cuff forces the supervisor watches: estimate (from the joint torque sensors, "
        "as on the device) or truth (the simulated forces: the ideal comparison, a force "
        "sensor in every cuff) (default estimate)",
    )
    p.add_argument(
        "--estop-at",
        type=float,
        default=None,
        metavar="SEC",
        help="emergency stop at this time [s] (default: none)",
    )


def flags_config(args: argparse.Namespace) -> SimConfig:
    """The run's SimConfig from the long options alone (``SimConfig()``'s defaults beneath).

    The duration: ``--duration``, else the ``--session``'s, else the ramp-in,
    ``--cycles`` (default 2) gait cycles at full speed and the ramp-out.
    """
    gait = gait_params_from(args)
    ramp_in = args.ramp_in
    if ramp_in is not None:
        ramp_in = v.non_negative("ramp_in", ramp_in, "s")
    ramp_out = v.non_negative("ramp_out", args.ramp_out, "s")
    modes = mode_config_from(args)
    if args.duration is not None:
        duration = args.duration
    elif modes["session"] is not None:  # the segments' durations
        duration = modes["session"].total_s
    elif args.exercise == "calibration":
        duration = CALIBRATION_DURATION_S
    else:
        cycles = 2.0 if args.cycles is None else v.positive("cycles", args.cycles)
        lead = gait.period if ramp_in is None else ramp_in
        duration = lead + cycles * gait.period + ramp_out
        if duration > MAX_DURATION_S:
            most = (MAX_DURATION_S - lead - ramp_out) / gait.period
            raise InvalidParameter(
                "cycles",
                args.cycles,
                f"at most {most:.6g} at the {gait.period:g} s period",
                f"the run would last {duration:.4g} s, beyond {MAX_DURATION_S:g} s",
            )
    motor = motor_preset(args.motor)
    stiffness = v.non_negative("joint_stiffness", args.joint_stiffness, "N·m/rad")
    rigid = CompliantJoint(damping_Nm_s_per_rad=args.joint_damping)  # checks the damping
    compliance = CompliantJoint(stiffness, args.joint_damping, True) if stiffness > 0 else rigid
    base = PDGains.paper_printed() if args.motor == "paper-printed" else PDGains()
    gains = PDGains(
        kp=args.kp if args.kp is not None else base.kp,
        kd=args.kd if args.kd is not None else base.kd,
    )
    return SimConfig(
        gait=gait,
        exo=args.exo,
        patient=args.patient,
        controller=args.controller or "pd",
        gains=gains,
        motor=motor,
        duration_s=duration,
        ramp_in_s=ramp_in,
        ramp_out_s=ramp_out,
        cuff_fit=args.cuff_fit,
        misalignment=Misalignment(
            _pair("misalignment_hip", args.misalignment_hip),
            _pair("misalignment_knee", args.misalignment_knee),
        ),
        control_rate_hz=args.rate,
        plant_substeps=args.substeps,
        patient_torque=args.patient_torque,
        safety=not args.no_safety,
        safety_use_estimate=args.safety_force == "estimate",
        estop_at_s=args.estop_at,
        cuff_force_limit_N=args.cuff_force_limit,
        estimator=args.estimator,
        joint_compliance=compliance,
        **treadmill_config_from(args),
        exercise=args.exercise,
        **modes,
        belief=Belief(
            patient=args.controller_patient,
            exo=args.controller_exo,
            patient_height_m=args.patient_height,
            patient_mass_kg=args.patient_mass,
            patient_sex=args.patient_sex,
            cuffs=CuffParams() if args.controller_cuffs == "split" else None,
        ),
    )


def _pair(name: str, text: str) -> tuple[float, float]:
    """``"DX,DZ"`` as two floats [m] (range checked by :class:`~exo_ctrl.plant.Misalignment`)."""
    allowed = f"two numbers DX,DZ in [-{MAX_MISALIGNMENT_M:g}, {MAX_MISALIGNMENT_M:g}] m"
    parts = text.split(",")
    try:
        if len(parts) != 2:
            raise ValueError(text)
        return float(parts[0]), float(parts[1])
    except ValueError:
        raise InvalidParameter(name, text, allowed) from None
