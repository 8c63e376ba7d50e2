"""Tests of exo_ctrl.model.geometry: leg lengths, joint signs and zeros read from a model."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl.model import JOINT_NAMES, SIDES, BodyModel, human_urdf_path


def test_default_exo_joints_lengths_and_signs(
    exo: BodyModel, exo_path: Path, joint_elements, xyz
) -> None:
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


def test_default_exo_hip_positions(
    exo: BodyModel, exo_path: Path, joint_elements, xyz, world_points
) -> None:
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


def test_human_patient_loads_with_z_up(human: BodyModel, joint_elements, xyz, world_points) -> None:
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


def test_joint_axis_not_lateral(tmp_path: Path, exo_text: str, broken, check_invalid) -> None:
    text = exo_text.replace('<axis xyz="0.0 1.0 0.0"/>', '<axis xyz="1 0 0"/>', 1)
    assert text != exo_text
    path = broken(tmp_path, text)
    check_invalid(
        path,
        f"invalid model: 'left_knee' in {path}: axis in the world is [1.0, 0.0, 0.0]; a sagittal "
        "joint must turn about the lateral axis ±y (x forward, z up)",
    )
