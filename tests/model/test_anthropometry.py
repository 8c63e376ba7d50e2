"""Patients from height and mass: de Leva 1996's tables, checked through the URDF and Pinocchio.

References typed here: de Leva's Table 4 fractions for the thigh, the leg
and the foot (male: 14.16 %, 4.33 %, 1.37 % of body mass), the paper's
Table I patient (80 kg: thigh 11.3 kg, shank and foot 4.65 kg), and the
inertia of the shank link about the knee computed segment by segment from
the table (leg and foot each about the knee by the parallel-axis theorem),
against what Pinocchio reads from the generated URDF.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl import cli
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import load_body, patient_from_anthropometry, write_urdf


def test_the_papers_patient_is_close_to_table_one() -> None:
    b = patient_from_anthropometry(1.75, 80.0, "male")
    assert b.thigh_mass == pytest.approx(0.1416 * 80.0, rel=1e-12)
    assert b.thigh_mass == pytest.approx(11.3, rel=0.01)  # Table I: 11.3 kg
    assert b.shank_mass == pytest.approx((0.0433 + 0.0137) * 80.0, rel=1e-12)
    assert b.shank_mass == pytest.approx(4.65, rel=0.03)  # Table I: 4.65 kg (4.56 here)
    # Lengths: the reference subjects' scaled by stature, knee to sole = leg + ankle height.
    assert b.thigh_length == pytest.approx(0.4222 * 1.75 / 1.741, rel=1e-12)
    assert b.shank_length == pytest.approx(0.4340 * 1.75 / 1.741 + 0.039 * 1.75, rel=1e-12)


@pytest.mark.parametrize("sex", ["female", "male"])
def test_the_urdf_carries_the_tables_inertia_about_the_knee(tmp_path: Path, sex: str) -> None:
    """The shank link's mass, first and second moments about the knee, segment by segment."""
    height, mass = 1.68, 64.0
    table = {
        "male": ((0.0433, 0.4459, 0.255, 0.4340, 1.741), (0.0137, 0.257, 0.2581)),
        "female": ((0.0481, 0.4416, 0.271, 0.4323, 1.735), (0.0129, 0.299, 0.2283)),
    }[sex]
    (m_leg, c_leg, r_leg, l_leg, stature), (m_foot, r_foot, l_foot) = table
    scale = height / stature
    l_leg, l_foot = l_leg * scale, l_foot * scale
    m_leg, m_foot = m_leg * mass, m_foot * mass
    # About the knee: each segment's own sagittal moment plus m d².
    moment = m_leg * (c_leg * l_leg) + m_foot * l_leg
    inertia = m_leg * ((r_leg * l_leg) ** 2 + (c_leg * l_leg) ** 2) + m_foot * (
        (r_foot * l_foot) ** 2 + l_leg**2
    )
    body = load_body(
        write_urdf(patient_from_anthropometry(height, mass, sex), tmp_path / "p.urdf"),
        name="patient",
    )
    model = body.model
    joint = model.getJointId("left_knee")
    link = model.inertias[joint]
    assert link.mass == pytest.approx(m_leg + m_foot, rel=1e-12)
    com = np.asarray(link.lever)
    assert np.linalg.norm(com) == pytest.approx(moment / (m_leg + m_foot), rel=1e-9)
    # Pinocchio's inertia about the joint: I_com + m |c|², sagittal axis (y).
    about_joint = link.inertia[1, 1] + link.mass * (com[0] ** 2 + com[2] ** 2)
    assert about_joint == pytest.approx(inertia, rel=1e-9)
    assert isinstance(link, pin.Inertia)


RANGE = "(adults: the range of the regressions)"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ((2.5, 80.0, "male"), f"height must be in [1.4, 2.1] m; got 2.5 {RANGE}"),
        ((1.7, 20.0, "male"), f"mass must be in [35, 150] kg; got 20.0 {RANGE}"),
        ((1.7, 70.0, "other"), "sex must be one of female, male; got 'other'"),
        ((float("nan"), 70.0, "male"), "height must be a finite number [m]; got nan"),
    ],
)  # fmt: skip
def test_out_of_range_bodies_are_refused(args: tuple, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        patient_from_anthropometry(*args)
    assert str(info.value) == message


def test_the_cli_writes_a_patient_and_names_the_fitted_exoskeleton(tmp_path: Path, capsys) -> None:
    out = tmp_path / "p.urdf"
    argv = ["urdf", "--kind", "patient", "--height", "1.62", "--mass", "55", "--sex", "female"]
    assert cli.main([*argv, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    b = patient_from_anthropometry(1.62, 55.0, "female")
    body = load_body(out, name="patient")
    assert body.legs["left"].thigh_length == pytest.approx(b.thigh_length, rel=1e-9)
    assert f"--thigh-length {b.thigh_length:.4g} --shank-length {b.shank_length:.4g}" in printed
    # The moving mass: both legs with their feet, (14.78 + 4.81 + 1.29) % of 55 kg each.
    assert body.mass == pytest.approx(2 * 0.2088 * 55.0, rel=1e-9)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--kind", "exo", "--height", "1.7", "--mass", "70"],
         "--height must be unset for --kind exo; got 1.7 (height and mass describe a patient)"),
        (["--kind", "patient", "--height", "1.7"],
         "--mass must be a body mass [kg] given with --height; got None"),
        (["--kind", "patient", "--mass", "70"],
         "--height must be a stature [m] given with --mass; got None"),
        (["--kind", "patient", "--height", "1.2", "--mass", "70"],
         "height must be in [1.4, 2.1] m; got 1.2 (adults: the range of the regressions)"),
    ],
)  # fmt: skip
def test_cli_bad_bodies_exit_2_with_one_line(
    tmp_path: Path, capsys, argv: list, message: str
) -> None:
    out = tmp_path / "p.urdf"
    assert cli.main(["urdf", *argv, "--out", str(out)]) == 2
    assert capsys.readouterr().err == f"exo-ctrl urdf: error: {message}\n"
    assert not out.exists()
