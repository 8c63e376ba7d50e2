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


def respond(
    params: BeltParams, v0: float, v_set: float, load: np.ndarray, h: float = H
) -> np.ndarray:
    rec = params.new_record()
    rec["v"] = v0
    speed = np.zeros_like(load)
    belt_response(rec, v_set, load, h, speed)
    return speed


def test_the_controller_holds_the_set_speed_and_reaches_a_new_one() -> None:
    params = BeltParams()
    held = respond(params, 0.6, 0.6, np.zeros(2000))
    np.testing.assert_allclose(held, 0.6, rtol=0, atol=1e-15)
    stepped = respond(params, 0.0, 0.6, np.zeros(6000))
    assert abs(stepped[-1] - 0.6) < 1e-5
    assert np.all(np.isfinite(stepped))


def test_a_friction_load_dips_the_speed_by_the_loops_analytic_peak_and_is_rejected() -> None:
    """At a step h = 0.1 ms (ω_c h = 0.019: the explicit step's error is of that order,
    1.8 % at the plant's 1 ms), the dip within 0.5 %; its time within 5 % (the peak is
    flat: 5 % off it the speed differs by 0.1 %)."""
    params = BeltParams()
    h = 1e-4
    load = np.zeros(20000)
    load[1000:] = -50.0  # the feet hold back with 50 N
    speed = respond(params, 1.0, 1.0, load, h)
    w = math.pi * params.bandwidth_hz  # ω_c / 2
    dip, at = 1.0 - speed.min(), (np.argmin(speed) - 1000) * h
    expected = 50.0 / (params.mass_kg * w * math.e)
    print(
        f"dip {dip * 1e3:.2f} mm/s at {at * 1e3:.1f} ms;",
        f"analytic {expected * 1e3:.2f} mm/s at {1e3 / w:.1f} ms",
    )
    assert dip == pytest.approx(expected, rel=0.005)
    assert at == pytest.approx(1.0 / w, rel=0.05)
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


def braked(params: BeltParams, v0: float, load: np.ndarray, f_brake: float | None = None):
    """The belt from v0 with its brake on (set speed v0: the brake ignores it)."""
    rec = params.new_record()
    rec["v"] = v0
    rec["brake"] = 1.0
    if f_brake is not None:
        rec["f_brake"] = f_brake
    speed = np.zeros_like(load)
    belt_response(rec, v0, load, H, speed)
    return speed, rec


def test_the_brake_stops_the_belt_at_f_max_over_m_b_and_holds_it_at_rest() -> None:
    """While the limit binds v(t) = v0 - (F_br / m_b) t exactly (explicit steps of a constant
    force); the last step takes what is left, and then the belt stays at rest, whatever the set
    speed, against a load the brake can take."""
    params = BeltParams()
    a = params.force_limit_N / params.mass_kg  # 50 m/s²
    v0 = 0.583
    speed, rec = braked(params, v0, np.zeros(100))
    n = math.floor(v0 / (a * H))  # 11 full steps at the limit
    np.testing.assert_allclose(speed[:n], v0 - a * H * np.arange(1, n + 1), rtol=0, atol=1e-14)
    assert np.all(speed[n:] == 0.0)
    assert rec["held"][0] == 1.0 and rec["integral"][0] == 0.0  # the PI is out
    # At rest against a 600 N pull (< F_br): the brake takes it all, the belt stays.
    speed, rec = braked(params, 0.0, np.full(50, -600.0))
    assert np.all(speed == 0.0) and rec["f_drive"][0] == 600.0


def test_a_load_beyond_the_brake_drags_the_belt_at_the_force_difference() -> None:
    """A stated braking force of 200 N against a 300 N pull: the brake slips at its limit and
    the belt accelerates at (300 - 200) / m_b from rest."""
    params = BeltParams()
    speed, rec = braked(params, 0.0, np.full(100, -300.0), f_brake=200.0)
    expected = -(300.0 - 200.0) / params.mass_kg * H * np.arange(1, 101)
    np.testing.assert_allclose(speed, expected, rtol=1e-12, atol=1e-15)
    assert rec["f_drive"][0] == 200.0
