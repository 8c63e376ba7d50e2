"""``exo-ctrl urdf``: generate an exoskeleton or patient URDF."""

from __future__ import annotations

import argparse
import re
import string
from pathlib import Path

from .. import _validate as v
from .._io import DerivedOutput, check_output
from ..exceptions import InvalidParameter
from ..model import (
    DEFAULT_URDF_NAMES,
    SEXES,
    BodyParams,
    draw_cohort,
    load_body,
    patient_from_anthropometry,
    write_urdf,
)
from ..model.cohort import MAX_COHORT
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
    cohort = p.add_argument_group(
        "virtual cohort (exo_ctrl/model/cohort.py; --kind patient with --height and --mass)"
    )
    cohort.add_argument(
        "--cohort",
        type=int,
        default=None,
        metavar="N",
        help=f"write N true patients drawn around the one of --height, --mass, --sex "
        f"(segment lengths, masses, centres of mass, radii of gyration), 1 to {MAX_COHORT}, "
        "no unit (default: none, one patient)",
    )
    cohort.add_argument(
        "--seed",
        type=int,
        default=None,
        metavar="S",
        help="the cohort's seed, an integer >= 0, no unit (default 0; with --cohort only)",
    )
    p.add_argument(
        "--out",
        required=True,
        metavar="PATH",
        help="output URDF file (a directory: the body's default name in it); with --cohort "
        "an existing directory (files patient_s{SEED}_{I}.urdf, I from 0, zero-padded to 3 "
        "digits or more) or a pattern with {i} (e.g. cohort/p{i:02d}.urdf)",
    )
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
    if args.cohort is not None or args.seed is not None:
        return _run_cohort(args)
    if args.out and Path(args.out).is_dir():  # a directory: the body's default file name in it
        args.out = DerivedOutput(Path(args.out) / DEFAULT_URDF_NAMES[args.kind])
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


#: The widest field a cohort pattern may format (``{i:032d}``) [characters].
MAX_PATTERN_WIDTH = 32


def _pattern_problem(out: str) -> str:
    """Why a cohort pattern's fields cannot be formatted cheaply ("" if they can).

    Each field's format spec is read before any formatting: a width or
    precision over :data:`MAX_PATTERN_WIDTH` (``{i:999999999}`` asked for
    gigabytes) or a nested field is refused.
    """
    try:
        fields = list(string.Formatter().parse(out))
    except ValueError as exc:
        return f"the pattern fails: {exc}"
    for _, name, spec, _ in fields:
        if name is None or not spec:
            continue
        if "{" in spec:
            return f"a nested field in {{{name}:{spec}}}"
        widths = [int(d) for d in re.findall(r"\d+", spec)]
        if widths and max(widths) > MAX_PATTERN_WIDTH:
            return f"the field {{{name}:{spec}}} is wider than {MAX_PATTERN_WIDTH} characters"
    return ""


def _cohort_paths(out: str, n: int, seed: int) -> list[str | Path]:
    """The cohort's output files: in a directory, or from a pattern with ``{i}``.

    Neither the names a directory gets nor the files a pattern expands to
    were named by the user literally (:class:`~exo_ctrl._io.DerivedOutput`:
    never written through a link).
    """
    if out and Path(out).is_dir():
        width = max(3, len(str(n - 1)))
        return [DerivedOutput(Path(out) / f"patient_s{seed}_{i:0{width}d}.urdf") for i in range(n)]
    allowed = "an existing directory or a file pattern with {i} (e.g. cohort/p{i:02d}.urdf)"
    if "{i" not in out:
        raise InvalidParameter("--out", out, allowed, "--cohort writes one file per patient")
    spec_problem = _pattern_problem(out)
    if spec_problem:
        raise InvalidParameter("--out", out, allowed, spec_problem)
    try:
        paths = [DerivedOutput(out.format(i=i)) for i in range(n)]
    except (IndexError, KeyError, ValueError) as exc:
        raise InvalidParameter("--out", out, allowed, f"the pattern fails: {exc}") from None
    if len({Path(p) for p in paths}) < n:
        raise InvalidParameter("--out", out, allowed, "two patients would share a file")
    return paths


def _run_cohort(args: argparse.Namespace) -> int:
    """``--cohort N --seed S``: N patients around --height and --mass; every path checked first."""
    if args.cohort is None:
        raise InvalidParameter("--seed", args.seed, "given with --cohort only")
    if args.kind != "patient":
        raise InvalidParameter("--cohort", args.cohort, "given with --kind patient only")
    if args.cohort < 1 or args.cohort > MAX_COHORT:
        raise InvalidParameter("--cohort", args.cohort, f"an integer in [1, {MAX_COHORT}]")
    seed = 0 if args.seed is None else args.seed
    if seed < 0:
        raise InvalidParameter("--seed", seed, "an integer >= 0")
    for name, _ in _OPTIONS:
        if getattr(args, name.replace("-", "_")) is not None:
            raise InvalidParameter(
                f"--{name}", getattr(args, name.replace("-", "_")), "unset with --cohort",
                "the cohort draws the segments",
            )  # fmt: skip
    for option, value, what in (("--height", args.height, "a stature [m]"),
                                ("--mass", args.mass, "a body mass [kg]")):  # fmt: skip
        if value is None:
            raise InvalidParameter(option, None, f"{what} given with --cohort")
    paths = _cohort_paths(args.out, args.cohort, seed)
    for path in paths:
        check_output(path, "--out")
    cohort = draw_cohort(
        args.cohort,
        seed,
        v.finite("height", args.height, "m"),
        v.finite("mass", args.mass, "kg"),
        args.sex,
    )
    print(
        f"cohort of {args.cohort} around de Leva's {args.sex} patient of {args.height:g} m, "
        f"{args.mass:g} kg, seed {seed} (spreads: exo_ctrl/model/cohort.py)"
    )
    print(f"{'file':<40}{'thigh [m]':>10}{'shank [m]':>10}{'thigh [kg]':>11}{'shank [kg]':>11}")
    for params, path in zip(cohort, paths, strict=True):
        write_urdf(params, path)
        load_body(path, name="patient")  # the project's URDF checks, on what was written
        print(
            f"{path!s:<40}{params.thigh_length:>10.4f}{params.shank_length:>10.4f}"
            f"{params.thigh_mass:>11.3f}{params.shank_mass:>11.3f}"
        )
    return 0
