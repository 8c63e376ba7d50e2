"""Joint encoders and joint torque sensors of the exoskeleton.

Each drive carries two sensors on the link side of the gearbox:

- an absolute encoder for the joint angle: the reading is the true angle
  plus white noise, quantised to the encoder's resolution Δq,
  ``q_m = Δq round((q + n_q) / Δq)``;
- a strain-gauge joint torque sensor between gearbox and link: the reading
  is the plant's :attr:`~exo_ctrl.plant.plant.Plant.sensor_torque` (drive torque
  minus the rotor's reflected inertia times acceleration) plus a constant
  bias β and white noise, quantised to Δτ,
  ``τ_m = Δτ round((τ + β + n_τ) / Δτ)``.

The sensors are sampled at ``sample_rate_hz``; between samples the last
sample is held (the readings of a control tick that falls between two
samples are the previous sample's).

**Velocity.**  A real drive has no velocity sensor: it differentiates the
encoder.  Here the joint speed is the finite difference of the quantised,
noisy encoder angle over one sample period T_s, passed through a first-order
low-pass filter of cut-off f_v (``velocity_filter_hz``),

    v_k = v_{k-1} + α (Δq_m / T_s − v_{k-1}),   α = 1 − exp(−2π f_v T_s).

The filter starts at the true speed of the first sample (as if the device
had been running), so there is no start-up transient.  ``velocity="true"``
passes the plant's speed through unchanged instead (the ideal sensor).  The
momentum observer (:mod:`exo_ctrl.estimation.observer`) uses this speed once, in
p = M(q) q̇; it never differentiates it again.

**Defaults and where they come from** (override them for a real device):

- ``encoder_resolution_rad = 2π / 2¹⁷`` (4.8e-5 rad): a 17-bit single-turn
  absolute encoder on the joint (output) side, the class of the off-axis
  magnetic and optical absolute encoders built into exoskeleton and
  collaborative-robot joints (e.g. the RLS AksIM-2 family, offered at up to
  20 bits per turn).  Chosen: the low end of that class.
- ``encoder_noise_std_rad = 2e-5`` rad: position jitter below one count
  (≈ 0.4 LSB), as such encoders specify "noise below 1 LSB".  Chosen.
- ``velocity_filter_hz = 30`` Hz: chosen.  Quantisation and jitter make the
  raw 1 kHz finite difference noisy (std ≈ √2 · 2.4e-5 rad / 1 ms ≈ 0.03
  rad/s); 30 Hz brings that to about 0.005 rad/s for a lag of 5 ms.  On the
  default run with the default observer gain the worst cuff's RMS error was
  4.1 / 4.5 / 5.1 % of its peak at 20 / 30 / 50 Hz, and 3.0 / 2.7 / 3.0 %
  beyond the observer's own lag; 20 Hz's lower total comes from its lag
  partly offsetting the observer's on this gait, at an 8 ms speed lag for
  the controller, so 30 Hz is kept.
- ``torque_noise_std_Nm = 0.2`` N·m: strain-gauge joint torque sensors in
  exoskeleton and robot joints (spoke-type sensors with full bridges, or
  commercial static torque sensors of 100–400 N·m range such as those in the
  Project MARCH exoskeleton) reach a noise of 0.1–0.5 N·m at 1 kHz with a
  16-bit acquisition; 0.2 N·m is chosen in that range.
- ``torque_resolution_Nm = 0.01`` N·m: a 16-bit converter over about
  ±300 N·m (chosen).
- ``torque_bias_Nm = 0``: a zero offset (zero drift of such sensors is of
  the order of 0.1–0.5 % of full scale, 0.4–1.8 N·m for a 360 N·m sensor);
  zero by default, set it to study its effect
  (:func:`exo_ctrl.estimation.observer.bias_effect_bound`,
  :func:`exo_ctrl.estimation.observer.estimate_bias`).
- ``sample_rate_hz = 1000`` Hz: the sensors are read every control tick of
  a 1 kHz (EtherCAT-class) control loop.
- ``seed = 0``: noise is drawn from ``numpy.random.default_rng(seed)`` so
  that a run is reproducible.

:meth:`SensorParams.ideal` gives noise-free, unquantised, unbiased sensors
read every tick with the true speed, for tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import _validate as v
from .._jit import Status, check, kernel, record
from ..exceptions import InvalidParameter
from .readings import SensorReadings

__all__ = ["SENSOR_FIELDS", "SensorParams", "Sensors", "read_joints"]

#: Noise samples drawn at a time (per sensor kind), to keep a read cheap.
NOISE_BLOCK = 1000

VELOCITY_SOURCES = ("encoder", "true")


#: Why the sensors' numbers have upper and lower bounds: squared, inverted or
#: counted in ticks, the values beyond them overflow.
_SANE = "a sanity range: beyond it the models' arithmetic overflows"


@dataclass(frozen=True)
class SensorParams:
    """Encoder and torque-sensor parameters, the same for the four joints.

    See the module docstring for the values and their sources.

    Attributes:
        encoder_resolution_rad: encoder quantisation step Δq [rad] (0: none).
        encoder_noise_std_rad: white noise on the angle, std [rad].
        velocity: ``"encoder"`` (filtered finite difference of the encoder)
            or ``"true"`` (the plant's joint speed, ideal).
        velocity_filter_hz: cut-off of the first-order low-pass on the
            finite-difference speed [Hz] (``velocity="encoder"`` only).
        torque_noise_std_Nm: white noise on the torque, std [N·m].
        torque_bias_Nm: constant torque offset β per joint, (4,) or scalar
            [N·m]; stored as a tuple of 4.
        torque_resolution_Nm: torque quantisation step Δτ [N·m] (0: none).
        sample_rate_hz: sampling rate [Hz]; None samples every control tick.
        seed: seed of the noise generator.

    Raises:
        InvalidParameter: a field is out of its range.

    """

    encoder_resolution_rad: float = 2.0 * math.pi / 2**17
    encoder_noise_std_rad: float = 2e-5
    velocity: str = "encoder"
    velocity_filter_hz: float = 30.0
    torque_noise_std_Nm: float = 0.2
    torque_bias_Nm: tuple[float, ...] | float = 0.0
    torque_resolution_Nm: float = 0.01
    sample_rate_hz: float | None = 1000.0
    seed: int = 0

    def __post_init__(self) -> None:
        v.non_negative("encoder_resolution", self.encoder_resolution_rad, "rad")
        if self.encoder_resolution_rad > 0.1:
            raise InvalidParameter(
                "encoder_resolution", self.encoder_resolution_rad, "in [0, 0.1] rad"
            )
        v.non_negative("encoder_noise_std", self.encoder_noise_std_rad, "rad")
        v.within("encoder_noise_std", self.encoder_noise_std_rad, 0.0, 1.0, "rad", _SANE)
        if isinstance(self.velocity, np.ndarray) or self.velocity not in VELOCITY_SOURCES:
            raise InvalidParameter("velocity", self.velocity, "'encoder' or 'true'")
        v.positive("velocity_filter", self.velocity_filter_hz, "Hz")
        v.within("velocity_filter", self.velocity_filter_hz, 0.01, 1e6, "Hz", _SANE)
        v.non_negative("torque_noise_std", self.torque_noise_std_Nm, "N·m")
        v.within("torque_noise_std", self.torque_noise_std_Nm, 0.0, 1e4, "N·m", _SANE)
        v.non_negative("torque_resolution", self.torque_resolution_Nm, "N·m")
        v.within("torque_resolution", self.torque_resolution_Nm, 0.0, 1e4, "N·m", _SANE)
        raw = self.torque_bias_Nm
        many = isinstance(raw, (tuple, list)) or (isinstance(raw, np.ndarray) and raw.ndim > 0)
        for b in raw if many else (raw.item() if isinstance(raw, np.ndarray) else raw,):
            if isinstance(b, (str, bytes, bool, np.bool_)):
                v.finite("torque_bias", b, "N·m")  # refuses text and truth values
        try:
            bias = np.broadcast_to(np.asarray(self.torque_bias_Nm, dtype=float), (4,))
        except (TypeError, ValueError, OverflowError):  # OverflowError: an int beyond float
            raise InvalidParameter(
                "torque_bias", self.torque_bias_Nm, "a finite number or 4 of them [N·m]"
            ) from None
        for b in bias:
            v.finite("torque_bias", float(b), "N·m")
        object.__setattr__(self, "torque_bias_Nm", tuple(float(b) for b in bias))
        if self.sample_rate_hz is not None:
            v.positive("sample_rate", self.sample_rate_hz, "Hz")
            v.within("sample_rate", self.sample_rate_hz, 0.01, 1e6, "Hz", _SANE)
        v.seed("seed", self.seed)

    @property
    def bias(self) -> np.ndarray:
        """Torque bias β per joint [N·m], (4,)."""
        return np.array(self.torque_bias_Nm, dtype=float)

    @classmethod
    def ideal(cls) -> SensorParams:
        """No noise, no quantisation, no bias, sampled every tick, true speed."""
        return cls(
            encoder_resolution_rad=0.0,
            encoder_noise_std_rad=0.0,
            velocity="true",
            torque_noise_std_Nm=0.0,
            torque_bias_Nm=0.0,
            torque_resolution_Nm=0.0,
            sample_rate_hz=None,
        )


class Sensors:
    """The four joints' encoders and torque sensors, read once per control tick.

    :meth:`read` writes into buffers allocated once and returns the same
    :class:`~exo_ctrl.control.base.SensorReadings` object every time (copy its
    arrays to keep them).  Noise is drawn in blocks of :data:`NOISE_BLOCK`
    samples; the sequence depends only on ``seed`` and the number of samples
    taken, so a run is reproducible.  A read is one call of the compiled
    kernel :func:`read_joints`.

    Args:
        params: sensor parameters.
        dt: control period Δt [s] (the spacing of tick indices k).

    """

    def __init__(self, params: SensorParams | None = None, dt: float = 1e-3) -> None:
        self.params = params if params is not None else SensorParams()
        self.dt = v.positive("dt", dt, "s")
        p = self.params
        self._period = 0.0 if p.sample_rate_hz is None else 1.0 / p.sample_rate_hz
        self._noisy_q = p.encoder_noise_std_rad > 0
        self._noisy_tau = p.torque_noise_std_Nm > 0
        self._bias = p.bias
        self._has_bias = bool(np.any(self._bias != 0))
        self._true_speed = p.velocity == "true"
        # Parameters, state, readings and noise blocks in one record
        # (SENSOR_FIELDS); the readings' arrays are views of it.
        self.record = record(SENSOR_FIELDS)
        r = self.record
        s = r[0]
        #: Noise blocks: [0] encoder, [1] torque sensor, each (NOISE_BLOCK, 4).
        self._noise = r["noise"][0]
        r["bias"][0] = self._bias
        s["dt"] = self.dt
        s["period"] = self._period
        s["res_q"] = p.encoder_resolution_rad
        s["filter_hz"] = p.velocity_filter_hz
        s["res_tau"] = p.torque_resolution_Nm
        s["noisy_q"] = self._noisy_q
        s["noisy_tau"] = self._noisy_tau
        s["has_bias"] = self._has_bias
        s["true_speed"] = self._true_speed
        self._depleted = r["depleted"]
        self._row = r["row"]
        self._samples = r["samples"]
        self.readings = SensorReadings(q=r["q"][0], dq=r["dq"][0], tau=r["tau"][0])
        self.reset()

    def reset(self) -> None:
        """Restart: reseed the noise and forget the held sample and speed filter."""
        self._rng = np.random.default_rng(self.params.seed)
        s = self.record[0]
        s["started"] = False
        s["next_t"] = -math.inf
        s["samples"] = 0
        self.draw()

    def read(
        self, k: int, q_true: np.ndarray, dq_true: np.ndarray, tau_true: np.ndarray
    ) -> SensorReadings:
        """The readings at control tick k (t_k = k Δt).

        Args:
            k: control tick index (t_k = k Δt); ticks must not go back in time.
            q_true: true joint angles [rad], (4,).
            dq_true: true joint speeds [rad/s], (4,).
            tau_true: true torque at the sensor (plant ``sensor_torque``) [N·m], (4,).

        Returns:
            The readings (the same object every call, overwritten by the next).

        """
        if not (type(q_true) is type(dq_true) is type(tau_true) is np.ndarray):
            q_true, dq_true, tau_true = v.arrays(
                (4,), q_true=q_true, dq_true=dq_true, tau_true=tau_true
            )
        status = read_joints(k, q_true, dq_true, tau_true, self.record)
        if status:
            check(status, "Sensors.read", q_true=q_true, dq_true=dq_true, tau_true=tau_true)
        if self._depleted[0]:
            self.draw()
        return self.readings

    @property
    def samples(self) -> int:
        """Number of samples taken since construction or :meth:`reset`."""
        return int(self._samples[0])

    def draw(self) -> None:
        """Draw a block of noise (encoder first, then torque: the stream's order).

        A read calls it when the kernel used the last block up.
        """
        p = self.params
        if self._noisy_q:
            self._rng.standard_normal(out=self._noise[0])
            np.multiply(self._noise[0], p.encoder_noise_std_rad, out=self._noise[0])
        if self._noisy_tau:
            self._rng.standard_normal(out=self._noise[1])
            np.multiply(self._noise[1], p.torque_noise_std_Nm, out=self._noise[1])
        self._row[0] = 0
        self._depleted[0] = False


#: Fields of the sensors' record.  Readings: ``q`` [rad], ``dq`` [rad/s],
#: ``tau`` [N·m] (4 each); ``bias`` β [N·m] (4); parameters ``dt`` Δt [s],
#: ``period`` T_s [s] (0: every tick), ``res_q`` Δq [rad], ``filter_hz`` f_v
#: [Hz], ``res_tau`` Δτ [N·m] and the flags ``noisy_q``, ``noisy_tau``,
#: ``has_bias``, ``true_speed``; state: ``started``, ``last_t`` the time of
#: the last sample [s], ``next_t`` that of the next [s], ``t0`` the first's [s]
#: (the grid's origin), ``row`` of the noise
#: block for the next sample, ``samples`` taken, ``depleted`` (the last read
#: used the block up: draw the next); ``noise``, the blocks (encoder, torque).
SENSOR_FIELDS = [
    ("q", np.float64, (4,)),
    ("dq", np.float64, (4,)),
    ("tau", np.float64, (4,)),
    ("bias", np.float64, (4,)),
    ("dt", np.float64),
    ("period", np.float64),
    ("res_q", np.float64),
    ("filter_hz", np.float64),
    ("res_tau", np.float64),
    ("last_t", np.float64),
    ("next_t", np.float64),
    ("t0", np.float64),
    ("row", np.int64),
    ("samples", np.int64),
    ("noisy_q", np.bool_),
    ("noisy_tau", np.bool_),
    ("has_bias", np.bool_),
    ("true_speed", np.bool_),
    ("started", np.bool_),
    ("depleted", np.bool_),
    ("noise", np.float64, (2, NOISE_BLOCK, 4)),
]


@kernel
def _quantise(x: float, step: float) -> float:
    """Quantise a value: step · round(x / step), half to even (x itself when step is 0)."""
    if step > 0.0:
        return np.rint(x / step) * step
    return x


@kernel
def read_joints(k, q_true, dq_true, tau_true, sensors):
    """One read at tick k: hold, or take a sample into the readings (module docstring).

    ``sensors``: the record of :data:`SENSOR_FIELDS`.  Returns
    ``Status.WRONG_LENGTH`` (nothing done) when an input is not of length 4,
    else ``Status.OK``; ``depleted`` is set when the sample used the last row
    of the noise block (the caller draws the next block).
    """
    if q_true.shape[0] != 4 or dq_true.shape[0] != 4 or tau_true.shape[0] != 4:
        return Status.WRONG_LENGTH.value
    s = sensors[0]
    dt = s.dt
    t = k * dt
    started = s.started
    if started and t < s.next_t - 1e-9 * dt:
        return Status.OK.value  # hold the last sample
    noise = s.noise
    i = s.row
    res_q = s.res_q
    res_tau = s.res_tau
    noisy_q = s.noisy_q
    noisy_tau = s.noisy_tau
    has_bias = s.has_bias
    differentiate = not s.true_speed and started
    period = alpha = 0.0
    if differentiate:
        period = t - s.last_t
        alpha = 1.0 - math.exp(-2.0 * math.pi * s.filter_hz * period)
    for j in range(4):
        # Encoder: q_m = Δq round((q + n_q) / Δq).
        q_prev = s.q[j]
        q = q_true[j] + noise[0, i, j] if noisy_q else q_true[j]
        q = _quantise(q, res_q)
        s.q[j] = q
        # Speed: v += α ((q_m - q_m,prev) / T_s - v), or the true speed.
        if differentiate:
            dq = s.dq[j]
            s.dq[j] = dq + ((q - q_prev) / period - dq) * alpha
        else:
            s.dq[j] = dq_true[j]
        # Torque sensor: τ_m = Δτ round((τ + β + n_τ) / Δτ).
        tau = tau_true[j]
        if has_bias:
            tau = tau + s.bias[j]
        if noisy_tau:
            tau = tau + noise[1, i, j]
        s.tau[j] = _quantise(tau, res_tau)
    # Samples on the grid t_0 + n T_s set by the first sample: the next grid
    # time after t, as t_0 + n T_s (a sum of periods drifts by rounding: at
    # 1 kHz it held one frame a tick at 7.984 s).
    period_s = s.period
    if not started:
        s.t0 = t
    if period_s > 0.0:
        n = math.floor((t - s.t0) / period_s + 1e-6) + 1
        s.next_t = s.t0 + n * period_s
    else:
        s.next_t = t
    s.last_t = t
    s.started = True
    s.row = i + 1
    s.samples += 1
    s.depleted = i + 1 == noise.shape[1]
    return Status.OK.value
