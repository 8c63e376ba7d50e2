"""The cuffs' force sensors (exo_ctrl/sensing/cuff_load.py): statistics, hold, refusals.

The sensor reads a plant cuff record built here with a known force and
orientation: every cuff's exoskeleton link points straight down (u = (0, −1),
n = (1, 0)), so the true normal component is f_x and the along one −f_z.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from exo_ctrl._jit import record
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plant.cuffs import CUFF_FIELDS
from exo_ctrl.sensing import CuffSensorParams, CuffSensors
from exo_ctrl.sim import SimConfig

DT = 1e-3


def _plant(fx: float = 10.0, fz: float = -20.0) -> np.ndarray:
    """A plant cuff record: forces (fx, fz) on every cuff, links pointing down."""
    cuffs = record(CUFF_FIELDS)
    c = cuffs[0]
    c["cs"][:8] = 1.0  # cos θ = 1, sin θ = 0
    c["along0"][:] = (0.0, -1.0)
    c["f"][:4] = fx
    c["f"][4:] = fz
    return cuffs


def _errors(params: CuffSensorParams, ticks: int, plant: np.ndarray) -> np.ndarray:
    """Reading − truth at every tick, (ticks, 4, 2) [N]."""
    sensors = CuffSensors(params, DT)
    out = np.empty((ticks, 4, 2))
    for k in range(ticks):
        out[k] = sensors.read(k, plant) - sensors.record["true"][0]
    return out


def test_true_components_are_the_link_frame_normal_and_along() -> None:
    sensors = CuffSensors(CuffSensorParams(mode="full", noise_std_N=0.0, offset_std_N=0.0), DT)
    sensors.read(0, _plant(10.0, -20.0))
    np.testing.assert_allclose(sensors.record["true"][0], [[10.0, 20.0]] * 4)
    np.testing.assert_allclose(sensors.reading, [[10.0, 20.0]] * 4)


def test_noise_sd_is_the_parameter() -> None:
    params = CuffSensorParams(
        mode="full", noise_std_N=0.25, offset_std_N=0.0, drift_N_per_sqrt_s=0.0, sample_rate_hz=1e3
    )
    e = _errors(params, 5000, _plant())  # 40,000 samples: the SD's standard error is 0.35 %
    print(f"\nnoise SD {e.std():.4f} N (parameter 0.25), mean {e.mean():+.4f} N")
    assert abs(e.std() / 0.25 - 1.0) < 0.02
    assert abs(e.mean()) < 0.01


def test_offset_is_drawn_once_per_run_with_the_parameter_sd() -> None:
    offsets = []
    for seed in range(150):
        params = CuffSensorParams(mode="full", noise_std_N=0.0, drift_N_per_sqrt_s=0.0, seed=seed)
        e = _errors(params, 20, _plant())
        np.testing.assert_array_equal(e, np.broadcast_to(e[0], e.shape))  # constant over the run
        offsets.append(e[0].ravel())
    sd = np.std(offsets)  # 1,200 draws: the SD's standard error is 2 %
    print(f"\noffset SD {sd:.3f} N over 1200 draws (parameter 1.0)")
    assert abs(sd - 1.0) < 0.08
    again = _errors(CuffSensorParams(mode="full", noise_std_N=0.0, seed=7), 3, _plant())
    reference = _errors(CuffSensorParams(mode="full", noise_std_N=0.0, seed=7), 3, _plant())
    np.testing.assert_array_equal(again, reference)  # seeded: the same run twice


def test_drift_is_a_random_walk_of_the_parameter_intensity() -> None:
    """w(T) has variance σ_w² T: over T = 2 s at 100 Hz, 40 runs × 8 axes."""
    rate, ticks = 1.0, 2001
    ends = []
    for seed in range(40):
        params = CuffSensorParams(
            mode="full",
            noise_std_N=0.0,
            offset_std_N=0.0,
            drift_N_per_sqrt_s=rate,
            sample_rate_hz=100.0,
            seed=seed,
        )
        e = _errors(params, ticks, _plant())
        ends.append(e[-1].ravel())
        steps = np.diff(e[::10], axis=0)  # one step per sample
        assert abs(steps.std() / (rate * math.sqrt(0.01)) - 1.0) < 0.1
    sd = np.std(ends) / math.sqrt((ticks - 1) * DT)
    print(f"\ndrift SD at T over sqrt(T) {sd:.3f} N/sqrt(s) (parameter {rate})")
    assert abs(sd - rate) < 0.15 * rate  # 320 draws: the SD's standard error is 4 %


def test_samples_are_held_between_samples() -> None:
    params = CuffSensorParams(mode="full", sample_rate_hz=250.0)
    sensors = CuffSensors(params, DT)
    plant = _plant()
    fresh, values = [], []
    for k in range(12):
        plant[0]["f"][:4] = 10.0 + k  # the true force changes every tick
        sensors.read(k, plant)
        fresh.append(bool(sensors.readings["fresh"][0]))
        values.append(sensors.reading[0, 0])
    assert fresh == [True, False, False, False] * 3
    for k in range(12):
        assert values[k] == values[4 * (k // 4)]
    assert sensors.record["samples"][0] == 3


def test_normal_set_reads_only_the_normal() -> None:
    sensors = CuffSensors(CuffSensorParams(mode="normal"), DT)
    sensors.read(0, _plant())
    assert np.all(np.isfinite(sensors.reading[:, 0]))
    assert np.all(np.isnan(sensors.reading[:, 1]))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"mode": "both"}, "cuff_sensors mode must be one of none, normal, full; got 'both'"),
        ({"mode": None}, "cuff_sensors mode must be one of none, normal, full; got None"),
        (
            {"noise_std_N": -1.0},
            "cuff_sensors noise_std must be in [0, 10000] N; got -1.0 "
            "(a sanity range: beyond it the filter's arithmetic overflows)",
        ),
        (
            {"sample_rate_hz": 0.0},
            "cuff_sensors sample_rate must be in [1, 100000] Hz; got 0.0 "
            "(a sanity range: beyond it the filter's arithmetic overflows)",
        ),
        ({"seed": -1}, "cuff_sensors seed must be an integer >= 0; got -1"),
        ({"seed": 1.5}, "cuff_sensors seed must be an integer >= 0; got 1.5"),
        (
            {"tare_s": -0.1},
            "cuff_sensors tare must be in [0, 60] s; got -0.1 (a minute at most)",
        ),
    ],
)
def test_bad_values_are_refused_with_the_exact_message(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParameter) as err:
        CuffSensorParams(**kwargs)
    assert str(err.value) == message


def test_sensors_without_the_kalman_filter_are_refused() -> None:
    with pytest.raises(InvalidParameter) as err:
        SimConfig(estimator="momentum", cuff_sensors=CuffSensorParams(mode="full"))
    assert str(err.value) == (
        "cuff_sensors mode must be none unless estimator is kalman; got 'full' "
        "(the cuff sensors' readings are fused by the Kalman filter)"
    )
