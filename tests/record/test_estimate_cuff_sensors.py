"""Offline estimation of a run that fused cuff sensors fuses their logged readings.

A recording logs the cuff sensors' readings as the filter got them
(``cuff_sensor_normal``, ``cuff_sensor_along``, ``cuff_sensor_fresh``,
exo_ctrl/sim/schema.py); ``exo-ctrl estimate`` rebuilds the filter with the
run's cuff sensors, puts the readings into it row by row and reproduces the
live estimate, the tare included.  A recording without the readings (made
before they were logged) is estimated from the joint torques alone, and says so.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl.estimation import kalman_series
from exo_ctrl.model import load_exo
from exo_ctrl.record import RerunRecorder, estimate_file
from exo_ctrl.record.estimate_models import CUFF_READINGS, recorded_kalman
from exo_ctrl.sensing import CuffSensorParams
from exo_ctrl.sim import SimConfig, simulate


@pytest.mark.parametrize("tare_s", [0.0, 0.3])
@pytest.mark.parametrize("mode", ["normal", "full"])
def test_the_offline_estimate_with_cuff_sensors_equals_the_live_one(tmp_path, mode, tare_s) -> None:
    """1 s: the filter's settling, a 0.3 s tare or none, then the fused samples."""
    sensors = CuffSensorParams(mode=mode, tare_s=tare_s)
    config = SimConfig(controller="ct", duration_s=1.0, cuff_sensors=sensors)
    path = tmp_path / f"cuffs_{mode}.rrd"
    live = simulate(config, observers=[RerunRecorder(path)]).signals
    fresh = live["cuff_sensor_fresh"]
    assert fresh.sum() == 500  # 500 Hz over 1 s
    assert np.all(np.abs(live["cuff_sensor_normal"]).max(axis=0) > 10.0)
    assert np.any(live["cuff_sensor_along"] != 0.0) == (mode == "full")
    est = estimate_file(path)
    assert est.series.estimator == "kalman"
    assert not [w for w in est.warnings if "cuff sensors" in w]
    np.testing.assert_allclose(est.series.force, live["cuff_force_est"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(est.series.tau_ext, live["tau_ext_est"], rtol=0, atol=1e-9)


def test_without_the_readings_the_offline_filter_runs_on_the_torques_and_says_so(exo) -> None:
    config = SimConfig(controller="ct", cuff_sensors=CuffSensorParams(mode="normal"))
    kalman, notes, readings = recorded_kalman("run.rrd", config, exo)
    assert kalman.cuff_meas is None and readings is None
    assert notes == [
        "run.rrd: the run fused cuff sensors (cuff_sensors.mode = normal), whose readings the "
        "recording does not hold: this estimate is the joint torques' alone"
    ]
    signals = {
        name: np.zeros((3, 4) if name != "cuff_sensor_fresh" else 3) for name in CUFF_READINGS
    }
    kalman, notes, readings = recorded_kalman("run.rrd", config, exo, signals)
    assert kalman.cuff_meas is not None and readings is not None and notes == []
    plain = recorded_kalman("run.rrd", SimConfig(controller="ct"), exo, signals)
    assert plain[0].cuff_meas is None and plain[1:] == ([], None)


def test_a_second_pass_of_the_same_filter_tares_again(tmp_path) -> None:
    """kalman_series restarts the filter: the tare and the model-error forces start anew."""
    sensors = CuffSensorParams(mode="full", tare_s=0.3)
    config = SimConfig(controller="ct", duration_s=0.6, cuff_sensors=sensors)
    live = simulate(config).signals
    kalman, _, readings = recorded_kalman("run.rrd", config, load_exo(None), live)
    args = (np.arange(config.n_ticks) * config.dt, live["q_meas"], live["dq_meas"])
    first = kalman_series(*args, live["tau_sensor"], kalman, cuff_readings=readings).force
    second = kalman_series(*args, live["tau_sensor"], kalman, cuff_readings=readings).force
    np.testing.assert_array_equal(first, second)
    np.testing.assert_allclose(first, live["cuff_force_est"], rtol=0, atol=1e-9)
