r"""The belt monitor: the belt encoder against the speed the belt's forces predict.

With the belt modelled (contact on) the feet carry body weight and their
friction (hundreds of newtons with body-weight support) moves the 20 kg belt: its
speed leaves the set speed by a quarter of a metre per second in healthy
runs, so a limit on |v_set − v̂| either false-alarms under load or misses a
stop.  The device knows every force on the belt instead: the treadmill's
drive reports its force F_d (:mod:`exo_ctrl.plant.belt`, ``f_motor``), the
foot plates' load cells read the friction F_x,i on each foot
(:mod:`exo_ctrl.sensing.foot_load`; the force on the belt is −F_x,i along x,
+F_x,i along the belt's backward speed v_b), and the datasheet gives the
belt's equivalent mass m_b, so

.. math::

    m_b \dot v_b = F_d + \sum_i F_{x,i}.

A belt that stops (a jammed roller, the treadmill's own emergency stop), an
encoder that fails or any force the device does not know makes the encoder
disagree with this.

**Residual.**  Each tick k the readings of the last step give its speed
increment u = Δt (F_d + Σ F_x,i) / m_b; the monitor integrates them into the
model's speed change w_k = Σ u and travel y_k (trapezoidal, as the belt moves).
The encoder reads the mean speed over its window of N ticks,
v̂_k = Δx (n_k − n_{k−N}) / (N Δt) (:mod:`exo_ctrl.sensing.belt_encoder`),
and the model predicts how that mean changes from one window to the next,
whatever the unknown initial speed (it cancels in the second difference):

.. math::

    r_k = \hat v_k - \hat v_{k-N} - \frac{y_k - 2 y_{k-N} + y_{k-2N}}{N Δt}
        = \frac{Δt}{N} \sum_{s=1}^{2N} g(s)\,\frac{δF_{k-s}}{m_b} + ε_q,

δF the force on the belt the readings miss (true − read), g(s) = s − ½ for s ≤ N and
2N − s + ½ for N < s ≤ 2N (a triangle of area N²), ε_q the counts'
quantisation.  ``belt speed deviation`` (row :data:`BELT`, column 0 of the
monitor record, m/s) is |r_k|, formed from tick 2N on.

**Threshold** (:func:`threshold_mps`), the bound of a healthy r:

- quantisation: each count is floor(x / Δx), off by [0, Δx), so the second
  difference of counts is off by less than 2 Δx: |ε_q| < 2 q, q = Δx / (N Δt)
  (3.8 mm/s with the default encoder: 7.6 mm/s);
- the load cells' noise σ_F per foot (white): σ_r = (Δt / N) √(Σ g²) √n_f σ_F / m_b
  for the n_f feet read (0.37 mm/s with 2 N and the two foot plates; with the
  patient's feet on the belt their shoes' load cells too, n_f = 4: 0.52 mm/s),
  taken at :data:`NOISE_SIGMAS` = 6 σ_r;
- a bias of the drive's report (its current measurement) of
  :data:`DRIVE_REPORT_ACCURACY` = 1 % of its force limit F_max (assumed: an
  industrial servo drive measures its current within 1–2 % of its rating):
  a constant δF gives r = N Δt δF / m_b (5 mm/s for 10 N).

With the defaults 7.6 + 2.2 + 5.0 = 14.8 mm/s (:data:`BELT_DEVIATION_MPS`).
Measured (tests/safety/test_belt_monitor_load.py): the largest healthy |r|
is 8.1 mm/s over PD and CT, 30 % and 50 % body-weight support, synchronised
or not (7.0–7.9 mm/s with the pelvis fixed), where |v_set − v̂| reaches
0.23–0.32 m/s under the feet's 500–840 N of friction.  With plant substeps
the readings are the last substep's (8.6 mm/s at 4 substeps).  Forces on
the belt the model lacks enter r as N Δt δF / m_b (0.5 mm/s per N with the
defaults): a real treadmill's deck friction under load must be identified
into the model (it is not simulated here).  The patient's feet, when they
meet the belt (``ContactParams.patient_feet``), pull on it too: their shoes'
load cells (:mod:`exo_ctrl.sensing.foot_load`) enter Σ F_x,i; without them the
default run with the patient's feet read their friction (up to 99 N, both feet) as a fault
and stopped at its first touchdown (0.87 s, 0.039 m/s).

**Persistence** P = N + 1 ticks beyond the threshold on the same side.  A
count off at one tick moves r at three isolated ticks; a count jump (a lost
or a spurious run of counts) moves it one way for N ticks and the other way
for the next N: neither gives N + 1 in a row on one side.  A non-finite r
(a NaN reading) counts as beyond on the run's side and is reported as not
finite.

**Detection** (:func:`detection_bound_s`).  A brake of F_br with the drive
out is a missed force δF = −F_br while the belt decelerates: after n ≤ N
braked steps r = −(Δt / N) (n² / 2) F_br / m_b.  With the healthy part at
most the threshold r_th, the channel is beyond it from the first n with
|r_fault| > 2 r_th on, and trips N ticks later: 14 ms for the default stop
(0.58 m/s, 1000 N on 20 kg, r_th = 14.8 mm/s; measured 13 ms with the pelvis
fixed and with 50 % support), against 22 ms (measured 17) for the
set-speed monitor it replaces.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel, record
from ..plant import BeltParams
from ..sensing import BeltEncoder, BeltEncoderParams, FootLoad, FootLoadParams
from ..sensing.belt_encoder import MAX_WINDOW_TICKS

__all__ = [
    "BELT",
    "BELT_DEVIATION_MPS",
    "BELT_MONITOR_FIELDS",
    "DRIVE_REPORT_ACCURACY",
    "NOISE_SIGMAS",
    "BeltMonitor",
    "belt_monitor",
    "belt_monitor_record",
    "detection_bound_s",
    "residual_weights",
    "threshold_mps",
]

#: The monitor record's row of the belt channel (after the plausibility groups).
BELT = 13

#: The load cells' noise in the threshold, in standard deviations of r.
NOISE_SIGMAS = 6.0

#: The drive's force report's accuracy, a fraction of its force limit (assumed).
DRIVE_REPORT_ACCURACY = 0.01

#: The rings' length: two encoder windows of the longest, and one.
RING = 2 * MAX_WINDOW_TICKS + 1


def residual_weights(window_ticks: int) -> np.ndarray:
    """g(s), s = 1 … 2N: the weight of the missed force s steps back in r (module docstring)."""
    s = np.arange(1, 2 * window_ticks + 1, dtype=float)
    return np.where(s <= window_ticks, s - 0.5, 2 * window_ticks - s + 0.5)


def threshold_mps(
    window_ticks: int,
    dt: float,
    resolution_m: float,
    load_noise_N: float,
    mass_kg: float,
    force_limit_N: float,
    feet: int = 2,
) -> float:
    """r_th = 2 q + 6 σ_r + N Δt (0.01 F_max) / m_b [m/s] (module docstring).

    Args:
        window_ticks: the encoder's window N [ticks].
        dt: control period Δt [s].
        resolution_m: the encoder's count Δx [m].
        load_noise_N: the load cells' noise σ_F per component [N].
        mass_kg: the belt's equivalent mass m_b (datasheet) [kg].
        force_limit_N: the drive's force limit F_max (datasheet) [N].
        feet: n_f, the feet whose load cells are read (2, or 4 with the patient's).

    """
    n = int(window_ticks)
    g = residual_weights(n)
    quantisation = 2.0 * resolution_m / (n * dt)
    noise = dt / n * math.sqrt(float(g @ g)) * math.sqrt(feet) * load_noise_N / mass_kg
    bias = n * dt * DRIVE_REPORT_ACCURACY * force_limit_N / mass_kg
    return quantisation + NOISE_SIGMAS * noise + bias


def _default_threshold() -> float:
    enc, belt = BeltEncoderParams(), BeltParams()
    window = max(math.floor(enc.window_s / 1e-3 + 0.5), 1)
    noise = FootLoadParams().noise_std_N
    return threshold_mps(window, 1e-3, enc.resolution_m, noise, belt.mass_kg, belt.force_limit_N)


#: r_th of the default encoder, load cells and treadmill at 1 kHz [m/s] (14.8 mm/s).
BELT_DEVIATION_MPS = _default_threshold()

#: The monitor's record.  ``window`` N [ticks], ``dt`` Δt [s], ``inv_m`` 1/m_b
#: [1/kg]; ``persist`` P and ``count`` [ticks], ``side`` ±1 of the run (0:
#: none); ``ticks`` calls so far, ``w`` [m/s] and ``y`` [m] the model's speed
#: change and travel; ``residual`` r of the last tick [m/s] (NaN before 2N);
#: the rings ``travel`` y [m] and ``speed`` v̂ [m/s].
BELT_MONITOR_FIELDS = [
    ("window", np.int64),
    *((name, np.float64) for name in ("dt", "inv_m", "persist", "count", "side")),
    ("ticks", np.int64),
    *((name, np.float64) for name in ("w", "y", "residual")),
    ("travel", np.float64, (RING,)),
    ("speed", np.float64, (RING,)),
]


def belt_monitor_record(window_ticks: int, dt: float, mass_kg: float) -> np.ndarray:
    """A fresh record for an encoder window of N = ``window_ticks`` ticks (P = N + 1).

    Args:
        window_ticks: the encoder's window N [ticks] (at most the encoder's longest).
        dt: control period Δt [s].
        mass_kg: the belt's equivalent mass m_b (datasheet) [kg].

    """
    state = record(BELT_MONITOR_FIELDS)
    r = state[0]
    r["window"], r["dt"], r["inv_m"] = int(window_ticks), float(dt), 1.0 / mass_kg
    r["persist"] = int(window_ticks) + 1
    r["residual"] = math.nan
    return state


class BeltMonitor:
    """The belt monitor's readings, datasheet and record (module docstring).

    Args:
        encoder: the belt encoder (its reading ``speed``, window and count).
        foot_load: the foot plates' load cells (their reading ``belt_force``
            (4, 2) [N], x the friction on each foot, the patient's shoes' rows
            zero without them; their noise and the feet read).
        drive_force: the treadmill drive's report of its force, (1,) [N],
            written by the caller each tick before :func:`belt_monitor` runs.
        datasheet: the treadmill's datasheet (m_b and F_max; not the belt's state).

    Attributes:
        threshold_mps: r_th [m/s].
        record: the record of :data:`BELT_MONITOR_FIELDS`.
        args: the kernel's readings and record, ``belt_monitor(*args, mon)``.

    """

    def __init__(
        self,
        encoder: BeltEncoder,
        foot_load: FootLoad,
        drive_force: np.ndarray,
        datasheet: BeltParams,
    ) -> None:
        enc = encoder.record[0]
        window, dt = int(enc["window"]), float(enc["dt"])
        self.threshold_mps = threshold_mps(
            window,
            dt,
            float(enc["res"]),
            foot_load.params.noise_std_N,
            datasheet.mass_kg,
            datasheet.force_limit_N,
            foot_load.feet,
        )
        self.record = belt_monitor_record(window, dt, datasheet.mass_kg)
        self.args = (encoder.speed, drive_force, foot_load.belt_force, self.record)


@kernel
def belt_monitor(speed, drive, foot, state, mon):
    """One tick of the belt monitor: row :data:`BELT` of the monitor record's ``excess``.

    Args:
        speed: the belt encoder's reading v̂_k, (1,) [m/s].
        drive: the drive's report of its force over the last step, (1,) [N].
        foot: the load cells' reading of the last step, (n, 2) [N] (column 0:
            the friction on each foot along x; every row is summed).
        state: the record of :data:`BELT_MONITOR_FIELDS`.
        mon: the monitor record (``excess`` and ``limit`` row BELT; column
            0 is the channel, columns 1-3 stay unused, -1).

    """
    s = state[0]
    m = mon[0]
    n = s.window
    k = s.ticks
    size = s.travel.shape[0]
    if k > 0:  # the last step's forces: m_b dv_b/dt = F_d + Σ F_x,i
        total = drive[0]
        for i in range(foot.shape[0]):
            total += foot[i, 0]
        u = s.dt * total * s.inv_m
        s.y += s.dt * (s.w + 0.5 * u)
        s.w += u
    s.travel[k % size] = s.y
    s.speed[k % size] = speed[0]
    s.ticks = k + 1
    for i in range(1, 4):
        m.excess[BELT, i] = -1.0
    if k < 2 * n:
        m.excess[BELT, 0] = -1.0
        return
    change = s.y - 2.0 * s.travel[(k - n) % size] + s.travel[(k - 2 * n) % size]
    r = speed[0] - s.speed[(k - n) % size] - change / (n * s.dt)
    s.residual = r
    excess = abs(r) - m.limit[BELT, 0]
    if not excess <= 0.0:  # beyond, or NaN (which keeps the run's side)
        side = 1.0 if r > 0.0 else (-1.0 if r < 0.0 else s.side)
        s.count = s.count + 1.0 if side == s.side else 1.0
        s.side = side
    else:
        s.count = 0.0
        s.side = 0.0
    m.excess[BELT, 0] = excess if s.count >= s.persist else -1.0


def detection_bound_s(
    speed_mps: float,
    deceleration_mps2: float,
    window_ticks: int,
    dt: float,
    resolution_m: float,
    threshold: float | None = None,
    held_mps2: float = 0.0,
) -> float:
    """The longest time from a belt stop's onset to the channel's trip [s] (module docstring).

    The missed deceleration is at least ``deceleration_mps2`` until the
    missed speed reaches the set speed (the belt at rest), then the feet's
    friction on the held belt, missed too, is at most ``held_mps2`` against
    it.  The healthy part of r is at most the threshold, so the channel is
    beyond it where the fault's part exceeds twice the threshold; it trips
    N ticks after the first tick from which that holds for N + 1 ticks.

    Args:
        speed_mps: the belt speed at the onset [m/s].
        deceleration_mps2: a lower bound of F_br / m_b [m/s²].
        window_ticks: the encoder's window N [ticks].
        dt: control period Δt [s].
        resolution_m: the encoder's count Δx [m] (in the threshold when
            ``threshold`` is None: the default load cells and treadmill).
        threshold: r_th [m/s] (None: :func:`threshold_mps` with Δx and the
            default load cells and treadmill).
        held_mps2: the missed force on the held belt over m_b, against the
            fault [m/s²].

    Returns:
        The bound [s]; ``inf`` when the stop's residual never stays beyond.

    """
    n = int(window_ticks)
    if threshold is None:
        b = BeltParams()
        noise = FootLoadParams().noise_std_N
        threshold = threshold_mps(n, dt, resolution_m, noise, b.mass_kg, b.force_limit_N)
    if speed_mps <= 0.0 or deceleration_mps2 <= 0.0:
        return math.inf
    steps = math.ceil(speed_mps / (deceleration_mps2 * dt)) + 4 * n
    missed = np.full(steps, held_mps2)  # the missed acceleration per step [m/s²]
    lost = 0.0
    for i in range(steps):
        a = min(deceleration_mps2, (speed_mps - lost) / dt)
        if a <= 0.0:
            break
        missed[i] = -a
        lost += a * dt
    # r after j + 1 braked steps: (Δt / N) Σ_s g(s) a_{j+1-s}, a convolution
    fault = dt / n * np.convolve(missed, residual_weights(n))[:steps]
    beyond = fault < -2.0 * threshold
    for j in range(steps - n):
        if beyond[j : j + n + 1].all():
            return (j + 1 + n) * dt
    return math.inf
