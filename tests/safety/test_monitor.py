"""The limit monitor kernel: each channel's excess, the tick's verdict, its status."""

from __future__ import annotations

import math

import numpy as np
import pytest

from exo_ctrl._jit import Status
from exo_ctrl.model import CUFF_NAMES, JOINT_NAMES
from exo_ctrl.safety import ResolvedLimits, channels, monitor, monitor_record
from exo_ctrl.safety.monitor import CUFF, CURRENT, GROUPS, LOWER, SPEED, TORQUE, UPPER, VOLTAGE

LIMITS = ResolvedLimits(
    q_lower=np.array([-0.4, 0.1, -0.4, 0.1]),
    q_upper=np.array([0.7, 1.5, 0.7, 1.5]),
    speed_limit=np.full(4, 6.0),
    current_limit=np.full(4, 9.0),
    cuff_limit=np.array([220.0, 130.0, 220.0, 130.0]),
)


def inputs() -> dict[str, np.ndarray]:
    """Readings well inside the limits."""
    return {
        "cuff_force": np.array([[30.0, -40.0], [10.0, 20.0], [0.0, 50.0], [-5.0, 5.0]]),
        "q": np.array([0.2, 0.5, -0.1, 0.9]),
        "dq": np.array([1.0, -2.0, 0.5, 3.0]),
        "tau": np.array([10.0, -20.0, 5.0, 1.0]),
        "current_A": np.array([1.0, -2.0, 3.0, -4.0]),
        "u_cmd": np.array([0.5, -1.0, 2.0, 0.0]),
    }


def call(state: np.ndarray, t: float = 0.1, **changes: np.ndarray) -> int:
    x = {**inputs(), **changes}
    return monitor(x["cuff_force"], x["q"], x["dq"], x["tau"], x["current_A"], x["u_cmd"], t, state)


def test_every_channel_excess_is_value_minus_limit() -> None:
    state = monitor_record(LIMITS, math.inf)
    x = inputs()
    assert call(state) == Status.OK
    s = state[0]
    f = x["cuff_force"]
    np.testing.assert_array_equal(s["excess"][CUFF], (f**2).sum(axis=1) - LIMITS.cuff_limit**2)
    np.testing.assert_array_equal(s["excess"][UPPER], x["q"] - LIMITS.q_upper)
    np.testing.assert_array_equal(s["excess"][LOWER], LIMITS.q_lower - x["q"])
    np.testing.assert_array_equal(s["excess"][SPEED], np.abs(x["dq"]) - 6.0)
    np.testing.assert_array_equal(s["excess"][CURRENT], np.abs(x["current_A"]) - 9.0)
    assert np.all(s["excess"][TORQUE] < 0) and np.all(s["excess"][VOLTAGE] < 0)
    assert s["worst"] == 0.0 and s["passed"]
    np.testing.assert_array_equal(s["q_last"], x["q"])
    np.testing.assert_array_equal(s["u_last"], x["u_cmd"])
    assert len(GROUPS) == s["excess"].shape[0] == 14  # 7 limit groups, 6 plausibility, belt


def test_worst_sums_the_violations_and_the_last_good_tick_is_kept() -> None:
    state = monitor_record(LIMITS, math.inf)
    assert call(state) == Status.OK
    good_q = state[0]["q_last"].copy()
    q = inputs()["q"]
    q[1] = 1.6  # 0.1 rad over its upper limit
    dq = inputs()["dq"]
    dq[3] = -6.5  # 0.5 rad/s over
    assert call(state, q=q, dq=dq) == Status.OK
    s = state[0]
    assert s["worst"] == pytest.approx(0.6, rel=1e-12)
    assert not s["passed"]
    np.testing.assert_array_equal(s["q_last"], good_q)
    q[1] = math.nan
    assert call(state, q=q) == Status.OK
    assert math.isnan(state[0]["worst"]) and not state[0]["passed"]
    tau = inputs()["tau"]
    tau[0] = math.inf
    assert call(state, tau=tau) == Status.OK
    assert state[0]["worst"] == math.inf and not state[0]["passed"]


def test_no_tick_passes_after_the_estop_time_or_once_stopped() -> None:
    state = monitor_record(LIMITS, 0.5)
    assert call(state, t=0.499) == Status.OK and state[0]["passed"]
    assert call(state, t=0.5) == Status.OK and not state[0]["passed"]
    assert state[0]["worst"] == 0.0
    state = monitor_record(LIMITS, math.inf)
    state["state"] = 1.0
    assert call(state) == Status.OK and not state[0]["passed"]
    assert np.isnan(state[0]["q_last"]).all()


@pytest.mark.parametrize(
    "change",
    [
        {"q": np.zeros(3)},
        {"dq": np.zeros(5)},
        {"tau": np.zeros(3)},
        {"current_A": np.zeros(2)},
        {"u_cmd": np.zeros(3)},
        {"cuff_force": np.zeros((2, 2))},
        {"cuff_force": np.zeros((4, 3))},
    ],
)
def test_wrong_lengths_are_a_status_and_write_nothing(change) -> None:
    state = monitor_record(LIMITS, math.inf)
    before = state.tobytes()  # the raw bytes: a copy() leaves an aligned record's padding out
    assert call(state, **change) == Status.WRONG_LENGTH
    assert state.tobytes() == before


def test_channels_name_and_measure_each_violation() -> None:
    table = channels(LIMITS, use_estimate=False)
    assert len(table) == 56
    assert table[44].quantity == "torque sensor vs current left_hip" and table[44].limit > 1e300
    assert table[51].quantity == "still encoder vs current right_knee" and table[51].unit == "A"
    assert table[52].quantity == "belt speed deviation" and table[52].limit > 1e300
    assert channels(LIMITS, False, belt_limit=0.1)[52].limit == 0.1
    assert [c.quantity for c in table[:4]] == [f"cuff force {n}" for n in CUFF_NAMES]
    assert [c.quantity for c in table[4:8]] == [f"angle {n}" for n in JOINT_NAMES]
    assert table[8].quantity == "angle left_hip" and table[8].limit == -0.4
    assert table[5].limit == 1.5 and table[1].limit == 130.0
    assert channels(LIMITS, use_estimate=True)[0].quantity == "estimated cuff force left_thigh"
    # The value is recovered from the excess the kernel writes.
    state = monitor_record(LIMITS, math.inf)
    f = inputs()["cuff_force"]
    f[1] = (120.0, 90.0)  # |f| = 150 N > 130 N
    q = inputs()["q"]
    q[2] = -0.45  # below -0.4 rad
    assert call(state, cuff_force=f, q=q) == Status.OK
    excess = state[0]["excess"].ravel()
    value, text = table[1].describe(float(excess[1]))
    assert value == pytest.approx(150.0, rel=1e-12)
    assert text == "cuff force left_shank 150 N > limit 130 N"
    value, text = table[LOWER * 4 + 2].describe(float(excess[LOWER * 4 + 2]))
    assert value == pytest.approx(-0.45, rel=1e-12)
    assert text == "angle right_hip -0.45 rad < lower limit -0.4 rad"
    assert table[TORQUE * 4].finite_only(1.0) and table[0].finite_only(math.nan)
    assert not table[0].finite_only(1.0)
