r"""Still encoder against the drive's current: a joint that reads still must draw U/R.

**The blind spot it closes.**  A frozen encoder makes the joint look still
while it moves.  The drive-model residual (:mod:`.plausibility`) sees that
as a torque reading the speed reading cannot explain, but it is not
evaluated while the model's current is at the driver's limit, and with a
frozen encoder it is: the speed reading decays to zero, so the model's
current (U − i_G ω̂/k_E)/R is the whole command over 0.1 Ω, beyond the
limit for any U above R I_max (3.3 V with the default drive).  A hip frozen
while its drive was at the limit (a 28 A driver, PD) was named by that
residual only 168–189 ms after the onset; a slow knee's after 67–74 ms
(345–560 ms in transparent, aan and path); and a frozen hip that threw
transparent's force loop into a limit cycle between the current limits
(σ_d = 100 N·m/√s without the lead, ModeParams' docstring) was never
named.  This check names them after 52–58 ms, 23–47 ms (24–160 ms) and
36 ms.

**The physics.**  While the encoder's readings stay within a band ±w of
one reading (the still run's anchor), the joint is still: its speed
averages out over the run, and with it the rotor's back-EMF i_G ω/k_E.  The
winding is then a resistor and an inductor across the voltage U the driver
applies, and its current, stepped exactly over each tick as the plant's
driver does (:mod:`exo_ctrl.plant.motor` at ω = 0), is

.. math::

    I_∞ = U/R,\quad \bar I_k = \mathrm{clip}\bigl(I_∞ + (I_{k-1} − I_∞)\,φ,\ ±I_{max}\bigr),
    \quad I_k = \mathrm{clip}\bigl(I_∞ + (I_{k-1} − I_∞)\,e^{−Δt R/L},\ ±I_{max}\bigr),

φ = (1 − e^{−x})/x, x = Δt R/L; Ī the tick's mean, which the driver's
current sensor reads (:mod:`exo_ctrl.sensing.current_sensor`), U the
voltage sent last tick clipped to the supply.  The datasheet gives R at
25 °C; copper's 0.393 %/K puts a winding between −6 % (10 °C) and +20 %
(50 K warmer) of it (:data:`RESISTANCE_RANGE`; the current sensor's gain
error, a few per cent, is inside that), so the check steps three windings,
cold, the datasheet's and warm (each its own R in I_∞ and in x), and the
band spans their Ī (at steady state [U/(1.2 R), U/(0.94 R)]); a tick's
residual is how far the reading I_m lies outside it,
ρ = I_m − clamp(I_m, band).  Nothing here depends on the speed reading,
the torque sensor or the gearbox; the driver's clip is modelled, not
avoided, so the check holds whether the drive is at its limit or not.

**What a still joint leaves in ρ.**  The true current is the clip of the
still winding's less the back-EMF current b = (i_G/k_E) ω/R (through the
winding's lag); the clip is monotone and 1-Lipschitz, so each ρ lies
between 0 and −b.  Averaged over a window of M ticks, ρ is therefore at
most (i_G/k_E)/R times the angle the joint swept in one direction over the
window, over M Δt; for any motion slower than 1/(M Δt) (50 Hz: a shank of
4.65 kg swings on its 8 N/mm cuff at 7 Hz; compliant joints, whose rotor moves
behind its spring while the link is still, are left out) that is at most
the true angle's spread over the window, which is the readings' spread s_k
(max − min over the window's M + 1 readings) plus Δq + 12 σ_q (each reading
is the angle within Δq/2 of quantisation and 6 σ_q of noise).  With the
current sensor's white noise and quantisation, σ_I,eff² = σ_I² + ΔI²/12,
through the mean: the channel's value is |mean ρ| − S_k, its limit T,

.. math::

    S_k = \frac{i_G/k_E}{R}\,\frac{s_k}{M\,Δt},\qquad
    T = \frac{i_G/k_E}{R}\,\frac{Δq + 12\,σ_q}{M\,Δt} + 6\,\frac{σ_{I,eff}}{\sqrt M}
    = 0.65 + 0.07 = 0.72\ \mathrm{A}

with the default drive and sensors (45 A per rad/s of back-EMF current;
M = :data:`WINDOW_TICKS` = 20; :func:`still_threshold`).  A still joint's
readings stay within w = Δq + 4√2 σ_q = 1.6e-4 rad of the anchor (two
readings differ by more with probability 6e-5, which only restarts the
run), so S_k ≤ 0.72 A and |mean ρ| ≤ 1.44 A.  The window counts from
:data:`SETTLE_TICKS` = 5 ticks after the anchor (the model's current
starts at the reading; 0.24⁵ = 1e-3 of that error is left after them).
On the default runs (PD, CT, QP, spastic, the active patient in
transparent, aan and path, body-weight support on the belt, an e-stop)
|mean ρ| − S_k peaks at 0.02 A against T = 0.72 A (tests/safety/test_still.py;
|mean ρ| itself at 0.46 A).

**Detection.**  A frozen encoder repeats its last reading, so its still
run starts at the tick before the onset, its readings' spread is 0 (S_k =
0) and its first full window ends S + M − 1 = 24 ticks after the onset
(:func:`earliest_detection_ticks`).  A joint frozen while it moves at ω
draws (i_G/k_E)|ω|/R less current than the still winding (motoring), less
the band's warm side, I_∞/6: it is detected in its first full window when
(5/6)(i_G/k_E)|ω|/R − |I|/6 > T on average over the window (|ω| > 0.06
rad/s at |I| ≤ 10 A), later while its speed builds up.  A joint frozen
while its drive is at the limit is detected once the current reading
leaves the limit while the still winding's stays there (or the converse),
within M ticks: with the 28 A driver the estimated cuff forces stop the
run first (3–10 ms), and the stop's ramp takes the drive off its limit.

**What it cannot see.**  A drive held at its limit by a command that puts
the still winding beyond it too (|U|/R > I_max): the current is the
limit's either way, and the torque sensor reads η^s i_G k_m I_max less the
rotor's inertia torque, within the gearbox's standstill band [η, 1/η] of
what a blocked joint reads.  A joint frozen that way runs away at the
drive's full torque with nothing in its own readings to tell (0.5 s and
1.45 rad with a 28 A driver and the cuff forces measured); only the leg's
momentum balance can tell: the estimated cuff forces, which then carry the
leg's inertial torque, pass their limit within 3–16 ms (the default
supervisor watches them), or a driver that reports the voltage it applies
(a back-EMF speed), which the plant does not model.

A joint whose angle or current reading is not finite gets excess 0 and
restarts its still run at its next finite reading (the limit monitor flags it).
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel
from ..plant import MotorParams
from ..sensing import CurrentSensorParams, SensorParams

__all__ = [
    "BAND_SIGMAS",
    "NOISE_SIGMAS",
    "RESISTANCE_RANGE",
    "SETTLE_TICKS",
    "STILL",
    "STILL_FIELDS",
    "WINDOW_TICKS",
    "earliest_detection_ticks",
    "init_still",
    "reading_margin",
    "still_band",
    "still_limit",
    "still_threshold",
    "still_winding",
    "sweep_current",
]

#: The monitor record's row of the still-encoder group (after the plausibility rows).
STILL = 12

#: M: the window the residual is averaged over [ticks] (module docstring).
WINDOW_TICKS = 20

#: S: ticks after a still run's anchor before its residuals are averaged.
SETTLE_TICKS = 5

#: The winding's resistance over the datasheet's (at 25 °C), lowest and highest: copper's
#: 0.393 %/K from a 10 °C cold winding (−6 %) to one 50 K warmer (+20 %).
RESISTANCE_RANGE = (0.94, 1.20)

#: Standard deviations of two readings' noise in the still band w.
BAND_SIGMAS = 4.0

#: Standard deviations of a reading's noise in the true angle's spread, and of the mean in T.
NOISE_SIGMAS = 6.0

#: The check's part of the plausibility record (fields prefixed ``st_``):
#: ``st_band`` w [rad], ``st_emf`` (i_G/k_E)/R/(M Δt) [A/rad]; per winding
#: (cold, datasheet, warm) ``st_inv_r`` 1/R_w [1/Ω], ``st_phi`` and ``st_eps``
#: its step's φ and e^{−Δt R_w/L}; per winding and joint ``st_mem`` its current
#: at the end of the last tick [A], (3, 4); per joint ``st_anchor`` the still
#: run's anchor reading [rad], ``st_n`` ticks since it (−1: restart at the next
#: finite reading), ``st_mean`` the last full window's mean ρ [A] and
#: ``st_sweep`` its S_k [A] (0: none); ``st_ring`` the window's ρ [A], (M, 4),
#: ``st_qring`` its readings [rad], (M + 1, 4).
STILL_FIELDS = [
    *((name, np.float64) for name in ("st_band", "st_emf")),
    *((name, np.float64, (3,)) for name in ("st_inv_r", "st_phi", "st_eps")),
    ("st_mem", np.float64, (3, 4)),
    *((name, np.float64, (4,)) for name in ("st_anchor", "st_n", "st_mean", "st_sweep")),
    ("st_ring", np.float64, (WINDOW_TICKS, 4)),
    ("st_qring", np.float64, (WINDOW_TICKS + 1, 4)),
]


def still_band(sensors: SensorParams) -> float:
    """The still band w = Δq + 4 √2 σ_q: how far a still joint's readings stray [rad]."""
    noise = BAND_SIGMAS * math.sqrt(2.0) * sensors.encoder_noise_std_rad
    return sensors.encoder_resolution_rad + noise


def reading_margin(sensors: SensorParams) -> float:
    """Δq + 12 σ_q: the true angles' spread beyond the readings' [rad] (module docstring)."""
    return sensors.encoder_resolution_rad + 2.0 * NOISE_SIGMAS * sensors.encoder_noise_std_rad


def sweep_current(motor: MotorParams, spread_rad: float, dt: float) -> float:
    """(i_G/k_E)/R · spread/(M Δt): the back-EMF current of a sweep over a window [A]."""
    emf = motor.back_emf_V_per_rad_s / motor.resistance_ohm  # A per rad/s
    return emf * spread_rad / (WINDOW_TICKS * dt)


def still_threshold(
    motor: MotorParams,
    sensors: SensorParams,
    dt: float,
    current: CurrentSensorParams | None = None,
) -> float:
    """T = (i_G/k_E)/R · (Δq + 12 σ_q)/(M Δt) + 6 σ_I,eff/√M [A] (module docstring).

    Args:
        motor: the drive's datasheet.
        sensors: the joint sensors' parameters.
        dt: control period Δt [s].
        current: the current sensors' parameters (None: the default driver's; the
            supervisor passes the run's datasheet, ``current_sensor``).

    """
    current = current if current is not None else CurrentSensorParams()
    sigma = math.sqrt(current.noise_std_A**2 + current.resolution_A**2 / 12.0)
    noise = NOISE_SIGMAS * sigma / math.sqrt(WINDOW_TICKS)
    return sweep_current(motor, reading_margin(sensors), dt) + noise


def still_limit(
    motor: MotorParams,
    sensors: SensorParams,
    dt: float,
    current: CurrentSensorParams | None = None,
) -> np.ndarray:
    """The group's limit row, (4,) [A]: T for every joint."""
    return np.full(4, still_threshold(motor, sensors, dt, current))


def earliest_detection_ticks() -> int:
    """S + M − 1: ticks from a frozen encoder's onset to the end of its first full window."""
    return SETTLE_TICKS + WINDOW_TICKS - 1


def init_still(state: np.ndarray, motor: MotorParams, sensors: SensorParams, dt: float) -> None:
    """Fill the check's constants into the record ``state`` (every joint to restart)."""
    s = state[0]
    s["st_band"] = still_band(sensors)
    s["st_emf"] = sweep_current(motor, 1.0, dt)
    for w, scale in enumerate((RESISTANCE_RANGE[0], 1.0, RESISTANCE_RANGE[1])):
        x = dt * scale / motor.electrical_time_constant_s  # Δt R_w / L
        s["st_inv_r"][w] = 1.0 / (scale * motor.resistance_ohm)
        s["st_phi"][w] = -math.expm1(-x) / x
        s["st_eps"][w] = math.exp(-x)
    s["st_n"] = -1.0


@kernel
def _clip(x: float, limit: float) -> float:
    return min(max(x, -limit), limit)


@kernel
def still_winding(q, current, state, mon):  # pragma: no cover - compiled
    """One tick of the check (module docstring): row STILL of ``mon``'s ``excess``.

    Run before the plausibility monitors, whose ``u_prev`` is then still the
    voltage sent last tick.

    Args:
        q: joint angle readings, (4,) [rad].
        current: drive current readings, (4,) [A] (the mean over the last step).
        state: the plausibility record (its ``st_`` fields, and ``u_prev``,
            ``u_max``, ``i_max``).
        mon: the monitor record: excess = |mean ρ| − S_k − T (T its limit row
            STILL) over a full window, −1 otherwise.

    The caller checks the lengths (all 4).

    """
    s = state[0]
    m = mon[0]
    e, lim = m.excess, m.limit
    ring, qring = s.st_ring, s.st_qring
    size = WINDOW_TICKS + 1
    for j in range(4):
        qj, ij = q[j], current[j]
        if not (math.isfinite(qj) and math.isfinite(ij)):
            e[STILL, j] = 0.0
            s.st_n[j] = -1.0
            continue
        if s.st_n[j] < 0.0 or abs(qj - s.st_anchor[j]) > s.st_band:
            s.st_anchor[j] = qj  # a new still run from this reading
            s.st_n[j] = 0.0
            for w in range(3):
                s.st_mem[w, j] = ij
            s.st_mean[j] = s.st_sweep[j] = 0.0
            qring[0, j] = qj
            e[STILL, j] = -1.0
            continue
        n = s.st_n[j] + 1.0
        s.st_n[j] = n
        qring[int(n) % size, j] = qj
        u = min(max(s.u_prev[j], -s.u_max), s.u_max)  # sent last tick, applied since
        lo, hi = math.inf, -math.inf
        for w in range(3):  # the cold, the datasheet's and the warm winding
            i_inf = u * s.st_inv_r[w]
            d0 = s.st_mem[w, j] - i_inf
            mean = _clip(i_inf + d0 * s.st_phi[w], s.i_max)
            s.st_mem[w, j] = _clip(i_inf + d0 * s.st_eps[w], s.i_max)
            lo, hi = min(lo, mean), max(hi, mean)
        rho = ij - min(max(ij, lo), hi)
        if n <= SETTLE_TICKS:
            e[STILL, j] = -1.0
            continue
        ring[int(n) % WINDOW_TICKS, j] = rho
        if n < SETTLE_TICKS + WINDOW_TICKS:
            e[STILL, j] = -1.0
            continue
        total, q_lo, q_hi = 0.0, qj, qj
        for i in range(WINDOW_TICKS):
            total += ring[i, j]
        for i in range(size):
            q_lo, q_hi = min(q_lo, qring[i, j]), max(q_hi, qring[i, j])
        s.st_mean[j] = total / WINDOW_TICKS
        s.st_sweep[j] = s.st_emf * (q_hi - q_lo)
        e[STILL, j] = abs(s.st_mean[j]) - s.st_sweep[j] - lim[STILL, j]
