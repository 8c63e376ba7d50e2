"""Safety limits: their defaults and sources, their resolution, their validation messages."""

from __future__ import annotations

import math

import numpy as np
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.safety import (
    CURRENT_LIMIT_FACTOR,
    ISO_TS_15066_CUFF_FORCE_N,
    SafetyLimits,
    SafetySupervisor,
    resolve_limits,
)
from exo_ctrl.sim import SimConfig, build

DT = 1e-3


def test_default_limits_come_from_iso_and_the_urdfs() -> None:
    setup = build(SimConfig(controller="ct", duration_s=0.01))
    motor = setup.plant.motor_params
    sup = SafetySupervisor(SafetyLimits(), setup.exo, setup.patient, motor, DT)
    np.testing.assert_array_equal(sup.cuff_limit, [220.0, 130.0, 220.0, 130.0])
    lo = np.maximum(setup.exo.position_limits[0], setup.patient.position_limits[0])
    hi = np.minimum(setup.exo.position_limits[1], setup.patient.position_limits[1])
    np.testing.assert_allclose(sup.q_lower, lo + 0.05)
    np.testing.assert_allclose(sup.q_upper, hi - 0.05)
    np.testing.assert_allclose(
        sup.speed_limit, np.minimum(setup.exo.velocity_limit, setup.patient.velocity_limit)
    )
    np.testing.assert_allclose(sup.current_limit, 1.1 * motor.current_limit_A)
    assert SafetyLimits(cuff_force_factor=0.5).cuff_limit_N.tolist() == [110, 65, 110, 65]


def test_resolved_limits_are_the_supervisors() -> None:
    setup = build(SimConfig(controller="ct", duration_s=0.01))
    motor = setup.plant.motor_params
    limits = SafetyLimits()
    resolved = resolve_limits(limits, setup.exo, setup.patient, motor)
    sup = SafetySupervisor(limits, setup.exo, setup.patient, motor, DT)
    for name in ("q_lower", "q_upper", "speed_limit", "current_limit", "cuff_limit"):
        np.testing.assert_array_equal(getattr(resolved, name), getattr(sup, name))
    assert ISO_TS_15066_CUFF_FORCE_N == (220.0, 130.0, 220.0, 130.0)
    np.testing.assert_array_equal(
        resolved.current_limit, np.full(4, CURRENT_LIMIT_FACTOR * motor.current_limit_A)
    )


def test_explicit_limits_replace_the_urdfs_and_the_drive() -> None:
    setup = build(SimConfig(controller="ct", duration_s=0.01))
    limits = SafetyLimits(
        position_lower_rad=(-0.5, 0.0, -0.5, 0.0),
        position_upper_rad=(0.5, 1.0, 0.5, 1.0),
        speed_limit_rad_s=2.0,
        current_limit_A=3.0,
        cuff_force_factor=0.5,
    )
    resolved = resolve_limits(limits, setup.exo, setup.patient, setup.plant.motor_params)
    np.testing.assert_array_equal(resolved.q_lower, [-0.5, 0.0, -0.5, 0.0])
    np.testing.assert_array_equal(resolved.q_upper, [0.5, 1.0, 0.5, 1.0])
    np.testing.assert_array_equal(resolved.speed_limit, [2.0] * 4)
    np.testing.assert_array_equal(resolved.current_limit, [3.0] * 4)
    np.testing.assert_array_equal(resolved.cuff_limit, [110.0, 65.0, 110.0, 65.0])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"cuff_force_N": -5}, "cuff_force_N[left_thigh] must be > 0 N; got -5.0"),
        (
            {"cuff_force_N": (220, 130, 220)},
            "cuff_force_N must be a number or 4 numbers (one per cuff: left_thigh, left_shank, "
            "right_thigh, right_shank); got",
        ),
        ({"cuff_force_factor": 1.5}, "cuff_force_factor must be in (0, 1]; got 1.5"),
        ({"cuff_force_factor": 0}, "cuff_force_factor must be > 0; got 0"),
        ({"rom_margin_rad": -0.1}, "rom_margin_rad must be >= 0 rad; got -0.1"),
        (
            {"position_lower_rad": (0, 0, 1.0, 0), "position_upper_rad": (1, 1, 0.5, 1)},
            "position_upper_rad[right_hip] must be > position_lower_rad (1 rad); got 0.5",
        ),
        ({"speed_limit_rad_s": 0.0}, "speed_limit_rad_s[left_hip] must be > 0 rad/s; got 0.0"),
        ({"current_limit_A": math.inf}, "current_limit_A must be a finite number [A]; got inf"),
    ],
)
def test_safety_limits_validation_messages(kwargs, message) -> None:
    with pytest.raises(InvalidParameter) as exc:
        SafetyLimits(**kwargs)
    assert str(exc.value).startswith(message)
