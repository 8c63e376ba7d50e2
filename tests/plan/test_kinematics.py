"""Tests of exo_ctrl.plan.kinematics, checked against Pinocchio's model of the URDF and by hand."""

from __future__ import annotations

import math
import tracemalloc

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl._validate import MAX_ALLOCATION_BYTES
from exo_ctrl.exceptions import ExoCtrlError, InvalidParameter, UnreachableFootTarget
from exo_ctrl.model import SIDES, BodyModel
from exo_ctrl.plan.gait import GaitParams, GaitPlan
from exo_ctrl.plan.kinematics import (
    PLAN_BYTES_PER_SAMPLE,
    forward_kinematics,
    inverse_kinematics,
    joint_accelerations,
    joint_rates,
    plan_joints,
)

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
SHORT_THIGH, SHORT_SHANK = 0.45, 0.40  # the conftest short_exo [m]


def leg_q(body: BodyModel, side: str, q_hip, q_knee) -> np.ndarray:
    """Joint vector (JOINT_NAMES order) with one leg set and the other at zero."""
    q = np.zeros(4)
    s = SIDES.index(side)
    q[2 * s], q[2 * s + 1] = q_hip, q_knee
    return q


def pin_points(body: BodyModel, q: np.ndarray, side: str) -> dict[str, np.ndarray]:
    """World x–z of the hip and knee joints and the foot frame, straight from Pinocchio."""
    model = body.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, body.to_model_q(q))
    s = SIDES.index(side)
    hip, knee = body.joint_ids[2 * s], body.joint_ids[2 * s + 1]
    foot = data.oMf[model.getFrameId(f"{side}_foot")].translation
    return {
        "hip": data.oMi[hip].translation[[0, 2]].copy(),
        "knee": data.oMi[knee].translation[[0, 2]].copy(),
        "foot": foot[[0, 2]].copy(),
    }


def pin_foot_in_hip(body: BodyModel, side: str, phi1: float, phi2: float) -> np.ndarray:
    """Foot relative to the hip (x, z) from Pinocchio, for absolute angles (φ1, φ2)."""
    qh, qk = body.legs[side].absolute_to_joint(phi1, phi2)
    q = leg_q(body, side, float(qh), float(qk))
    foot = body.frame_position(q, f"{side}_foot")
    pts = pin_points(body, q, side)
    return foot[[0, 2]] - pts["hip"]


def random_reachable(rng: np.random.Generator, l1: float, l2: float, n: int) -> np.ndarray:
    """n points (x, z) with |l1 - l2| + margin < r < 0.98 (l1 + l2), all around the hip."""
    r = rng.uniform(abs(l1 - l2) + 0.05, 0.98 * (l1 + l2), n)
    a = rng.uniform(-math.pi, math.pi, n)
    return np.column_stack((r * np.cos(a), r * np.sin(a)))


# --------------------------------------------------------------------------- IK / FK


@pytest.mark.parametrize("which", ["default", "short"])
def test_inverse_then_pinocchio_forward_returns_the_target(
    which: str, exo: BodyModel, short_exo: BodyModel
) -> None:
    body = exo if which == "default" else short_exo
    rng = np.random.default_rng(7)
    for side in SIDES:
        l1, l2 = body.legs[side].thigh_length, body.legs[side].shank_length
        pts = random_reachable(rng, l1, l2, 200)
        phi1, phi2 = inverse_kinematics(pts[:, 0], pts[:, 1], l1, l2)
        x, z = forward_kinematics(phi1, phi2, l1, l2)
        np.testing.assert_allclose(np.column_stack((x, z)), pts, atol=1e-9)
        for i in range(0, 200, 4):
            got = pin_foot_in_hip(body, side, phi1[i], phi2[i])
            np.testing.assert_allclose(got, pts[i], atol=1e-9)


@pytest.mark.parametrize("z", [-0.9, -0.5, -1.03, 0.5, 0.9])
def test_ik_is_exact_and_continuous_at_x_zero(z: float, exo: BodyModel) -> None:
    """The paper's arctan(z/x) branch jumps by π at x = 0; atan2 does not."""
    l1 = l2 = 0.52
    phi1, phi2 = inverse_kinematics(0.0, z, l1, l2)
    x_fk, z_fk = forward_kinematics(phi1, phi2, l1, l2)
    assert (float(x_fk), float(z_fk)) == pytest.approx((0.0, z), abs=1e-12)
    np.testing.assert_allclose(pin_foot_in_hip(exo, "left", phi1, phi2), [0.0, z], atol=1e-9)
    for dx in (1e-12, -1e-12):
        p1, p2 = inverse_kinematics(dx, z, l1, l2)
        assert float(p1) == pytest.approx(float(phi1), abs=1e-9)
        assert float(p2) == pytest.approx(float(phi2), abs=1e-9)
    # knee forward for the foot straight below: symmetric triangle, knee at x = +l1 sin(half angle)
    if z < 0:
        half = math.acos(-z / 2 / l1)  # angle between thigh and vertical
        assert float(phi1) == pytest.approx(-math.pi / 2 + half, abs=1e-12)
        assert float(phi2) == pytest.approx(-math.pi / 2 - half, abs=1e-12)


def test_ik_agrees_with_the_papers_formula_for_x_positive() -> None:
    rng = np.random.default_rng(3)
    l1, l2 = 0.45, 0.40
    pts = random_reachable(rng, l1, l2, 500)
    pts = pts[pts[:, 0] > 1e-3]
    x, z = pts.T
    r2 = x**2 + z**2
    paper1 = np.arctan(z / x) + np.arccos((l1**2 - l2**2 + r2) / (2 * l1 * np.sqrt(r2)))
    paper2 = paper1 + (math.pi + np.arccos((l1**2 + l2**2 - r2) / (2 * l1 * l2)))
    phi1, phi2 = inverse_kinematics(x, z, l1, l2)
    np.testing.assert_allclose(np.angle(np.exp(1j * (phi1 - paper1))), 0.0, atol=1e-9)
    np.testing.assert_allclose(np.angle(np.exp(1j * (phi2 - paper2))), 0.0, atol=1e-9)


def test_knee_is_forward_and_flexed(exo: BodyModel) -> None:
    rng = np.random.default_rng(11)
    l1 = l2 = 0.52
    pts = random_reachable(rng, l1, l2, 400)
    pts = pts[pts[:, 1] < -0.05]  # feet below the hip
    phi1, phi2 = inverse_kinematics(pts[:, 0], pts[:, 1], l1, l2)
    knee = l1 * np.column_stack((np.cos(phi1), np.sin(phi1)))
    # knee in front of the hip→foot line: for a line going down, d × k > 0 puts k on the +x side
    cross = pts[:, 0] * knee[:, 1] - pts[:, 1] * knee[:, 0]
    assert np.all(cross > 0)
    # where the line is vertical-ish the knee x is ahead of the line's x at the knee height
    line_x_at_knee = pts[:, 0] * knee[:, 1] / pts[:, 1]
    assert np.all(knee[:, 0] > line_x_at_knee)
    _, q_knee = exo.legs["left"].absolute_to_joint(phi1, phi2)
    assert np.all(q_knee > 0)
    # the same knee angle, straight from the law of cosines
    r = np.hypot(pts[:, 0], pts[:, 1])
    inner = np.arccos((l1**2 + l2**2 - r**2) / (2 * l1 * l2))
    np.testing.assert_allclose(q_knee, math.pi - inner, atol=1e-9)


# --------------------------------------------------------------------------- angle conventions


def test_joint_absolute_round_trips(exo: BodyModel, human: BodyModel) -> None:
    rng = np.random.default_rng(5)
    for body in (exo, human):
        for side in SIDES:
            leg = body.legs[side]
            qh, qk = rng.uniform(-3.0, 3.0, (2, 300))
            p1, p2 = leg.joint_to_absolute(qh, qk)
            bh, bk = leg.absolute_to_joint(p1, p2)
            np.testing.assert_allclose(bh, qh, atol=1e-12)
            np.testing.assert_allclose(bk, qk, atol=1e-12)
            # absolute → joint → absolute, for φ anywhere (any branch, ±2π)
            a1, a2 = rng.uniform(-2 * math.pi, 2 * math.pi, (2, 300))
            c1, c2 = leg.joint_to_absolute(*leg.absolute_to_joint(a1, a2))
            np.testing.assert_allclose(np.cos(c1 - a1), 1.0, atol=1e-12)
            np.testing.assert_allclose(np.cos(c2 - a2), 1.0, atol=1e-12)


def test_generated_urdf_angle_convention(exo: BodyModel) -> None:
    rng = np.random.default_rng(9)
    for side in SIDES:
        leg = exo.legs[side]
        qh, qk = rng.uniform(-0.5, 2.0, (2, 50))
        p1, p2 = leg.joint_to_absolute(qh, qk)
        np.testing.assert_allclose(p1, -math.pi / 2 + qh, atol=1e-14)
        np.testing.assert_allclose(p2, p1 - qk, atol=1e-14)
        # the same convention measured on Pinocchio's model: directions of thigh and shank
        for i in range(0, 50, 5):
            pts = pin_points(exo, leg_q(exo, side, qh[i], qk[i]), side)
            thigh, shank = pts["knee"] - pts["hip"], pts["foot"] - pts["knee"]
            assert math.cos(math.atan2(thigh[1], thigh[0]) - p1[i]) == pytest.approx(1, abs=1e-12)
            assert math.cos(math.atan2(shank[1], shank[0]) - p2[i]) == pytest.approx(1, abs=1e-12)


def test_positive_joint_angles_are_flexion(exo: BodyModel) -> None:
    rest = pin_points(exo, np.zeros(4), "left")
    hip_flexed = pin_points(exo, leg_q(exo, "left", 0.3, 0.0), "left")
    knee_flexed = pin_points(exo, leg_q(exo, "left", 0.0, 0.3), "left")
    assert hip_flexed["knee"][0] > rest["knee"][0] + 0.1  # thigh swings forward
    assert knee_flexed["foot"][0] < rest["foot"][0] - 0.1  # shank swings backward
    np.testing.assert_allclose(knee_flexed["knee"], rest["knee"], atol=1e-12)


def test_human_angle_convention_matches_pinocchio(human: BodyModel) -> None:
    """A URDF with other axes (knee about -z of a y-up model): φ from q still fits Pinocchio."""
    rng = np.random.default_rng(21)
    for side in SIDES:
        leg = human.legs[side]
        for qh, qk in rng.uniform(0.0, 1.5, (10, 2)):
            p1, p2 = leg.joint_to_absolute(qh, qk)
            pts = pin_points(human, leg_q(human, side, qh, qk), side)
            x, z = forward_kinematics(p1, p2, leg.thigh_length, leg.shank_length)
            np.testing.assert_allclose([x, z], pts["foot"] - pts["hip"], atol=1e-9)


# --------------------------------------------------------------------------- rates


def smooth_path(t: np.ndarray):
    """A smooth foot path (x, z), with its first and second derivatives, inside the reach."""
    x = 0.05 + 0.2 * np.sin(2 * t)
    z = -0.6 + 0.1 * np.cos(3 * t)
    dx, dz = 0.4 * np.cos(2 * t), -0.3 * np.sin(3 * t)
    ddx, ddz = -0.8 * np.sin(2 * t), -0.9 * np.cos(3 * t)
    return (x, z), (dx, dz), (ddx, ddz)


@pytest.mark.parametrize(("l1", "l2"), [(0.52, 0.52), (0.45, 0.40)])
def test_joint_rates_and_accelerations_match_finite_differences_of_ik(l1: float, l2: float) -> None:
    t = np.linspace(0.0, 3.0, 301)
    h = 1e-4
    (x, z), (dx, dz), (ddx, ddz) = smooth_path(t)
    p1, p2 = inverse_kinematics(x, z, l1, l2)
    pp1, pp2 = inverse_kinematics(*smooth_path(t + h)[0], l1, l2)
    pm1, pm2 = inverse_kinematics(*smooth_path(t - h)[0], l1, l2)
    d1, d2 = joint_rates(p1, p2, l1, l2, dx, dz)
    np.testing.assert_allclose(d1, (pp1 - pm1) / (2 * h), atol=1e-6)
    np.testing.assert_allclose(d2, (pp2 - pm2) / (2 * h), atol=1e-6)
    a1, a2 = joint_accelerations(p1, p2, d1, d2, l1, l2, ddx, ddz)
    np.testing.assert_allclose(a1, (pp1 - 2 * p1 + pm1) / h**2, atol=1e-4)
    np.testing.assert_allclose(a2, (pp2 - 2 * p2 + pm2) / h**2, atol=1e-4)


def test_leg_jacobian_and_its_derivative_match_pinocchio(exo: BodyModel) -> None:
    model = exo.model
    data = model.createData()
    rng = np.random.default_rng(13)
    for _ in range(25):
        q = rng.uniform([-0.5, 0.1, -0.5, 0.1], [2.0, 2.0, 2.0, 2.0])
        dq = rng.normal(size=4)
        ddq = rng.normal(size=4)
        qm, vm, am = exo.to_model_q(q), exo.to_model_q(dq), exo.to_model_q(ddq)
        pin.forwardKinematics(model, data, qm, vm, am)
        pin.updateFramePlacements(model, data)
        pin.computeJointJacobians(model, data, qm)
        for s, side in enumerate(SIDES):
            leg = exo.legs[side]
            l1, l2 = leg.thigh_length, leg.shank_length
            fid = exo.foot_frame_ids[s]
            jac = pin.computeFrameJacobian(model, data, qm, fid, LWA)
            v_foot = jac @ vm
            assert abs(v_foot[1]) < 1e-12  # sagittal motion only
            a_foot = pin.getFrameClassicalAcceleration(model, data, fid, LWA).linear
            p1, p2 = leg.joint_to_absolute(q[2 * s], q[2 * s + 1])
            d1, d2 = joint_rates(p1, p2, l1, l2, v_foot[0], v_foot[2])
            np.testing.assert_allclose(leg.rates_to_joint(d1, d2), dq[2 * s : 2 * s + 2], atol=1e-9)
            a1, a2 = joint_accelerations(p1, p2, d1, d2, l1, l2, a_foot[0], a_foot[2])
            np.testing.assert_allclose(
                leg.rates_to_joint(a1, a2), ddq[2 * s : 2 * s + 2], atol=1e-8
            )


def test_plan_joints_derivatives_match_finite_differences(exo: BodyModel) -> None:
    p = GaitParams()
    plan = GaitPlan(p)
    T, beta = p.period, p.duty_factor
    t_b = (1 - beta) * T / 2
    t_d = t_b + beta * T
    bounds = np.array([k * T / 2 + b for k in range(-1, 4) for b in (0.0, t_b, t_d)])
    h = 1e-5
    t = np.linspace(0.0, T, 600)
    t = t[np.min(np.abs(t[:, None] - bounds[None, :]), axis=1) > 10 * h]
    j = plan_joints(plan, exo, t)
    jp, jm = plan_joints(plan, exo, t + h), plan_joints(plan, exo, t - h)
    np.testing.assert_allclose(j.dq, (jp.q - jm.q) / (2 * h), atol=1e-6 * np.abs(j.dq).max())
    np.testing.assert_allclose(j.ddq, (jp.dq - jm.dq) / (2 * h), atol=1e-5 * np.abs(j.ddq).max())
    # and q really puts Pinocchio's feet on the planned path
    for i in range(0, t.size, 37):
        for s, side in enumerate(SIDES):
            pts = pin_points(exo, j.q[i], side)
            np.testing.assert_allclose(pts["foot"] - pts["hip"], j.foot_pos[i, s], atol=1e-9)
    assert np.all(j.q[:, [1, 3]] > 0)  # knees flexed all along


# --------------------------------------------------------------------------- other lengths


def test_other_lengths_change_the_kinematics(exo: BodyModel, short_exo: BodyModel) -> None:
    for side in SIDES:
        assert short_exo.legs[side].thigh_length == pytest.approx(SHORT_THIGH, abs=1e-12)
        assert short_exo.legs[side].shank_length == pytest.approx(SHORT_SHANK, abs=1e-12)
        assert exo.legs[side].thigh_length == pytest.approx(0.52, abs=1e-12)
    target = (0.12, -0.7)
    short_leg = short_exo.legs["left"]
    p1s, p2s = inverse_kinematics(*target, short_leg.thigh_length, short_leg.shank_length)
    np.testing.assert_allclose(pin_foot_in_hip(short_exo, "left", p1s, p2s), target, atol=1e-9)
    # the default leg's angles put the short leg's foot elsewhere
    p1d, p2d = inverse_kinematics(*target, 0.52, 0.52)
    qs = np.array(short_leg.absolute_to_joint(p1s, p2s))
    qd = np.array(exo.legs["left"].absolute_to_joint(p1d, p2d))
    assert np.max(np.abs(qs - qd)) > 0.05
    miss = pin_foot_in_hip(short_exo, "left", p1d, p2d) - np.array(target)
    assert np.linalg.norm(miss) > 0.05
    # same gait, different joint plan
    plan = GaitPlan(GaitParams(step_length=0.3, hip_height=0.75, lift_height=0.08))
    t = np.linspace(0, 1.2, 50)
    jd, js = plan_joints(plan, exo, t), plan_joints(plan, short_exo, t)
    np.testing.assert_allclose(jd.foot_pos, js.foot_pos)
    assert np.max(np.abs(jd.q - js.q)) > 0.05


# --------------------------------------------------------------------------- unreachable


def test_ik_refuses_a_point_beyond_reach() -> None:
    with pytest.raises(UnreachableFootTarget) as info:
        inverse_kinematics(0.3, -1.2, 0.52, 0.52)
    exc = info.value
    assert isinstance(exc, ValueError)
    assert isinstance(exc, ExoCtrlError)
    assert exc.point == (0.3, -1.2)
    assert exc.reach == pytest.approx((0.0, 1.04))
    # r = sqrt(0.09 + 1.44) = 1.23693
    assert str(exc) == (
        "foot target (x = 0.3 m, z = -1.2 m) is 1.237 m from the hip; "
        "the leg reaches from 0 m to 1.04 m"
    )


def test_ik_names_the_first_bad_point_of_an_array() -> None:
    x = np.array([0.0, 0.1, 0.02, 0.9])
    z = np.array([-0.8, -0.7, -0.03, -0.9])
    with pytest.raises(UnreachableFootTarget) as info:
        inverse_kinematics(x, z, SHORT_THIGH, SHORT_SHANK)  # too close: r < 0.05
    assert info.value.point == pytest.approx((0.02, -0.03))
    assert info.value.reach == pytest.approx((0.05, 0.85))
    assert "the leg reaches from 0.05 m to 0.85 m" in str(info.value)


def test_ik_refuses_the_hip_itself_and_nan() -> None:
    for point in ((0.0, 0.0), (math.nan, -0.5)):
        with pytest.raises(UnreachableFootTarget):
            inverse_kinematics(*point, 0.52, 0.52)


def test_plan_outside_the_range_of_motion_is_refused(exo: BodyModel) -> None:
    """A low hip brings the foot within 0.4 m of it at the top of the swing: the knee must
    flex by π - arccos((l1² + l2² - r²) / (2 l1 l2)) = 2.35 rad > the URDF's 2.09 rad."""
    p = GaitParams(hip_height=0.5, lift_height=0.1, step_length=0.2)
    r = p.hip_height - p.lift_height
    knee = math.pi - math.acos((2 * 0.52**2 - r**2) / (2 * 0.52**2))
    with pytest.raises(InvalidParameter) as info:
        plan_joints(GaitPlan(p), exo, np.linspace(0.0, p.period, 121))
    exc = info.value
    assert exc.name == "left_knee angle on the plan"
    assert exc.value == pytest.approx(knee, abs=1e-4)
    assert str(exc).startswith(
        "left_knee angle on the plan must be within the range of motion [-0.05, 2.09] rad of "
    )
    assert str(exc).endswith("(at t = 0 s)")  # the left foot is at the top of its swing at t = 0


# ------------------------------------------------------------------ memory cap (issue 19)


def test_plan_memory_per_sample_is_bounded_by_the_stated_figure(exo: BodyModel) -> None:
    """tracemalloc sees every numpy allocation: the peak of plan_joints per sample."""
    plan = GaitPlan(GaitParams())
    plan_joints(plan, exo, np.arange(10) * 1e-3)  # warm: nothing lazily allocated later
    n = 200_000
    t = np.arange(n) * 1e-3
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        joints = plan_joints(plan, exo, t)
        peak = tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()
    assert joints.q.shape == (n, 4)
    # the result alone holds 24 numbers a sample; the bound is within 25 % of the peak
    assert 24 * 8 * n < peak <= PLAN_BYTES_PER_SAMPLE * n < 1.25 * peak


def test_plan_beyond_the_memory_cap_is_refused_before_allocating(exo: BodyModel) -> None:
    n = MAX_ALLOCATION_BYTES // PLAN_BYTES_PER_SAMPLE + 1  # 2,684,355 samples
    t = np.broadcast_to(0.0, (n,))  # no memory behind it
    tracemalloc.start()
    try:
        with pytest.raises(InvalidParameter) as info:
            plan_joints(GaitPlan(GaitParams()), exo, t)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1_000_000
    assert str(info.value) == (
        "t must be shorter so that the plan samples fit in the 1 GiB memory cap "
        "(at most 2,684,354 of 400 B each); got (2684355,) "
        "(2,684,355 plan samples would need 1,073,742,000 B)"
    )
