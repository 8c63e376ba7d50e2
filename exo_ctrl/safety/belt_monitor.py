r"""The belt monitor: the treadmill's measured speed against its set speed.

With the belt modelled (contact on) the device knows the treadmill's set
speed v_set (the session's command, :mod:`exo_ctrl.plant.belt`) and reads the
belt encoder's speed v̂ (:mod:`exo_ctrl.sensing.belt_encoder`).  A belt that
stops (a jammed roller, the treadmill's own emergency stop), runs away or
whose encoder fails makes them disagree; the gait, planned for the belt
(and, synchronised, from v̂), then drags or pushes the stance feet.  The
monitor's one channel, ``belt speed deviation`` (row :data:`BELT`, column
0 of the monitor record, m/s), is violated when

.. math::

    |v_{set} - \hat v| > Δv_{max}\quad\text{for } P \text{ ticks in a row},

and its value is the deviation of the tick it trips on.

**Threshold** :data:`BELT_DEVIATION_MPS` = 0.1 m/s.  The largest deviation
of the default contact runs (measured with the default 10 ms encoder
window: the heel-strike dips, a foot's friction impulse slowing the 20 kg
belt, the encoder's 3.8 mm/s quantum and its 5 ms lag during the ramp-in):
PD 12 mm/s synchronised, 18 mm/s with the precomputed plan; CT 8 mm/s either
way (and the QP, on the same precomputed plan); the spastic PD run 25 mm/s,
after its stop, its held stance feet dragging on the running belt; a speed
profile 0.4 → 0.7 m/s 12-13 mm/s (tests/safety/test_belt_monitor.py prints the
PD and CT runs).  The
threshold is four times the largest, 0.1 m/s, a sixth of the default belt
speed (0.58 m/s).

**Persistence** P = N + 1 ticks, N the encoder's window in ticks (11 ms by
default).  The healthy runs never come within a factor of three of the
threshold, so the dips need none; the persistence is against the sensor:
the reading is a count difference over N ticks, so one wrong count (a
miscount, a glitch on the line) enters and leaves the difference within N
ticks, and N + 1 readings in a row beyond the threshold cannot come from a
single count.

**Detection time.**  A belt braked at F_br decelerates at a ≥ (F_br -
Σ μ F_n) / m_b (the feet's friction at most against it); the reading, the
mean speed over the last N ticks, passes the threshold plus one quantum
Δx / (N Δt) within (Δv_max + Δx / (N Δt)) / a + N Δt, and the channel
trips P - 1 ticks later.  With the drive's 1000 N on the 20 kg belt (the
feet carry a few N with the fixed pelvis): 2 + 10 + 10 ms, about 22 ms.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel, record

__all__ = [
    "BELT",
    "BELT_DEVIATION_MPS",
    "BELT_MONITOR_FIELDS",
    "belt_monitor",
    "belt_monitor_record",
    "detection_bound_s",
]

#: The monitor record's row of the belt channel (after the plausibility groups).
BELT = 11

#: Largest |v_set - v̂| of a healthy belt and encoder [m/s] (module docstring).
BELT_DEVIATION_MPS = 0.1

#: The belt monitor's state: ``persist`` P [ticks], ``count`` readings beyond
#: the threshold in a row.
BELT_MONITOR_FIELDS = [("persist", np.float64), ("count", np.float64)]


def belt_monitor_record(window_ticks: int) -> np.ndarray:
    """The monitor's record for an encoder window of N = ``window_ticks`` ticks (P = N + 1)."""
    state = record(BELT_MONITOR_FIELDS)
    state["persist"] = int(window_ticks) + 1
    return state


def detection_bound_s(
    speed_mps: float,
    deceleration_mps2: float,
    window_ticks: int,
    dt: float,
    resolution_m: float,
) -> float:
    """The longest time from a belt stop's onset to the channel's trip [s] (module docstring).

    Args:
        speed_mps: the set speed at the onset [m/s] (must exceed the threshold
            plus a quantum, or the stop is not seen: ``inf``).
        deceleration_mps2: a lower bound of the braked belt's deceleration [m/s²].
        window_ticks: the encoder's window N [ticks].
        dt: control period Δt [s].
        resolution_m: the encoder's count Δx [m].

    """
    quantum = resolution_m / (window_ticks * dt)
    if speed_mps <= BELT_DEVIATION_MPS + quantum or deceleration_mps2 <= 0.0:
        return math.inf
    drop = (BELT_DEVIATION_MPS + quantum) / deceleration_mps2
    return drop + window_ticks * dt + window_ticks * dt  # reading's window, then P - 1 ticks


@kernel
def belt_monitor(k, set_speed, measured, state, mon):
    """One tick of the belt monitor: row :data:`BELT` of the monitor record's ``excess``.

    Args:
        k: control tick index.
        set_speed: the treadmill's set speed per tick, (n, 2) [m/s, m/s²]
            (column 0 read).
        measured: the belt encoder's reading, (1,) [m/s].
        state: the record of :data:`BELT_MONITOR_FIELDS`.
        mon: the monitor record (``excess`` and ``limit`` row BELT; column
            0 is the channel, columns 1-3 stay unused, -1).

    """
    s = state[0]
    m = mon[0]
    n = set_speed.shape[0]
    dev = abs(set_speed[k if k < n else n - 1, 0] - measured[0])
    excess = dev - m.limit[BELT, 0]
    if not excess <= 0.0:  # a NaN reading counts as beyond
        s.count += 1.0
    else:
        s.count = 0.0
    m.excess[BELT, 0] = excess if s.count >= s.persist else -1.0
    for i in range(1, 4):
        m.excess[BELT, i] = -1.0
