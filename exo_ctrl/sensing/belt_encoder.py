"""The treadmill's belt-speed sensor: an incremental encoder on a roller.

The encoder counts the belt's travel x_b (:mod:`exo_ctrl.plant.belt`) in
steps of Δx, ``n = floor(x_b / Δx)``, and the speed is the count difference
over a window of N control ticks, ``v_m = Δx (n_k - n_{k-N}) / (N Δt)``
(fewer ticks at the start, the first reading being the true speed).  Its
resolution is Δx / (N Δt) and it lags by N Δt / 2.

**Defaults** (chosen; a treadmill's speed feedback of this class):
``resolution_m = 3.8e-5`` m, a 2048-line encoder read in quadrature (8192
counts a turn) on a roller of 0.10 m diameter (π · 0.10 / 8192);
``window_s = 0.01`` s: a speed resolution of 3.8 mm/s and a 5 ms lag.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import _validate as v
from .._jit import kernel, record

__all__ = ["BELT_ENCODER_FIELDS", "BeltEncoder", "BeltEncoderParams", "belt_tick"]

#: The longest window, in ticks (the record's ring of counts).
MAX_WINDOW_TICKS = 1000


@dataclass(frozen=True)
class BeltEncoderParams:
    """The belt-speed encoder (module docstring).

    Attributes:
        resolution_m: Δx, belt travel per count [m].
        window_s: the speed's difference window [s] (at least one tick, at
            most :data:`MAX_WINDOW_TICKS`).

    Raises:
        InvalidParameter: a resolution or window that is not a finite number > 0.

    """

    resolution_m: float = 3.8e-5
    window_s: float = 0.01

    def __post_init__(self) -> None:
        res = v.positive("belt encoder resolution", self.resolution_m, "m")
        object.__setattr__(self, "resolution_m", res)
        object.__setattr__(self, "window_s", v.positive("belt encoder window", self.window_s, "s"))


#: Fields of the encoder's record: ``res`` Δx [m], ``dt`` Δt [s], ``window``
#: N [ticks], ``counts`` the ring of the last counts, ``speed`` the reading
#: [m/s].
BELT_ENCODER_FIELDS = [
    ("res", np.float64),
    ("dt", np.float64),
    ("window", np.int64),
    ("counts", np.float64, (MAX_WINDOW_TICKS + 1,)),
    ("speed", np.float64),
]


class BeltEncoder:
    """The belt-speed reading, one per control tick.

    Args:
        params: the encoder.
        dt: control period Δt [s].

    """

    def __init__(self, params: BeltEncoderParams, dt: float) -> None:
        self.params = params
        self.record = record(BELT_ENCODER_FIELDS)
        r = self.record[0]
        r["res"], r["dt"] = params.resolution_m, float(dt)
        r["window"] = min(max(math.floor(params.window_s / dt + 0.5), 1), MAX_WINDOW_TICKS)
        #: The last reading [m/s], (1,) (filled in place).
        self.speed = self.record["speed"]

    def read(self, k: int, belt: np.ndarray) -> float:
        """The reading at tick ``k`` of the belt record ``belt`` (fields ``x``, ``v``) [m/s]."""
        read_belt(self.record, k, belt)
        return float(self.speed[0])


@kernel
def read_belt(encoder: np.ndarray, k: int, belt: np.ndarray) -> None:
    """Count the belt's travel and difference the counts over the window (in place)."""
    e = encoder[0]
    b = belt[0]
    n = np.floor(b.x / e.res)
    size = MAX_WINDOW_TICKS + 1
    e.counts[k % size] = n
    if k == 0:
        e.speed = b.v
        return
    back = e.window if k >= e.window else k
    e.speed = e.res * (n - e.counts[(k - back) % size]) / (back * e.dt)


@kernel
def belt_tick(
    encoder: np.ndarray, k: int, belt: np.ndarray, set_speed: np.ndarray, drive_force: np.ndarray
) -> None:
    """Control tick ``k`` on the belt: its set speed, the encoder's read, the drive's report.

    The treadmill's set speed and rate of tick k (``set_speed[k]``, [m/s, m/s²])
    into the belt record ``belt`` (``v_set``, ``a_set``), the encoder's read
    (:func:`read_belt`), and the treadmill drive's report of its force (the
    belt's ``f_motor``) into ``drive_force`` [N], (1,).
    """
    b = belt[0]
    b.v_set = set_speed[k, 0]
    b.a_set = set_speed[k, 1]
    read_belt(encoder, k, belt)
    drive_force[0] = b.f_motor
