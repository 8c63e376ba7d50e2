"""The loaded touchdowns off the default patient: a reduced, seeded campaign of tools/touchdowns.py.

Six points of the campaign's seed 0 (issue 31, item 4: 30-50 % body-weight support, a passive,
active or spastic patient): a true patient of 1.55-1.95 m and 50-110 kg drawn around de Leva's
by the cohort's spreads (the exoskeleton fitted to its legs, the device holding the nominal
patient), knee misaligned 0-2 cm, the true cuffs scattered, CT with the supervisor on, the
clinic presets' gaits in proportion to the legs.  Each point walks three cycles without a stop
and touches down within the issue's bounds, or the run said before it started why it might not
(the drives' reach: a plan that needs more torque than they give; never a silent miss).  The
full campaign's table is in docs/performance.md.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

import touchdowns as tool  # noqa: E402

POINTS = 6
SEED = 0
#: The drives' reach warning (exo_ctrl/control/drive_reach.py): the planned torque beyond them.
REACH = "the plan needs more torque than the drives'"


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> list[dict]:
    folder = tmp_path_factory.mktemp("touchdowns")
    points = tool.draw_points(POINTS, SEED, tool.PATIENTS, ("supported",))
    return [tool.run_point(p, folder, "ct", 3) for p in points]


def test_the_points_span_the_patients_and_the_supports(results) -> None:
    assert {r["patient_torque"] for r in results} == set(tool.PATIENTS)
    for r in results:
        assert 0.3 <= r["bws"] <= 0.5 and 1.55 <= r["height_m"] <= 1.95


def test_every_point_walks_within_the_issues_bounds_or_was_warned(results) -> None:
    for r in results:
        print(
            f"{r['index']} {r['patient_torque']}: {r['down_mps']:.3f} / {r['along_mps']:.3f} / "
            f"{r['slip_rms_mps']:.4f} m/s, stop {r['stop']}, warnings {len(r['warnings'])}"
        )
        assert r["outcome"] == "completed"
        within = (
            r["stop"] is None
            and r["touchdowns"] >= 6
            and max(r["down_mps"], r["along_mps"]) < tool.BOUND_MPS
            and r["slip_rms_mps"] < tool.SLIP_RMS_MPS
        )
        assert within is r["held"]
        reach = any(w.startswith(REACH) for w in r["warnings"])  # the one said for these
        assert within or reach, r


def test_the_gait_is_the_presets_in_proportion_to_the_legs(tmp_path: Path) -> None:
    """Hip height, lift and step length scale with the leg (thigh + shank) over 1.04 m."""
    point = tool.draw_points(1, SEED, ("spastic",), ("supported",))[0]
    config = tool.point_config(point, tmp_path, "ct", 3)
    preset = tool.load_scenario(preset="clinic-spastic").config.gait
    k = config.gait.hip_height / preset.hip_height
    assert config.gait.step_length == pytest.approx(preset.step_length * k, rel=1e-12)
    assert config.gait.lift_height == pytest.approx(preset.lift_height * k, rel=1e-12)
    assert config.gait.period == preset.period and config.duration_s == 4 * preset.period
    assert 0.7 < k < 1.0  # de Leva's legs, shorter than the presets' 1.04 m


def test_an_unwritable_json_is_refused_before_the_campaign(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """Exit 2 naming --json and why, before any point runs (the points file comes last)."""
    missing = tmp_path / "missing" / "points.json"
    assert tool.main(["--points", "1", "--json", str(missing)]) == 2
    err = capsys.readouterr().err
    assert err == f"touchdowns: --json {missing}: directory {missing.parent} does not exist\n"
    assert not missing.parent.exists()
