"""``exo-ctrl urdf``: generate an exoskeleton or patient URDF."""

from __future__ import annotations

import argparse
from pathlib import Path

from .. import _validate as v
from ..exceptions import InvalidParameter
from ..model import (
    DEFAULT_URDF_NAMES,
    SEXES,
    BodyParams,
    load_body,
    patient_from_anthropometry,
    write_urdf,
)
from .common import check_outputs

__all__ = ["register", "run"]

#: The body options: name and unit (defaults: paper Table I).
_OPTIONS = (
    ("thigh-length", "m"),
    ("shank-length", "m"),
    ("thigh-mass", "kg"),
    ("shank-mass", "kg"),
    ("thigh-cuff", "m"),
    ("shank-cuff", "m"),
)


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``urdf`` subcommand."""
    p = sub.add_parser("urdf", help="generate an exoskeleton or patient URDF")
    p.add_argument(
        "--kind",
        choices=("exo", "patient"),
        required=True,
        help="the body to generate: exo (the exoskeleton) or patient (the patient's legs)",
    )
    exo, patient = BodyParams.exo_default(), BodyParams.patient_default()
    for name, unit in _OPTIONS:
        field = name.replace("-", "_")
        p.add_argument(
            f"--{name}",
            type=float,
            default=None,
            metavar=unit.upper(),
            help=f"{name.replace('-', ' ')} [{unit}] (default: exo {getattr(exo, field):g}, "
            f"patient {getattr(patient, field):g}, paper Table I; a cuff not given keeps its "
            "fraction of a changed link length)",
        )
    body = p.add_argument_group(
        "patient from height and mass (de Leva 1996's segment tables; --kind patient only)"
    )
    body.add_argument(
        "--height",
        type=float,
        default=None,
        metavar="M",
        help="stature [m], 1.4 to 2.1 (default: none, the paper's patient); needs --mass",
    )
    body.add_argument(
        "--mass",
        type=float,
        default=None,
        metavar="KG",
        help="body mass [kg], 35 to 150 (default: none); needs --height",
    )
    body.add_argument(
        "--sex",
        choices=SEXES,
        default="male",
        help="which of de Leva's tables (default male, as the paper's patient)",
    )
    p.add_argument("--out", required=True, metavar="PATH", help="output URDF file")
    p.set_defaults(func=run)


def _base(args: argparse.Namespace) -> BodyParams:
    """The body before the length, mass and cuff options: the default or the regressions'."""
    if args.height is None and args.mass is None:
        return BodyParams.exo_default() if args.kind == "exo" else BodyParams.patient_default()
    if args.kind != "patient":
        given = "--height" if args.height is not None else "--mass"
        value = args.height if args.height is not None else args.mass
        raise InvalidParameter(
            given, value, "unset for --kind exo", "height and mass describe a patient"
        )
    if args.mass is None:
        raise InvalidParameter("--mass", None, "a body mass [kg] given with --height")
    if args.height is None:
        raise InvalidParameter("--height", None, "a stature [m] given with --mass")
    return patient_from_anthropometry(
        v.finite("height", args.height, "m"), v.finite("mass", args.mass, "kg"), args.sex
    )


def run(args: argparse.Namespace) -> int:
    """Write the URDF; a cuff not given keeps its place as a fraction of its link."""
    if Path(args.out).is_dir():  # a directory: the body's default file name in it
        args.out = str(Path(args.out) / DEFAULT_URDF_NAMES[args.kind])
    check_outputs(args, out="--out")
    base = _base(args)
    names = [name.replace("-", "_") for name, _ in _OPTIONS]
    changes = {name: getattr(args, name) for name in names if getattr(args, name) is not None}
    for seg in ("thigh", "shank"):
        length = changes.get(f"{seg}_length")
        if length is not None and f"{seg}_cuff" not in changes:
            changes[f"{seg}_cuff"] = (
                getattr(base, f"{seg}_cuff") / getattr(base, f"{seg}_length") * length
            )
    params = base.replace(**changes)
    path = write_urdf(params, args.out)
    body = load_body(path, name=args.kind)
    thigh, shank = body.legs["left"].thigh_length, body.legs["left"].shank_length
    legs = f"legs {thigh:.4g} m + {shank:.4g} m, moving mass {body.mass:.4g} kg"
    print(f"wrote {path}: {args.kind}, {legs}")
    if args.height is not None:
        print(
            "  an exoskeleton fitted to these legs (joints aligned): exo-ctrl urdf --kind exo "
            f"--thigh-length {thigh:.4g} --shank-length {shank:.4g} --out EXO.urdf"
        )
    return 0
