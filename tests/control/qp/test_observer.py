"""The cuff-state observer: δ, δ̇ recovered from forces made by the cuff law; its parameters."""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl.control.qp import (
    CuffHorizonModel,
    CuffStateObserver,
)
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plant.cuffs import CuffParams


def test_observer_recovers_deflection_and_rate_from_the_cuff_law(exo, patient, motor, plan):
    """f = −J (K δ + C δ̇): a force history from a known δ(t) gives δ̂ → δ, δ̂̇ → δ̇."""
    model = CuffHorizonModel(exo, patient, motor)
    cuffs = CuffParams()
    obs = CuffStateObserver(cuffs.stiffness_N_per_m, cuffs.damping_N_s_per_m, 1e-3, 0.0)
    q = plan.q[300]
    model.linearise(q, np.zeros(4))
    jac = model.jac
    for n in range(400):
        t = n * 1e-3
        delta = 2e-3 * np.array([np.sin(8 * t), np.cos(5 * t), np.sin(3 * t), 1.0])
        rate = 2e-3 * np.array([8 * np.cos(8 * t), -5 * np.sin(5 * t), 3 * np.cos(3 * t), 0.0])
        s = cuffs.stiffness_N_per_m * delta + cuffs.damping_N_s_per_m * rate
        force = np.concatenate([-jac[leg] @ s[2 * leg : 2 * leg + 2] for leg in (0, 1)])
        obs.update(model, force.reshape(4, 2), np.zeros(4))
    # Exact up to the zero-order hold of s: δ̂ lags by about h/2, so
    # |δ̂ − δ| ≤ (h/2) max|δ̇| = 0.5e-3 · 2e-3 · 8 = 8e-6 rad and
    # |δ̂̇ − δ̇| ≤ (K/C) · 8e-6 = 6.4e-4 rad/s.
    np.testing.assert_allclose(obs.delta, delta, atol=1e-5, rtol=0)
    np.testing.assert_allclose(obs.ddelta, rate, atol=8e-4, rtol=0)
    np.testing.assert_array_equal(obs.disturbance, 0.0)  # bandwidth 0


def test_bad_horizon_and_observer_parameters_are_refused(exo, patient, motor) -> None:
    with pytest.raises(InvalidParameter, match="horizon_ticks must be strictly increasing"):
        CuffHorizonModel(exo, patient, motor, horizon_ticks=(10, 5))
    with pytest.raises(InvalidParameter, match="horizon_ticks"):
        CuffHorizonModel(exo, patient, motor, horizon_ticks=(0, 5))
    with pytest.raises(InvalidParameter, match="dt"):
        CuffHorizonModel(exo, patient, motor, dt=0.0)
    with pytest.raises(InvalidParameter, match="disturbance_bandwidth"):
        CuffStateObserver(8000.0, 100.0, 1e-3, -1.0)
    with pytest.raises(InvalidParameter, match="cuff damping"):
        CuffStateObserver(8000.0, 0.0)
