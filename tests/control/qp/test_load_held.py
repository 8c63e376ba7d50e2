"""The QP's cuff-force bound on a reduced, seeded campaign of tools/load_held.py (issue 31).

Twelve points of the campaign's seed 0 drawn with the spastic patient and
the pelvis fixed: step length 0.25–0.50 m, period 0.9–1.5 s, bound
100–180 N, a true patient of 1.55–1.95 m and 50–110 kg drawn around de
Leva's by the cohort's spreads (the exoskeleton fitted to its legs, the
device holding the nominal patient), knee misaligned 0–2 cm.  Every point
that runs must keep the true peak cuff force within 5 % of the USER's bound
(the bound × 1.05, never a margin the code computes), with no QP fallback
after the start.  Then twelve points with the pelvis supported (30–50 %
body-weight support, the belt, contact and the patient's feet on), spastic
and active, without cuff sensors and with 2-axis ones: a bound below the
plan's load plus its margin is refused before the run, and the walk stops
where a leg leaves its plan (exo_ctrl/safety/departure.py); every point that
runs holds within 5 %, the stop included.  The full campaign (200 points)
is the tool's: its table is in docs/performance.md.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import exo_ctrl.safety.yield_command as yield_command
import exo_ctrl.sim.tick as tick
from exo_ctrl.sim import simulate

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT / "tools"))

import load_held as tool  # noqa: E402

#: The user's promise: the true peak within 5 % of the bound they set.
TOLERANCE = 0.05
POINTS = 12
SEED = 0


@pytest.fixture(scope="module")
def campaign() -> list[dict]:
    return tool.campaign(POINTS, SEED, progress=False, patients=("spastic",), pelvis=("fixed",))


def test_the_points_are_seeded_and_span_the_ranges() -> None:
    points = tool.draw_points(POINTS, SEED, ("spastic",), ("fixed",))
    assert points == tool.draw_points(POINTS, SEED, ("spastic",), ("fixed",))
    assert points[:3] == tool.draw_points(3, SEED, ("spastic",), ("fixed",))
    for p in points:
        assert tool.STEP_M[0] <= p["step_length_m"] <= tool.STEP_M[1]
        assert tool.PERIOD_S[0] <= p["period_s"] <= tool.PERIOD_S[1]
        assert tool.BOUND_N[0] <= p["bound_N"] <= tool.BOUND_N[1]
        assert tool.HEIGHT_M[0] <= p["height_m"] <= tool.HEIGHT_M[1]
        assert tool.MASS_KG[0] <= p["mass_kg"] <= tool.MASS_KG[1]
        assert sum(x * x for x in p["knee_xz"]) <= tool.KNEE_MISALIGNMENT_M**2
        assert p["patient_torque"] == "spastic" and p["pelvis"] == "fixed"


def test_every_point_holds_within_5_percent_of_the_users_bound(campaign) -> None:
    text, _ = tool.report(campaign)
    print("\n" + text)
    ran = [r for r in campaign if r["outcome"] == "completed"]
    assert len(ran) >= POINTS - 2  # the planner refuses few points
    for r in campaign:
        assert r["outcome"] in ("completed", "refused"), r
        if r["outcome"] == "completed":
            assert r["peak_N"] <= r["bound_N"] * (1.0 + TOLERANCE), r
            assert r["margin_N"] > 0.0


def test_the_supported_points_walk_the_synchronised_plan(tmp_path) -> None:
    """The supported points follow the belt (the QP's default; ``--sync off``: precomputed);
    the fixed ones have none to follow."""
    fixed, supported = (tool.draw_points(1, SEED, ("spastic",), (p,))[0] for p in tool.PELVIS)
    assert supported["pelvis"] == "supported" and fixed["pelvis"] == "fixed"
    assert tool.point_config(supported, tmp_path).synced
    assert not tool.point_config(supported, tmp_path, sync=False).synced
    for sync in (True, False):
        assert not tool.point_config(fixed, tmp_path, sync=sync).synced


@pytest.mark.parametrize("sensors", ["none", "full"])
def test_every_supported_point_that_runs_holds_within_5_percent(sensors: str) -> None:
    results = tool.campaign(
        POINTS, SEED, progress=False, pelvis=("supported",), cuff_sensors=sensors
    )
    text, _ = tool.report(results)
    print("\n" + text)
    ran = [r for r in results if r["outcome"] == "completed"]
    assert len(ran) >= 3
    for r in results:
        assert r["outcome"] in ("completed", "refused"), r
        if r["outcome"] == "refused":
            assert r["kind"] == "bound" and "the plan puts on the cuff" in r["reason"], r
        else:
            assert r["peak_N"] <= r["bound_N"] * (1.0 + TOLERANCE), r
            assert r["qp_failures"] == 0, r


def test_the_departure_stop_is_what_holds_a_spastic_supported_point(tmp_path, monkeypatch) -> None:
    """Point 11 of the full campaign: stopped, within its bound; without the stop, 20 % past it."""
    (point,) = tool.draw_points(12, SEED)[11:]
    assert point["pelvis"] == "supported" and point["patient_torque"] == "spastic"
    config = tool.point_config(point, tmp_path)
    stopped = simulate(config)
    (cause, state) = stopped.events[:2]
    assert cause["kind"] == "violation" and cause["quantity"].startswith("departure_")
    assert cause["value"] > cause["limit"] == pytest.approx(0.1 / 1.04, rel=0.02)
    assert state["message"].startswith("safety state normal -> stopping: controlled stop (yield)")
    peak = np.linalg.norm(stopped.cuff_force, axis=2).max()
    assert peak <= point["bound_N"] * (1.0 + TOLERANCE)
    k = round(cause["t"] / config.dt)
    departure = np.abs(stopped.q[:k] - stopped.q_des[:k]).max()
    assert departure <= cause["limit"] + 1e-3  # the legs were on their plan until the stop
    monkeypatch.setattr(tick, "departure_for", lambda *_: None)
    walked = simulate(config)
    assert not walked.events  # the supervisor is off: nothing stops the walk
    assert np.linalg.norm(walked.cuff_force, axis=2).max() > point["bound_N"] * 1.2


def test_the_look_ahead_stops_the_sagging_stance_leg_before_the_swing_foot_lands(
    tmp_path, monkeypatch
) -> None:
    """Point 118 with 2-axis cuff sensors (active, pelvis supported, the knee 1.9 cm off):
    stopped on the departure the legs reach within the harness's arrest, within its bound;
    on the present departure alone the stop came as the swing foot landed, the pelvis
    falling, and the exoskeleton's knee ran into the limb: past the bound and its 5 %, the
    yield's force feedback notwithstanding (without it, 30 % past).
    """
    point = tool.draw_points(119, SEED)[118]
    assert point["pelvis"] == "supported" and point["patient_torque"] == "active"
    config = tool.point_config(point, tmp_path, "full")
    bound = point["bound_N"] * (1.0 + TOLERANCE)
    ahead = simulate(config, keep_history=True)
    cause = ahead.events[0]
    assert cause["quantity"].startswith("departure_") and cause["value"] > cause["limit"]
    k = round(cause["t"] / config.dt)
    assert np.abs(ahead.q[k] - ahead.q_des[k]).max() < cause["limit"]  # the look-ahead's stop
    assert np.linalg.norm(ahead.cuff_force, axis=2).max() <= bound
    present_only = tick.departure_for

    def without_look_ahead(*args):
        monitor = present_only(*args)
        monitor.lookahead_s = 0.0
        return monitor

    monkeypatch.setattr(tick, "departure_for", without_look_ahead)
    late = simulate(config)
    assert late.events[0]["t"] > cause["t"] + 0.5  # a cycle later
    assert np.linalg.norm(late.cuff_force, axis=2).max() > bound


def test_the_departure_stops_yield_carries_the_exoskeleton_after_an_active_swing(
    tmp_path, monkeypatch
) -> None:
    """Point 65 with 2-axis cuff sensors on the precomputed plan (active, 60 kg, pelvis
    supported): after the departure stop the patient swings the right leg on, and the yield,
    feeding the estimated cuff forces back (exo_ctrl/safety/yield_command.py), keeps the
    thigh cuff within the bound; without the feedback the patient drags the exoskeleton's
    inertia by the cuff more than 20 % past it.
    """
    point = tool.draw_points(66, SEED)[65]
    assert point["pelvis"] == "supported" and point["patient_torque"] == "active"
    config = tool.point_config(point, tmp_path, "full", sync=False)
    fed = simulate(config)
    cause = fed.events[0]
    assert cause["quantity"].startswith("departure_")
    assert np.linalg.norm(fed.cuff_force, axis=2).max() <= point["bound_N"] * (1.0 + TOLERANCE)
    monkeypatch.setattr(yield_command, "MAX_FORCE_GAIN", 0.0)
    plain = simulate(config)
    assert plain.events[0]["t"] == cause["t"]  # the same stop
    assert np.linalg.norm(plain.cuff_force, axis=2).max() > point["bound_N"] * 1.2
