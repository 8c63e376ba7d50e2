"""Tests of exo_ctrl.model.loader: what is read from a URDF, checked against the file's own text."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl.model import CUFF_NAMES, JOINT_NAMES, SIDES, BodyModel, load_body, load_patient


def test_default_exo_masses(exo: BodyModel, exo_path: Path) -> None:
    root = ET.parse(exo_path).getroot()
    link_mass = {
        link.get("name"): float(link.find("inertial/mass").get("value"))
        for link in root.findall("link")
        if link.find("inertial") is not None
    }
    legs_mass = sum(m for name, m in link_mass.items() if name != "pelvis")
    assert legs_mass == pytest.approx(2 * (3.5 + 4.5))
    assert exo.mass == pytest.approx(16.0, abs=1e-12)
    for side in SIDES:
        hip, knee = exo.joint_ids[2 * SIDES.index(side)], exo.joint_ids[2 * SIDES.index(side) + 1]
        assert exo.model.inertias[hip].mass == pytest.approx(3.5)
        assert exo.model.inertias[knee].mass == pytest.approx(4.5)
    # gravity along -z
    np.testing.assert_allclose(exo.model.gravity.linear, [0, 0, -9.81])


def test_default_exo_limits_come_from_the_urdf(
    exo: BodyModel, exo_path: Path, joint_elements
) -> None:
    joints = joint_elements(exo_path)
    lower, upper = exo.position_limits
    for j, name in enumerate(JOINT_NAMES):
        limit = joints[name].find("limit")
        dyn = joints[name].find("dynamics")
        assert lower[j] == pytest.approx(float(limit.get("lower")))
        assert upper[j] == pytest.approx(float(limit.get("upper")))
        assert exo.effort_limit[j] == pytest.approx(float(limit.get("effort")))
        assert exo.velocity_limit[j] == pytest.approx(float(limit.get("velocity")))
        assert exo.damping[j] == pytest.approx(float(dyn.get("damping")))
        assert exo.friction[j] == pytest.approx(float(dyn.get("friction")))
    np.testing.assert_allclose(lower, [-0.52, -0.05, -0.52, -0.05])
    np.testing.assert_allclose(upper, [2.09] * 4)


def test_cuff_frames_of_the_default_exo(exo: BodyModel, world_points) -> None:
    _, pts = world_points(exo, np.zeros(4))
    for side in SIDES:
        hip, knee = pts[f"{side}_hip"], pts[f"{side}_knee"]
        assert np.linalg.norm(pts[f"{side}_thigh_cuff"] - hip) == pytest.approx(0.39)
        assert np.linalg.norm(pts[f"{side}_shank_cuff"] - knee) == pytest.approx(0.45)
    assert len(exo.cuff_frame_ids) == 4
    assert [exo.model.frames[f].name for f in exo.cuff_frame_ids] == [
        c + "_cuff" for c in CUFF_NAMES
    ]


def test_human_cuff_frames_at_the_stated_fractions(human: BodyModel, world_points) -> None:
    rng = np.random.default_rng(1)
    for q in [np.zeros(4), *rng.uniform(0.0, 1.2, (3, 4))]:
        _, pts = world_points(human, q)
        for side in SIDES:
            hip, knee, foot = pts[f"{side}_hip"], pts[f"{side}_knee"], pts[f"{side}_foot"]
            np.testing.assert_allclose(
                pts[f"{side}_thigh_cuff"], hip + 0.39 / 0.52 * (knee - hip), atol=1e-9
            )
            np.testing.assert_allclose(
                pts[f"{side}_shank_cuff"], knee + 0.45 / 0.52 * (foot - knee), atol=1e-9
            )


def test_load_patient_presets(human: BodyModel) -> None:
    again = load_patient("human")
    assert again.legs == human.legs
    assert again.name == "patient"
    default = load_patient(None)
    assert default.legs["left"].thigh_length == pytest.approx(0.52)
    assert default.mass == pytest.approx(2 * (11.3 + 4.65))


def test_missing_file(tmp_path: Path, check_invalid) -> None:
    path = tmp_path / "nowhere.urdf"
    check_invalid(path, f"invalid model: {path}: file not found")


def test_joint_map_naming_a_missing_joint(exo_path: Path, check_invalid) -> None:
    joint_map = {j: j for j in JOINT_NAMES} | {"right_knee": "right_elbow"}
    exc = check_invalid(
        exo_path,
        f"invalid model: 'right_elbow' in {exo_path}: joint not found (needed as right_knee)",
        joint_map=joint_map,
    )
    assert exc.element == "right_elbow"


def test_urdf_with_a_renamed_joint(tmp_path: Path, exo_text: str, broken, check_invalid) -> None:
    text = exo_text.replace('<joint name="left_knee"', '<joint name="left_knee_pitch"')
    assert text != exo_text
    path = broken(tmp_path, text)
    check_invalid(
        path, f"invalid model: 'left_knee' in {path}: joint not found (needed as left_knee)"
    )


def test_missing_cuff_frame(tmp_path: Path, exo_text: str, broken, check_invalid) -> None:
    text = exo_text.replace('"right_shank_cuff"', '"right_ankle_strap"')
    assert text.count("right_ankle_strap") == 2  # the link and its joint's child
    path = broken(tmp_path, text)
    check_invalid(
        path,
        f"invalid model: 'right_shank_cuff' in {path}: frame not found "
        "(cuffs and feet are named frames)",
    )


def test_a_valid_edit_still_loads(tmp_path: Path, exo_text: str, broken) -> None:
    """Control for the edits above: a harmless change (heavier pelvis) loads."""
    text = exo_text.replace('<mass value="1.0"/>', '<mass value="2.0"/>', 1)
    assert text != exo_text
    body = load_body(broken(tmp_path, text))
    assert body.mass == pytest.approx(16.0)
