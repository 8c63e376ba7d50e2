"""The ramped start and stop (exo_ctrl.plan.ramp) and the plan's row rule (exo_ctrl.plan.rows).

"C2 through the ramp": the ramp factor is C², the ramped paths start at the
standing point at rest, their velocities and accelerations are the
derivatives of their positions (finite differences), they are continuous
across the ramp's end, and where the gait's own acceleration jumps (its cubic segments join at A, B
and D: the paper's paths are C¹) the ramped one jumps by no more.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import BodyModel
from exo_ctrl.plan import (
    NO_TAIL,
    GaitParams,
    GaitPlan,
    Ramp,
    RampedGait,
    layout,
    plan_joints,
    plan_row,
    smoothstep,
)
from exo_ctrl.sim import SimConfig, build

GAIT = GaitParams()
T_R = 1.2  # [s], one default period
T_O = 0.8  # [s]
END = 4.4  # [s]
RAMP = Ramp(T_R, T_O, END)


def test_smoothstep_values_and_derivatives() -> None:
    u = np.linspace(0.0, 1.0, 2001)
    s, ds, dds = smoothstep(u)
    assert s[0] == 0.0 and s[-1] == 1.0
    for d in (ds, dds):
        assert d[0] == 0.0 and d[-1] == 0.0
    assert np.all(np.diff(s) > 0.0)  # rises monotonically
    h = u[1] - u[0]
    np.testing.assert_allclose(np.gradient(s, h)[1:-1], ds[1:-1], atol=5e-6)
    np.testing.assert_allclose(np.gradient(ds, h)[1:-1], dds[1:-1], atol=5e-5)
    # Outside [0, 1] the step is flat: 0 before, 1 after.
    s, ds, dds = smoothstep(np.array([-0.5, 1.5]))
    assert s.tolist() == [0.0, 1.0] and ds.tolist() == [0.0, 0.0] and dds.tolist() == [0.0, 0.0]


def test_ramp_factor_is_c2_and_one_between_the_ramps() -> None:
    t = np.linspace(0.0, END, 44001)
    h = t[1] - t[0]
    s, ds, dds = RAMP.factor(t)
    np.testing.assert_allclose(np.gradient(s, h)[1:-1], ds[1:-1], atol=1e-5)
    # σ''' jumps at the ramps' ends: there the difference is O(h σ''') = O(1e-3).
    np.testing.assert_allclose(np.gradient(ds, h)[1:-1], dds[1:-1], atol=5e-3)
    between = (t >= T_R) & (t <= END - T_O)
    assert np.all(s[between] == 1.0) and np.all(ds[between] == 0.0) and np.all(dds[between] == 0)
    assert s[0] == ds[0] == dds[0] == 0.0
    assert s[-1] == ds[-1] == dds[-1] == 0.0
    # Analytic peak slope: S' peaks at 15/8 at u = 1/2.
    assert np.max(ds) == pytest.approx(15.0 / 8.0 / T_R, rel=1e-6)


def test_start_stands_at_rest_with_both_feet_on_the_belt_line() -> None:
    feet = RampedGait(GAIT, RAMP).feet(np.array([0.0, END]))
    for i in (0, 1):
        np.testing.assert_array_equal(feet.pos[i], [[0.0, -GAIT.hip_height]] * 2)
        np.testing.assert_array_equal(feet.vel[i], np.zeros((2, 2)))
        np.testing.assert_array_equal(feet.acc[i], np.zeros((2, 2)))
        assert feet.stance[i].all()


def test_ramped_path_derivatives_match_finite_differences() -> None:
    plan = RampedGait(GAIT, RAMP)
    h = 1e-6
    # Away from the segment joins A, B, D (where the gait's acceleration jumps).
    t = np.linspace(0.013, END - 0.011, 397)
    f0, fp, fm = plan.feet(t), plan.feet(t + h), plan.feet(t - h)
    np.testing.assert_allclose((fp.pos - fm.pos) / (2 * h), f0.vel, atol=1e-6)
    np.testing.assert_allclose((fp.vel - fm.vel) / (2 * h), f0.acc, atol=2e-4)


def test_stance_feet_stay_on_the_belt_line_and_the_lift_grows_with_sigma() -> None:
    plan = RampedGait(GAIT, RAMP)
    base = GaitPlan(GAIT)
    t = np.linspace(0.0, T_R, 12001)
    feet, nominal = plan.feet(t), base.feet(t)
    sigma = RAMP.factor(t)[0]
    z0 = -GAIT.hip_height
    on_belt = nominal.stance
    np.testing.assert_array_equal(feet.pos[:, :, 1][on_belt], z0)
    # Every point is p0 + σ (p - p0): the lift above the belt is σ times the gait's.
    np.testing.assert_allclose(
        feet.pos[:, :, 1] - z0, sigma[:, None] * (nominal.pos[:, :, 1] - z0), atol=1e-15
    )
    np.testing.assert_allclose(feet.pos[:, :, 0], sigma[:, None] * nominal.pos[:, :, 0])
    # The right foot is at the top of its swing (A) at t = T_s / 2: σ h_s = h_s / 2 above the belt.
    top = plan.feet(np.array([GAIT.period / 2]))
    assert top.pos[0, 1, 1] - z0 == pytest.approx(0.5 * GAIT.lift_height, abs=1e-15)


def test_after_the_ramp_in_the_path_is_the_gait_bit_for_bit() -> None:
    t = np.arange(1200, 3500) * 1e-3
    ramped, nominal = RampedGait(GAIT, RAMP).feet(t), GaitPlan(GAIT).feet(t)
    for name in ("pos", "vel", "acc", "stance"):
        np.testing.assert_array_equal(getattr(ramped, name), getattr(nominal, name))


def _largest_jumps(t: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Largest change between neighbouring samples, per column."""
    return np.max(np.abs(np.diff(values, axis=0)), axis=0)


def test_ramp_adds_no_discontinuity_of_its_own(exo: BodyModel) -> None:
    """Position, velocity and acceleration across t = T_r, and the jumps at B and D."""
    plan = RampedGait(GAIT, RAMP)
    eps = 1e-9
    before, after = plan.feet(np.array([T_R - eps])), plan.feet(np.array([T_R + eps]))
    for name in ("pos", "vel", "acc"):
        np.testing.assert_allclose(getattr(before, name), getattr(after, name), atol=1e-6)
    # Dense sampling: the ramped acceleration changes between samples no more than
    # the nominal gait's (whose jumps at B and D are the largest changes).
    t = np.linspace(0.0, T_R, 240_001)
    ramped, nominal = plan.feet(t), GaitPlan(GAIT).feet(t)
    jump_r = _largest_jumps(t, ramped.acc.reshape(t.size, 4))
    jump_n = _largest_jumps(t, nominal.acc.reshape(t.size, 4))
    assert np.all(jump_r <= jump_n + 1e-3)
    assert np.max(_largest_jumps(t, ramped.vel.reshape(t.size, 4))) < 1e-3  # continuous
    # The joint plan too: q̇ and q̈ at t = 0 zero, q̈ jumps no larger than the gait's.
    jr = plan_joints(plan, exo, t[::10])
    jn = plan_joints(GaitPlan(GAIT), exo, t[::10])
    np.testing.assert_allclose(jr.dq[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(jr.ddq[0], 0.0, atol=1e-12)
    assert np.all(_largest_jumps(t, jr.ddq) <= _largest_jumps(t, jn.ddq) + 1e-2)
    h = t[10] - t[0]
    tj = t[::10]
    # The gait's segments join (A, B, D of either leg) at multiples of 0.3 s.
    smooth = np.abs(tj - 0.3 * np.round(tj / 0.3)) > 2 * h
    smooth[[0, -1]] = False
    np.testing.assert_allclose(np.gradient(jr.q, h, axis=0)[smooth], jr.dq[smooth], atol=1e-6)
    np.testing.assert_allclose(np.gradient(jr.dq, h, axis=0)[smooth], jr.ddq[smooth], atol=1e-4)


def test_belt_speed_rises_with_sigma() -> None:
    plan = RampedGait(GAIT, RAMP)
    t = np.array([0.0, 0.3, 0.6, T_R, 2.0, END - 0.4, END])
    np.testing.assert_allclose(plan.belt_speed_at(t), RAMP.factor(t)[0] * GAIT.belt_speed)
    assert plan.belt_speed_at(2.0)[0] == GAIT.belt_speed


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"ramp_in_s": -0.1}, "ramp_in must be >= 0 s; got -0.1"),
        ({"ramp_out_s": float("nan")}, "ramp_out must be a finite number [s]; got nan"),
        (
            {"ramp_in_s": 1.5, "ramp_out_s": 1.0, "end_s": 2.0},
            "ramp_in must be at most 1 s, within the run; got 1.5 "
            "(the run lasts 2 s, of which the ramp-out takes the last 1 s)",
        ),
        (
            {"ramp_out_s": 2.5, "end_s": 2.0},
            "ramp_out must be at most 2 s, within the run; got 2.5 (the run lasts 2 s)",
        ),
    ],
)
def test_ramp_refuses_bad_times(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        Ramp(**kwargs)
    assert str(info.value) == message


def test_a_plan_may_end_within_its_ramp_in() -> None:
    ramp = Ramp(3.0, 0.0, 2.0)
    assert ramp.factor(2.0)[0] == pytest.approx(smoothstep(2.0 / 3.0)[0])
    # The run's default ramp-in is one period, also in a shorter run (which ends in it).
    assert SimConfig(duration_s=0.5).ramp == Ramp(1.2, 0.0, 0.5)


# --------------------------------------------------------------------------- the row rule


def test_row_rule_holds_the_ramps_and_one_period() -> None:
    lay = layout(5000, 1e-3, 1.2, ramp_in_s=1.2, ramp_out_s=0.8)
    assert (lay.lead, lay.period, lay.tail) == (1200, 1200, 4201)
    assert lay.rows == 1200 + 1200 + 800  # ticks 4201..5000
    expected = [
        *range(1200),
        *(1200 + (k - 1200) % 1200 for k in range(1200, 4201)),
        *(2400 + k - 4201 for k in range(4201, 5001)),
    ]
    assert [plan_row(k, lay.lead, lay.period, lay.tail) for k in range(5001)] == expected
    ticks = lay.ticks()
    assert [lay.row(k) for k in ticks] == list(range(lay.rows))  # each row serves its own tick
    # Without a ramp: today's k mod P.
    plain = layout(5000, 1e-3, 1.2)
    assert (plain.rows, plain.lead, plain.tail) == (1200, 0, NO_TAIL)
    assert [plain.row(k) for k in range(0, 5000, 7)] == [k % 1200 for k in range(0, 5000, 7)]
    # A run too short for the compact form holds every tick; so does a period of no whole tick.
    assert layout(2399, 1e-3, 1.2, ramp_in_s=1.2).period == 0
    assert layout(50_000, 1e-3, 1.2003).rows == 50_001


@pytest.mark.parametrize(
    "kwargs",
    [
        {"duration_s": 5.0, "ramp_out_s": 0.8},
        {"duration_s": 4.0, "ramp_in_s": 0.65, "ramp_out_s": 0.35, "control_rate_hz": 800.0},
        {"duration_s": 3.6, "ramp_in_s": 0.0, "ramp_out_s": 1.0},
    ],
)
def test_compact_plan_gives_every_tick_the_targets_of_the_full_plan(
    exo: BodyModel, kwargs: dict
) -> None:
    """Through the plan's rule each tick reads what a plan of every tick holds for it."""
    config = SimConfig(**kwargs)
    plan = build(config).plan
    assert plan.period_ticks and plan.q.shape[0] == config.plan_rows < config.n_ticks
    ticks = np.arange(config.n_ticks + 1)
    full = plan_joints(RampedGait(config.gait, config.ramp), exo, ticks * config.dt)
    rows = plan.rows(0, ticks.size)
    np.testing.assert_allclose(plan.q[rows], full.q, atol=1e-12, rtol=0)
    np.testing.assert_allclose(plan.dq[rows], full.dq, atol=1e-10, rtol=0)
    np.testing.assert_allclose(plan.ddq[rows], full.ddq, atol=1e-8, rtol=0)
    # It ends standing at rest, and starts so after a ramp-in.
    for k in (0, config.n_ticks) if config.ramp_in > 0 else (config.n_ticks,):
        np.testing.assert_allclose(full.dq[k], 0.0, atol=1e-12)
