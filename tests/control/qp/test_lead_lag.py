"""The observer's lead–lag on the force estimate: it undoes the estimator's filter exactly."""

from __future__ import annotations

import math

import numpy as np
import pytest

from exo_ctrl.control.qp import CuffHorizonModel, CuffStateObserver
from exo_ctrl.exceptions import InvalidParameter


def _estimate(force: np.ndarray, gain: float, h: float) -> np.ndarray:
    """The momentum observer's discrete first-order filter, r ← r + a (e − r), applied to force."""
    a = -math.expm1(-gain * h)
    out = np.empty_like(force)
    r = force[0].copy()
    for k, e in enumerate(force):
        r += a * (e - r)
        out[k] = r
    return out


def test_lead_lag_restores_the_filtered_force(exo, patient, motor, plan) -> None:
    """f̂ = K_O-filtered f; with ω_f = K_O nothing changes, with ω_f → ∞ f itself comes back.

    f̃ then is f filtered at ω_f: checked against the same filter applied to f.
    """
    h, gain = 1e-3, 100.0
    t = np.arange(300) * h
    force = np.zeros((300, 4, 2))
    force[:, 1, 0] = 80.0 * np.sin(2 * np.pi * 3 * t) + 40.0 * (t > 0.1)
    est = _estimate(force, gain, h)
    model = CuffHorizonModel(exo, patient, motor)
    model.linearise(plan.q[300], np.zeros(4))
    for w_f, expected in ((gain, est), (400.0, _estimate(force, 400.0, h))):
        obs = CuffStateObserver(8000.0, 100.0, h, 0.0, gain, w_f)
        seen = np.empty_like(force)
        for k in range(300):
            obs.update(model, est[k], np.zeros(4))
            seen[k] = obs.record["fast"][0]
        # The same filter from the same start (f̂_0 = f_0): equal to rounding.
        np.testing.assert_allclose(seen[1:], expected[1:], atol=1e-8, rtol=0)
    # Lag: a ramp's filtered value trails by 1/ω: 10 ms at K_O, 2.5 ms at 400 1/s.
    assert np.abs(seen - force).max() < np.abs(est - force).max()


def test_lead_lag_slower_than_the_estimate_is_refused() -> None:
    with pytest.raises(InvalidParameter, match="restored_bandwidth must be >= the estimate's"):
        CuffStateObserver(8000.0, 100.0, 1e-3, 30.0, 100.0, 50.0)
