"""The QP's cuff-force bound on a reduced, seeded campaign of tools/load_held.py (issue 31).

Twelve points of the campaign's seed 0 drawn with the spastic patient and
the pelvis fixed: step length 0.25–0.50 m, period 0.9–1.5 s, bound
100–180 N, a true patient of 1.55–1.95 m and 50–110 kg drawn around de
Leva's by the cohort's spreads (the exoskeleton fitted to its legs, the
device holding the nominal patient), knee misaligned 0–2 cm.  Every point
that runs must keep the true peak cuff force within 5 % of the USER's bound
(the bound × 1.05, never a margin the code computes), with no QP fallback
after the start.  The full campaign (200 points, spastic and active,
fixed and supported pelvis) is the tool's: its table is in
docs/performance.md, where the cases that do not hold yet are measured.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

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


def test_sync_on_puts_the_supported_points_on_the_synchronised_plan(tmp_path) -> None:
    """``--sync on``: the supported points follow the belt; the fixed ones have none to follow."""
    fixed, supported = (tool.draw_points(1, SEED, ("spastic",), (p,))[0] for p in tool.PELVIS)
    assert supported["pelvis"] == "supported" and fixed["pelvis"] == "fixed"
    for point in (fixed, supported):
        assert not tool.point_config(point, tmp_path).synced  # the QP's default: precomputed
    assert tool.point_config(supported, tmp_path, sync=True).synced
    assert not tool.point_config(fixed, tmp_path, sync=True).synced
