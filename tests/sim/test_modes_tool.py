"""tools/modes.py on a tiny case: its table holds the figures of the same runs made here.

Two modes on two active patients, 2.4 s runs (the ramp-in and one gait
cycle).  The runs are made directly from their definition (not through the
tool's config), and each figure recomputed from their summaries.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl.control.modes import ModeParams
from exo_ctrl.control.modes.path import PathParams
from exo_ctrl.plant.patient_active import ActiveParams
from exo_ctrl.sim import SimConfig, simulate

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))

import modes as tool  # noqa: E402

DURATION_S = 2.4
CASES = {
    ("guidance 0.5", "weak (0.3)"): (
        "guidance",
        ModeParams(guidance=0.5),
        ActiveParams(strength=0.3, period_s=1.0, step_length_m=0.30),
    ),
    ("transparent", "weak (0.3)"): (
        "transparent",
        ModeParams(),
        ActiveParams(strength=0.3, period_s=1.0, step_length_m=0.30),
    ),
    ("guidance 0.5", "spastic"): (
        "guidance",
        ModeParams(guidance=0.5),
        ActiveParams(spastic=True, period_s=1.0, step_length_m=0.30),
    ),
    ("transparent", "spastic"): (
        "transparent",
        ModeParams(),
        ActiveParams(spastic=True, period_s=1.0, step_length_m=0.30),
    ),
}


@pytest.fixture(scope="module")
def rows():
    return tool.run_table(DURATION_S, ("guidance 0.5", "transparent"), ("weak (0.3)", "spastic"))


def test_table_equals_the_runs_made_directly(rows, tmp_path):
    assert [(r.mode, r.patient) for r in rows] == [
        ("guidance 0.5", "weak (0.3)"),
        ("transparent", "weak (0.3)"),
        ("guidance 0.5", "spastic"),
        ("transparent", "spastic"),
    ]
    for row in rows:
        mode, params, patient = CASES[(row.mode, row.patient)]
        config = SimConfig(
            patient_torque="active",
            patient_active=patient,
            mode=mode,
            modes=params,
            duration_s=DURATION_S,
        )
        s = simulate(config).summary()
        run = s["interaction"]["run"]
        (cycle,) = [c for c in s["interaction"]["cycles"] if c["cycle"] != "ramp_in"]
        assert (
            row.force_true_N == run["rms_interaction_force_N"] == cycle["rms_interaction_force_N"]
        )
        assert row.force_est_N == run["rms_interaction_force_estimated_N"]
        torque = np.array(list(run["patient_rms_torque_Nm"].values()))
        assert row.patient_torque_Nm == pytest.approx(math.sqrt(np.mean(torque**2)), rel=1e-12)
        assert row.patient_work_J == pytest.approx(sum(run["patient_positive_work_J"].values()))
        assert row.device_work_J == pytest.approx(sum(run["device_positive_work_J"].values()))
        err = np.array(list(run["rms_tracking_error_rad"].values()))
        assert row.tracking_error_mrad == pytest.approx(1e3 * math.sqrt(np.mean(err**2)))
        assert row.gps_deg == s["gait_profile_score_deg"]["actual"]
        assert row.gps_planned_deg == s["gait_profile_score_deg"]["planned"]
        assert row.safety_state == s["safety_state"]
    text = tool.table(rows)
    assert len(text.splitlines()) == 2 + len(rows) + 2
    assert f"{rows[0].force_true_N:.2f}" in text.splitlines()[2]
    png = tmp_path / "modes.png"
    tool.plot(rows, png, DURATION_S)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_bad_duration_is_exit_2(capsys):
    with pytest.raises(SystemExit) as exc:
        tool.main(["--duration", "1.0"])
    assert exc.value.code == 2
    assert "duration must be >= 2.4 s" in capsys.readouterr().err


def test_the_path_row_holds_the_path_figure():
    """``path 0.03``: a 0.03 m tunnel, and its row's path error from the run's feet figures.

    The other modes have no path figure: a dash in the table.
    """
    (row,) = tool.run_table(DURATION_S, ("path 0.03",), ("healthy",))
    config = SimConfig(
        patient_torque="active",
        patient_active=ActiveParams(period_s=1.0, step_length_m=0.30),
        mode="path",
        path=PathParams(tunnel_width_m=0.03),
        duration_s=DURATION_S,
    )
    run = simulate(config).summary()["interaction"]["run"]
    feet = np.array(list(run["path_error_rms_m"].values()))
    assert row.path_error_mm == pytest.approx(1e3 * math.sqrt(np.mean(feet**2)), rel=1e-12)
    assert 0.0 < row.path_error_mm < 1e3 * 0.03  # the tunnel holds the feet in RMS
    line = tool.table([row]).splitlines()[2]
    assert f"{row.path_error_mm:.2f}" in line
    assert tool.config_of("path 0.03", "healthy", DURATION_S).path.tunnel_width_m == 0.03
    assert math.isnan(tool.row_of("aan", "healthy", _without_path(run)).path_error_mm)


def _without_path(run: dict) -> dict:
    """A summary whose run block lacks the path figures (as in a mode other than path)."""
    block = {k: v for k, v in run.items() if not k.startswith("path_")}
    return {
        "interaction": {"run": block, "cycles": [{"cycle": 0}]},
        "gait_profile_score_deg": {"actual": 0.0, "planned": 0.0},
        "safety_state": "normal",
        "safety_events": [],
    }
