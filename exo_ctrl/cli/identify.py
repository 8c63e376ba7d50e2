"""``exo-ctrl identify``: the patient's segment inertias from a calibration run's sensor readings.

The run is a recording (``exo-ctrl simulate --exercise calibration --out
RUN.rrd``) or a CSV log (:func:`~exo_ctrl.estimation.read_csv_log`); the
method is :mod:`exo_ctrl.estimation.identification`.  The identified patient
is written to ``--out`` (required: nothing is written that was not named)
and is then what the device holds with ``exo-ctrl simulate
--controller-patient PATIENT.urdf``.
"""

from __future__ import annotations

import argparse
import warnings
from pathlib import Path

from ..estimation.identification import (
    DEFAULT_CUTOFF_HZ,
    body_model,
    calibration_samples,
    identify_patient,
)
from ..model import SEXES, nominal_patient, write_urdf
from ..record.estimate import read_sensor_log
from ..sim.belief import PAPER_PATIENT
from .common import add_accept_implausible, check_outputs, write_json

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    """Add the ``identify`` subcommand."""
    p = sub.add_parser(
        "identify",
        help="identify the patient's segment inertias from a calibration run "
        "(simulate --exercise calibration) and write them as a patient URDF",
    )
    p.add_argument(
        "file", metavar="RUN.rrd|LOG.csv", help="an exo_ctrl recording (.rrd) or a CSV log (.csv)"
    )
    p.add_argument(
        "--out", required=True, metavar="PATIENT.urdf", help="the identified patient's URDF"
    )
    p.add_argument(
        "--exo",
        default=None,
        metavar="URDF",
        help="exoskeleton URDF (default: the recording's, or urdf/exoskeleton.urdf)",
    )
    p.add_argument(
        "--height",
        type=float,
        default=None,
        metavar="M",
        help=f"the patient's stature for the prior [m] (default: the recording's, else "
        f"{PAPER_PATIENT['height_m']:g})",
    )
    p.add_argument(
        "--mass",
        type=float,
        default=None,
        metavar="KG",
        help=f"the patient's body mass for the prior [kg] (default: the recording's, else "
        f"{PAPER_PATIENT['mass_kg']:g})",
    )
    p.add_argument(
        "--sex", choices=SEXES, default=None, help="de Leva's table for the prior (default male)"
    )
    p.add_argument(
        "--cutoff",
        type=float,
        default=DEFAULT_CUTOFF_HZ,
        metavar="HZ",
        help=f"low-pass cut-off of the fit [Hz] (default {DEFAULT_CUTOFF_HZ:g})",
    )
    add_accept_implausible(p)
    p.add_argument(
        "--summary",
        default=None,
        metavar="PATH.json",
        help="write the figures to this JSON file (default: none)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Identify, write the URDF (and the summary), print the table.

    The output paths are checked before the input is read.  The patient's
    link lengths are the exoskeleton's (it is adjusted to them); the prior
    is de Leva's patient of that stature, mass and sex
    (:func:`~exo_ctrl.model.nominal_patient`).
    """
    check_outputs(args, {"the input file": args.file}, out="--out", summary="--summary")
    path = Path(args.file)
    height, mass, sex = args.height, args.mass, args.sex
    log = read_sensor_log(path, args.exo, accept=args.accept_implausible)
    for note in log.notes:
        warnings.warn(note, RuntimeWarning, stacklevel=2)
    exo, t, q, tau = log.exo, log.t, log.q, log.tau
    if log.result is not None:
        belief = log.result.config.belief
        height = height if height is not None else belief.patient_height_m
        mass = mass if mass is not None else belief.patient_mass_kg
        sex = sex or belief.patient_sex
    height = PAPER_PATIENT["height_m"] if height is None else height
    mass = PAPER_PATIENT["mass_kg"] if mass is None else mass
    leg = exo.legs["left"]
    prior = nominal_patient(leg.thigh_length, leg.shank_length, height, mass, sex or "male")
    samples = calibration_samples(t, q, tau, args.cutoff, source=str(path))
    found = identify_patient(samples, exo, body_model(prior), prior)
    write_urdf(found.patient, args.out)
    if args.summary:
        write_json(args.summary, found.summary())
    print(
        f"identified from {path} (prior: de Leva {sex or 'male'}, {height:g} m, {mass:g} kg; "
        f"cut-off {args.cutoff:g} Hz)"
    )
    print(found.table())
    print(f"patient URDF: {args.out} (use it with simulate --controller-patient {args.out})")
    return 0
