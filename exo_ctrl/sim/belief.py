"""What the device believes: the models the controller, the estimator and the supervisor hold.

The plant simulates the truth: the exoskeleton and patient URDFs of
:class:`~exo_ctrl.sim.config.SimConfig`.  A real device does not hold the
patient's true segment inertias; it holds a model.  :class:`Belief` names
it:

- ``patient="truth"``: the true patient's URDF, loaded again (the ideal
  comparison: a device that knows its patient perfectly; a figure made with
  it must say so);
- ``patient="nominal"``: what a clinic can know: the patient's measured leg
  lengths (those of the true model: the exoskeleton is adjusted to them),
  stature, body mass and sex, with masses, centres of mass and radii of
  gyration from de Leva's tables
  (:func:`~exo_ctrl.model.nominal_patient`);
- a URDF path: a model of the user's, e.g. the identified patient that
  ``exo-ctrl identify RUN.rrd --out PATIENT.urdf`` wrote from a calibration
  run (``--controller-patient PATIENT.urdf``; the name ``"identified"``
  alone is refused with that hint: the device holds the file the user names).

The default is ``"nominal"``: a real device does not know its patient's
segment inertias.  ``"truth"`` stays available for the ideal comparison, and
a figure made with it says so.

The exoskeleton model is its URDF (default: the true one's file, loaded
again), or another file, to study a device whose model is wrong.

The drive model is the installed drive's datasheet (default: the nominal
values of :attr:`~exo_ctrl.sim.config.SimConfig.motor`, a parameter set of
its own, so that a true drive that differs from its datasheet, e.g. a
winding warmer than 25 °C, can be studied by giving the device the nominal
one).  The cuff model is the published cuffs (default: the run's
``SimConfig.cuffs``, by default :class:`~exo_ctrl.plant.cuffs.CuffParams`'
published normal and shear stiffness, cited there): what a manufacturer
builds its model from.  The patient's true cuffs scatter around them
(:mod:`exo_ctrl.plant.cuff_scatter`), so the device's cuff model is honest,
not exact; ``Belief(cuffs=...)`` gives it another (``CuffParams.isotropic()``,
the isotropic 8 N/mm it held before).
The treadmill's datasheet (belt and rollers' equivalent mass, the drive's
force limit; what the supervisor's belt monitor predicts the belt with) is
the installed treadmill's nominal values by default
(:attr:`~exo_ctrl.plant.contact.ContactParams.belt`), a parameter set of its
own, so that a belt heavier or lighter than its datasheet can be studied.
The soles' contact law on the belt (stiffness k and exponent n of
F = k δⁿ; what the loading phase of the plan sinks the stance feet by,
:mod:`~exo_ctrl.plan.loading`) is likewise the installed soles' nominal
values (:class:`~exo_ctrl.plant.contact.ContactParams`) unless given.

Either way the device's models are objects of their own, never the plant's.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

from .. import _validate as v
from ..exceptions import InvalidParameter
from ..model import (
    SEXES,
    BodyModel,
    default_urdf_path,
    load_exo,
    load_patient,
    nominal_patient,
    write_urdf,
)
from ..model.anthropometry import body_mass_from_legs, stature_from_legs
from ..model.cohort import BENCHMARK_KNEE_MISALIGNMENT_M
from ..plant import BeltParams, ContactParams, CuffParams, MotorParams
from ..plant.cuff_scatter import DEFAULT_SPREAD, checked_spread
from ..plant.misalignment import MAX_MISALIGNMENT_M

__all__ = [
    "PAPER_PATIENT",
    "PATIENT_BELIEFS",
    "Belief",
    "device_exo",
    "device_patient",
]

#: The named patient models (anything else is a URDF path).
PATIENT_BELIEFS = ("truth", "nominal")

#: The paper's patient (Table I): 1.75 m, 80 kg, and a man's segment table
#: (Table I's thigh is 14.1 % of the body mass, de Leva's male 14.16 %).
PAPER_PATIENT = {"height_m": 1.75, "mass_kg": 80.0, "sex": "male"}


@dataclass(frozen=True)
class Belief:
    """The device's models (module docstring).

    Attributes:
        patient: ``"truth"``, ``"nominal"`` or a patient URDF path.
        exo: the exoskeleton URDF the device holds (None: the true one's file).
        patient_height_m: the patient's stature for the nominal model [m]
            (None: the paper's 1.75 m, for the default patient only).
        patient_mass_kg: the patient's body mass for the nominal model [kg]
            (None: the paper's 80 kg, for the default patient only).
        patient_sex: ``"female"`` or ``"male"``: which table.
        motor: the drive's datasheet the device holds (None: the nominal
            values of the run's drive, ``SimConfig.motor``).
        cuffs: the cuff model the device holds (None: the published cuffs,
            the run's ``SimConfig.cuffs``: :meth:`cuff_model_of`).
        belt: the treadmill's datasheet the device holds (None: the nominal
            values of the run's belt, ``SimConfig.contact.belt``).
        soles: the soles' contact law the device holds, (k [N/m^n], n [-])
            (None: the nominal values of the run's contact,
            ``SimConfig.contact``).
        cuff_spread_rel: the spread s the device assumes for a patient's true
            cuffs around its cuff model, for the QP's margin [-], in [0,
            :data:`~exo_ctrl.plant.cuff_scatter.MAX_SPREAD`] (None: the
            literature's, :data:`~exo_ctrl.plant.cuff_scatter.DEFAULT_SPREAD`,
            cited there; 0: the device knows its patient's cuffs exactly).
        knee_fit_tolerance_m: how far the patient's knee axis may lie from the
            exoskeleton's after the fit [m], in [0,
            :data:`~exo_ctrl.plant.misalignment.MAX_MISALIGNMENT_M`] (None: the
            benchmark cohort's largest,
            :data:`~exo_ctrl.model.cohort.BENCHMARK_KNEE_MISALIGNMENT_M`, 3 cm, cited
            there); the along-shank force such an offset makes is what the supervisor
            cannot see without 2-axis cuff sensors (:mod:`exo_ctrl.sim.tone_load`).

    Raises:
        InvalidParameter: an unknown sex, a height or mass not > 0, a motor,
            cuffs or belt that are not parameter sets, soles that are not a
            pair (k > 0, n ≥ 1), a cuff spread outside [0, MAX_SPREAD], a knee
            fit tolerance outside [0, MAX_MISALIGNMENT_M].

    """

    patient: str = "nominal"
    exo: str | None = None
    patient_height_m: float | None = None
    patient_mass_kg: float | None = None
    patient_sex: str = "male"
    motor: MotorParams | None = None
    cuffs: CuffParams | None = None
    belt: BeltParams | None = None
    soles: tuple[float, float] | None = None
    cuff_spread_rel: float | None = None
    knee_fit_tolerance_m: float | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.patient, str) or not self.patient:
            raise InvalidParameter(
                "controller_patient", self.patient, "truth, nominal or a URDF path"
            )
        if self.patient == "identified":
            raise InvalidParameter(
                "controller_patient",
                self.patient,
                "truth, nominal or a URDF path",
                "for an identified patient give the file exo-ctrl identify --out wrote",
            )
        v.one_of("patient_sex", self.patient_sex, SEXES)
        if self.patient_height_m is not None:
            v.positive("patient_height", self.patient_height_m, "m")
        if self.patient_mass_kg is not None:
            v.positive("patient_mass", self.patient_mass_kg, "kg")
        if self.motor is not None and not isinstance(self.motor, MotorParams):
            raise InvalidParameter("belief motor", self.motor, "a MotorParams or None")
        if self.cuffs is not None and not isinstance(self.cuffs, CuffParams):
            raise InvalidParameter("belief cuffs", self.cuffs, "a CuffParams or None")
        if self.belt is not None and not isinstance(self.belt, BeltParams):
            raise InvalidParameter("belief belt", self.belt, "a BeltParams or None")
        if self.soles is not None:
            if not isinstance(self.soles, tuple) or len(self.soles) != 2:
                raise InvalidParameter(
                    "belief soles", self.soles, "a pair (k [N/m^n] > 0, n >= 1) or None"
                )
            k = v.positive("belief sole stiffness", self.soles[0], "N/m^n")
            n = v.finite("belief sole exponent", self.soles[1])
            if n < 1.0:
                raise InvalidParameter("belief sole exponent", self.soles[1], ">= 1")
            object.__setattr__(self, "soles", (k, n))
        if self.cuff_spread_rel is not None:
            spread = checked_spread("belief cuff_spread_rel", self.cuff_spread_rel)
            object.__setattr__(self, "cuff_spread_rel", spread)
        if self.knee_fit_tolerance_m is not None:
            tol = v.finite("belief knee_fit_tolerance_m", self.knee_fit_tolerance_m, "m")
            if not 0.0 <= tol <= MAX_MISALIGNMENT_M:
                raise InvalidParameter(
                    "belief knee_fit_tolerance_m", tol, f"in [0, {MAX_MISALIGNMENT_M:g}] m"
                )
            object.__setattr__(self, "knee_fit_tolerance_m", tol)

    def cuff_spread(self) -> float:
        """s, the spread the device assumes for its patient's true cuffs [-]."""
        return DEFAULT_SPREAD if self.cuff_spread_rel is None else self.cuff_spread_rel

    def knee_fit_tolerance(self) -> float:
        """d_max, how far the patient's knee axis may lie from the exoskeleton's [m]."""
        tol = self.knee_fit_tolerance_m
        return BENCHMARK_KNEE_MISALIGNMENT_M if tol is None else tol

    def cuff_model_of(self, published: CuffParams) -> CuffParams:
        """The cuffs the device believes in: ``cuffs``, or the published cuffs.

        Args:
            published: the cuffs the run's true cuffs scatter around
                (``SimConfig.cuffs``; default the published split cuffs,
                :class:`~exo_ctrl.plant.cuffs.CuffParams`): a manufacturer's
                model.  (The QP's bound needs the split model: the isotropic
                one shares a hip's load between thigh and shank otherwise,
                :mod:`exo_ctrl.control.qp.margin`'s e_cuffs.)

        """
        return self.cuffs if self.cuffs is not None else published

    def motor_model(self, installed: MotorParams) -> MotorParams:
        """The drive the device believes in: ``motor``, or the installed drive's datasheet.

        Args:
            installed: the run's drive (``SimConfig.motor``): its nominal values
                are the datasheet's.

        """
        return self.motor if self.motor is not None else installed

    def belt_model(self, installed: BeltParams) -> BeltParams:
        """The treadmill datasheet the device believes in: ``belt``, or the installed one's.

        Args:
            installed: the run's belt (``SimConfig.contact.belt``): its nominal
                values are the datasheet's.

        """
        return self.belt if self.belt is not None else installed

    def sole_model(self, installed: ContactParams) -> tuple[float, float]:
        """The soles' contact law the device believes in: (k [N/m^n], n [-]).

        Args:
            installed: the run's contact (``SimConfig.contact``): its nominal
                values are the datasheet's.

        """
        if self.soles is not None:
            return self.soles
        return installed.stiffness_N_per_m_n, installed.exponent


def device_exo(belief: Belief, exo_path: str | None) -> BodyModel:
    """The exoskeleton model the device holds: ``belief.exo``, else the true one's file, anew.

    Raises:
        ExoCtrlError: a URDF that cannot be loaded.

    """
    return load_exo(belief.exo if belief.exo is not None else exo_path)


def is_default_patient(patient_path: str | os.PathLike[str] | None) -> bool:
    """Whether ``patient_path`` names the committed default patient (None, or its file)."""
    if patient_path is None:
        return True
    default = default_urdf_path("patient")
    try:
        return os.path.samefile(patient_path, default)
    except (OSError, TypeError, ValueError):
        return False


def nominal_stature(
    belief: Belief, patient_path: str | None, true_patient: BodyModel
) -> tuple[float, float, list[str]]:
    """The stature [m] and body mass [kg] the nominal patient is built for, and notes on them.

    Given values are taken; for the default patient (also named by its
    file) the paper's 1.75 m and 80 kg; for a patient URDF, what is not given
    is read from it, and a note says so: the stature whose de Leva thigh and
    shank make the URDF's leg length, the body mass whose de Leva leg share
    is the URDF's mass (a clinic weighs the patient and measures the legs).

    Raises:
        InvalidParameter: example-robot-data's human (a whole body) without
            the stature and mass.

    """
    height, mass = belief.patient_height_m, belief.patient_mass_kg
    if is_default_patient(patient_path):
        height = height if height is not None else PAPER_PATIENT["height_m"]
        mass = mass if mass is not None else PAPER_PATIENT["mass_kg"]
        return height, mass, []
    if patient_path == "human" and (height is None or mass is None):
        missing = "patient_height" if height is None else "patient_mass"
        raise InvalidParameter(
            missing,
            None,
            "given for a nominal model of example-robot-data's human (a whole body)",
            "the device's nominal patient is built from the stature and body mass "
            "(--set belief.patient_height_m=M --set belief.patient_mass_kg=KG); "
            'belief.patient = "truth" gives the device the true patient (the ideal comparison)',
        )
    notes = []
    leg = true_patient.legs["left"]
    if height is None:
        height = stature_from_legs(leg.thigh_length, leg.shank_length, belief.patient_sex)
        notes.append(
            f"the nominal patient's stature, {height:.3f} m, is the one whose de Leva thigh and "
            f"shank make the patient URDF's {leg.thigh_length + leg.shank_length:.3f} m leg "
            "(belief.patient_height_m sets it)"
        )
    if mass is None:
        mass = body_mass_from_legs(true_patient.mass, belief.patient_sex)
        notes.append(
            f"the nominal patient's body mass, {mass:.1f} kg, is the patient URDF's "
            f"{true_patient.mass:.2f} kg of legs over de Leva's leg share "
            "(belief.patient_mass_kg sets it)"
        )
    return height, mass, notes


def device_patient(belief: Belief, patient_path: str | None, true_patient: BodyModel) -> BodyModel:
    """The patient model the device holds, loaded anew (the truth's file, a URDF, or nominal).

    Args:
        belief: what the device believes.
        patient_path: the true patient's URDF, ``"human"`` or None (the default).
        true_patient: the true patient's model, for its measured leg lengths only.

    Raises:
        InvalidParameter: a nominal model of example-robot-data's human
            without its height and mass (:func:`nominal_stature`).
        ExoCtrlError: a URDF that cannot be loaded.

    """
    if belief.patient == "truth":
        return load_patient(patient_path)
    if belief.patient != "nominal":
        return load_patient(belief.patient)
    height, mass, _ = nominal_stature(belief, patient_path, true_patient)
    leg = true_patient.legs["left"]
    params = nominal_patient(leg.thigh_length, leg.shank_length, height, mass, belief.patient_sex)
    with tempfile.TemporaryDirectory(prefix="exo_ctrl_nominal_") as folder:
        path = write_urdf(params, Path(folder) / "nominal_patient.urdf")
        return load_patient(str(path))
