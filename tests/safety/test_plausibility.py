"""The plausibility monitors: analytic residuals, and no false alarm on the default runs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from exo_ctrl.plant import ContactParams, MotorParams
from exo_ctrl.safety import ResolvedLimits, monitor_record
from exo_ctrl.safety.plausibility import (
    AGE,
    DRIVE,
    DRIVE_RESIDUAL_NM,
    JUMP,
    STUCK,
    STUCK_READINGS,
    plausibility,
    plausibility_limits,
    plausibility_record,
)
from exo_ctrl.sensing import SensorParams
from exo_ctrl.sim import SimConfig, simulate

DT = 1e-3
MOTOR = MotorParams()
LIMITS = ResolvedLimits(*(np.full(4, 1e9) for _ in range(5)))


def fresh(sensors: SensorParams) -> tuple[np.ndarray, np.ndarray]:
    mon = monitor_record(LIMITS, math.inf)
    mon["limit"][0][DRIVE : AGE + 3] = plausibility_limits(MOTOR, sensors, DT, np.full(4, 6.0))
    return plausibility_record(MOTOR, sensors, DT), mon


def test_a_held_drive_at_rest_is_consistent_and_an_offset_shows_through_the_filter() -> None:
    """At rest with U across the winding the sensor reads i_G k_m U / R (η^s = 1 at ω = 0).

    An offset b on the reading then appears in r through the filter F alone:
    r_n = b (1 - (1 - α)^n), α = 1 - exp(-2π f_v Δt).
    """
    sensors = SensorParams()
    state, mon = fresh(sensors)
    u = np.array([1.0, -2.0, 0.5, 3.0])
    tau = MOTOR.torque_per_amp_Nm_per_A * u / MOTOR.resistance_ohm
    q, dq = np.zeros(4), np.zeros(4)
    for _ in range(50):
        plausibility(q, dq, tau, u, 0.0, state, mon)
    np.testing.assert_allclose(state["residual"][0], 0.0, atol=1e-9)
    b = 40.0
    alpha = 1.0 - math.exp(-2.0 * math.pi * sensors.velocity_filter_hz * DT)
    # Detected at the first n with b (1 - (1 - α)^n) > 30 N·m: n = 8 at 30 Hz, 1 kHz.
    first = math.ceil(math.log(1.0 - DRIVE_RESIDUAL_NM / b) / math.log(1.0 - alpha))
    assert first == 8
    for n in range(1, 12):
        plausibility(q, dq, tau + b + 1e-4 * n, u, 0.0, state, mon)  # changing: not stuck
        expected = b * (1.0 - (1.0 - alpha) ** n)
        np.testing.assert_allclose(state["residual"][0], expected, rtol=1e-3, atol=2e-3)
        assert np.all(mon["excess"][0][DRIVE] > 0.0) == (n >= first)


def test_jump_stuck_and_age_channels() -> None:
    sensors = SensorParams()
    state, mon = fresh(sensors)
    lim = mon["limit"][0]
    jump = 6.0 * DT + 2 * sensors.encoder_resolution_rad + 8 * math.sqrt(2) * 2e-5
    assert lim[JUMP, 0] == pytest.approx(jump)
    assert lim[STUCK, 0] == STUCK_READINGS and lim[AGE, 0] == 0.5 * DT
    q, dq, u = np.zeros(4), np.zeros(4), np.zeros(4)
    tau = np.zeros(4)
    plausibility(q, dq, tau, u, 0.0, state, mon)
    for n in range(1, STUCK_READINGS + 2):
        plausibility(q, dq, tau, u, 0.0, state, mon)
        assert mon["excess"][0][STUCK, 0] == n - 1 - STUCK_READINGS  # the first sets the last
    q2 = q + 1.01 * jump
    plausibility(q2, dq, tau + 0.01, u, 2 * DT, state, mon)
    assert mon["excess"][0][JUMP, 0] == pytest.approx(0.01 * jump)
    assert mon["excess"][0][AGE, 0] == pytest.approx(1.5 * DT)
    assert mon["excess"][0][STUCK, 0] == -STUCK_READINGS
    # A noise-free torque sensor is never taken as stuck.
    assert plausibility_limits(MOTOR, SensorParams.ideal(), DT, np.ones(4))[2, 0] > 1e300


ON = ContactParams(enabled=True)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"controller": "pd"},
        {"controller": "ct"},
        {"controller": "qp"},
        {"controller": "pd", "patient_torque": "spastic"},
        {"controller": "pd", "contact": ON},
        {"controller": "pd", "contact": ON, "sync": False},
        {"controller": "ct", "contact": ON},
        {"controller": "ct", "contact": ON, "sync": False},
        # (over the belt a bound the gait's load leaves: at the default 120 N the QP leaves
        # its plan and the departure stop acts, tests/control/qp/test_closed_loop.py)
        {"controller": "qp", "contact": ON, "cuff_force_limit_N": 200.0},
        {"controller": "pd", "patient_torque": "spastic", "contact": ON},
    ],
    ids=[
        "pd",
        "ct",
        "qp",
        "spastic",
        "pd-contact",
        "pd-contact-nosync",
        "ct-contact",
        "ct-contact-nosync",
        "qp-contact",
        "spastic-contact",
    ],
)
def test_no_false_alarm_on_the_default_runs(kwargs) -> None:
    """No plausibility channel, nor the belt monitor with the belt, is violated on the default
    runs (the spastic run is stopped by its estimated cuff force alone, and the hold that
    follows, its feet held on the running belt, trips nothing)."""
    result = simulate(SimConfig(**kwargs))
    names = (
        "drive model residual",
        "encoder step",
        "equal torque readings",
        "command age",
        "still encoder vs current",
        "belt speed deviation",
    )
    bad = [e for e in result.events if str(e.get("quantity", "")).startswith(names)]
    assert bad == []
    if "patient_torque" in kwargs:
        assert result.safety_state == "holding"
        assert result.events[0]["quantity"].startswith("estimated cuff force")
    else:
        assert result.safety_state == "normal"
