"""Every kernel status maps to its exception, in one place (exo_ctrl._jit.check).

Each status is produced by a real kernel where one returns it, and by
``check`` directly for the message.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl._jit import Status, check
from exo_ctrl.exceptions import InvalidParameter, KernelStatusError, SimulationDiverged
from exo_ctrl.plant import CuffParams, Plant
from exo_ctrl.sensing import SensorParams, Sensors


def test_every_status_is_mapped() -> None:
    """A new status without a branch in check() would raise KernelStatusError: none does."""
    for status in Status:
        if status == Status.OK:
            check(status, "here")
            continue
        inputs = (
            {"quantity": "speed", "value": 1.0, "limit": 0.5}
            if status == Status.DIVERGED
            else {"x": np.array([np.nan, 0.0, 0.0])}
        )
        with pytest.raises((InvalidParameter, SimulationDiverged)):
            check(status, "here", **inputs)


def test_ok_raises_nothing_even_with_bad_inputs_named() -> None:
    check(Status.OK, "here", x=np.zeros(2))


def test_wrong_length_names_the_first_bad_input() -> None:
    with pytest.raises(InvalidParameter, match=r"^b must be an array of shape \(4,\)"):
        check(Status.WRONG_LENGTH, "here", a=np.zeros(4), b=np.zeros(3), c=np.zeros(2))


def test_not_finite_names_the_first_bad_input() -> None:
    with pytest.raises(InvalidParameter, match=r"^b must be finite numbers"):
        check(Status.NOT_FINITE, "here", a=np.zeros(4), b=np.array([0.0, np.nan, 0.0, 0.0]))


def test_diverged_is_a_simulation_divergence_with_its_figures() -> None:
    with pytest.raises(SimulationDiverged) as info:
        check(Status.DIVERGED, "here", 1.5, quantity="left_hip speed", value=120.0, limit=100.0)
    assert info.value.time == 1.5 and info.value.value == 120.0 and info.value.limit == 100.0


def test_a_code_that_is_not_a_status_is_a_programming_error() -> None:
    with pytest.raises(KernelStatusError, match="here: kernel returned 99, not a Status"):
        check(99, "here")


def test_kernels_return_their_status_and_the_callers_raise(exo, patient) -> None:
    """WRONG_LENGTH from the sensors' and the plant's kernels; DIVERGED from the plant's."""
    sensors = Sensors(SensorParams(), 1e-3)
    with pytest.raises(InvalidParameter, match=r"^tau_true must be an array of shape \(4,\)"):
        sensors.read(0, np.zeros(4), np.zeros(4), np.zeros(5))
    plant = Plant(exo, patient, dt=1e-3, cuffs=CuffParams())
    plant.reset(np.zeros(4), np.zeros(4))
    with pytest.raises(InvalidParameter, match=r"^voltage_V must be an array of shape \(4,\)"):
        plant.step(np.zeros(3))
    plant.reset(np.zeros(4), np.full(4, 200.0))  # beyond the divergence limit
    with pytest.raises(SimulationDiverged, match="speed"):
        plant.step(np.zeros(4))
