"""An active patient walking the device's own gait does not fight the device.

The active patient (exo_ctrl/plant/patient_active.py) tracks the same gait
as the device's plan, so it carries its own legs: the cuffs then carry less
than they do for a passive patient, whose legs the device carries.  Checked
on two patients of de Leva's proportions far from the default one (a light
1.58 m woman and a heavy 1.80 m man), each with the exoskeleton fitted to
their legs and the gait's hip height and lift scaled to their leg length,
under computed torque with the pelvis fixed.  With the damping delayed with
the reflex, these two shook their cuffs to 1.1 kN and 0.3 kN.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from exo_ctrl.model import fitted_exo, write_urdf
from exo_ctrl.model.anthropometry import patient_from_anthropometry
from exo_ctrl.plan import GaitParams
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.belief import Belief

#: The default gait's leg (thigh + shank) [m]: 0.9 m hip height for 1.04 m.
REFERENCE_LEG_M = 1.04


def _config(tmp_path, height_m: float, mass_kg: float, sex: str, period_s: float) -> SimConfig:
    patient = patient_from_anthropometry(height_m, mass_kg, sex)
    k = (patient.thigh_length + patient.shank_length) / REFERENCE_LEG_M
    base = GaitParams()
    gait = GaitParams(
        period=period_s,
        step_length=0.3,
        hip_height=base.hip_height * k,
        lift_height=base.lift_height * k,
    )
    return SimConfig(
        gait=gait,
        exo=str(write_urdf(fitted_exo(patient), tmp_path / "exo.urdf")),
        patient=str(write_urdf(patient, tmp_path / "patient.urdf")),
        controller="ct",
        safety=False,
        duration_s=3.0 * period_s,
        belief=Belief(patient_height_m=height_m, patient_mass_kg=mass_kg, patient_sex=sex),
    )


@pytest.mark.parametrize(
    ("height_m", "mass_kg", "sex", "period_s"),
    [(1.58, 54.0, "female", 0.97), (1.80, 90.0, "male", 1.39)],
)
def test_active_patient_loads_the_cuffs_less_than_a_passive_one(
    tmp_path, height_m, mass_kg, sex, period_s
) -> None:
    config = _config(tmp_path, height_m, mass_kg, sex, period_s)
    peaks = {}
    for kind in ("none", "active"):
        result = simulate(dataclasses.replace(config, patient_torque=kind))
        assert result.status == "completed"
        peaks[kind] = np.array(list(result.summary()["peak_cuff_force_N"].values()))
    assert np.all(peaks["active"] <= peaks["none"]), peaks
