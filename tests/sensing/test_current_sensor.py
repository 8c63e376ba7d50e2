"""The drives' current sensors: the supervisor reads a measurement, never the plant's current.

Checks: the ideal sensor reads the mean current exactly; the default one's
error has the stated noise (sample std within its sampling error) and sits on
the converter's grid; the sequence depends only on the seed; the supervisor's
over-current monitor trips on what the sensor reads (a reading beyond the
limit stops the gait, whatever the plant's current); bad parameters are
refused by name.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.sensing import CurrentSensor, CurrentSensorParams


def test_the_ideal_sensor_reads_the_mean_current_exactly() -> None:
    sensor = CurrentSensor(CurrentSensorParams.ideal())
    current = np.array([1.25, -3.5, 31.9, 0.0])
    np.testing.assert_array_equal(sensor.read(current), current)


def test_the_default_noise_and_grid() -> None:
    p = CurrentSensorParams()
    sensor = CurrentSensor(p)
    true = np.array([10.0, -5.0, 0.3, 20.0])
    n = 5000  # five noise blocks: the redraw is exercised
    got = np.array([sensor.read(true).copy() for _ in range(n)])
    err = got - true
    # On the grid: an integer number of steps.
    steps = got / p.resolution_A
    np.testing.assert_allclose(steps, np.rint(steps), atol=1e-9)
    # The noise: σ² + ΔI²/12 (quantisation as uniform), within 4 sampling std.
    expected = np.sqrt(p.noise_std_A**2 + p.resolution_A**2 / 12.0)
    std = err.std(axis=0)
    assert np.all(np.abs(std - expected) < 4.0 * expected / np.sqrt(2.0 * n)), std
    assert np.all(np.abs(err.mean(axis=0)) < 4.0 * expected / np.sqrt(n))


def test_the_sequence_depends_only_on_the_seed() -> None:
    x = np.array([1.0, 2.0, 3.0, 4.0])
    a = [CurrentSensor(CurrentSensorParams(seed=3)).read(x).copy() for _ in range(2)]
    np.testing.assert_array_equal(a[0], a[1])
    b = CurrentSensor(CurrentSensorParams(seed=4)).read(x)
    assert not np.array_equal(a[0], b)


def test_the_supervisor_trips_on_the_reading_not_the_truth() -> None:
    """A current sensor with 40 A of noise: the monitor stops the run on its readings."""
    from exo_ctrl.sim import SimConfig, simulate

    exact = simulate(SimConfig(duration_s=0.2, current_sensor=CurrentSensorParams.ideal()))
    assert exact.summary()["safety_state"] == "normal"
    noisy = simulate(
        SimConfig(duration_s=0.2, current_sensor=CurrentSensorParams(noise_std_A=40.0))
    )
    summary = noisy.summary()
    assert summary["safety_state"] != "normal"
    first = summary["safety_events"][0]
    assert first["quantity"].startswith("current ") and first["t"] == 0.0
    assert first["value"] > first["limit"] == pytest.approx(1.1 * 32.0)
    # The plant's true currents never came near the threshold.
    assert np.max(np.abs(noisy.signals["current"])) < 32.0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"noise_std_A": -1.0}, "current sensor noise_std must be >= 0"),
        ({"resolution_A": float("nan")}, "current sensor resolution must be"),
        ({"seed": -1}, "current sensor seed must be an integer >= 0; got -1"),
        ({"seed": True}, "current sensor seed must be an integer >= 0; got True"),
    ],
)
def test_bad_parameters_are_refused_by_name(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        CurrentSensorParams(**kwargs)
    assert str(info.value).startswith(message)
