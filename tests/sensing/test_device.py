"""The device's sensors read in one compiled call equal the two sensors read apart.

Checks: over 2,500 ticks (the joints' and the currents' noise blocks of
1,000 samples each redrawn twice), a sample rate below the tick rate (held
readings) and a smooth motion, :class:`DeviceSensors` gives bit for bit the
readings of a :class:`Sensors` and a :class:`CurrentSensor` of the same
seeds read one after the other; a reading of the wrong length is refused by
name with nothing read (neither sensor's noise advanced); a mean-current
source that is not the plant's kind of array is refused with its message.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.sensing import (
    CurrentSensor,
    CurrentSensorParams,
    DeviceSensors,
    SensorParams,
    Sensors,
)

DT = 1e-3


def _pair(params: SensorParams) -> tuple[Sensors, CurrentSensor]:
    return Sensors(params, DT), CurrentSensor(CurrentSensorParams(seed=5))


@pytest.mark.parametrize("rate_hz", [1000.0, 400.0])
def test_one_call_reads_as_the_two_sensors_apart(rate_hz: float) -> None:
    params = SensorParams(sample_rate_hz=rate_hz, torque_bias_Nm=(0.3, 0.0, -0.2, 0.1))
    joints, currents = _pair(params)
    apart_joints, apart_currents = _pair(params)
    mean = np.zeros(4)
    device = DeviceSensors(joints, currents, mean)
    phase = np.array([0.0, 0.7, 1.9, 2.6])
    for k in range(2500):
        t = k * DT
        q = 0.4 * np.sin(2.0 * np.pi * t / 1.2 + phase)
        dq = 0.4 * 2.0 * np.pi / 1.2 * np.cos(2.0 * np.pi * t / 1.2 + phase)
        tau = 40.0 * np.cos(2.0 * np.pi * t / 1.2 + 2.0 * phase)
        mean[:] = 12.0 * np.sin(2.0 * np.pi * t / 0.6 + phase)
        got = device.read(k, q, dq, tau)
        want = apart_joints.read(k, q, dq, tau)
        want_current = apart_currents.read(mean)
        for a, b in ((got.q, want.q), (got.dq, want.dq), (got.tau, want.tau)):
            assert a.tobytes() == b.tobytes(), k
        assert device.current.tobytes() == want_current.tobytes(), k
    assert joints.samples == apart_joints.samples == round(2500 * rate_hz * DT)


def test_a_reading_of_the_wrong_length_is_refused_with_nothing_read() -> None:
    joints, currents = _pair(SensorParams())
    device = DeviceSensors(joints, currents, np.full(4, 2.0))
    before = currents.record.tobytes()  # raw: a copy() leaves the record's padding out
    with pytest.raises(InvalidParameter, match=r"^q_true must be"):
        device.read(0, np.zeros(3), np.zeros(4), np.zeros(4))
    assert joints.samples == 0
    assert currents.record.tobytes() == before


@pytest.mark.parametrize("bad", [np.zeros(3), np.zeros(4, dtype=np.float32), [0.0] * 4])
def test_a_mean_current_source_not_of_four_float64_is_refused(bad: object) -> None:
    joints, currents = _pair(SensorParams())
    message = f"mean_current_A must be a float64 array of shape (4,) [A]; got {bad!r}"
    with pytest.raises(InvalidParameter, match=f"^{re.escape(message)}$"):
        DeviceSensors(joints, currents, bad)  # type: ignore[arg-type]
