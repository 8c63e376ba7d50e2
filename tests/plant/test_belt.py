"""The treadmill belt's speed controller, against the analytic response of its closed loop.

m_b dv/dt = F_d + F_load with F_d = K_p e + K_i ∫e: under a load step F the
speed error is e(s)/F(s) = -s / (m_b s² + K_p s + K_i); with K_p = m_b ω_c and
K_i = m_b ω_c² / 4 (double pole at -ω = -ω_c / 2), e(t) = (F / m_b) t e^{-ω t},
peak F / (m_b ω e) at t = 1 / ω; without the integral, e → F / K_p.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plant import BeltParams
from exo_ctrl.plant.belt import belt_response

H = 1e-3


def respond(params: BeltParams, v0: float, v_set: float, load: np.ndarray) -> np.ndarray:
    rec = params.new_record()
    rec["v"] = v0
    speed = np.zeros_like(load)
    belt_response(rec, v_set, load, H, speed)
    return speed


def test_the_controller_holds_the_set_speed_and_reaches_a_new_one() -> None:
    params = BeltParams()
    held = respond(params, 0.6, 0.6, np.zeros(2000))
    np.testing.assert_allclose(held, 0.6, rtol=0, atol=1e-15)
    stepped = respond(params, 0.0, 0.6, np.zeros(6000))
    assert abs(stepped[-1] - 0.6) < 1e-5
    assert np.all(np.isfinite(stepped))


def test_a_friction_load_dips_the_speed_by_the_loops_analytic_peak_and_is_rejected() -> None:
    params = BeltParams()
    load = np.zeros(8000)
    load[1000:] = -50.0  # the feet hold back with 50 N
    speed = respond(params, 1.0, 1.0, load)
    w = math.pi * params.bandwidth_hz  # ω_c / 2
    dip, at = 1.0 - speed.min(), (np.argmin(speed) - 1000) * H
    expected = 50.0 / (params.mass_kg * w * math.e)
    print(
        f"dip {dip * 1e3:.2f} mm/s at {at:.3f} s;",
        f"analytic {expected * 1e3:.2f} mm/s at {1 / w:.3f} s",
    )
    assert dip == pytest.approx(expected, rel=0.01)
    assert at == pytest.approx(1.0 / w, abs=0.01)
    assert abs(speed[-1] - 1.0) < 1e-6  # the integral removes it


def test_without_the_integral_a_load_slows_the_belt_by_f_over_kp() -> None:
    params = BeltParams(integral=False)
    load = np.full(5000, -20.0)
    speed = respond(params, 1.0, 1.0, load)
    kp, ki = params.gains
    assert ki == 0.0
    assert 1.0 - speed[-1] == pytest.approx(20.0 / kp, rel=1e-9)


def test_the_drive_force_is_held_at_its_limit() -> None:
    params = BeltParams(force_limit_N=100.0)
    speed = respond(params, 0.0, 1.0, np.zeros(100))
    # at the limit the belt accelerates at F_max / m_b
    assert speed[-1] == pytest.approx(100 * H * 100.0 / params.mass_kg, rel=1e-12)


def test_bad_belt_parameters_are_refused() -> None:
    with pytest.raises(InvalidParameter, match="belt mass must be > 0 kg; got 0"):
        BeltParams(mass_kg=0)
    with pytest.raises(InvalidParameter, match="belt height must be > 0 m"):
        BeltParams(height_m=-0.1)
