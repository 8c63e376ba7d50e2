"""Offline estimation of a run that fused cuff sensors says it runs without them.

The cuff sensors' readings are not recorded (exo_ctrl/record/estimate_models.py),
so the offline filter is the joint torques' alone, and says so.
"""

from __future__ import annotations

from exo_ctrl.record.estimate_models import recorded_kalman
from exo_ctrl.sensing import CuffSensorParams
from exo_ctrl.sim import SimConfig


def test_the_offline_filter_says_the_cuff_sensors_are_not_recorded(exo) -> None:
    config = SimConfig(controller="ct", cuff_sensors=CuffSensorParams(mode="normal"))
    kalman, notes = recorded_kalman("run.rrd", config, exo)
    assert kalman.cuff_meas is None
    assert notes == [
        "run.rrd: the run fused cuff sensors (cuff_sensors.mode = normal), whose readings a "
        "recording does not hold: this estimate is the joint torques' alone"
    ]
    assert recorded_kalman("run.rrd", SimConfig(controller="ct"), exo)[1] == []
