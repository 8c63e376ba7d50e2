"""The ``simulate`` options of the interaction modes and the active patient (issue 18)."""

from __future__ import annotations

import argparse
from typing import Any

from ..control.modes import MODES, ModeParams, PathParams
from ..control.modes.params import FORCE_GAINS
from ..exceptions import InvalidParameter
from ..plant.patient_active import ActiveParams
from ..safety import STOP_REACTIONS
from ..sim.session import load_session

__all__ = ["add_mode_options", "mode_config_from"]


def add_mode_options(p: argparse.ArgumentParser) -> None:
    """Add ``--mode`` and its parameters, and the active patient's options."""
    m, a, path = ModeParams(), ActiveParams(), PathParams()
    g = p.add_argument_group("interaction modes (exo_ctrl/control/modes)")
    g.add_argument(
        "--mode",
        choices=MODES,
        default="tracking",
        help="tracking (the controller's position control), guidance (its impedance scaled "
        "by --guidance around the plan, the device's own dynamics compensated), transparent "
        "(the device carries itself and drives the estimated cuff force towards zero) or aan "
        "(assist-as-needed: a support per gait phase learned cycle by cycle from the error) "
        "or path (a tunnel of --tunnel-width around the planned foot path, the patient setting "
        "the pace along it) (default tracking)",
    )
    g.add_argument(
        "--stop-reaction",
        choices=STOP_REACTIONS,
        default=None,
        help="how the safety supervisor's stop ends: hold (the posture, stiffly) or yield "
        "(gravity compensation and damping, the device no longer drives, an active patient "
        "moves the legs; exo_ctrl/safety/stop_reaction.py) (default: hold in tracking and in "
        "guidance with G = 1, yield in the other modes)",
    )
    g.add_argument(
        "--tunnel-width",
        type=float,
        default=path.tunnel_width_m,
        metavar="M",
        help="path's tunnel half-width around the planned foot path [m]: no force inside, a "
        f"stiff damped wall outside (default {path.tunnel_width_m:g})",
    )
    g.add_argument(
        "--path-support",
        type=float,
        default=path.support_N,
        metavar="N",
        help=f"path's supportive force along the path's tangent [N] (default {path.support_N:g})",
    )
    g.add_argument(
        "--session",
        default=None,
        metavar="FILE.json",
        help="a session: a JSON list of segments, each {duration [s], mode, its parameters "
        "(guidance, force_gain, aan_forgetting, aan_gain, tunnel_width, path_support), "
        "belt_speed [m/s] with --contact on}, switched bumplessly and logged as events; the run "
        "lasts their sum (exo_ctrl/sim/session.py) (default: none, --mode throughout)",
    )
    g.add_argument(
        "--guidance",
        type=float,
        default=m.guidance,
        metavar="G",
        help="guidance share G in [0, 1], no unit: 1 tracking, 0 the free command "
        "(transparent's compensation with guidance's force gain) "
        f"(default {m.guidance:g})",
    )
    kalman = FORCE_GAINS[("transparent", "kalman")]
    momentum = FORCE_GAINS[("transparent", "momentum")]
    g.add_argument(
        "--force-gain",
        type=float,
        default=None,
        metavar="K",
        help="force feedback gain, no unit, on the estimated interaction torque in transparent "
        "and guidance, all joints: the exoskeleton's inertia is felt divided by 1 + K "
        f"(default per mode and estimator: transparent {kalman[0]:g} at the hips, "
        f"{kalman[1]:g} at the knees with the Kalman filter, {momentum[0]:g} with the "
        f"momentum observer; guidance {FORCE_GAINS[('guidance', 'kalman')][0]:g})",
    )
    g.add_argument(
        "--aan-forgetting",
        type=float,
        default=m.aan_forgetting,
        metavar="F",
        help="aan's forgetting factor f in [0, 1) per cycle, no unit "
        f"(default {m.aan_forgetting:g})",
    )
    g.add_argument(
        "--aan-gain",
        type=float,
        default=m.aan_gain[0],
        metavar="NM_PER_RAD",
        help=f"aan's learning gain g [N·m/rad] (default {m.aan_gain[0]:g})",
    )
    g = p.add_argument_group(
        "active patient (--patient-torque active; exo_ctrl/plant/patient_active)"
    )
    g.add_argument(
        "--patient-strength",
        default="1",
        metavar="S|S1,S2,S3,S4",
        help="strength in [0, 1] (1 healthy, 0 paralysed), one value or four in joint order "
        "left_hip,left_knee,right_hip,right_knee (default 1)",
    )
    g.add_argument(
        "--patient-step-length",
        type=float,
        default=None,
        metavar="M",
        help="the patient's preferred step length [m] (default: none, the device's)",
    )
    g.add_argument(
        "--patient-period",
        type=float,
        default=None,
        metavar="SEC",
        help="the patient's preferred gait period [s] (default: none, the device's)",
    )
    g.add_argument(
        "--patient-delay",
        type=float,
        default=a.delay_s,
        metavar="SEC",
        help=f"the patient's feedback delay [s] (default {a.delay_s:g})",
    )
    g.add_argument(
        "--patient-seed",
        type=int,
        default=a.seed,
        metavar="S",
        help=f"seed of the patient's step-to-step variability, no unit (default {a.seed})",
    )
    g.add_argument(
        "--patient-spastic",
        action="store_true",
        help="add the spastic torques to the active patient's",
    )


def mode_config_from(args: argparse.Namespace) -> dict[str, Any]:
    """SimConfig's mode, stop_reaction, modes, path, session and patient_active fields.

    Raises:
        InvalidParameter: a value outside its range, or active-patient
            options without ``--patient-torque active``.

    """
    active = args.patient_torque == "active"
    given = [
        name
        for name, value in (
            ("--patient-step-length", args.patient_step_length),
            ("--patient-period", args.patient_period),
            ("--patient-spastic", args.patient_spastic or None),
            ("--patient-strength", None if args.patient_strength == "1" else 1),
        )
        if value is not None
    ]
    if given and not active:
        raise InvalidParameter(
            "patient_torque", args.patient_torque, f"active with {given[0]} (an active patient's)"
        )
    session = None
    if args.session is not None:
        if args.cycles is not None:
            raise InvalidParameter(
                "cycles", args.cycles, "unset with --session", "its segments' durations set the run"
            )
        session = load_session(args.session)
    return {
        "mode": args.mode,
        "stop_reaction": args.stop_reaction,
        "path": PathParams(tunnel_width_m=args.tunnel_width, support_N=args.path_support),
        "session": session,
        "modes": ModeParams(
            guidance=args.guidance,
            force_gain=args.force_gain,
            aan_forgetting=args.aan_forgetting,
            aan_gain=args.aan_gain,
        ),
        "patient_active": ActiveParams(
            strength=_numbers("patient_strength", args.patient_strength),
            step_length_m=args.patient_step_length,
            period_s=args.patient_period,
            delay_s=args.patient_delay,
            seed=args.patient_seed,
            spastic=args.patient_spastic,
        ),
    }


def _numbers(name: str, text: str) -> float | tuple[float, ...]:
    """One number or four comma-separated ones (ranges are checked by ActiveParams)."""
    parts = text.split(",")
    try:
        values = tuple(float(x) for x in parts)
    except ValueError:
        raise InvalidParameter(name, text, "a number or four comma-separated numbers") from None
    if len(values) == 1:
        return values[0]
    return values
