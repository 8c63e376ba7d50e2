"""A patient drawn for an episode: the benchmark cohort's spreads around the scenario's run.

With ``cohort=True`` each :meth:`~exo_ctrl.envs.TreadmillEnv.reset` draws one
patient of :func:`~exo_ctrl.model.benchmark_cohort` (stature, body mass, sex,
segment parameters around de Leva's, knee misalignment) from the
environment's random generator, and runs the scenario on it as
``tools/robustness.py`` does: the exoskeleton adjusted to the patient's leg
lengths (:func:`~exo_ctrl.model.fitted_exo`), the gait's hip height, step
length and lift scaled by the patient's leg length over the scenario
device's, and the device told the stature, mass and sex (its nominal
patient); the true patient and misalignment are the plant's only.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ..model import benchmark_cohort, fitted_exo, load_exo, write_urdf
from ..plant import Misalignment
from ..sim import SimConfig

__all__ = ["cohort_config"]


def cohort_config(config: SimConfig, rng: np.random.Generator, folder: Path, tag: str) -> SimConfig:
    """``config`` run on a patient drawn with ``rng`` (module docstring).

    Args:
        config: the scenario's run.
        rng: the environment's generator (one integer drawn: the cohort's seed).
        folder: where the drawn patient's and fitted exoskeleton's URDFs are written.
        tag: the files' suffix (``exo_<tag>.urdf``, ``patient_<tag>.urdf``).

    """
    seed = int(rng.integers(0, 2**31 - 1))
    patient = benchmark_cohort(1, seed)[0]
    exo_path = write_urdf(fitted_exo(patient.params), folder / f"exo_{tag}.urdf")
    patient_path = write_urdf(patient.params, folder / f"patient_{tag}.urdf")
    leg = load_exo(config.exo).legs["left"]
    scale = (patient.params.thigh_length + patient.params.shank_length) / (
        leg.thigh_length + leg.shank_length
    )
    g = config.gait
    gait = dataclasses.replace(
        g,
        hip_height=g.hip_height * scale,
        step_length=g.step_length * scale,
        lift_height=g.lift_height * scale,
    )
    belief = dataclasses.replace(
        config.belief,
        patient="nominal",
        patient_height_m=patient.height_m,
        patient_mass_kg=patient.mass_kg,
        patient_sex=patient.sex,
    )
    return dataclasses.replace(
        config,
        gait=gait,
        exo=str(Path(exo_path)),
        patient=str(Path(patient_path)),
        misalignment=Misalignment(knee_xz=patient.knee_misalignment_xz),
        belief=belief,
    )
