"""The hip's rise and fall over the cycle (GaitParams.pelvis_excursion), in every planner.

ΔH(φ) = (e/2) cos(4π φ), φ = t / T_s; each foot's path relative to the hip is
the fixed-hip path with z - ΔH, so relative to the belt it is unchanged.
Checked: e = 0 is the fixed-hip plan bit for bit; with e > 0 the path relative
to the belt equals the fixed-hip one, the hip's extremes sit at the
mid-stances and the transfers, rates are the derivatives of positions, the
paths stay C¹; the mid-stance knee extends by what the law of cosines
predicts; the online generator and the ramps plan the same hip; too large an
excursion is refused naming the largest the leg reaches.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from exo_ctrl.exceptions import ExoCtrlError, InvalidParameter
from exo_ctrl.model import load_exo
from exo_ctrl.plan import (
    GaitParams,
    GaitPlan,
    OnlineGait,
    Ramp,
    RampedGait,
    SpeedAdaptation,
    max_step_length,
    plan_joints,
)
from exo_ctrl.plan.gait import MIN_KNEE_FLEXION_RAD

DT = 1e-3
#: The pair the report proposes for a supported pelvis: H_s 1.0 m, e 5 cm.
H_S, E = 1.0, 0.05


@pytest.fixture(scope="module")
def exo():
    return load_exo(None)


def fixed_hip_feet(plan: GaitPlan, t: np.ndarray) -> tuple[np.ndarray, ...]:
    """Both feet as the planner made them before the excursion: its per-leg paths only."""
    n = t.shape[0]
    out = [np.empty((n, 2, 2)) for _ in range(3)]
    for leg, offset in enumerate((0.0, 0.5 * plan.params.period)):
        pos, vel, acc, _ = plan._leg(np.mod(t + offset, plan.params.period))
        for arr, part in zip(out, (pos, vel, acc), strict=True):
            arr[:, leg] = part
    return tuple(out)


def knee_flexion_deg(r: np.ndarray | float, l1: float = 0.52, l2: float = 0.52) -> np.ndarray:
    """π - γ, γ the knee's inner angle by the law of cosines for a hip-to-foot distance r [m]."""
    return np.degrees(np.pi - np.arccos((l1 * l1 + l2 * l2 - np.square(r)) / (2 * l1 * l2)))


# ------------------------------------------------------------------------------ e = 0


def test_zero_excursion_is_the_fixed_hip_plan_bit_for_bit(exo) -> None:
    t = np.arange(2401) * DT
    for params in (GaitParams(), GaitParams(duty_factor=0.6, step_length=0.3)):
        plan = GaitPlan(params)
        feet = plan.feet(t)
        for got, old in zip((feet.pos, feet.vel, feet.acc), fixed_hip_feet(plan, t), strict=True):
            assert np.array_equal(got, old)
        assert np.array_equal(plan.hip(t), np.zeros((3, t.size)))
    assert GaitParams(pelvis_excursion=0.0) == GaitParams()
    joints = plan_joints(RampedGait(GaitParams(), Ramp(1.2)), exo, t)
    assert joints.hip is None  # nothing new in a fixed-hip plan
    gen = OnlineGait(SpeedAdaptation(GaitParams()), None, exo, DT)
    assert gen.plan.hip is None and gen.hip() == (0.0, 0.0, 0.0)


# ------------------------------------------------------------------------------ e > 0


@pytest.mark.parametrize("beta", [0.5, 0.6])
def test_the_path_relative_to_the_belt_is_the_fixed_hip_path(beta: float) -> None:
    base = GaitParams(hip_height=H_S, duty_factor=beta)
    moving = GaitPlan(dataclasses.replace(base, pelvis_excursion=E))
    t = np.linspace(-1.3, 3.7, 5001)
    feet, old = moving.feet(t), GaitPlan(base).feet(t)
    hip = moving.hip(t)
    for got, ref, d in zip(
        (feet.pos, feet.vel, feet.acc), (old.pos, old.vel, old.acc), hip, strict=True
    ):
        assert np.array_equal(got[:, :, 0], ref[:, :, 0])  # x untouched
        np.testing.assert_allclose(got[:, :, 1] + d[:, None], ref[:, :, 1], rtol=0, atol=1e-12)
    assert np.array_equal(feet.stance, old.stance)
    # a stance foot is on the belt line, H(t) = H_s + ΔH below the hip
    st = feet.stance
    np.testing.assert_allclose(
        feet.pos[:, :, 1][st], -(H_S + np.broadcast_to(hip[0][:, None], st.shape)[st]), atol=1e-12
    )


@pytest.mark.parametrize("beta", [0.5, 0.6])
def test_hip_is_highest_at_both_mid_stances_and_lowest_at_the_transfers(beta: float) -> None:
    params = GaitParams(hip_height=H_S, pelvis_excursion=E, duty_factor=beta)
    plan = GaitPlan(params)
    T = params.period
    h, dh, _ = plan.hip(np.array([0.0, 0.25, 0.5, 0.75]) * T)
    np.testing.assert_allclose(h, [E / 2, -E / 2, E / 2, -E / 2], rtol=0, atol=1e-15)
    np.testing.assert_allclose(dh, 0.0, atol=1e-15)
    # mid-stance: each foot straight below the hip (x = 0) when the hip is highest
    feet = plan.feet(np.array([0.5 * T, 0.0]))  # left's mid-stance, right's
    np.testing.assert_allclose(feet.pos[0, 0], [0.0, -(H_S + E / 2)], atol=1e-12)
    np.testing.assert_allclose(feet.pos[1, 1], [0.0, -(H_S + E / 2)], atol=1e-12)
    assert feet.stance[0, 0] and feet.stance[1, 1]
    # the transfers: the middle of the double support (the touchdown itself at β = 0.5)
    touchdown = 0.5 * params.swing_time  # left foot at B
    lift_off = 0.5 * T - 0.5 * params.swing_time  # right foot at D
    assert 0.5 * (touchdown + lift_off) == pytest.approx(0.25 * T, abs=1e-15)
    # peak to peak e, mean H_s
    t = np.linspace(0.0, T, 4096, endpoint=False)
    h = plan.hip(t)[0]
    assert h.max() - h.min() == pytest.approx(E, abs=1e-15)
    assert h.mean() == pytest.approx(0.0, abs=1e-16)


def test_rates_are_the_derivatives_of_the_positions() -> None:
    plan = GaitPlan(GaitParams(hip_height=H_S, pelvis_excursion=E, duty_factor=0.6))
    p = plan.params
    edges = np.array([0.0, 0.5 * p.swing_time, 0.5 * p.swing_time + p.stance_time])  # A, B, D
    t = np.linspace(0.0, 2.4, 1201)
    # away from the segment joins of either leg (the accelerations jump there)
    joins = np.concatenate([np.mod(edges + o, p.period) for o in (0.0, 0.5 * p.period)])
    joins = np.concatenate((joins, joins + p.period, [2 * p.period]))
    t = t[np.min(np.abs(t[:, None] - joins[None, :]), axis=1) > 1e-3]
    h = 1e-6
    up, down, mid = plan.feet(t + h), plan.feet(t - h), plan.feet(t)
    np.testing.assert_allclose((up.pos - down.pos) / (2 * h), mid.vel, rtol=0, atol=1e-7)
    np.testing.assert_allclose((up.vel - down.vel) / (2 * h), mid.acc, rtol=0, atol=2e-5)
    hu, hd, hm = plan.hip(t + h), plan.hip(t - h), plan.hip(t)
    np.testing.assert_allclose((hu[0] - hd[0]) / (2 * h), hm[1], rtol=0, atol=1e-9)
    np.testing.assert_allclose((hu[1] - hd[1]) / (2 * h), hm[2], rtol=0, atol=1e-7)


def test_feet_are_c1_at_the_phase_boundaries() -> None:
    for beta in (0.5, 0.6):
        plan = GaitPlan(GaitParams(hip_height=H_S, pelvis_excursion=E, duty_factor=beta))
        p = plan.params
        # A, B, D of the left foot (the right foot's are half a period on), and the cycle's end
        bounds = np.array([0.0, 0.5 * p.swing_time, 0.5 * p.swing_time + p.stance_time, p.period])
        bounds = np.concatenate((bounds, bounds + 0.5 * p.period))
        h = 1e-9
        before, after = plan.feet(bounds - h), plan.feet(bounds + h)
        # a jump would stay O(1); continuity leaves O(h × rate)
        assert np.abs(after.pos - before.pos).max() < 10 * h
        assert np.abs(after.vel - before.vel).max() < 1e-6
        # the accelerations jump only in x and z of the paths (B, D), never by ΔH
        old = GaitPlan(dataclasses.replace(p, pelvis_excursion=0.0))
        jump = after.acc - before.acc
        old_jump = old.feet(bounds + h).acc - old.feet(bounds - h).acc
        np.testing.assert_allclose(jump, old_jump, rtol=0, atol=1e-5)


# ------------------------------------------------------------------------------ the knee


def test_the_excursion_extends_the_mid_stance_knee_by_the_law_of_cosines(exo) -> None:
    leg = exo.legs["left"]
    l1, l2 = leg.thigh_length, leg.shank_length
    lines = []
    cases = [(0.90, 0.0), (0.90, 0.04), (0.98, 0.0), (0.98, 0.04), (H_S, 0.0), (H_S, E)]
    mid_stance = {}
    for hs, e in cases:
        params = GaitParams(hip_height=hs, pelvis_excursion=e)
        t = np.arange(round(params.period / DT)) * DT
        joints = plan_joints(GaitPlan(params), exo, t)  # the reach check passes
        flexion = np.degrees(joints.phi[:, 0] - joints.phi[:, 1])
        stance = GaitPlan(params).feet(t).stance[:, 0]
        i_mid = round(0.5 * params.period / DT)  # left foot at x = 0
        mid_stance[hs, e] = flexion[i_mid]
        # the law of cosines with the leg as long as the hip is high, r = H_s + e/2
        assert flexion[i_mid] == pytest.approx(knee_flexion_deg(hs + e / 2, l1, l2), abs=1e-9)
        lines.append(
            f"H_s {hs:.2f} m, e {e:.2f} m: stance knee flexion {flexion[stance].min():.1f}-"
            f"{flexion[stance].max():.1f} deg (mid-stance {flexion[i_mid]:.1f}), whole cycle "
            f"{flexion.min():.1f}-{flexion.max():.1f} deg"
        )
        if e > 0.0:  # with the hip highest there, mid-stance is the straightest point of stance
            assert np.argmin(np.where(stance, flexion, np.inf)) == i_mid
    print("\n" + "\n".join(lines))
    for hs, e in cases:
        if e > 0.0:
            lowered = mid_stance[hs, 0.0] - mid_stance[hs, e]
            predicted = knee_flexion_deg(hs, l1, l2) - knee_flexion_deg(hs + e / 2, l1, l2)
            assert lowered == pytest.approx(predicted, abs=1e-9)
            assert lowered > 0.0
    # the proposed pair extends the knee to 10-20 deg at mid-stance
    assert 10.0 <= mid_stance[H_S, E] <= 20.0


def test_the_longest_step_search_includes_the_excursion(exo) -> None:
    """The hip is lowest at the transfers, where the step's ends are: a longer step fits."""
    base = GaitParams(hip_height=H_S)
    moving = dataclasses.replace(base, pelvis_excursion=E)
    s_fixed, s_moving = max_step_length(base, exo), max_step_length(moving, exo)
    print(f"\nlongest step at H_s {H_S} m: {s_fixed:.4f} m fixed hip, {s_moving:.4f} m, e {E} m")
    assert s_moving > s_fixed + 0.05
    t = np.linspace(0.0, base.period, 512, endpoint=False)
    plan_joints(GaitPlan(dataclasses.replace(moving, step_length=s_moving)), exo, t)
    with pytest.raises(ExoCtrlError, match=r"reaches|range of motion"):
        plan_joints(GaitPlan(dataclasses.replace(base, step_length=s_moving)), exo, t)


# ------------------------------------------------------------------------------ online, ramps


def run_online(gen: OnlineGait, n: int, speeds) -> dict[str, np.ndarray]:
    out = {k: [] for k in ("q", "dq", "pos", "vel", "hip")}
    for k in range(n):
        gen.step(k, float(speeds(k)))
        p = gen.plan
        for name, arr in zip(out, (p.q, p.dq, p.foot_pos, p.foot_vel), strict=False):
            out[name].append(arr[0].copy())
        out["hip"].append(np.array(gen.hip()))
    return {k: np.array(v) for k, v in out.items()}


def test_online_at_a_steady_speed_is_the_offline_plan(exo) -> None:
    gait = GaitParams(hip_height=H_S, pelvis_excursion=E)
    gen = OnlineGait(SpeedAdaptation(gait), None, exo, DT)
    n = 3000
    got = run_online(gen, n, lambda k: gait.belt_speed)
    t = np.arange(n) * DT
    ref = plan_joints(GaitPlan(gait), exo, t)
    np.testing.assert_allclose(got["pos"], ref.foot_pos, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got["vel"], ref.foot_vel, rtol=0, atol=1e-11)
    np.testing.assert_allclose(got["q"], ref.q, rtol=0, atol=1e-11)
    np.testing.assert_allclose(got["dq"], ref.dq, rtol=0, atol=1e-10)
    np.testing.assert_allclose(got["hip"], ref.hip, rtol=0, atol=1e-11)
    assert gen.plan.hip is not None and np.array_equal(gen.plan.hip[0], got["hip"][-1])


def test_ramps_start_at_rest_with_the_hip_at_its_mean_height(exo) -> None:
    gait = GaitParams(hip_height=H_S, pelvis_excursion=E)
    t_r = 1.2
    ramped = RampedGait(gait, Ramp(t_r, 0.8, 4.4))
    t = np.arange(4401) * DT
    hip = ramped.hip(t)
    feet = ramped.feet(t)
    for i in (0, -1):  # standing, at rest, at both ends
        assert [h[i] for h in hip] == [0.0, 0.0, 0.0]
        np.testing.assert_array_equal(feet.pos[i], [[0.0, -H_S]] * 2)
        np.testing.assert_array_equal(feet.vel[i], np.zeros((2, 2)))
        np.testing.assert_array_equal(feet.acc[i], np.zeros((2, 2)))
    # σ ΔH: its rates are its derivatives (C² ramp), and after the ramp-in it is ΔH
    h = 1e-6
    tt = t[10:-10:7]
    up, down, mid = ramped.hip(tt + h), ramped.hip(tt - h), ramped.hip(tt)
    np.testing.assert_allclose((up[0] - down[0]) / (2 * h), mid[1], rtol=0, atol=1e-9)
    np.testing.assert_allclose((up[1] - down[1]) / (2 * h), mid[2], rtol=0, atol=1e-6)
    steady = (t >= t_r) & (t <= 3.6)
    assert np.array_equal(hip[0][steady], GaitPlan(gait).hip(t[steady])[0])
    # a stance foot stays on the belt line during the ramps, flagged as stance
    below = -(feet.pos[:, :, 1] + hip[0][:, None])  # the foot's depth below the hip's mean height
    np.testing.assert_allclose(below[feet.stance], H_S, rtol=0, atol=1e-12)
    # the online generator's ramp: the same hip and the same heights (its x differs: the
    # belt ramps in with it), at rest at t = 0
    gen = OnlineGait(SpeedAdaptation(gait), None, exo, DT, ramp_in_s=t_r)
    assert gen.hip() == (0.0, 0.0, 0.0)
    np.testing.assert_array_equal(gen.plan.foot_pos[0, :, 1], [-H_S, -H_S])
    np.testing.assert_array_equal(gen.plan.foot_vel[0], np.zeros((2, 2)))
    n = 2400
    got = run_online(gen, n, lambda k: gen.belt_speed(k * DT)[0])
    in_ramp = RampedGait(gait, Ramp(t_r))
    ref_feet, ref_hip = in_ramp.feet(t[:n]), np.column_stack(in_ramp.hip(t[:n]))
    np.testing.assert_allclose(got["hip"], ref_hip, rtol=0, atol=1e-11)
    np.testing.assert_allclose(got["pos"][:, :, 1], ref_feet.pos[:, :, 1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(got["vel"][:, :, 1], ref_feet.vel[:, :, 1], rtol=0, atol=1e-11)


# ------------------------------------------------------------------------------ bad values


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (float("nan"), "pelvis_excursion must be a finite number [m]; got nan"),
        (-0.01, "pelvis_excursion must be >= 0 m; got -0.01"),
        ("0.04", "pelvis_excursion must be a finite number [m]; got '0.04'"),
        (
            1.6,
            "pelvis_excursion must be < 2 (hip_height - lift_height) = 1.6 m; got 1.6 (the lifted "
            "swing foot would rise to the hip when the hip is at its lowest, H_s - e/2)",
        ),
    ],
)
def test_bad_values_are_refused(value, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        GaitParams(pelvis_excursion=value)
    assert str(info.value) == message


def test_an_excursion_the_leg_cannot_reach_names_the_largest_it_can(exo) -> None:
    leg = exo.legs["left"]
    l1, l2 = leg.thigh_length, leg.shank_length
    r_max = math.sqrt(l1**2 + l2**2 + 2 * l1 * l2 * math.cos(MIN_KNEE_FLEXION_RAD))
    # the binding point: the foot at mid-stance, straight below the hip at its highest
    e_max = 2.0 * (r_max - H_S)
    params = GaitParams(hip_height=H_S, pelvis_excursion=0.1)
    with pytest.raises(InvalidParameter) as info:
        GaitPlan(params).check_reach(l1, l2)
    assert str(info.value) == (
        f"pelvis_excursion must be at most {math.floor(e_max * 1e4) / 1e4:g} m for this gait and a "
        f"0.52 m + 0.52 m leg; got 0.1 (left foot path point (x = -2.776e-17 m, z = -1.05 m) "
        f"at t = 0.6 s is 1.05 m from the hip; the leg reaches from 0 m to {r_max:.4g} m "
        f"(set by step_length = 0.35 m, hip_height = {H_S:g} m, lift_height = 0.1 m, "
        "pelvis_excursion = 0.1 m, shape_coeff = 0.5))"
    )
    GaitPlan(dataclasses.replace(params, pelvis_excursion=e_max - 1e-6)).check_reach(l1, l2)
    # a path out of reach with the hip fixed is the path's fault: the old error
    with pytest.raises(ExoCtrlError, match=r"^left foot path point") as info:
        GaitPlan(GaitParams(step_length=1.5, pelvis_excursion=0.01)).check_reach(l1, l2)
    assert not isinstance(info.value, InvalidParameter)
