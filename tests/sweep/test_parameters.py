"""Tests of exo_ctrl.sweep.parameters: the ``--param`` syntax, ranges and exact messages."""

from __future__ import annotations

import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.sim import CONTROLLERS
from exo_ctrl.sweep import parse_param


def test_parse_lists_and_ranges():
    assert parse_param("step_length=0.3,0.35,0.3") == ("step_length", (0.3, 0.35))
    assert parse_param(" period = 1.0:1.4:5 ") == ("period", (1.0, 1.1, 1.2, 1.3, 1.4))
    assert parse_param("step_length=0.3:0.5:3") == ("step_length", (0.3, 0.4, 0.5))
    assert parse_param("controller=ct,pd") == ("controller", ("ct", "pd"))
    assert parse_param("gear_ratio=50") == ("gear_ratio", (50.0,))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "stride=0.3",
            "sweep parameter must be one of step_length, lift_height, hip_height, shape_coeff, "
            "period, duty_factor, patient_thigh_mass, patient_shank_mass, patient_thigh_length, "
            "patient_shank_length, cuff_stiffness, cuff_damping, gear_ratio, controller; "
            "got 'stride'",
        ),
        ("step_length", "--param must be NAME=V1,V2,... or NAME=LO:HI:N; got 'step_length'"),
        ("step_length=", "--param must be NAME=V1,V2,... or NAME=LO:HI:N; got 'step_length='"),
        (
            "step_length=0.3:0.5",
            "step_length must be V1,V2,... or LO:HI:N with LO < HI and an integer N >= 2; "
            "got '0.3:0.5'",
        ),
        (
            "step_length=0.5:0.3:3",
            "step_length must be V1,V2,... or LO:HI:N with LO < HI and an integer N >= 2; "
            "got '0.5:0.3:3'",
        ),
        (
            "step_length=0.3:0.5:2.5",
            "step_length must be V1,V2,... or LO:HI:N with LO < HI and an integer N >= 2; "
            "got '0.3:0.5:2.5'",
        ),
        (
            "step_length=0.3:0.5:1",
            "step_length must be V1,V2,... or LO:HI:N with LO < HI and an integer N >= 2; "
            "got '0.3:0.5:1'",
        ),
        ("step_length=0.3,nan", "step_length must be a finite number [m]; got 'nan'"),
        ("step_length=nan:0.5:3", "step_length must be a finite number [m]; got 'nan'"),
        ("shape_coeff=inf", "shape_coeff must be a finite number; got 'inf'"),
        ("lift_height=0.1,,0.2", "lift_height must be a finite number [m]; got ''"),
        ("step_length=-0.3", "step_length must be in (0, 2] m; got -0.3"),
        ("duty_factor=1", "duty_factor must be in [0.5, 1); got 1.0"),
        ("patient_thigh_mass=20", "patient_thigh_mass must be in [7, 14] kg; got 20.0"),
        ("patient_shank_length=0.3", "patient_shank_length must be in [0.39, 0.65] m; got 0.3"),
        (
            "controller=lqr",
            f"controller must be one of {', '.join(CONTROLLERS)}; got 'lqr'",
        ),
    ],
)
def test_parse_errors(text, message):
    with pytest.raises(InvalidParameter) as info:
        parse_param(text)
    assert str(info.value) == message
