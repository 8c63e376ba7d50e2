"""Tests of exo_ctrl.model.checks: malformed and non-physical URDFs named exactly."""

from __future__ import annotations

from pathlib import Path


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
