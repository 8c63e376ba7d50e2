"""``exo-ctrl urdf``: generate an exoskeleton or patient URDF."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..model import DEFAULT_URDF_NAMES, BodyParams, load_body, write_urdf
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
    p.add_argument("--out", required=True, metavar="PATH", help="output URDF file")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Write the URDF; a cuff not given keeps its place as a fraction of its link."""
    if Path(args.out).is_dir():  # a directory: the body's default file name in it
        args.out = str(Path(args.out) / DEFAULT_URDF_NAMES[args.kind])
    check_outputs(args, out="--out")
    base = BodyParams.exo_default() if args.kind == "exo" else BodyParams.patient_default()
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
    print(
        f"wrote {path}: {args.kind}, legs {body.legs['left'].thigh_length:g} m + "
        f"{body.legs['left'].shank_length:g} m, moving mass {body.mass:.4g} kg"
    )
    return 0
