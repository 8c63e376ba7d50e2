"""The session's speed profile and the gait's adaptation law (walk ratio, reach cap)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from exo_ctrl.exceptions import ExoCtrlError, InvalidParameter
from exo_ctrl.model import load_exo
from exo_ctrl.plan import GaitParams, GaitPlan, SpeedAdaptation, SpeedProfile, plan_joints
from exo_ctrl.plan.adapt import max_step_length
from exo_ctrl.plan.profile import PROFILE_FORMAT, profile_at


def test_profile_is_piecewise_linear_held_outside_its_points() -> None:
    p = SpeedProfile.parse("1:0.4, 4:0.7,5:0.5")
    t = np.array([0.0, 1.0, 2.5, 4.0, 4.5, 5.0, 9.0])
    v, a = p.at(t)
    np.testing.assert_allclose(v, [0.4, 0.4, 0.55, 0.7, 0.6, 0.5, 0.5], rtol=0, atol=1e-15)
    np.testing.assert_allclose(a, [0.0, 0.1, 0.1, -0.2, -0.2, 0.0, 0.0], rtol=0, atol=1e-15)
    times, speeds = p.arrays()
    for tk, vk, ak in zip(t, v, a, strict=True):  # the compiled lookup is the same function
        assert profile_at(times, speeds, tk) == pytest.approx((vk, ak), abs=1e-15)
    assert p.text() == "1:0.4,4:0.7,5:0.5"
    # the rate is the derivative of the speed (central differences inside the pieces)
    tt = np.linspace(0.1, 8.9, 1000)
    h = 1e-6
    fd = (p.at(tt + h)[0] - p.at(tt - h)[0]) / (2 * h)
    inside = np.min(np.abs(tt[:, None] - np.array(p.times)), axis=1) > 2 * h
    np.testing.assert_allclose(fd[inside], p.at(tt)[1][inside], atol=1e-8)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "3:0.5,1:0.6",
            "speed_profile must be times in increasing order; got '3:0.5,1:0.6' "
            "(point 2, 1:0.6 is not after 3 s)",
        ),
        ("0:-0.5", "speed_profile must be speeds >= 0.01 m/s; got '0:-0.5' (point 1, 0:-0.5)"),
        ("0:0", "speed_profile must be speeds >= 0.01 m/s; got '0:0' (point 1, 0:0)"),
        ("-1:0.5", "speed_profile must be times >= 0 s; got '-1:0.5' (point 1, -1:0.5)"),
        (
            "0:0.5;1",
            f"speed_profile must be {PROFILE_FORMAT}; got '0:0.5;1' ('0:0.5;1' is not T:V)",
        ),
        ("0:nan", "speed_profile must be finite times and speeds; got '0:nan' (point 1, 0:nan)"),
        ("", f"speed_profile must be {PROFILE_FORMAT}; got '' ('' is not T:V)"),
    ],
)
def test_a_bad_profile_is_refused_naming_the_point(text: str, message: str) -> None:
    with pytest.raises(InvalidParameter) as err:
        SpeedProfile.parse(text)
    assert str(err.value) == message


def test_the_law_keeps_the_walk_ratio_k_v_and_the_duty_factor() -> None:
    ref = GaitParams()
    law = SpeedAdaptation(ref)
    # through the configured gait's own point
    assert law.step_length(ref.belt_speed) == pytest.approx(ref.step_length, rel=1e-15)
    assert law.period(ref.belt_speed) == pytest.approx(ref.period, rel=1e-14)
    ratio0 = ref.step_length**2 / (2 * ref.duty_factor * ref.belt_speed)  # s / cadence [m·s]
    for v in (0.2, 0.4, 0.7, 1.3):
        g = law.gait(v)
        assert g.belt_speed == pytest.approx(v, rel=1e-14)  # v = s / (β T)
        cadence = 2.0 / g.period  # steps per second
        assert g.step_length / cadence == pytest.approx(ratio0, rel=1e-14)
        assert (g.shape_coeff, g.duty_factor, g.lift_height, g.hip_height) == (
            ref.shape_coeff,
            ref.duty_factor,
            ref.lift_height,
            ref.hip_height,
        )
    capped = SpeedAdaptation(ref, max_step_m=0.4)
    assert capped.step_length(2.0) == 0.4 and capped.capped(2.0)
    assert capped.period(2.0) == pytest.approx(0.4 / (0.5 * 2.0))


def test_the_step_cap_is_the_longest_step_the_leg_reaches_within_its_ranges() -> None:
    exo = load_exo(None)
    gait = GaitParams(hip_height=0.98)  # the reach binds close to the belt line
    cap = max_step_length(gait, exo)
    print(f"s_max {cap:.4f} m at H_s 0.98 m; {max_step_length(GaitParams(), exo):.4f} m at 0.9 m")
    t = np.linspace(0.0, gait.period, 512, endpoint=False)
    plan_joints(GaitPlan(dataclasses.replace(gait, step_length=cap)), exo, t)
    with pytest.raises(ExoCtrlError):
        plan_joints(GaitPlan(dataclasses.replace(gait, step_length=cap + 1e-3)), exo, t)
