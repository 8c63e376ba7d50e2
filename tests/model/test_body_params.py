"""Tests of exo_ctrl.model.body_params: validation of the body parameters, exact messages."""

from __future__ import annotations

import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import BodyParams

EXO = BodyParams.exo_default()


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"thigh_length": -0.1}, "thigh_length must be > 0 m; got -0.1"),
        ({"shank_length": 0.0}, "shank_length must be > 0 m; got 0.0"),
        ({"thigh_mass": float("nan")}, "thigh_mass must be a finite number [kg]; got nan"),
        ({"thigh_cuff": 0.6}, "thigh_cuff must be in (0, 0.52] m (the thigh length); got 0.6"),
        ({"shank_cuff": 0.0}, "shank_cuff must be in (0, 0.52] m (the shank length); got 0.0"),
        (
            {"shank_length": 0.4},
            "shank_cuff must be in (0, 0.4] m (the shank length); got 0.45",
        ),
        ({"kind": "robot"}, "kind must be 'exo' or 'patient'; got 'robot'"),
        ({"joint_damping": -1.0}, "joint_damping must be >= 0 N·m·s/rad; got -1.0"),
        (
            {"knee_range": (1.0, 0.5)},
            "knee_range must be (lower, upper) with finite lower < upper [rad]; got (1.0, 0.5)",
        ),
        ({"thigh_com_ratio": 1.0}, "thigh_com_ratio must be in (0, 1); got 1.0"),
    ],
)
def test_bad_params_exact_messages(overrides: dict, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        BodyParams.exo_default(**overrides)
    assert str(info.value) == message
    assert info.value.name == next(iter(overrides)) or "cuff" in info.value.name
    assert isinstance(info.value, ValueError)


def test_non_physical_radius_rejected() -> None:
    with pytest.raises(InvalidParameter) as info:
        BodyParams.patient_default(shank_radius=0.5)
    assert str(info.value) == (
        "shank_radius must be < 0.43264 m (2 × shank_gyration_ratio × shank_length); got 0.5 "
        "(otherwise the inertia violates the triangle inequality)"
    )


def test_params_frozen_and_replace_validates() -> None:
    with pytest.raises(AttributeError):
        EXO.thigh_length = 0.4  # type: ignore[misc]
    assert EXO.replace(thigh_length=0.4).thigh_length == 0.4
    with pytest.raises(InvalidParameter):
        EXO.replace(thigh_length=0.3)  # the 0.39 m cuff no longer fits
    assert BodyParams.exo_default().hip_width == BodyParams.patient_default().hip_width
