"""The belt monitor's residual (exo_ctrl/safety/belt_monitor.py) on an exactly integrated belt.

The belt here is m_b dv/dt = F_d + Σ F_x stepped as the plant steps it (explicit speed,
trapezoidal travel), counted by the belt encoder's own kernel; the monitor gets the step's
drive force and foot forces as the device reads them.  Each test checks one term of the
derivation: the quantisation bound 2 q, the bias N Δt δF / m_b, the load cells' σ_r, the
persistence against count glitches, the trip tick of a brake and the detection bound.  The
runs of the simulator (body-weight support, the belt stop) are in test_belt_monitor_load.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from exo_ctrl.safety import ResolvedLimits, monitor_record
from exo_ctrl.safety.belt_monitor import (
    BELT,
    BELT_DEVIATION_MPS,
    DRIVE_REPORT_ACCURACY,
    NOISE_SIGMAS,
    belt_monitor,
    belt_monitor_record,
    detection_bound_s,
    residual_weights,
    threshold_mps,
)
from exo_ctrl.sensing import BeltEncoder, BeltEncoderParams
from exo_ctrl.sensing.belt_encoder import read_belt

DT = 1e-3
N = 10
MASS = 20.0
RES = 3.8e-5
Q = RES / (N * DT)  # the reading's quantum, 3.8 mm/s
LIMITS = ResolvedLimits(*(np.full(4, 1e9) for _ in range(5)))


def belt_readings(force_N: np.ndarray, v0: float, resolution_m: float = RES) -> np.ndarray:
    """The encoder's reading at ticks 0 … n of a belt driven by the net force ``force_N[j]``
    over step j (the plant's step: v explicit, x trapezoidal); a force that would reverse the
    belt holds it at rest (a brake)."""
    encoder = BeltEncoder(BeltEncoderParams(resolution_m=resolution_m), DT)
    belt = np.zeros(1, dtype=[("x", float), ("v", float)])
    belt["v"] = v0
    out = np.zeros(force_N.shape[0] + 1)
    for k in range(out.shape[0]):
        read_belt(encoder.record, k, belt)
        out[k] = encoder.speed[0]
        if k < force_N.shape[0]:
            v = float(belt["v"][0])
            v_next = max(v + DT * force_N[k] / MASS, 0.0) if v > 0.0 else v
            belt["x"] += 0.5 * DT * (v + v_next)
            belt["v"] = v_next
    return out


def monitor(speed: np.ndarray, drive_N: np.ndarray, feet_N: np.ndarray, limit: float):
    """The residual r and the channel's excess per tick: tick k gets step k - 1's readings
    (``drive_N[j]``, ``feet_N[j]`` (2,) the friction on each foot along x)."""
    state = belt_monitor_record(N, DT, MASS)
    mon = monitor_record(LIMITS, math.inf)
    mon["limit"][0][BELT, 0] = limit
    reading, drive, foot = np.zeros(1), np.zeros(1), np.zeros((2, 2))
    r = np.full(speed.shape[0], math.nan)
    excess = np.zeros(speed.shape[0])
    for k in range(speed.shape[0]):
        reading[0] = speed[k]
        if k > 0:
            drive[0] = drive_N[k - 1]
            foot[:, 0] = feet_N[k - 1]
        belt_monitor(reading, drive, foot, state, mon)
        r[k] = state["residual"][0]
        excess[k] = mon["excess"][0][BELT, 0]
        assert np.all(mon["excess"][0][BELT, 1:] < 0.0)
    return r, excess


def loaded_belt(n: int = 4000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The default treadmill's PI (K_p = 251 N·s/m, K_i = 790 N/m) under alternating half-sine
    friction pulses of -100 N on each foot (0.6 s stance each): set speed 0.58 m/s; the drive's
    force per step, the feet's per step and the net force."""
    t = np.arange(n) * DT
    phase = (t % 1.2) / 0.6
    left = np.where(phase < 1.0, -100.0 * np.sin(np.pi * np.minimum(phase, 1.0)), 0.0)
    right = np.where(phase >= 1.0, -100.0 * np.sin(np.pi * (phase - 1.0)), 0.0)
    feet = np.stack((left, right), axis=1)
    drive = np.zeros(n)
    v, integral = 0.58, 0.0
    for j in range(n):
        integral += DT * (0.58 - v)
        drive[j] = 251.0 * (0.58 - v) + 790.0 * integral
        v += DT * (drive[j] + feet[j].sum()) / MASS
    return drive, feet, drive + feet.sum(axis=1)


def test_the_threshold_is_the_sum_of_the_derived_terms() -> None:
    """2 q + 6 σ_r + N Δt (0.01 F_max) / m_b, σ_r = (Δt / N) √(Σ g²) √2 σ_F / m_b; Σ g = N²."""
    g = residual_weights(N)
    assert g.sum() == pytest.approx(N * N, rel=1e-15)
    assert g @ g == pytest.approx(2 * sum((s - 0.5) ** 2 for s in range(1, N + 1)), rel=1e-15)
    sigma = DT / N * math.sqrt(665.0) * math.sqrt(2.0) * 2.0 / MASS
    bias = N * DT * DRIVE_REPORT_ACCURACY * 1000.0 / MASS
    expected = 2 * Q + NOISE_SIGMAS * sigma + bias
    assert threshold_mps(N, DT, RES, 2.0, MASS, 1000.0) == pytest.approx(expected, rel=1e-12)
    assert math.isclose(BELT_DEVIATION_MPS, expected, rel_tol=1e-12)
    print(f"threshold {1e3 * expected:.2f} mm/s: 2q {2e3 * Q:.2f}, 6σ {6e3 * sigma:.2f}, bias 5.00")


def test_a_loaded_belt_far_from_its_set_speed_stays_within_the_quantisation_bound() -> None:
    """Exact readings: |r| < 2 q while the belt sags a quarter of a metre per second under the
    feet (the old set-speed limit, 0.1 m/s, would trip).  With the foot forces' sign wrong
    (taken as the force on the belt) the channel trips: the sign matters."""
    drive, feet, net = loaded_belt()
    speed = belt_readings(net, 0.58)
    assert np.max(np.abs(speed - 0.58)) > 0.2
    r, excess = monitor(speed, drive, feet, BELT_DEVIATION_MPS)
    assert np.all(np.isnan(r[: 2 * N])) and np.all(excess < 0.0)
    worst = np.nanmax(np.abs(r))
    print(f"loaded belt: |v_set - v̂| up to {np.max(np.abs(speed - 0.58)):.3f} m/s, |r| {worst:.4f}")
    assert Q < worst < 2 * Q
    _, wrong = monitor(speed, drive, -feet, BELT_DEVIATION_MPS)
    assert np.any(wrong > 0.0)


def test_a_missed_constant_force_gives_n_dt_force_over_mass() -> None:
    """A drive report 10 N above the force applied (a fine encoder: no quantisation):
    r = -N Δt δF / m_b from tick 2N on (the model expects the belt to gain speed)."""
    drive, feet, net = loaded_belt(600)
    speed = belt_readings(net, 0.58, resolution_m=1e-13)
    r, _ = monitor(speed, drive + 10.0, feet, 1.0)
    np.testing.assert_allclose(r[2 * N :], -N * DT * 10.0 / MASS, atol=1e-8)


def test_the_load_cells_noise_gives_the_derived_spread() -> None:
    """White noise σ_F = 2 N on each foot's reading: std(r) = (Δt / N) √(Σ g²) √2 σ_F / m_b."""
    rng = np.random.default_rng(7)
    drive, feet, net = loaded_belt(40000)
    speed = belt_readings(net, 0.58, resolution_m=1e-13)
    r, _ = monitor(speed, drive, feet + rng.normal(0.0, 2.0, feet.shape), 1.0)
    g = residual_weights(N)
    sigma = DT / N * math.sqrt(g @ g) * math.sqrt(2.0) * 2.0 / MASS
    print(f"std(r) {np.nanstd(r):.3e} m/s against σ_r {sigma:.3e}")
    assert np.nanstd(r) == pytest.approx(sigma, rel=0.05)


def test_a_brake_trips_at_the_derived_tick_within_the_bound() -> None:
    """Braked at 1000 N from tick 100 (0.58 m/s: at rest after 11.6 steps), the drive's
    report 0: after n braked steps r = -(Δt / N)(n² / 2) F_br / m_b, beyond the threshold
    from n = 3 (2N r_th m_b / (Δt F_br) = 5.9), tripping N ticks later; the bound (the
    healthy part against it at the threshold) is 14 ms."""
    k0, n = 100, 200
    drive = np.full(n, 0.0)
    net = np.where(np.arange(n) >= k0, -1000.0, 0.0)
    speed = belt_readings(net, 0.58, resolution_m=1e-13)
    r, excess = monitor(speed, drive, np.zeros((n, 2)), BELT_DEVIATION_MPS)
    crossing = math.floor(math.sqrt(2 * N * BELT_DEVIATION_MPS * MASS / (DT * 1000.0))) + 1
    assert crossing == 3
    for j in range(1, crossing + 1):
        assert r[k0 + j] == pytest.approx(-DT / N * j * j / 2 * 1000.0 / MASS, rel=1e-6)
    trips = np.flatnonzero(excess > 0.0)
    assert trips[0] == k0 + crossing + N
    assert excess[trips[0]] == pytest.approx(abs(r[trips[0]]) - BELT_DEVIATION_MPS, rel=1e-12)
    bound = detection_bound_s(0.58, 50.0, N, DT, RES)
    assert (trips[0] - k0) * DT <= bound + 1e-12
    assert bound == pytest.approx(0.014, abs=1e-12)


def test_the_detection_bound() -> None:
    """14 ms for the default stop (0.583 m/s at 1000 N on 20 kg, even at 45 m/s²); later with
    friction on the held belt against it; never for a belt slower than twice the threshold
    can show (its whole change of mean speed is below 2 r_th)."""
    assert detection_bound_s(0.583, 45.0, N, DT, RES) == pytest.approx(0.014, abs=1e-12)
    assert detection_bound_s(0.583, 50.0, N, DT, RES, held_mps2=20.0) == pytest.approx(
        0.014, abs=1e-12
    )
    slow = detection_bound_s(0.583, 5.0, N, DT, RES)
    assert 0.014 < slow < math.inf
    assert detection_bound_s(1.9 * BELT_DEVIATION_MPS, 50.0, N, DT, RES) == math.inf
    assert detection_bound_s(0.583, 0.0, N, DT, RES) == math.inf


def test_count_glitches_never_trip_it() -> None:
    """A count off by 4000 (15 cm of belt) for one tick, then a permanent jump of 4000
    counts: |r| reaches metres per second, beyond the threshold for 2N ticks in a row, but
    never N + 1 in a row on one side."""
    enc = BeltEncoderParams()
    encoder = BeltEncoder(enc, DT)
    belt = np.zeros(1, dtype=[("x", float), ("v", float)])
    n, v = 400, 0.6
    speed = np.zeros(n)
    for k in range(n):
        belt["v"] = v
        belt["x"] = v * k * DT + (4000 * enc.resolution_m if k == 100 or k >= 200 else 0.0)
        read_belt(encoder.record, k, belt)
        speed[k] = encoder.speed[0]
    r, excess = monitor(speed, np.zeros(n), np.zeros((n, 2)), BELT_DEVIATION_MPS)
    beyond = np.abs(r) > BELT_DEVIATION_MPS
    longest = max(len(run) for run in "".join("x" if b else " " for b in beyond).split())
    assert np.nanmax(np.abs(r)) > 10.0 and longest == 2 * N
    assert np.all(excess < 0.0)


def test_a_nan_reading_trips_after_the_persistence_and_reads_not_finite() -> None:
    n = 100
    speed = np.full(n, 0.6)
    speed[60:] = math.nan
    _, excess = monitor(speed, np.zeros(n), np.zeros((n, 2)), BELT_DEVIATION_MPS)
    assert np.all(excess[: 60 + N] < 0.0)
    assert math.isnan(excess[60 + N])
