"""The supervisor's one-call check equals the still encoder's check, the plausibility
monitors, the torque-sensor consistency, then the limit monitor.

Checks: over 300 ticks of a moving joint state with realistic limits (some
channels violated, a NaN frame, a stale command, a joint held still), :func:`check_readings`
leaves the plausibility and monitor records byte for byte as the four
kernels called in turn, and returns the monitor's status; with the checks
off the plausibility record and its rows are untouched; a wrong length is
the monitor's WRONG_LENGTH, with the records as the kernels leave them (the
still and consistency checks run only on inputs of length 4).
"""

from __future__ import annotations

import math

import numpy as np

from exo_ctrl._jit import Status
from exo_ctrl.plant import MotorParams
from exo_ctrl.safety import ResolvedLimits, monitor, monitor_record
from exo_ctrl.safety.consistency import CONSIST, consistency
from exo_ctrl.safety.monitor import LIMIT_GROUPS
from exo_ctrl.safety.plausibility import (
    DRIVE,
    plausibility,
    plausibility_limits,
    plausibility_record,
)
from exo_ctrl.safety.still import STILL, still_winding
from exo_ctrl.safety.tick_check import check_readings
from exo_ctrl.sensing import SensorParams

DT = 1e-3
MOTOR = MotorParams()
SPEED = np.full(4, 6.0)
LIMITS = ResolvedLimits(
    np.full(4, -1.0), np.full(4, 1.2), SPEED, np.full(4, 30.0), np.full(4, 150.0)
)


def records() -> tuple[np.ndarray, np.ndarray]:
    sensors = SensorParams()
    mon = monitor_record(LIMITS, 0.25)  # an e-stop time inside the run
    mon["limit"][0][DRIVE : STILL + 1] = plausibility_limits(MOTOR, sensors, DT, SPEED)
    # The made-up torques fit no drive model, nor the made-up currents.
    mon["limit"][0][[DRIVE, CONSIST]] = np.finfo(float).max
    return plausibility_record(MOTOR, sensors, DT), mon


def tick_inputs(k: int) -> tuple:
    t = k * DT
    ph = np.array([0.0, 0.9, 2.1, 2.8])
    q = 1.1 * np.sin(2.0 * np.pi * t / 1.2 + ph)  # beyond the lower limit at times
    dq = 1.1 * 2.0 * np.pi / 1.2 * np.cos(2.0 * np.pi * t / 1.2 + ph)
    tau = 60.0 * np.sin(2.0 * np.pi * t / 0.2 + ph)
    u = 4.0 * np.cos(2.0 * np.pi * t / 0.25 + ph)
    current = 35.0 * np.sin(2.0 * np.pi * t / 0.5 + ph)  # over 30 A at times
    f = np.stack((120.0 * np.sin(t + ph), 140.0 * np.cos(3.0 * t + ph)), axis=1)
    if k == 120:  # a corrupted frame
        q[2] = dq[2] = tau[2] = math.nan
    if k >= 150:  # the right knee held still from 0.15 s on (its still run and window fill)
        q[3] = 0.4
    age = 2.0 * DT if 200 <= k < 210 else 0.0  # a stale command
    return f, q, dq, tau, current, u, age, t


def test_one_call_equals_the_three_kernels_in_turn() -> None:
    plaus_a, mon_a = records()
    plaus_b, mon_b = records()
    violated = 0
    for k in range(300):
        f, q, dq, tau, current, u, age, t = tick_inputs(k)
        status = check_readings(f, q, dq, tau, current, u, age, t, True, plaus_a, mon_a)
        still_winding(q, current, plaus_b, mon_b)
        plausibility(q, dq, tau, u, age, plaus_b, mon_b)
        consistency(q, dq, tau, current, plaus_b, mon_b)
        expected = monitor(f, q, dq, tau, current, u, t, mon_b)
        assert status == expected == Status.OK.value
        assert plaus_a.tobytes() == plaus_b.tobytes(), k
        assert mon_a.tobytes() == mon_b.tobytes(), k
        violated += not mon_a["passed"][0]
    assert 0 < violated < 300  # the run passes and violates
    assert mon_a["excess"][0][STILL, 3] > 0.0  # the made-up current is no still winding's


def test_with_the_checks_off_the_plausibility_rows_are_untouched() -> None:
    plaus, mon = records()
    mon["excess"][0][LIMIT_GROUPS:] = -7.0
    before = plaus.tobytes()
    for k in range(50):
        check_readings(*tick_inputs(k), False, plaus, mon)
    assert plaus.tobytes() == before
    np.testing.assert_array_equal(mon["excess"][0][LIMIT_GROUPS:], -7.0)


def test_a_wrong_length_is_the_monitors_status() -> None:
    """A short angle array: nothing written; a short current array: as the kernels in turn.

    (The plausibility monitors do not read the currents: they run, the still and consistency
    checks do not, the limit monitor refuses.)
    """
    for which in (1, 4):  # q, the current reading
        plaus_a, mon_a = records()
        plaus_b, mon_b = records()
        args = list(tick_inputs(3))
        args[which] = np.zeros(3)
        f, q, dq, tau, current, u, age, t = args
        before = (plaus_a.tobytes(), mon_a.tobytes())
        status = check_readings(*args, True, plaus_a, mon_a)
        assert status == Status.WRONG_LENGTH.value
        plausibility(q, dq, tau, u, age, plaus_b, mon_b)
        assert monitor(f, q, dq, tau, current, u, t, mon_b) == status
        assert (plaus_a.tobytes(), mon_a.tobytes()) == (plaus_b.tobytes(), mon_b.tobytes())
        assert (plaus_a.tobytes() == before[0]) == (which == 1)
