"""Fixtures of the safety tests."""

from __future__ import annotations

import pytest

from exo_ctrl.sim import SimConfig, build


@pytest.fixture(scope="module")
def device():
    """The device's models of the default run (exoskeleton, nominal patient, datasheet)."""
    setup = build(SimConfig(duration_s=0.1))
    return setup.device_exo, setup.device_patient, setup.device_motor
