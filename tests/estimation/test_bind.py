"""The estimators' bound updates (``bind``): the tick's call equals ``update`` bit for bit.

The control tick calls each estimator through ``bind(readings)``, a call
without arguments on arrays checked once; it must give exactly what
``update(readings)`` gives on the same readings, through the start, the
running filter, a reset and a restart after non-finite readings.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl.estimation import CuffForceEstimator, CuffForceKalman
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import load_exo, load_patient
from exo_ctrl.plant.cuffs import CuffParams
from exo_ctrl.sensing import SensorReadings
from exo_ctrl.sensing.sensors import SensorParams

DT = 1e-3


@pytest.fixture(scope="module")
def models():
    return load_exo(None), load_patient(None)


def _estimators(models, kind: str):
    exo, patient = models
    if kind == "kalman":
        make = lambda: CuffForceKalman(  # noqa: E731
            exo, patient, DT, cuffs=CuffParams.isotropic(), sensors=SensorParams()
        )
    else:
        make = lambda: CuffForceEstimator(exo, DT)  # noqa: E731
    return make(), make()


def _readings(k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A walking-like sequence of readings (smooth angles, speeds, torques)."""
    t = k * DT
    w = 2.0 * np.pi / 1.2
    q = np.array([0.3, 0.6, 0.1, 0.9]) + 0.2 * np.sin(w * t + np.array([0.0, 1.0, 3.1, 4.1]))
    dq = 0.2 * w * np.cos(w * t + np.array([0.0, 1.0, 3.1, 4.1]))
    tau = np.array([20.0, -8.0, 15.0, -5.0]) + 10.0 * np.sin(3.0 * w * t + np.arange(4))
    return q, dq, tau


@pytest.mark.parametrize("kind", ["kalman", "momentum"])
def test_the_bound_update_is_update(models, kind: str) -> None:
    by_update, by_bind = _estimators(models, kind)
    held = SensorReadings(np.zeros(4), np.zeros(4), np.zeros(4))
    update = by_bind.bind(held)
    for k in range(400):
        q, dq, tau = _readings(k)
        if k == 250:  # a non-finite torque (the Kalman filter holds its last one)
            tau[1] = np.nan
        if k == 300:
            by_update.reset()
            by_bind.reset()
        held.q[:], held.dq[:], held.tau[:] = q, dq, tau
        expected = by_update.update(SensorReadings(q, dq, tau)).copy()
        got = update()
        np.testing.assert_array_equal(got, expected)
    assert np.any(expected != 0.0)
    np.testing.assert_array_equal(by_bind.record, by_update.record)


@pytest.mark.parametrize("kind", ["kalman", "momentum"])
def test_bind_refuses_readings_it_cannot_hold(models, kind: str) -> None:
    est, _ = _estimators(models, kind)
    bad = SensorReadings(np.zeros(4), np.zeros(3), np.zeros(4))
    with pytest.raises(InvalidParameter) as info:
        est.bind(bad)
    assert str(info.value) == "dq must be a float64 array of shape (4,); got array([0., 0., 0.])"
