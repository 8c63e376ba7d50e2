"""The belt monitor: persistence exactly as derived, one miscount ignored, a stop caught in time.

The monitor (exo_ctrl/safety/belt_monitor.py) trips when |v_set - v̂| exceeds 0.1 m/s for
N + 1 ticks in a row, N the encoder's window.  The no-false-alarm runs are those of
tests/safety/test_plausibility.py (contact on and off); here the derivation's margin: the
largest healthy deviation stays below a third of the threshold.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from exo_ctrl.plant import ContactParams
from exo_ctrl.safety import ResolvedLimits, monitor_record
from exo_ctrl.safety.belt_monitor import (
    BELT,
    BELT_DEVIATION_MPS,
    belt_monitor,
    belt_monitor_record,
    detection_bound_s,
)
from exo_ctrl.sensing import BeltEncoder, BeltEncoderParams
from exo_ctrl.sensing.belt_encoder import read_belt
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.faults import Fault

DT = 1e-3
LIMITS = ResolvedLimits(*(np.full(4, 1e9) for _ in range(5)))
ON = ContactParams(enabled=True)


def fresh(window: int = 10) -> tuple[np.ndarray, np.ndarray]:
    mon = monitor_record(LIMITS, math.inf)
    mon["limit"][0][BELT, 0] = BELT_DEVIATION_MPS
    return belt_monitor_record(window), mon


def run(set_speed: np.ndarray, measured: np.ndarray, window: int = 10) -> np.ndarray:
    """The channel's excess per tick."""
    state, mon = fresh(window)
    sched = np.stack((set_speed, np.zeros_like(set_speed)), axis=1)
    reading = np.zeros(1)
    out = np.zeros(set_speed.shape[0])
    for k in range(set_speed.shape[0]):
        reading[0] = measured[k]
        belt_monitor(k, sched, reading, state, mon)
        out[k] = mon["excess"][0][BELT, 0]
        assert np.all(mon["excess"][0][BELT, 1:] < 0.0)
    return out


def test_a_deviation_trips_after_exactly_window_plus_one_ticks_and_resets() -> None:
    n = 60
    set_speed = np.full(n, 0.6)
    measured = np.full(n, 0.6)
    measured[10:21] = 0.45  # 11 ticks beyond 0.1 m/s: trips on the 11th
    measured[30:40] = 0.45  # 10 ticks: does not
    excess = run(set_speed, measured)
    assert np.flatnonzero(excess > 0.0).tolist() == [20]
    assert excess[20] == pytest.approx(0.15 - BELT_DEVIATION_MPS, abs=1e-12)
    assert np.all(excess[30:40] < 0.0)
    # A NaN reading counts as beyond the threshold, and is reported as not finite.
    measured[45:] = math.nan
    assert math.isnan(run(set_speed, measured)[55])


def test_one_miscount_never_trips_it() -> None:
    """A count off by 4000 (15 cm of belt) for one tick, then a permanent jump of 4000 counts:
    each moves the reading for at most N ticks, fewer than the persistence N + 1."""
    enc = BeltEncoderParams()
    rec = np.zeros(1, dtype=[("x", float), ("v", float)])
    encoder = BeltEncoder(enc, DT)
    n, v = 400, 0.6
    readings = np.zeros(n)
    for k in range(n):
        rec["v"] = v
        rec["x"] = v * k * DT + (4000 * enc.resolution_m if k == 100 or k >= 200 else 0.0)
        read_belt(encoder.record, k, rec)
        readings[k] = encoder.speed[0]
    assert np.max(np.abs(readings - v)) > 10.0  # the glitches are large
    assert np.all(run(np.full(n, v), readings) < 0.0)


def test_the_detection_bound_and_a_belt_stop_caught_within_it() -> None:
    """The default stop at full speed (0.583 m/s): the feet carry a few newtons (fixed pelvis),
    so the belt decelerates at nearly F_max / m_b = 50 m/s²; bound 2.1 + 10 + 10 ms."""
    bound = detection_bound_s(0.583, 50.0 - 5.0, 10, DT, 3.8e-5)
    assert bound == pytest.approx((0.1 + 3.8e-3) / 45.0 + 0.02, rel=1e-12)
    assert detection_bound_s(0.09, 50.0, 10, DT, 3.8e-5) == math.inf  # below the threshold
    result = simulate(SimConfig(contact=ON, faults=(Fault("belt_stop", 2.0),), duration_s=2.3))
    trips = [e for e in result.events if e["quantity"] == "belt speed deviation"]
    assert trips and trips[0]["limit"] == BELT_DEVIATION_MPS
    assert trips[0]["message"].startswith("|belt speed deviation| ")
    s = result.signals
    friction = np.abs(s["ground_force"][2000:2030, :, 0]).sum(axis=1).max()
    assert friction < 5.0  # the bound's assumption
    assert 0.0 < trips[0]["t"] - 2.0 <= bound + 1e-9
    assert result.safety_state == "holding"


@pytest.mark.parametrize("sync", [True, False], ids=["sync", "nosync"])
@pytest.mark.parametrize("controller", ["pd", "ct"])
def test_the_healthy_belt_stays_within_a_third_of_the_threshold(controller, sync) -> None:
    """The derivation's measurement: the largest |v_set - v̂| of the default contact runs."""
    s = simulate(SimConfig(controller=controller, contact=ON, sync=sync)).signals
    deviation = np.abs(s["belt_speed_set"] - s["belt_speed_meas"]).max()
    print(f"{controller} sync {sync}: largest deviation {1e3 * deviation:.1f} mm/s")
    assert deviation < BELT_DEVIATION_MPS / 3.0
