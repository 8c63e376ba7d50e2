"""The biofeedback panel: the per-cycle figures in the recording and the blueprint's tab."""

from __future__ import annotations

import math

import numpy as np
import pytest

from exo_ctrl.plant.patient_active import ActiveParams
from exo_ctrl.record import RerunRecorder, read_recording
from exo_ctrl.record.biofeedback import BIOFEEDBACK_SERIES, read_biofeedback
from exo_ctrl.record.blueprint import (
    BIOFEEDBACK_PANELS,
    MAX_LINES_PER_PANEL,
    blueprint_views,
)
from exo_ctrl.sim import SimConfig, simulate

#: aan on a weak active patient: every figure of the panel has values.
AAN = SimConfig(
    patient_torque="active",
    patient_active=ActiveParams(strength=0.3),
    mode="aan",
    duration_s=1.2 + 3 * 1.2,
)


@pytest.fixture(scope="module")
def aan_recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("bio") / "aan.rrd"
    result = simulate(AAN, observers=[RerunRecorder(path)])
    return path, result, result.summary()


def test_recording_holds_the_summary_per_cycle(aan_recording, verify):
    path, _, summary = aan_recording
    assert verify(path).returncode == 0
    got = read_biofeedback(path)
    assert set(got) == set(BIOFEEDBACK_SERIES)
    cycles = [c for c in summary["interaction"]["cycles"] if c["cycle"] != "ramp_in"]
    period = AAN.gait.period
    ends = [AAN.ramp_in + (c["cycle"] + 1) * period for c in cycles]
    assert len(cycles) == 3
    t, force = got["interaction_force/true"]
    np.testing.assert_allclose(t, ends, atol=1e-9)
    np.testing.assert_array_equal(force, [c["rms_interaction_force_N"] for c in cycles])
    _, est = got["interaction_force/estimated"]
    np.testing.assert_array_equal(est, [c["rms_interaction_force_estimated_N"] for c in cycles])
    _, torque = got["patient_torque"]
    for value, c in zip(torque, cycles, strict=True):
        per_joint = np.array(list(c["patient_rms_torque_Nm"].values()))
        assert value == pytest.approx(math.sqrt(np.mean(per_joint**2)), rel=1e-12)
    _, work = got["work/patient"]
    np.testing.assert_allclose(work, [sum(c["patient_positive_work_J"].values()) for c in cycles])
    _, gps = got["gait_profile_score/actual"]
    gps_cycles = summary["gait_profile_score_cycles"]
    np.testing.assert_array_equal(gps, [c["actual"] for c in gps_cycles])
    back = read_recording(path).summary()  # the reader rebuilds the scores from the file
    assert back["gait_profile_score_cycles"] == summary["gait_profile_score_cycles"]
    _, support = got["aan_support"]
    np.testing.assert_array_equal(support, summary["interaction"]["aan_support_rms_Nm"])


def test_a_passive_run_logs_only_the_gait_score(tmp_path):
    path = tmp_path / "default.rrd"
    simulate(SimConfig(), observers=[RerunRecorder(path)])
    got = read_biofeedback(path)
    assert set(got) == {"gait_profile_score/planned", "gait_profile_score/actual"}
    assert got["gait_profile_score/actual"][1].shape == (2,)


def test_blueprint_holds_the_biofeedback_tab(aan_recording):
    path, _, _ = aan_recording
    views = blueprint_views(path)
    bio = [v for v in views if v["origin"] == "biofeedback"]
    assert len(bio) == len(BIOFEEDBACK_PANELS)
    shown = {rule.lstrip("+ ").removeprefix("/biofeedback/") for v in bio for rule in v["contents"]}
    assert shown == set(BIOFEEDBACK_SERIES)
    for view in bio:
        assert view["class"] == "TimeSeries"
        assert len(view["contents"]) <= MAX_LINES_PER_PANEL
        assert view["legend_visible"] is False
        unit = BIOFEEDBACK_SERIES[view["contents"][0].lstrip("+ ").split("/biofeedback/")[1]][0]
        assert f"[{unit}]" in view["name"]
