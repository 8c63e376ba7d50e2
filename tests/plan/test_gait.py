"""Tests of exo_ctrl.plan.gait against the paper's §III planner, written out independently here."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from exo_ctrl.exceptions import ExoCtrlError, InvalidParameter, UnreachableFootTarget
from exo_ctrl.plan.gait import GaitParams, GaitPlan

#: (s, h_s, H_s, k_v, T_s): paper Fig. 3 (a) and (b), and the library's default.
VECTORS = {
    "fig3a": (0.2, 0.3, 0.7, 0.5, 4.0),
    "fig3b": (0.6, 0.1, 0.8, 0.25, 4.0),
    "default": (0.35, 0.10, 0.90, 0.5, 1.2),
}
CASES = [(name, beta) for name in VECTORS for beta in (0.5, 0.6)]
IDS = [f"{name}-beta{beta}" for name, beta in CASES]
EPS = 1e-9  # [s] offset either side of a phase boundary


def make(name: str, beta: float) -> GaitParams:
    s, h, H, kv, T = VECTORS[name]
    return GaitParams(
        step_length=s, lift_height=h, hip_height=H, shape_coeff=kv, period=T, duty_factor=beta
    )


def speeds(p: GaitParams) -> tuple[float, float]:
    """(v_f, v_b) from the definitions: the stance foot covers s in β T_s; v_b = v_f / k_v."""
    vf = p.step_length / (p.duty_factor * p.period)
    return vf, vf / p.shape_coeff


def phase_times(p: GaitParams) -> tuple[float, float]:
    """(t_B, t_D) in one cycle: A at 0, swing A→B takes half the swing time (1 - β) T_s / 2."""
    t_b = (1.0 - p.duty_factor) * p.period / 2.0
    return t_b, t_b + p.duty_factor * p.period


def at(plan: GaitPlan, t: float):
    """(pos, vel, acc) of both legs at one time, each (2 legs, 2 axes)."""
    f = plan.feet(np.array([t]))
    return f.pos[0], f.vel[0], f.acc[0]


def paper_cubic(t0: float, t1: float, q0: float, q1: float, dq0: float, dq1: float, t):
    """The paper's q(t0, t_last, q0, q_last, q̇0, q̇_last, t): solve its 4×4 system in absolute t."""
    m = np.array(
        [
            [1.0, t0, t0**2, t0**3],
            [1.0, t1, t1**2, t1**3],
            [0.0, 1.0, 2 * t0, 3 * t0**2],
            [0.0, 1.0, 2 * t1, 3 * t1**2],
        ]
    )
    k = np.linalg.solve(m, np.array([q0, q1, dq0, dq1]))
    t = np.asarray(t, dtype=float)
    return k[0] + k[1] * t + k[2] * t**2 + k[3] * t**3


def paper_feet(p: GaitParams, t: np.ndarray) -> np.ndarray:
    """Paper §III equations for β = 1/2, four equal intervals, in τ = mod(t, T_s).

    Returns positions (N, 2 legs, 2 axes).
    """
    s, h, H, T = p.step_length, p.lift_height, p.hip_height, p.period
    vf = 2.0 * s / T  # each foot is on the belt for two of the four intervals
    vb = vf / p.shape_coeff
    tA, tB, tC, tD = 0.0, T / 4, T / 2, 3 * T / 4
    tau = np.mod(t, T)
    out = np.empty((t.size, 2, 2))
    for i, u in enumerate(tau):
        if u < tB:
            lx = paper_cubic(tA, tB, 0.0, s / 2, vb, -vf, u)
            lz = paper_cubic(tA, tB, -(H - h), -H, 0.0, 0.0, u)
            rx, rz = -u * vf, -H
        elif u < tC:
            lx, lz = -u * vf + s, -H
            rx = paper_cubic(tB, tC, -s / 2, 0.0, -vf, vb, u)
            rz = paper_cubic(tB, tC, -H, -(H - h), 0.0, 0.0, u)
        elif u < tD:
            lx, lz = -u * vf + s, -H
            rx = paper_cubic(tC, tD, 0.0, s / 2, vb, -vf, u)
            rz = paper_cubic(tC, tD, -(H - h), -H, 0.0, 0.0, u)
        else:
            # the paper's "q(t_A, t_D, ...)" on [t_D, t_A) is the segment from t_D to T_s
            lx = paper_cubic(tD, T, -s / 2, 0.0, -vf, vb, u)
            lz = paper_cubic(tD, T, -H, -(H - h), 0.0, 0.0, u)
            rx, rz = -u * vf + 2 * s, -H
        out[i] = [[lx, lz], [rx, rz]]
    return out


# --------------------------------------------------------------------------- parameters


@pytest.mark.parametrize(("name", "beta"), CASES, ids=IDS)
def test_derived_speeds_and_times(name: str, beta: float) -> None:
    p = make(name, beta)
    vf, vb = speeds(p)
    assert p.belt_speed == pytest.approx(vf, rel=1e-14)
    assert p.swing_top_speed == pytest.approx(vb, rel=1e-14)
    assert p.stance_time + p.swing_time == pytest.approx(p.period, rel=1e-14)
    assert p.stance_time / p.period == pytest.approx(beta, rel=1e-14)
    # k_v = v_f / v_b (paper §III)
    assert p.belt_speed / p.swing_top_speed == pytest.approx(p.shape_coeff, rel=1e-14)
    if beta == 0.5:  # design.md: four equal phases give v_f = 2 s / T_s
        assert p.belt_speed == pytest.approx(2 * p.step_length / p.period, rel=1e-14)


# --------------------------------------------------------------------------- boundary conditions


@pytest.mark.parametrize(("name", "beta"), CASES, ids=IDS)
def test_boundary_conditions_at_A_B_D(name: str, beta: float) -> None:
    p = make(name, beta)
    plan = GaitPlan(p)
    s, h, H, T = p.step_length, p.lift_height, p.hip_height, p.period
    vf, vb = speeds(p)
    t_b, t_d = phase_times(p)
    expected = {
        "A": (0.0, [0.0, -(H - h)], [vb, 0.0]),
        "B": (t_b - EPS, [s / 2, -H], [-vf, 0.0]),  # end of the A→B swing
        "D": (t_d + EPS, [-s / 2, -H], [-vf, 0.0]),  # start of the D→A swing
    }
    for k in range(3):  # any cycle, and the right leg half a period later
        for point, (tau, pos, vel) in expected.items():
            for leg, shift in ((0, 0.0), (1, T / 2)):
                got_pos, got_vel, _ = at(plan, k * T + tau + shift)
                np.testing.assert_allclose(got_pos[leg], pos, atol=1e-7, err_msg=point)
                np.testing.assert_allclose(got_vel[leg], vel, atol=1e-6, err_msg=point)


@pytest.mark.parametrize(("name", "beta"), CASES, ids=IDS)
def test_positions_and_velocities_are_continuous_at_every_phase_boundary(
    name: str, beta: float
) -> None:
    p = make(name, beta)
    plan = GaitPlan(p)
    t_b, t_d = phase_times(p)
    T = p.period
    # left leg boundaries B, D, A(=T); the right leg has its boundaries at the same τ + T/2
    boundaries = [t_b, t_d, T, t_b + T / 2, t_d + T / 2, 1.5 * T, 2 * T + t_b]
    for tb in boundaries:
        p0, v0, _ = at(plan, tb - EPS)
        p1, v1, _ = at(plan, tb + EPS)
        np.testing.assert_allclose(p0, p1, atol=1e-6, err_msg=f"position at t = {tb}")
        np.testing.assert_allclose(v0, v1, atol=1e-6, err_msg=f"velocity at t = {tb}")


@pytest.mark.parametrize(("name", "beta"), CASES, ids=IDS)
def test_acceleration_jumps_at_touchdown_and_lift_off(name: str, beta: float) -> None:
    """Only C¹: the swing cubic arrives at B with a non-zero acceleration, stance has none."""
    p = make(name, beta)
    plan = GaitPlan(p)
    t_b, t_d = phase_times(p)
    for tb in (t_b, t_d):
        _, _, a_before = at(plan, tb - EPS)
        _, _, a_after = at(plan, tb + EPS)
        assert np.max(np.abs(a_before[0] - a_after[0])) > 1e-3


# --------------------------------------------------------------------------- cubic segments


@pytest.mark.parametrize(("name", "beta"), CASES, ids=IDS)
def test_swing_segments_match_the_papers_4x4_solve(name: str, beta: float) -> None:
    p = make(name, beta)
    plan = GaitPlan(p)
    s, h, H, T = p.step_length, p.lift_height, p.hip_height, p.period
    vf, vb = speeds(p)
    t_b, t_d = phase_times(p)
    cycle = 2 * T  # absolute times in the third cycle
    segments = {
        "A->B": (cycle, cycle + t_b, (0.0, s / 2, vb, -vf), (-(H - h), -H, 0.0, 0.0)),
        "D->A": (cycle + t_d, cycle + T, (-s / 2, 0.0, -vf, vb), (-H, -(H - h), 0.0, 0.0)),
    }
    for label, (t0, t1, xbc, zbc) in segments.items():
        t = np.linspace(t0, t1, 41)[1:-1]
        x = paper_cubic(t0, t1, *xbc, t)
        z = paper_cubic(t0, t1, *zbc, t)
        pos = plan.feet(t).pos[:, 0]
        np.testing.assert_allclose(pos[:, 0], x, atol=1e-8, err_msg=label)
        np.testing.assert_allclose(pos[:, 1], z, atol=1e-8, err_msg=label)


@pytest.mark.parametrize("name", list(VECTORS))
def test_both_legs_follow_the_papers_piecewise_equations(name: str) -> None:
    """β = 1/2 is the paper's schedule: compare both feet with its equations line by line."""
    p = make(name, 0.5)
    t = np.linspace(-p.period, 2 * p.period, 1201)
    np.testing.assert_allclose(GaitPlan(p).feet(t).pos, paper_feet(p, t), atol=1e-8)


# --------------------------------------------------------------------------- stance and timing


@pytest.mark.parametrize(("name", "beta"), CASES, ids=IDS)
def test_stance_foot_moves_with_the_belt_without_slip(name: str, beta: float) -> None:
    p = make(name, beta)
    vf, _ = speeds(p)
    n = 20000
    t = np.arange(n) * (p.period / n)
    f = GaitPlan(p).feet(t)
    st = f.stance
    assert st.any(axis=0).all()
    np.testing.assert_allclose(f.vel[..., 0][st], -p.belt_speed, rtol=1e-12)
    np.testing.assert_allclose(f.vel[..., 0][st], -vf, rtol=1e-12)
    np.testing.assert_allclose(f.vel[..., 1][st], 0.0, atol=0)
    np.testing.assert_allclose(f.pos[..., 1][st], -p.hip_height, atol=1e-15)
    np.testing.assert_allclose(f.acc[st], 0.0, atol=0)
    # the stance foot sweeps from +s/2 to -s/2
    x_st = f.pos[:, 0, 0][st[:, 0]]
    assert x_st.max() == pytest.approx(p.step_length / 2, abs=1e-12)
    assert x_st.min() == pytest.approx(-p.step_length / 2, abs=vf * p.period / n + 1e-12)
    # in swing the foot is off the belt (above -H) except at the touch-down/lift-off instants
    sw_z = f.pos[..., 1][~st]
    assert np.all(sw_z >= -p.hip_height - 1e-12)
    # stance fraction β, and β - (1 - β) = 2β - 1 of the time both feet are down
    frac = st.mean(axis=0)
    np.testing.assert_allclose(frac, beta, atol=2.0 / n)
    assert st.all(axis=1).mean() == pytest.approx(2 * beta - 1, abs=2.0 / n)
    assert st.any(axis=1).all()  # never both feet in the air


@pytest.mark.parametrize(("name", "beta"), CASES, ids=IDS)
def test_right_leg_is_left_leg_half_a_period_later_and_path_is_periodic(
    name: str, beta: float
) -> None:
    p = make(name, beta)
    plan = GaitPlan(p)
    T = p.period
    # sample times off the phase boundaries, where the acceleration jumps
    t = -T + (np.arange(997) + 0.37) * (3 * T / 997)
    f = plan.feet(t)
    shifted = plan.feet(t - T / 2)
    for attr in ("pos", "vel", "acc"):
        np.testing.assert_allclose(
            getattr(f, attr)[:, 1], getattr(shifted, attr)[:, 0], atol=1e-9, err_msg=attr
        )
    for k in (1, 3):
        later = plan.feet(t + k * T)
        for attr in ("pos", "vel", "acc"):
            np.testing.assert_allclose(getattr(later, attr), getattr(f, attr), atol=1e-9)
    # at t = 0 the left foot is at the top of its swing, the right one at mid-stance (x = 0)
    pos0, _, _ = at(plan, 0.0)
    np.testing.assert_allclose(pos0[0], [0.0, -(p.hip_height - p.lift_height)], atol=1e-15)
    assert pos0[1] == pytest.approx([0.0, -p.hip_height], abs=1e-12)


@pytest.mark.parametrize(("name", "beta"), CASES, ids=IDS)
def test_analytic_derivatives_match_central_differences(name: str, beta: float) -> None:
    p = make(name, beta)
    plan = GaitPlan(p)
    T = p.period
    t_b, t_d = phase_times(p)
    dt = 1e-5
    t = np.linspace(0.0, 2 * T, 1601)
    bounds = np.array(
        [k * T + b for k in range(-1, 4) for b in (0.0, t_b, t_d, T / 2, t_b + T / 2, t_d + T / 2)]
    )
    away = np.min(np.abs(t[:, None] - bounds[None, :]), axis=1) > 5 * dt
    t = t[away]
    f = plan.feet(t)
    fp, fm = plan.feet(t + dt), plan.feet(t - dt)
    scale_v = max(np.abs(f.vel).max(), 1.0)
    scale_a = max(np.abs(f.acc).max(), 1.0)
    np.testing.assert_allclose((fp.pos - fm.pos) / (2 * dt), f.vel, atol=1e-6 * scale_v)
    np.testing.assert_allclose((fp.vel - fm.vel) / (2 * dt), f.acc, atol=1e-6 * scale_a)


# --------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"step_length": math.nan}, "step_length must be a finite number [m]; got nan"),
        ({"period": -1.0}, "period must be > 0 s; got -1.0"),
        ({"period": 0.0}, "period must be > 0 s; got 0.0"),
        (
            {"lift_height": 0.9, "hip_height": 0.9},
            "lift_height must be < hip_height = 0.9 m; got 0.9 (the foot would rise to the hip)",
        ),
        (
            {"lift_height": 1.2, "hip_height": 0.9},
            "lift_height must be < hip_height = 0.9 m; got 1.2 (the foot would rise to the hip)",
        ),
        ({"duty_factor": 0.4}, "duty_factor must be in [0.5, 1); got 0.4"),
        ({"duty_factor": 1.0}, "duty_factor must be in [0.5, 1); got 1.0"),
        ({"duty_factor": math.nan}, "duty_factor must be a finite number; got nan"),
        ({"shape_coeff": 0.0}, "shape_coeff must be > 0; got 0.0"),
    ],
    ids=[
        "nan-step",
        "neg-period",
        "zero-period",
        "lift-eq-hip",
        "lift-gt-hip",
        "duty-low",
        "duty-one",
        "duty-nan",
        "kv-zero",
    ],
)
def test_bad_parameters_raise_with_exact_messages(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        GaitParams(**kwargs)
    assert str(info.value) == message
    assert isinstance(info.value, ValueError)
    assert isinstance(info.value, ExoCtrlError)
    name = next(iter(kwargs)) if "lift_height" not in kwargs else "lift_height"
    assert info.value.name == name


def test_duty_factor_interval_is_closed_at_one_half() -> None:
    assert GaitParams(duty_factor=0.5).duty_factor == 0.5
    assert GaitParams(duty_factor=0.999).stance_time == pytest.approx(0.999 * 1.2)


def test_unreachable_gait_names_the_point_and_the_reach() -> None:
    p = GaitParams(step_length=1.5)
    plan = GaitPlan(p)
    l1 = l2 = 0.52
    # largest hip-foot distance with the knee flexed by at least 0.1 rad (law of cosines)
    r_max = math.sqrt(l1**2 + l2**2 - 2 * l1 * l2 * math.cos(math.pi - 0.1))
    with pytest.raises(UnreachableFootTarget) as info:
        plan.check_reach(l1, l2)
    exc = info.value
    assert isinstance(exc, ValueError)
    assert isinstance(exc, ExoCtrlError)
    assert exc.reach == pytest.approx((0.0, r_max), abs=1e-12)
    assert f"the leg reaches from 0 m to {r_max:.4g} m" in str(exc)
    x, z = exc.point
    assert math.hypot(x, z) > r_max
    assert f"(x = {x:.4g} m, z = {z:.4g} m)" in str(exc)
    assert f"is {math.hypot(x, z):.4g} m from the hip" in str(exc)
    # the point is on the path at the reported time
    pos, _, _ = at(plan, exc.time)
    np.testing.assert_allclose(pos[0], exc.point, atol=1e-12)


def test_foot_too_close_to_the_hip_is_unreachable() -> None:
    plan = GaitPlan(GaitParams(hip_height=0.2, lift_height=0.05, step_length=0.1))
    with pytest.raises(UnreachableFootTarget) as info:
        plan.check_reach(0.52, 0.30)
    assert info.value.reach[0] == pytest.approx(0.22)
    assert math.hypot(*info.value.point) < 0.22
    assert "the leg reaches from 0.22 m to" in str(info.value)


def test_default_gait_is_reachable_by_the_paper_legs() -> None:
    GaitPlan(GaitParams()).check_reach(0.52, 0.52)  # must not raise
    f = GaitPlan(GaitParams()).feet(np.linspace(0, 1.2, 500))
    assert np.hypot(f.pos[..., 0], f.pos[..., 1]).max() < 1.04


def test_non_finite_time_is_refused() -> None:
    with pytest.raises(InvalidParameter):
        GaitPlan(GaitParams()).feet(np.array([0.0, math.nan]))


def test_validated_parameters_are_stored_as_floats() -> None:
    try:
        p = GaitParams(step_length="0.35")  # type: ignore[arg-type]
    except InvalidParameter:
        return  # refusing it is fine too
    assert isinstance(p.step_length, float)
    assert p.belt_speed == pytest.approx(0.35 / (0.5 * 1.2))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"step_length": "0.3"}, "step_length must be a finite number [m]; got '0.3'"),
        ({"period": True}, "period must be a finite number [s]; got True"),
    ],
)
def test_numbers_given_as_text_or_truth_values_are_refused(kwargs, message) -> None:
    with pytest.raises(InvalidParameter, match="^" + re.escape(message) + "$"):
        GaitParams(**kwargs)
