"""Tests of exo_ctrl.model.body: what is read from a URDF, checked against the file's own text."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.exceptions import ExoCtrlError, InvalidModel
from exo_ctrl.model.body import (
    CUFF_NAMES,
    JOINT_NAMES,
    SIDES,
    BodyModel,
    human_urdf_path,
    load_body,
    load_patient,
)


def joint_elements(path: Path) -> dict[str, ET.Element]:
    return {j.get("name"): j for j in ET.parse(path).getroot().findall("joint")}


def xyz(el: ET.Element | None) -> np.ndarray:
    return np.array([float(v) for v in el.get("xyz").split()])


def world_points(body: BodyModel, q: np.ndarray) -> tuple[pin.Data, dict[str, np.ndarray]]:
    """World positions of the driven joints and of the cuff and foot frames."""
    data = body.model.createData()
    pin.framesForwardKinematics(body.model, data, body.to_model_q(q))
    pts = {
        n: data.oMi[j].translation.copy() for n, j in zip(JOINT_NAMES, body.joint_ids, strict=True)
    }
    for name in [c + "_cuff" for c in CUFF_NAMES] + ["left_foot", "right_foot"]:
        pts[name] = data.oMf[body.model.getFrameId(name)].translation.copy()
    return data, pts


# --------------------------------------------------------------------------- default exo


def test_default_exo_joints_lengths_and_signs(exo: BodyModel, exo_path: Path) -> None:
    assert tuple(exo.model.names[j] for j in exo.joint_ids) == JOINT_NAMES
    assert exo.model.nq == 4
    joints = joint_elements(exo_path)
    for side in SIDES:
        leg = exo.legs[side]
        knee_origin = xyz(joints[f"{side}_knee"].find("origin"))
        foot_origin = xyz(joints[f"{side}_foot_joint"].find("origin"))
        assert leg.thigh_length == pytest.approx(np.linalg.norm(knee_origin), abs=1e-12)
        assert leg.shank_length == pytest.approx(np.linalg.norm(foot_origin), abs=1e-12)
        assert leg.thigh_length == pytest.approx(0.52)
        assert leg.shank_length == pytest.approx(0.52)
        assert leg.reach == pytest.approx((0.0, 1.04))
        # the legs hang straight down at q = 0
        assert leg.phi1_zero == pytest.approx(-math.pi / 2)
        assert leg.phi2_zero == pytest.approx(-math.pi / 2)
        # hip axis (0,-1,0): a right-hand turn about -y carries +x towards +z, so φ1 grows;
        # knee axis (0,1,0) turns the shank the other way relative to the thigh
        assert xyz(joints[f"{side}_hip"].find("axis")) == pytest.approx([0, -1, 0])
        assert xyz(joints[f"{side}_knee"].find("axis")) == pytest.approx([0, 1, 0])
        assert leg.sign_hip == 1.0
        assert leg.sign_knee == -1.0


def test_default_exo_hip_positions(exo: BodyModel, exo_path: Path) -> None:
    joints = joint_elements(exo_path)
    _, pts = world_points(exo, np.zeros(4))
    for side in SIDES:
        origin = xyz(joints[f"{side}_hip"].find("origin"))  # the pelvis is the fixed root
        np.testing.assert_allclose(pts[f"{side}_hip"], origin, atol=1e-12)
        assert exo.legs[side].hip_xz == pytest.approx((origin[0], origin[2]), abs=1e-12)
    assert pts["left_hip"][1] > 0 > pts["right_hip"][1]  # y left
    assert pts["left_hip"][1] - pts["right_hip"][1] == pytest.approx(0.20)
    # the foot hangs l1 + l2 below the hip at q = 0 (z up)
    for side in SIDES:
        assert pts[f"{side}_foot"][2] == pytest.approx(pts[f"{side}_hip"][2] - 1.04)


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


def test_default_exo_limits_come_from_the_urdf(exo: BodyModel, exo_path: Path) -> None:
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


def test_cuff_frames_of_the_default_exo(exo: BodyModel) -> None:
    _, pts = world_points(exo, np.zeros(4))
    for side in SIDES:
        hip, knee = pts[f"{side}_hip"], pts[f"{side}_knee"]
        assert np.linalg.norm(pts[f"{side}_thigh_cuff"] - hip) == pytest.approx(0.39)
        assert np.linalg.norm(pts[f"{side}_shank_cuff"] - knee) == pytest.approx(0.45)
    assert len(exo.cuff_frame_ids) == 4
    assert [exo.model.frames[f].name for f in exo.cuff_frame_ids] == [
        c + "_cuff" for c in CUFF_NAMES
    ]


# --------------------------------------------------------------------------- human patient


def test_human_patient_loads_with_z_up(human: BodyModel) -> None:
    assert tuple(human.model.names[j] for j in human.joint_ids) == tuple(
        j + "_Z" for j in JOINT_NAMES
    )
    assert human.model.nq == 4
    joints = joint_elements(human_urdf_path())
    for side in SIDES:
        thigh = np.linalg.norm(xyz(joints[f"{side}_knee_Z"].find("origin")))
        shank = np.linalg.norm(xyz(joints[f"{side}_ankle_Z"].find("origin")))
        leg = human.legs[side]
        assert leg.thigh_length == pytest.approx(thigh, abs=1e-9)
        assert leg.shank_length == pytest.approx(shank, abs=1e-9)
        assert leg.thigh_length == pytest.approx(0.44, abs=0.01)
        assert leg.shank_length == pytest.approx(0.44, abs=0.01)
    _, pts = world_points(human, np.zeros(4))
    for side in SIDES:
        hip, knee, foot = pts[f"{side}_hip"], pts[f"{side}_knee"], pts[f"{side}_foot"]
        assert foot[2] < knee[2] < hip[2]  # z up: the leg hangs below the hip
        assert foot[0] == pytest.approx(hip[0], abs=1e-9)
    assert pts["left_foot"][1] > 0 > pts["right_foot"][1]  # y left
    np.testing.assert_allclose(human.model.gravity.linear, [0, 0, -9.81])


def test_human_cuff_frames_at_the_stated_fractions(human: BodyModel) -> None:
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


# --------------------------------------------------------------------------- bad models


@pytest.fixture
def exo_text(exo_path: Path) -> str:
    return exo_path.read_text(encoding="utf-8")


def broken(tmp_path: Path, text: str, name: str = "bad.urdf") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def check_invalid(path: Path, message: str, **kwargs) -> InvalidModel:
    with pytest.raises(InvalidModel) as info:
        load_body(path, **kwargs)
    assert isinstance(info.value, ValueError)
    assert isinstance(info.value, ExoCtrlError)
    assert str(info.value) == message
    return info.value


def test_malformed_xml(tmp_path: Path) -> None:
    # expat reports the mismatched </robot> on line 3 at the (0-based) column of its name
    path = broken(tmp_path, '<robot name="x">\n<link name="a">\n</robot>\n')
    exc = check_invalid(path, f"invalid model: {path}: malformed XML at line 3, column 2")
    assert exc.element == ""


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nowhere.urdf"
    check_invalid(path, f"invalid model: {path}: file not found")


def test_joint_map_naming_a_missing_joint(exo_path: Path) -> None:
    joint_map = {j: j for j in JOINT_NAMES} | {"right_knee": "right_elbow"}
    exc = check_invalid(
        exo_path,
        f"invalid model: 'right_elbow' in {exo_path}: joint not found (needed as right_knee)",
        joint_map=joint_map,
    )
    assert exc.element == "right_elbow"


def test_urdf_with_a_renamed_joint(tmp_path: Path, exo_text: str) -> None:
    text = exo_text.replace('<joint name="left_knee"', '<joint name="left_knee_pitch"')
    assert text != exo_text
    path = broken(tmp_path, text)
    check_invalid(
        path, f"invalid model: 'left_knee' in {path}: joint not found (needed as left_knee)"
    )


def test_negative_mass(tmp_path: Path, exo_text: str) -> None:
    text = exo_text.replace('<mass value="4.5"/>', '<mass value="-4.5"/>', 1)
    assert text != exo_text
    path = broken(tmp_path, text)
    check_invalid(
        path,
        f"invalid model: 'left_shank' in {path}: mass must be a finite number > 0 kg; got -4.5",
    )


def test_inertia_violating_the_triangle_inequality(tmp_path: Path, exo_text: str) -> None:
    old = (
        'ixx="0.07965416666666668" ixy="0.0" ixz="0.0" iyy="0.07965416666666668" iyz="0.0" '
        'izz="0.001575"'
    )
    assert old in exo_text
    text = exo_text.replace(old, 'ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="5"', 1)
    path = broken(tmp_path, text)
    check_invalid(
        path,
        f"invalid model: 'left_thigh' in {path}: inertia is not physically valid: the principal "
        "moments 1, 1, 5 kg·m² must be > 0 and each smaller than the sum of the other two",
    )


def test_two_joints_onto_one_child_link(tmp_path: Path, exo_text: str) -> None:
    extra = (
        '  <joint name="brace" type="fixed">\n    <parent link="pelvis"/>\n'
        '    <child link="right_shank"/>\n  </joint>\n</robot>'
    )
    path = broken(tmp_path, exo_text.replace("</robot>", extra))
    check_invalid(
        path,
        f"invalid model: 'right_shank' in {path}: is the child of two joints "
        "('right_knee' and 'brace')",
    )


def test_joint_axis_not_lateral(tmp_path: Path, exo_text: str) -> None:
    text = exo_text.replace('<axis xyz="0.0 1.0 0.0"/>', '<axis xyz="1 0 0"/>', 1)
    assert text != exo_text
    path = broken(tmp_path, text)
    check_invalid(
        path,
        f"invalid model: 'left_knee' in {path}: axis in the world is [1.0, 0.0, 0.0]; a sagittal "
        "joint must turn about the lateral axis ±y (x forward, z up)",
    )


def test_missing_cuff_frame(tmp_path: Path, exo_text: str) -> None:
    text = exo_text.replace('"right_shank_cuff"', '"right_ankle_strap"')
    assert text.count("right_ankle_strap") == 2  # the link and its joint's child
    path = broken(tmp_path, text)
    check_invalid(
        path,
        f"invalid model: 'right_shank_cuff' in {path}: frame not found "
        "(cuffs and feet are named frames)",
    )


def test_a_valid_edit_still_loads(tmp_path: Path, exo_text: str) -> None:
    """Control for the edits above: a harmless change (heavier pelvis) loads."""
    text = exo_text.replace('<mass value="1.0"/>', '<mass value="2.0"/>', 1)
    assert text != exo_text
    body = load_body(broken(tmp_path, text))
    assert body.mass == pytest.approx(16.0)
