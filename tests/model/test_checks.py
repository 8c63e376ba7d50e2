"""Tests of exo_ctrl.model.checks: malformed and non-physical URDFs named exactly."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.exceptions import InvalidModel
from exo_ctrl.model import default_urdf_path, load_exo, load_patient
from exo_ctrl.model.checks import _inertia_fault
from exo_ctrl.sim import SimConfig, build


def test_malformed_xml(tmp_path: Path, broken, check_invalid) -> None:
    # expat reports the mismatched </robot> on line 3 at the (0-based) column of its name
    path = broken(tmp_path, '<robot name="x">\n<link name="a">\n</robot>\n')
    exc = check_invalid(path, f"invalid model: {path}: malformed XML at line 3, column 2")
    assert exc.element == ""


def test_negative_mass(tmp_path: Path, exo_text: str, broken, check_invalid) -> None:
    text = exo_text.replace('<mass value="4.5"/>', '<mass value="-4.5"/>', 1)
    assert text != exo_text
    path = broken(tmp_path, text)
    check_invalid(
        path,
        f"invalid model: 'left_shank' in {path}: mass must be a finite number > 0 kg; got -4.5",
    )


def test_inertia_violating_the_triangle_inequality(
    tmp_path: Path, exo_text: str, broken, check_invalid
) -> None:
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


def test_two_joints_onto_one_child_link(
    tmp_path: Path, exo_text: str, broken, check_invalid
) -> None:
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


# ------------------------------------------------------- non-physical inertias (issue 19)

SHANK_INERTIA = 'ixx="0.1024125" ixy="0.0" ixz="0.0" iyy="0.1024125" iyz="0.0" izz="0.002025"'


def _with_shank_inertia(exo_text: str, attributes: str) -> str:
    """The exoskeleton with the left shank's ``<inertia>`` attributes replaced."""
    assert exo_text.count(SHANK_INERTIA) == 2  # both shanks; the left one comes first
    return exo_text.replace(SHANK_INERTIA, attributes, 1)


@pytest.mark.parametrize(
    ("attributes", "reason"),
    [
        (
            'ixx="-1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.002"',
            "ixx = -1 kg·m² must be > 0",
        ),
        (
            'ixx="0.1" ixy="0" ixz="0" iyy="-0.5" iyz="0" izz="0.002"',
            "iyy = -0.5 kg·m² must be > 0",
        ),
        (
            'ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0"',
            "izz = 0 kg·m² must be > 0",
        ),
        (  # positive diagonal, eigenvalues -1, 1, 3: not positive definite
            'ixx="1" ixy="2" ixz="0" iyy="1" iyz="0" izz="1"',
            "the principal moments -1, 1, 3 kg·m² must be > 0 and each smaller than the sum "
            "of the other two",
        ),
        (  # positive definite but 1 + 1 < 2.5: no rigid body has it
            'ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="2.5"',
            "the principal moments 1, 1, 2.5 kg·m² must be > 0 and each smaller than the sum "
            "of the other two",
        ),
    ],
    ids=["negative-ixx", "negative-iyy", "zero-izz", "not-positive-definite", "triangle"],
)
def test_non_physical_inertia_names_the_link_and_the_reason(
    tmp_path: Path, exo_text: str, broken, check_invalid, attributes: str, reason: str
) -> None:
    path = broken(tmp_path, _with_shank_inertia(exo_text, attributes))
    exc = check_invalid(
        path, f"invalid model: 'left_shank' in {path}: inertia is not physically valid: {reason}"
    )
    assert exc.element == "left_shank"


@pytest.mark.parametrize("mass", ["0", "-1e-9", "nan", "inf"])
def test_non_positive_or_non_finite_mass(
    tmp_path: Path, exo_text: str, broken, check_invalid, mass: str
) -> None:
    text = exo_text.replace('<mass value="4.5"/>', f'<mass value="{mass}"/>', 1)
    path = broken(tmp_path, text)
    check_invalid(
        path,
        f"invalid model: 'left_shank' in {path}: mass must be a finite number > 0 kg; "
        f"got {float(mass):g}",
    )


def test_inertia_test_agrees_with_the_pseudo_inertia_of_pinocchio() -> None:
    """Independent derivation: Pinocchio's pseudo-inertia PD ⇔ the principal-moment test."""
    rng = np.random.default_rng(19)
    verdicts = []
    for _ in range(400):
        a = rng.normal(size=(3, 3))
        inertia = 0.5 * (a + a.T) + rng.uniform(0.0, 3.0) * np.eye(3)
        if np.any(np.diag(inertia) <= 0.0):
            continue  # Pinocchio's constructor refuses these outright
        mine = _inertia_fault(inertia) == ""
        pseudo = pin.Inertia(2.0, rng.normal(size=3), inertia).toPseudoInertia().toMatrix()
        theirs = bool(np.linalg.eigvalsh(0.5 * (pseudo + pseudo.T))[0] > 1e-12)
        assert mine == theirs, inertia
        verdicts.append(mine)
    assert 20 < sum(verdicts) < len(verdicts) - 20  # both verdicts exercised


# --- the two-link legs a closed-form leg model assumes (BodyModel.require_leg_chains) --------

QP_LEGS = "the QP cuff model needs each leg as a hip on the fixed frame and a knee on the hip"
QP_ORDER = (
    "the QP cuff model needs exactly the joints "
    "('left_hip', 'left_knee', 'right_hip', 'right_knee') in that order"
)


def test_the_committed_models_have_two_link_legs() -> None:
    for body in (load_exo(), load_patient(str(default_urdf_path("patient")))):
        body.require_leg_chains("the QP cuff model")  # raises nothing


@pytest.mark.parametrize(
    ("old", "new", "where", "reason"),
    [
        # the left hip on the right thigh: one chain of four joints, the right leg's
        # first in Pinocchio's depth-first order
        (
            '<joint name="left_hip" type="revolute">\n    <parent link="pelvis"/>',
            '<joint name="left_hip" type="revolute">\n    <parent link="right_thigh"/>',
            "",
            QP_ORDER,
        ),
        # the right knee on the pelvis: a leg of two parallel joints, not a chain
        (
            '<joint name="right_knee" type="revolute">\n    <parent link="right_thigh"/>',
            '<joint name="right_knee" type="revolute">\n    <parent link="pelvis"/>',
            "'right_hip' in ",
            QP_LEGS,
        ),
    ],
)
def test_a_leg_that_is_not_a_hip_knee_chain_is_named(
    tmp_path: Path, exo_text: str, broken, old: str, new: str, where: str, reason: str
) -> None:
    assert old in exo_text
    path = broken(tmp_path, exo_text.replace(old, new))
    body = load_exo(str(path))  # a valid URDF, loaded
    with pytest.raises(InvalidModel) as info:
        body.require_leg_chains("the QP cuff model")
    assert str(info.value) == f"invalid model: {where}{body.source}: {reason}"
    # a run refuses it when built: the plant first if the joints are out of order, else the QP
    first = "the plant needs exactly the joints" if reason == QP_ORDER else reason
    with pytest.raises(InvalidModel, match=first):
        build(SimConfig(controller="qp", exo=str(path), duration_s=0.1))
