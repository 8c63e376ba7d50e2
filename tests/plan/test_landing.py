"""The landing approach (exo_ctrl/plan/landing.py): the swing foot's last millimetres at v_a.

Against an independent calculation: the foot crosses the belt line at the planned
touchdown at -v_a, a' above it t_a before and a' below it t_a after, moving with the belt
along it from t_a before touchdown on; the path is C¹ at every join (positions and
velocities continuous, velocities the positions' derivatives); the press is over after
4 t_a; the online generator plans the same; v_a = 0 is the paper's path bit for bit;
bad values are refused by name.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import load_exo
from exo_ctrl.plan import (
    GaitParams,
    GaitPlan,
    OnlineGait,
    SpeedAdaptation,
    StanceSink,
    inverse_kinematics,
    plan_joints,
)

DT = 1e-3
PAPER = GaitParams(hip_height=1.0, pelvis_excursion=0.05, duty_factor=0.6)
V_A, DEPTH = 0.03, 0.002  # [m/s], [m]
GAIT = dataclasses.replace(PAPER, landing_speed_mps=V_A, landing_depth_m=DEPTH)
SINK = StanceSink(97.0 * 9.81 - 0.5 * 80.0 * 9.81, 97.0, 5.0e5, 1.5)


@pytest.fixture(scope="module")
def exo():
    return load_exo(None)


def _belt_frame(plan: GaitPlan, t: np.ndarray):
    """Left foot x [m], ẋ [m/s], height above the belt line [m], its rate [m/s] (hip fixed)."""
    f = plan.feet(t)
    return f.pos[:, 0, 0], f.vel[:, 0, 0], f.pos[:, 0, 1] + plan.params.hip_height, f.vel[:, 0, 1]


def test_the_foot_crosses_the_belt_line_at_the_approach_speed() -> None:
    gait = dataclasses.replace(GAIT, pelvis_excursion=0.0)
    plan = GaitPlan(gait)
    t_b = gait.swing_time / 2  # the left foot's planned touchdown
    t_a = DEPTH / V_A  # within min(T_sw/4, T_st/8) = min(0.12, 0.09) s
    assert t_a < 0.09
    v_f, s = gait.belt_speed, gait.step_length
    t = t_b + np.array([-t_a, -0.5 * t_a, 0.0, 0.5 * t_a, t_a])
    x, dx, z, dz = _belt_frame(plan, t)
    np.testing.assert_allclose(z, [DEPTH, DEPTH / 2, 0.0, -DEPTH / 2, -DEPTH], rtol=0, atol=1e-12)
    np.testing.assert_allclose(dz, -V_A, rtol=0, atol=1e-12)
    np.testing.assert_allclose(x, s / 2 - v_f * (t - t_b), rtol=0, atol=1e-12)
    np.testing.assert_allclose(dx, -v_f, rtol=0, atol=1e-12)
    # the press: deepest 1.28 a at 1.6 t_a after touchdown, over at 4 t_a, then the belt line
    t = t_b + t_a * np.array([1.6, 4.0, 5.0])
    _, _, z, dz = _belt_frame(plan, t)
    np.testing.assert_allclose(z, [-1.28 * DEPTH, 0.0, 0.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(dz, 0.0, rtol=0, atol=1e-12)
    # the top of the swing and lift-off are the paper's
    x, dx, z, dz = _belt_frame(plan, np.array([0.0, t_b + gait.stance_time]))
    np.testing.assert_allclose(z, [gait.lift_height, 0.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(dx, [v_f / gait.shape_coeff, -v_f], rtol=0, atol=1e-12)


@pytest.mark.parametrize("sink", [None, SINK])
def test_the_path_is_c1_and_its_rates_are_its_derivatives(sink) -> None:
    plan = GaitPlan(GAIT, sink)
    t_b, t_a = GAIT.swing_time / 2, DEPTH / V_A
    joins = t_b + t_a * np.array([-1.0, 0.0, 1.0, 4.0])
    h = 1e-9
    for tj in np.concatenate((joins, joins + GAIT.period / 2)):  # both legs' joins
        before, after = plan.feet(tj - h), plan.feet(tj + h)
        np.testing.assert_allclose(after.pos, before.pos, rtol=0, atol=1e-8)
        np.testing.assert_allclose(after.vel, before.vel, rtol=0, atol=1e-6)
    t = np.linspace(0.0, 2 * GAIT.period, 2401)
    every = np.concatenate((joins, [0.0, t_b + GAIT.stance_time]))  # and the paper's A, D
    every = (every[:, None] + GAIT.period / 2 * np.arange(-1, 5)[None, :]).ravel()
    t = t[np.min(np.abs(t[:, None] - every[None, :]), axis=1) > 1e-3]
    h = 1e-6
    up, down, mid = plan.feet(t + h), plan.feet(t - h), plan.feet(t)
    np.testing.assert_allclose((up.pos - down.pos) / (2 * h), mid.vel, rtol=0, atol=1e-7)
    np.testing.assert_allclose((up.vel - down.vel) / (2 * h), mid.acc, rtol=0, atol=5e-5)


def test_online_at_a_steady_speed_is_the_offline_plan(exo) -> None:
    gen = OnlineGait(SpeedAdaptation(GAIT), None, exo, DT, sink=SINK)
    n = 2400
    pos, q = [], []
    for k in range(n):
        gen.step(k, GAIT.belt_speed)
        pos.append(gen.plan.foot_pos[0].copy())
        q.append(gen.plan.q[0].copy())
    ref = plan_joints(GaitPlan(GAIT, SINK), exo, np.arange(n) * DT)
    np.testing.assert_allclose(np.array(pos), ref.foot_pos, rtol=0, atol=1e-11)
    np.testing.assert_allclose(np.array(q), ref.q, rtol=0, atol=1e-10)


def test_no_approach_is_the_papers_path_bit_for_bit() -> None:
    t = np.linspace(0.0, 2.4, 2401)
    a = GaitPlan(dataclasses.replace(GAIT, landing_speed_mps=0.0), SINK).feet(t)
    b = GaitPlan(PAPER, SINK).feet(t)
    for x, y in ((a.pos, b.pos), (a.vel, b.vel), (a.acc, b.acc)):
        assert np.array_equal(x, y)


def test_a_short_swing_caps_the_approach_and_keeps_its_speed() -> None:
    gait = dataclasses.replace(GAIT, pelvis_excursion=0.0, landing_depth_m=0.009)
    plan = GaitPlan(gait)
    t_a = min(gait.swing_time / 4, gait.stance_time / 8)  # 0.09 s < 0.009 / 0.03
    t_b = gait.swing_time / 2
    _, _, z, dz = _belt_frame(plan, t_b + np.array([-t_a, 0.0]))
    np.testing.assert_allclose(z, [V_A * t_a, 0.0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(dz, -V_A, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"landing_speed_mps": -0.01}, "landing_speed_mps must be in [0, 0.5] m/s; got -0.01"),
        (
            {"landing_speed_mps": float("nan")},
            "landing_speed_mps must be a finite number [m/s]; got nan",
        ),
        ({"landing_depth_m": 0.0}, "landing_depth_m must be > 0 m; got 0.0"),
        ({"landing_depth_m": 0.02}, "landing_depth_m must be in (0, 0.01] m"),
    ],
)
def test_bad_values_are_refused(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        dataclasses.replace(GAIT, **kwargs)
    assert str(info.value).startswith(message)


def _raised_stance_q(gen: OnlineGait, exo, leg: int, rise_m: float) -> np.ndarray:
    """The plan's last joint angles with leg ``leg``'s foot ``rise_m`` higher [rad], (4,)."""
    q = gen.plan.q[0].copy()
    x, z = gen.plan.foot_pos[0, leg]
    geo = exo.legs[("left", "right")[leg]]
    phi1, phi2 = inverse_kinematics(x, z + rise_m, geo.thigh_length, geo.shank_length)
    q[2 * leg : 2 * leg + 2] = geo.absolute_to_joint(phi1, phi2)
    return q


def test_the_approach_follows_the_stance_foots_measured_height(exo) -> None:
    """The right foot stands 1 mm higher than planned: the left lands 1 mm higher; unloaded."""
    rise, n = 0.001, 241  # to the left foot's planned touchdown at T_sw/2 = 0.24 s
    plain = OnlineGait(SpeedAdaptation(GAIT), None, exo, DT, sink=SINK)
    same = OnlineGait(SpeedAdaptation(GAIT), None, exo, DT, sink=SINK)
    raised = OnlineGait(SpeedAdaptation(GAIT), None, exo, DT, sink=SINK)
    light = np.zeros(2)  # the plates: no foot loaded
    for k in range(1, n):
        plain.step(k, GAIT.belt_speed)
        same.step(k, GAIT.belt_speed, same.plan.q[0].copy(), light)
        raised.step(k, GAIT.belt_speed, _raised_stance_q(raised, exo, 1, rise), light)
        if k == 60:  # a quarter of A -> B: weight S(1/4) = 0.104
            assert raised.plan.foot_pos[0, 0, 1] - plain.plan.foot_pos[0, 0, 1] < 0.11 * rise
    for gen in (same, raised):
        np.testing.assert_array_equal(gen.plan.foot_pos[0, 1], plain.plan.foot_pos[0, 1])
    np.testing.assert_allclose(same.plan.foot_pos[0], plain.plan.foot_pos[0], rtol=0, atol=1e-12)
    lift = raised.plan.foot_pos[0, 0, 1] - plain.plan.foot_pos[0, 0, 1]
    assert lift == pytest.approx(rise, rel=0.01)
