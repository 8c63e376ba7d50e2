"""The ``simulate`` options of the treadmill: belt, foot contact, synchronisation, the pelvis."""

from __future__ import annotations

import argparse
from typing import Any

from ..plan import GaitParams, SpeedProfile
from ..plant import BeltParams, ContactParams, PelvisParams

__all__ = ["add_treadmill_options", "treadmill_config_from"]


def add_treadmill_options(p: argparse.ArgumentParser) -> None:
    """The belt and foot–belt contact options (:mod:`exo_ctrl.plant.contact`) and the pelvis's."""
    c, b = ContactParams(), BeltParams()
    g = p.add_argument_group("treadmill belt and foot contact")
    g.add_argument(
        "--contact",
        choices=("on", "off"),
        default="on" if c.enabled else "off",
        help="the belt as a body with its own drive and the exoskeleton feet in Hunt–Crossley "
        f"contact with friction on it (default {'on' if c.enabled else 'off'}: the feet in free "
        "air, as the paper)",
    )
    g.add_argument(
        "--patient-feet",
        choices=("on", "off"),
        default="on" if c.patient_feet else "off",
        help="the patient's foot points meet the belt too, with the soles' contact law "
        "(exo_ctrl/plant/patient_feet.py; needs --contact on) (default "
        f"{'on' if c.patient_feet else 'off'}: only the exoskeleton's feet, the patient's "
        "foot free to sink below the belt)",
    )
    g.add_argument(
        "--friction",
        type=float,
        default=c.friction_coeff,
        metavar="MU",
        help=f"foot–belt friction coefficient μ [-] (default {c.friction_coeff:g}, a rubber sole)",
    )
    g.add_argument(
        "--belt-height",
        type=float,
        default=None,
        metavar="M",
        help="the belt's top below the hip joint [m] (default: the gait's hip height H_s, "
        f"{GaitParams().hip_height:g} m by default)",
    )
    g.add_argument(
        "--belt-mass",
        type=float,
        default=b.mass_kg,
        metavar="KG",
        help=f"belt + rollers + drive rotor as an equivalent mass [kg] (default {b.mass_kg:g})",
    )
    g.add_argument(
        "--belt-bandwidth",
        type=float,
        default=b.bandwidth_hz,
        metavar="HZ",
        help=f"the belt speed controller's bandwidth [Hz] (default {b.bandwidth_hz:g})",
    )
    g.add_argument(
        "--speed-profile",
        default=None,
        metavar="T1:V1,T2:V2,...",
        help="the session's belt set speed, piecewise linear through the points [s:m/s] "
        "(times increasing, speeds > 0; V1 before T1, the last speed after the last point; "
        "needs --contact on; default: the gait's belt speed)",
    )
    g.add_argument(
        "--sync",
        choices=("on", "off"),
        default=None,
        help="plan online from the measured belt speed, step length and period adapting to it "
        "(exo_ctrl/plan/online.py, adapt.py); off: the precomputed plan at the gait's belt speed "
        "(default: on with --contact on and pd or ct, off otherwise)",
    )
    pel = PelvisParams()
    g = p.add_argument_group("pelvis and body-weight support (exo_ctrl/plant/pelvis.py)")
    g.add_argument(
        "--pelvis",
        choices=("fixed", "supported"),
        default="fixed",
        help="fixed: the pelvis held by the frame (the paper); supported: exoskeleton and patient "
        "on a pelvis free to move vertically, lifted by a constant body-weight-support force, "
        "the legs carrying the rest through the belt (needs --contact on) (default fixed)",
    )
    g.add_argument(
        "--bws",
        type=float,
        default=pel.bws_fraction,
        metavar="FRACTION",
        help="body-weight support: the harness's force as a fraction of the patient's body "
        f"weight, in [0, 1] (default {pel.bws_fraction:g}); with --pelvis supported",
    )
    g.add_argument(
        "--body-mass",
        type=float,
        default=None,
        metavar="KG",
        help="the patient's body mass [kg], legs included (default: --patient-mass, else the "
        "paper patient's 80 kg); with --pelvis supported",
    )


def treadmill_config_from(args: argparse.Namespace) -> dict[str, Any]:
    """SimConfig's ``contact``, ``speed_profile``, ``sync`` and ``pelvis`` from the options."""
    belt = BeltParams(
        height_m=args.belt_height, mass_kg=args.belt_mass, bandwidth_hz=args.belt_bandwidth
    )
    return {
        "contact": ContactParams(
            enabled=args.contact == "on",
            friction_coeff=args.friction,
            belt=belt,
            patient_feet=args.patient_feet == "on",
        ),
        "speed_profile": None
        if args.speed_profile is None
        else SpeedProfile.parse(args.speed_profile),
        "sync": None if args.sync is None else args.sync == "on",
        "pelvis": PelvisParams(
            supported=args.pelvis == "supported",
            bws_fraction=args.bws,
            body_mass_kg=args.body_mass,
        ),
    }
