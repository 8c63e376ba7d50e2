"""The loading phase (exo_ctrl/plan/loading.py): the stance feet planned into the belt.

The sinks the plan gives must carry, through the contact law F = k δⁿ, exactly the
load W(t) = W₀ + M ΔḦ(t) at every instant, reach the belt's surface at touchdown and
lift-off with zero speed, have the rates of their positions, leave the paper's schedule
(β = ½) alone, and be planned the same online; and on the treadmill with 50 % support,
computed torque must then land the feet softly where the belt-line plan slammed them.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from exo_ctrl import SimConfig, simulate
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import load_exo
from exo_ctrl.plan import GaitParams, GaitPlan, OnlineGait, SpeedAdaptation, StanceSink, plan_joints
from exo_ctrl.plant import ContactParams, PelvisParams
from exo_ctrl.sim import setup as sim_setup

DT = 1e-3
K, N = 5.0e5, 1.5  # the contact law's defaults
M, FS = 97.0, 0.5 * 80.0 * 9.81  # the default moving mass and a 50 % support [kg, N]
W0 = M * 9.81 - FS
SINK = StanceSink(W0, M, K, N)
GAIT = GaitParams(hip_height=1.0, pelvis_excursion=0.05, duty_factor=0.6)


@pytest.fixture(scope="module")
def exo():
    return load_exo(None)


def test_the_sinks_carry_the_planned_load_at_every_instant() -> None:
    plan = GaitPlan(GAIT, SINK)
    t = np.linspace(0.0, 2 * GAIT.period, 4801)
    left, right = plan.sinks(t)
    s0 = (0.5 * W0 / K) ** (1 / N)
    assert SINK.standing_sink_m == pytest.approx(s0, rel=1e-15)
    carried = K * (left[:, 0] + s0) ** N + K * (right[:, 0] + s0) ** N
    load = W0 + M * plan.hip(t)[2]  # the hip's planned vertical acceleration's share
    np.testing.assert_allclose(carried, load, rtol=1e-12)
    # the swing foot (no load) stands s₀ above the sunk line, planned relative to the hip
    p = GAIT
    tau = np.mod(t, p.period) / p.period
    swing = (tau < 0.5 * (1 - p.duty_factor)) | (tau >= 0.5 * (1 + p.duty_factor))
    np.testing.assert_array_equal(left[swing, 0], -s0)


def test_touchdown_and_lift_off_meet_the_belt_surface_at_rest() -> None:
    plan = GaitPlan(GAIT, SINK)
    p = GAIT
    touchdown = 0.5 * p.swing_time
    lift_off = touchdown + p.stance_time
    s0 = SINK.standing_sink_m
    for edge in (touchdown, lift_off):
        for t in (edge - 1e-9, edge + 1e-9):
            row = plan.sinks(np.array([t]))[0][0]
            assert row[0] + s0 == pytest.approx(0.0, abs=1e-9)  # on the surface
            assert abs(row[1]) < 1e-6  # at rest relative to it [m/s]
    # the landing foot's loading sink grows as x² (w ≈ 10 x³, n = 1.5): finite acceleration
    d = (p.duty_factor - 0.5) * p.period
    u = np.array([1e-4, 1e-3]) * d
    rows = plan.sinks(touchdown + u)[0]
    ratio = (rows[1, 0] + s0) / (rows[0, 0] + s0)
    assert ratio == pytest.approx(100.0, rel=0.02)
    assert np.all(np.abs(rows[:, 2]) < 20.0)  # [m/s²]


def test_rates_are_the_derivatives_of_the_positions() -> None:
    plan = GaitPlan(GAIT, SINK)
    p = GAIT
    edges = np.array([0.0, 0.5 * p.swing_time, 0.5 * p.swing_time + p.stance_time])
    d = (p.duty_factor - 0.5) * p.period  # the double supports' ends join too
    edges = np.concatenate((edges, edges[1:2] + d, edges[2:3] - d))
    joins = np.concatenate([np.mod(edges + o, p.period) for o in (0.0, 0.5 * p.period)])
    joins = np.concatenate((joins, joins + p.period, [2 * p.period]))
    t = np.linspace(0.0, 2.4, 1201)
    t = t[np.min(np.abs(t[:, None] - joins[None, :]), axis=1) > 1e-3]
    h = 1e-6
    up, down, mid = plan.feet(t + h), plan.feet(t - h), plan.feet(t)
    np.testing.assert_allclose((up.pos - down.pos) / (2 * h), mid.vel, rtol=0, atol=1e-7)
    np.testing.assert_allclose((up.vel - down.vel) / (2 * h), mid.acc, rtol=0, atol=5e-5)


def test_the_papers_schedule_and_a_missing_sink_leave_the_plan_alone() -> None:
    t = np.linspace(0.0, 2.4, 2401)
    for params in (dataclasses.replace(GAIT, duty_factor=0.5), GAIT):
        sink = SINK if params.duty_factor == 0.5 else None
        a, b = GaitPlan(params, sink).feet(t), GaitPlan(params).feet(t)
        for x, y in ((a.pos, b.pos), (a.vel, b.vel), (a.acc, b.acc)):
            assert np.array_equal(x, y)


def test_online_at_a_steady_speed_is_the_offline_plan(exo) -> None:
    gen = OnlineGait(SpeedAdaptation(GAIT), None, exo, DT, sink=SINK)
    n = 2400
    pos, q, dq = [], [], []
    for k in range(n):
        gen.step(k, GAIT.belt_speed)
        pos.append(gen.plan.foot_pos[0].copy())
        q.append(gen.plan.q[0].copy())
        dq.append(gen.plan.dq[0].copy())
    ref = plan_joints(GaitPlan(GAIT, SINK), exo, np.arange(n) * DT)
    np.testing.assert_allclose(np.array(pos), ref.foot_pos, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.array(q), ref.q, rtol=0, atol=1e-11)
    np.testing.assert_allclose(np.array(dq), ref.dq, rtol=0, atol=1e-9)
    assert np.ptp(np.array(pos)[:, 1, 1]) > np.ptp(
        plan_joints(GaitPlan(GAIT), exo, np.arange(n) * DT).foot_pos[:, 1, 1]
    )


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"weight_N": -1.0}, "stance sink weight must be >= 0 N; got -1.0"),
        ({"exponent": 0.5}, "stance sink exponent must be >= 1; got 0.5"),
    ],
)
def test_bad_values_are_refused(kwargs: dict, message: str) -> None:
    args = {"weight_N": W0, "mass_kg": M, "stiffness_N_per_m_n": K, "exponent": N, **kwargs}
    with pytest.raises(InvalidParameter) as info:
        StanceSink(**args)
    assert str(info.value) == message


def _slip_rms(result, after_s: float) -> float:
    """RMS of the feet's slip speed while in contact after ``after_s`` [m/s]."""
    late = result.t > after_s
    state = np.asarray(result.signals["contact_state"])[late] > 0
    slip = np.asarray(result.signals["foot_slip"])[late]
    return float(np.sqrt(np.mean(slip[state] ** 2)))


def _touchdowns(result, after_s: float) -> tuple[float, float]:
    """The worst vertical and horizontal touchdown speeds after ``after_s`` [m/s]."""
    state = np.asarray(result.signals["contact_state"])
    velocity = np.asarray(result.signals["touchdown_velocity"])
    worst = np.zeros(2)
    for foot in range(2):
        on = np.flatnonzero((state[1:, foot] > 0) & (state[:-1, foot] == 0)) + 1
        on = on[result.t[on] > after_s]
        worst = np.maximum(worst, np.abs(velocity[on, foot]).max(axis=0)[::-1])
    return float(worst[0]), float(worst[1])


@pytest.mark.parametrize("sync", [False, True])
def test_computed_torque_lands_the_loaded_feet_softly(sync: bool, monkeypatch) -> None:
    """50 % support, β = 0.6: the loading plan against the belt-line plan (printed)."""
    config = SimConfig(
        controller="ct",
        contact=ContactParams(enabled=True),
        pelvis=PelvisParams(supported=True, bws_fraction=0.5),
        gait=GAIT,
        duration_s=5.0,
        safety=False,
        sync=sync,
    )
    loaded = simulate(config)
    monkeypatch.setattr(sim_setup, "stance_sink_for", lambda *a: None)
    flat = simulate(config)
    after = 2.4  # the ramp-in's touchdowns and the belt's settling over
    (v_loaded, x_loaded), (v_flat, x_flat) = _touchdowns(loaded, after), _touchdowns(flat, after)
    slip = [_slip_rms(r, after) for r in (loaded, flat)]
    print(
        f"sync {sync}: touchdown down {v_loaded:.3f} vs {v_flat:.3f} m/s, "
        f"slip at touchdown {x_loaded:.3f} vs {x_flat:.3f} m/s, slip RMS {slip[0]:.4f} vs "
        f"{slip[1]:.4f} m/s (loading plan vs belt line)"
    )
    assert v_loaded < 0.15 < 0.35 < v_flat
    assert x_loaded < 0.1 < 0.5 < x_flat
    assert slip[0] < 0.01 < 0.05 < slip[1]
