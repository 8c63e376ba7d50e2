r"""Instrumented cuffs: a force sensor between each cuff's shell and the exoskeleton link.

The joint torque sensors see two combinations of a leg's four cuff-force
components (:mod:`exo_ctrl.estimation.cuff_geometry`); the rest the
estimator takes from the device's models.  A force sensor in each cuff
measures what the torques cannot.  Three sensor sets (``mode``):

- ``"none"`` (default): no cuff sensor, the device as before;
- ``"normal"``: a single-axis load cell under each cuff's shell, reading
  the normal component n · f (n the exoskeleton link's normal, f the cuff's
  force on the exoskeleton);
- ``"full"``: a sensor reading both sagittal components in the link's
  frame, n · f and the along-link u · f (u the link's direction, joint →
  cuff).  The axes turn with the exoskeleton's link, to which the sensor is
  bolted.

**Model** (per cuff c and measured axis a, at the sensor's samples t_i on
the grid t₀ + i T_s, T_s = 1 / ``sample_rate_hz``; between samples the
last sample is held):

    y_i = f_a(t_i) + b_a + w_a(t_i) + e_i,
    e_i ~ N(0, σ_e²),   b_a ~ N(0, σ_b²) drawn once per run,
    w_a(t_{i+1}) = w_a(t_i) + σ_w √T_s ν_i,   ν_i ~ N(0, 1),   w_a(t₀) = 0,

f_a the plant's true component (the force over the last plant step, the
estimator's estimand), b the residual offset left after the sensor is
zeroed at the fit, w the zero drift over the session (a random walk), e the
white noise.  The offsets, then blocks of noise and of the walk's steps,
come from ``numpy.random.default_rng(seed)``: a run is reproducible.  The
truth (the offsets, the walk) stays in the sensor's record; the estimator
reads only the readings record (:data:`CUFF_READING_FIELDS`).

**The part and its values.**  The ATI Industrial Automation Axia80-M20
six-axis force/torque sensor, calibration SI-500-20 (F_x, F_y ±500 N,
F_z ±900 N; Document #9610-05-Ethernet Axia-09, "Manual, F/T Sensor,
Ethernet Axia", §4.8 Table 4.8 and §15.3), as used between a cuff and an
exoskeleton link; one axis of it for ``normal``, two for ``full``:

- ``noise_std_N`` = 0.25 N: the manual's §14.5 (Table 14.5, "Noise") calls
  jumps of the unloaded reading above 0.05 % of full scale abnormal:
  0.05 % of 500 N.  Taken as the noise's standard deviation (conservative:
  it is the bound on the jumps).
- ``offset_std_N`` = 1.0 N: chosen, 0.2 % of the 500 N range.  The manual
  has the sensor biased (zeroed) before use and names no residual offset;
  the zero stability of strain-gauge transducers of this class is 0.1–0.5 %
  of full scale (the figure :mod:`.sensors` uses for the joint torque
  sensors), and strapping a cuff on a limb preloads it.
- ``drift_N_per_sqrt_s`` = 0.05 N/√s: chosen; the walk's standard
  deviation is 0.16 N after 10 s and 0.5 N after 100 s, well inside the
  offset's: the manual (§14.5, "Drift") treats a reading that keeps moving
  after the load is removed as a fault, so a healthy sensor drifts slowly.
- ``sample_rate_hz`` = 500 Hz: chosen, half the control rate; the Axia's
  output rate is set by the user (the manual's ADC settings page, §6.4),
  so a real installation reads it slower than the joints to save bus time;
  the hold between samples is modelled.
- ``tare_s`` = 0 (off): the device's zeroing while it stands at the start
  (done by the estimator, :mod:`exo_ctrl.estimation.kalman_cuff`; 0.3 s,
  150 samples at 500 Hz, average the noise down to 0.02 N) takes the
  standing model's error for an offset: with the patient's cuffs scattered
  around the published ones it leaves up to 15 N on a measured component
  of the default gait (:mod:`exo_ctrl.control.qp.margin`, e_cuffs) to
  remove an offset of σ_b = 1 N, so it is off unless asked for.  Without
  it the estimator carries each axis's bias (offset and drift, from these
  σ_b and σ_w) as a state of its own and finds it over the gait
  (:mod:`exo_ctrl.estimation.kalman_cuff`).
- ``seed`` = 3: a stream of its own (the joints' sensors use 0, the current
  sensors 1, the foot plates 2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import _validate as v
from .._jit import kernel, record

__all__ = [
    "CUFF_READING_FIELDS",
    "CUFF_SENSOR_FIELDS",
    "CUFF_SENSOR_SETS",
    "CuffSensorParams",
    "CuffSensors",
    "read_cuffs",
]

#: The sensor sets (module docstring), by the number of axes each reads (0, 1, 2).
CUFF_SENSOR_SETS = ("none", "normal", "full")

#: Samples of noise (and of the walk's steps) drawn at a time, per axis.
NOISE_BLOCK = 1000

_SANE = "a sanity range: beyond it the filter's arithmetic overflows"


@dataclass(frozen=True)
class CuffSensorParams:
    """The cuffs' force sensors, the same for the four cuffs (module docstring).

    Attributes:
        mode: the sensor set, ``"none"``, ``"normal"`` or ``"full"`` (module docstring).
        noise_std_N: σ_e, white noise on each axis, std [N].
        offset_std_N: σ_b, std of the offset drawn once per run per axis [N].
        drift_N_per_sqrt_s: σ_w, intensity of the zero drift's random walk [N/√s].
        sample_rate_hz: the sensors' sample rate [Hz] (held between samples).
        seed: seed of the noise generator (an integer >= 0).
        tare_s: the device's zeroing at the start, while it stands [s]: the
            filter averages each axis's reading less its model's force over
            this window and subtracts the mean from later readings
            (:mod:`exo_ctrl.estimation.kalman_cuff`); 0: no tare (default,
            module docstring).

    Raises:
        InvalidParameter: a mode not in :data:`CUFF_SENSOR_SETS`, a negative
            or huge noise, offset or drift, a sample rate outside
            [1, 100000] Hz, a seed that is not an integer >= 0.

    """

    mode: str = "none"
    noise_std_N: float = 0.25
    offset_std_N: float = 1.0
    drift_N_per_sqrt_s: float = 0.05
    sample_rate_hz: float = 500.0
    seed: int = 3
    tare_s: float = 0.0

    def __post_init__(self) -> None:
        v.one_of("cuff_sensors mode", self.mode, CUFF_SENSOR_SETS)
        v.within("cuff_sensors noise_std", self.noise_std_N, 0.0, 1e4, "N", _SANE)
        v.within("cuff_sensors offset_std", self.offset_std_N, 0.0, 1e4, "N", _SANE)
        v.within("cuff_sensors drift", self.drift_N_per_sqrt_s, 0.0, 1e4, "N/√s", _SANE)
        v.within("cuff_sensors sample_rate", self.sample_rate_hz, 1.0, 1e5, "Hz", _SANE)
        v.seed("cuff_sensors seed", self.seed)
        v.within("cuff_sensors tare", self.tare_s, 0.0, 60.0, "s", "a minute at most")

    @property
    def axes(self) -> int:
        """Axes read per cuff: 0 (none), 1 (the normal), 2 (normal and along)."""
        return CUFF_SENSOR_SETS.index(self.mode)

    @property
    def on(self) -> bool:
        """Whether the run has cuff sensors."""
        return self.mode != "none"

    @property
    def tared(self) -> bool:
        """Whether the run has cuff sensors and the device tares them (``tare_s`` > 0)."""
        return self.on and self.tare_s > 0.0


#: The sensors' record.  Parameters: ``dt`` Δt [s], ``period`` T_s [s],
#: ``step`` σ_w √T_s [N], ``axes``; state: ``started``, ``t0`` the first
#: sample's time [s], ``next_t`` the next's [s], ``samples`` taken, ``row``
#: of the blocks, ``depleted`` (draw the next blocks); the truth the
#: estimator never reads: ``true`` the last sample's true (normal, along)
#: per cuff [N], ``offset`` b [N], ``drift`` w [N] (4, 2 each); ``noise``
#: and ``walk``, the blocks (NOISE_BLOCK, 8: cuff c's axis a in column 2 c + a).
CUFF_SENSOR_FIELDS = [
    ("dt", np.float64),
    ("period", np.float64),
    ("step", np.float64),
    ("axes", np.int64),
    ("started", np.bool_),
    ("t0", np.float64),
    ("next_t", np.float64),
    ("samples", np.int64),
    ("row", np.int64),
    ("depleted", np.bool_),
    ("true", np.float64, (4, 2)),
    ("offset", np.float64, (4, 2)),
    ("drift", np.float64, (4, 2)),
    ("noise", np.float64, (NOISE_BLOCK, 8)),
    ("walk", np.float64, (NOISE_BLOCK, 8)),
]

#: What the device reads, the estimator's input: ``reading`` (normal, along)
#: per cuff [N] (an axis not read: NaN), ``fresh`` (a new sample this tick),
#: ``axes`` read per cuff.
CUFF_READING_FIELDS = [
    ("reading", np.float64, (4, 2)),
    ("fresh", np.bool_),
    ("axes", np.int64),
]


class CuffSensors:
    """The four cuffs' force sensors, read once per control tick (module docstring).

    Args:
        params: the sensors (``params.on`` must be True to read anything).
        dt: control period Δt [s].

    Attributes:
        record: the sensors' record (:data:`CUFF_SENSOR_FIELDS`, the truth included).
        readings: the readings' record (:data:`CUFF_READING_FIELDS`), the estimator's input.
        reading: view of the readings (normal, along) per cuff [N], (4, 2).

    """

    def __init__(self, params: CuffSensorParams, dt: float) -> None:
        self.params = params
        self.dt = v.positive("dt", dt, "s")
        self.record = record(CUFF_SENSOR_FIELDS)
        self.readings = record(CUFF_READING_FIELDS)
        self.reading = self.readings["reading"][0]
        s = self.record
        s["dt"] = self.dt
        s["period"] = 1.0 / params.sample_rate_hz
        s["step"] = params.drift_N_per_sqrt_s * math.sqrt(1.0 / params.sample_rate_hz)
        s["axes"] = self.readings["axes"] = params.axes
        self.reset()

    def reset(self) -> None:
        """Restart: reseed, draw the offsets anew, forget the held sample and the walk."""
        self._rng = np.random.default_rng(self.params.seed)
        s = self.record
        s["offset"][0] = self._rng.normal(0.0, 1.0, (4, 2)) * self.params.offset_std_N
        s["drift"] = 0.0
        s["started"] = False
        s["samples"] = 0
        s["next_t"] = -math.inf
        self.readings["reading"] = math.nan
        self.readings["fresh"] = False
        if self.params.on:  # a run without cuff sensors draws nothing
            self.draw()

    def read(self, k: int, plant_cuffs: np.ndarray) -> np.ndarray:
        """Read at tick k the plant's cuffs (its cuff record); returns :attr:`reading`."""
        read_cuffs(k, plant_cuffs, self.record, self.readings)
        if self.record["depleted"][0]:
            self.draw()
        return self.reading

    def draw(self) -> None:
        """Draw the next blocks of noise and of the walk's steps (a read calls it)."""
        s = self.record[0]
        self._rng.standard_normal(out=s["noise"])
        np.multiply(s["noise"], self.params.noise_std_N, out=s["noise"])
        self._rng.standard_normal(out=s["walk"])
        s["row"] = 0
        s["depleted"] = False


@kernel
def read_cuffs(k, plant_cuffs, sensor, out):
    """One read at tick k: hold, or sample the true components into ``out`` (module docstring).

    ``plant_cuffs``: the plant's cuff record (:mod:`exo_ctrl.plant.cuffs`:
    ``f`` the forces on the exoskeleton, x then z; ``cs`` the links' cos
    and sin at the last force evaluation; ``along0``); ``sensor``,
    ``out``: the records of :data:`CUFF_SENSOR_FIELDS` and
    :data:`CUFF_READING_FIELDS`.
    """
    s = sensor[0]
    o = out[0]
    cr = plant_cuffs[0]
    t = k * s.dt
    o.fresh = False
    if s.started and t < s.next_t - 1e-9 * s.dt:
        return  # hold the last sample
    i = s.row
    for c in range(4):
        cc, sc = cr.cs[c], cr.cs[8 + c]
        ux = cr.along0[c, 0] * cc - cr.along0[c, 1] * sc
        uz = cr.along0[c, 1] * cc + cr.along0[c, 0] * sc
        fx, fz = cr.f[c], cr.f[4 + c]
        s.true[c, 0] = -uz * fx + ux * fz
        s.true[c, 1] = ux * fx + uz * fz
        for a in range(2):
            if s.started:
                s.drift[c, a] += s.step * s.walk[i, 2 * c + a]
            if a < s.axes:
                y = s.true[c, a] + s.offset[c, a] + s.drift[c, a] + s.noise[i, 2 * c + a]
                o.reading[c, a] = y
            else:
                o.reading[c, a] = math.nan
    if not s.started:
        s.t0 = t
    n = math.floor((t - s.t0) / s.period + 1e-6) + 1
    s.next_t = s.t0 + n * s.period
    s.started = True
    s.samples += 1
    s.row = i + 1
    s.depleted = i + 1 == s.noise.shape[0]
    o.fresh = True
