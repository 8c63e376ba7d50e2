"""The drives' current sensors: what the supervisor knows of the motor currents.

A servo driver measures its winding current to close its current loop; the
supervisor's over-current monitor reads that measurement, never the plant's
current.  The reading at control tick k is the mean winding current over the
last plant step (a driver averages its samples over the control period),
plus white noise, quantised to the converter's step ΔI,

    I_m = ΔI round((Ī + n_I) / ΔI),   n_I ~ N(0, σ_I²).

**Defaults** (chosen; the class of the Hall-effect current sensing of a
±50 A servo driver read by a 12-bit converter): ``resolution_A`` = 100 A /
4096 = 0.0244 A, ``noise_std_A`` = 0.05 A (about two steps after averaging
over a control period), ``seed`` = 1 (a stream of its own, apart from the
joint sensors' ``SensorParams.seed``).  :meth:`CurrentSensorParams.ideal`
reads the mean current exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import _validate as v
from .._jit import Status, check, kernel, record

__all__ = ["CURRENT_SENSOR_FIELDS", "CurrentSensor", "CurrentSensorParams"]

#: Noise samples drawn at a time, per drive.
NOISE_BLOCK = 1000


@dataclass(frozen=True)
class CurrentSensorParams:
    """The drives' current sensors, the same for the four drives (module docstring).

    Attributes:
        noise_std_A: σ_I, white noise on the reading, std [A].
        resolution_A: ΔI, the converter's step [A] (0: none).
        seed: seed of the noise generator (an integer >= 0).

    Raises:
        InvalidParameter: a negative noise or step, a seed that is not an integer >= 0.

    """

    noise_std_A: float = 0.05
    resolution_A: float = 100.0 / 4096
    seed: int = 1

    def __post_init__(self) -> None:
        v.non_negative("current sensor noise_std", self.noise_std_A, "A")
        v.non_negative("current sensor resolution", self.resolution_A, "A")
        sane = "a sanity range: beyond it the monitors' arithmetic overflows"
        v.within("current sensor noise_std", self.noise_std_A, 0.0, 1e3, "A", sane)
        v.within("current sensor resolution", self.resolution_A, 0.0, 1e3, "A", sane)
        v.seed("current sensor seed", self.seed)

    @classmethod
    def ideal(cls) -> CurrentSensorParams:
        """The exact mean current: no noise, no quantisation."""
        return cls(noise_std_A=0.0, resolution_A=0.0)


#: Fields of the sensor's record: ``current`` the reading [A] (4), ``res``
#: ΔI [A], ``row`` of the noise block for the next read, ``depleted`` (the
#: last read used the block up), ``noise`` the block (NOISE_BLOCK, 4) [A].
CURRENT_SENSOR_FIELDS = [
    ("current", np.float64, (4,)),
    ("res", np.float64),
    ("row", np.int64),
    ("depleted", np.bool_),
    ("noise", np.float64, (NOISE_BLOCK, 4)),
]


class CurrentSensor:
    """The four drives' current sensors, read once per control tick.

    :meth:`read` writes the reading into :attr:`current` (a view of the
    record, allocated once) and returns it.  The noise sequence depends only
    on the seed and the number of reads.

    Args:
        params: the sensors' parameters (None: the defaults).

    """

    def __init__(self, params: CurrentSensorParams | None = None) -> None:
        self.params = params if params is not None else CurrentSensorParams()
        self.record = record(CURRENT_SENSOR_FIELDS)
        self.record["res"][0] = self.params.resolution_A
        #: The reading [A], (4,): a view of the record, overwritten by each read.
        self.current = self.record["current"][0]
        self._noise = self.record["noise"][0]
        self._rng = np.random.default_rng(self.params.seed)
        self.draw()

    def read(self, current_true: np.ndarray) -> np.ndarray:
        """The reading of the mean currents ``current_true`` (4,) [A]; returns :attr:`current`."""
        if type(current_true) is not np.ndarray:
            (current_true,) = v.arrays((4,), current_true=current_true)
        status = read_current(current_true, self.record)
        if status:
            check(status, "CurrentSensor.read", current_true=current_true)
        if self.record["depleted"][0]:
            self.draw()
        return self.current

    def draw(self) -> None:
        """Draw the next block of noise (a read calls it when the block is used up)."""
        self._rng.standard_normal(out=self._noise)
        np.multiply(self._noise, self.params.noise_std_A, out=self._noise)
        self.record["row"][0] = 0
        self.record["depleted"][0] = False


@kernel
def read_current(current_true, sensor):
    """One read: I_m = ΔI round((Ī + n_I) / ΔI) per drive into ``sensor``'s ``current``.

    Returns ``Status.WRONG_LENGTH`` (nothing written) for an input not of
    length 4, else ``Status.OK``.  A NaN current reads as NaN (the monitor
    refuses it).
    """
    if current_true.shape[0] != 4:
        return Status.WRONG_LENGTH.value
    s = sensor[0]
    i = s.row
    step = s.res
    for j in range(4):
        x = current_true[j] + s.noise[i, j]
        s.current[j] = np.rint(x / step) * step if step > 0.0 else x
    s.row = i + 1
    s.depleted = i + 1 == s.noise.shape[0]
    return Status.OK.value
