"""Sensors: pass-through when ideal, quantisation, noise statistics, seeding, hold, speed.

Independent references: the quantisation and noise are checked against
their definitions (multiples of the step, sample std against the parameter,
the exact stream of ``numpy.random.default_rng(seed)``); the speed filter
against the closed-form first-order response to a ramp and its phase lag
on a sine.
"""

from __future__ import annotations

import math
import re
import tracemalloc

import numpy as np
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.sensing.readings import SensorReadings
from exo_ctrl.sensing.sensors import NOISE_BLOCK, SensorParams, Sensors

DT = 1e-3


def noiseless(**kw) -> SensorParams:
    """Ideal sensors with some fields changed."""
    base = {
        "encoder_resolution_rad": 0.0,
        "encoder_noise_std_rad": 0.0,
        "velocity": "true",
        "torque_noise_std_Nm": 0.0,
        "torque_resolution_Nm": 0.0,
        "sample_rate_hz": None,
    }
    base.update(kw)
    return SensorParams(**base)


def test_defaults_are_the_documented_hardware_values() -> None:
    p = SensorParams()
    assert p.encoder_resolution_rad == pytest.approx(2 * math.pi / 131072)
    assert p.encoder_noise_std_rad == 2e-5
    assert p.velocity == "encoder"
    assert p.velocity_filter_hz == 30.0
    assert p.torque_noise_std_Nm == 0.2
    assert p.torque_resolution_Nm == 0.01
    assert p.torque_bias_Nm == (0.0, 0.0, 0.0, 0.0)
    assert p.sample_rate_hz == 1000.0
    ideal = SensorParams.ideal()
    assert ideal.encoder_resolution_rad == 0 and ideal.encoder_noise_std_rad == 0
    assert ideal.torque_noise_std_Nm == 0 and ideal.torque_resolution_Nm == 0
    assert ideal.sample_rate_hz is None and ideal.velocity == "true"
    assert np.all(ideal.bias == 0)


def test_ideal_sensors_return_the_truth_every_tick() -> None:
    s = Sensors(SensorParams.ideal(), DT)
    rng = np.random.default_rng(1)
    for k in range(50):
        q, dq, tau = rng.normal(size=(3, 4))
        r = s.read(k, q, dq, tau)
        assert isinstance(r, SensorReadings)
        assert np.array_equal(r.q, q) and np.array_equal(r.dq, dq) and np.array_equal(r.tau, tau)
        assert r.cuff_force_est is None


def test_read_returns_the_same_buffers() -> None:
    s = Sensors(SensorParams(), DT)
    r0 = s.read(0, np.zeros(4), np.zeros(4), np.zeros(4))
    r1 = s.read(1, np.ones(4), np.zeros(4), np.zeros(4))
    assert r0 is r1


def test_quantisation_gives_multiples_of_the_resolution() -> None:
    res_q, res_tau = 2 * math.pi / 2**17, 0.01
    s = Sensors(noiseless(encoder_resolution_rad=res_q, torque_resolution_Nm=res_tau), DT)
    rng = np.random.default_rng(2)
    for k in range(200):
        q, tau = rng.uniform(-2, 2, 4), rng.uniform(-100, 100, 4)
        r = s.read(k, q, np.zeros(4), tau)
        assert np.allclose(r.q / res_q, np.round(r.q / res_q), atol=1e-6)
        assert np.all(np.abs(r.q - q) <= 0.5 * res_q + 1e-15)
        assert np.allclose(r.tau / res_tau, np.round(r.tau / res_tau), atol=1e-6)
        assert np.all(np.abs(r.tau - tau) <= 0.5 * res_tau + 1e-12)


def test_noise_and_bias_statistics() -> None:
    bias = (0.5, -1.0, 0.0, 2.0)
    p = noiseless(encoder_noise_std_rad=3e-4, torque_noise_std_Nm=0.2, torque_bias_Nm=bias)
    s = Sensors(p, DT)
    n = 20_000
    q_err = np.zeros((n, 4))
    tau_err = np.zeros((n, 4))
    q0, tau0 = np.full(4, 0.3), np.full(4, 10.0)
    for k in range(n):
        r = s.read(k, q0, np.zeros(4), tau0)
        q_err[k] = r.q - q0
        tau_err[k] = r.tau - tau0
    # std of a sample std of n normals: sigma / sqrt(2n) ≈ 0.5 %; allow 3 %.
    assert np.allclose(q_err.std(axis=0), 3e-4, rtol=0.03)
    assert np.allclose(tau_err.std(axis=0), 0.2, rtol=0.03)
    assert np.allclose(q_err.mean(axis=0), 0.0, atol=4 * 3e-4 / math.sqrt(n))
    assert np.allclose(tau_err.mean(axis=0), bias, atol=4 * 0.2 / math.sqrt(n))


def test_noise_is_the_seeded_stream_drawn_in_blocks() -> None:
    """Readings across several noise blocks are exactly default_rng(seed)'s stream."""
    seed, sq, st = 7, 1e-3, 0.5
    p = noiseless(encoder_noise_std_rad=sq, torque_noise_std_Nm=st, seed=seed)
    s = Sensors(p, DT)
    n = 2 * NOISE_BLOCK + 300
    got = np.array([s.read(k, np.zeros(4), np.zeros(4), np.zeros(4)).tau.copy() for k in range(n)])
    rng = np.random.default_rng(seed)
    expected = []
    for _ in range(3):
        rng.standard_normal((NOISE_BLOCK, 4))  # the encoder block is drawn first
        expected.append(st * rng.standard_normal((NOISE_BLOCK, 4)))
    assert np.array_equal(got, np.concatenate(expected)[:n])
    # Reproducible, and a different seed gives different noise.
    again = Sensors(p, DT)
    other = Sensors(noiseless(encoder_noise_std_rad=sq, torque_noise_std_Nm=st, seed=8), DT)
    a = [again.read(k, np.zeros(4), np.zeros(4), np.zeros(4)).tau.copy() for k in range(10)]
    b = [other.read(k, np.zeros(4), np.zeros(4), np.zeros(4)).tau.copy() for k in range(10)]
    assert np.array_equal(np.array(a), got[:10])
    assert not np.array_equal(np.array(a), np.array(b))
    # reset() restarts the stream.
    s.reset()
    assert np.array_equal(s.read(0, np.zeros(4), np.zeros(4), np.zeros(4)).tau, got[0])


def test_sample_and_hold_at_a_lower_rate() -> None:
    s = Sensors(noiseless(sample_rate_hz=250.0), DT)
    values = []
    for k in range(40):
        x = np.full(4, float(k))
        values.append(s.read(k, x, x, x).q[0])
    # A new sample every 4th tick (t = 0, 4, 8 ms, ...), held in between.
    assert values == [float(4 * (k // 4)) for k in range(40)]
    assert s.samples == 10
    # A rate that is not a divisor: samples stay on the grid n / 300 s.
    s = Sensors(noiseless(sample_rate_hz=300.0), DT)
    taken = [k for k in range(100) if s.read(k, np.full(4, k), np.zeros(4), np.zeros(4)).q[0] == k]
    grid = [math.ceil(n * 1000 / 300 - 1e-9) for n in range(30)]
    assert taken == grid[: len(taken)] and len(taken) == 30


def test_a_rate_equal_to_the_tick_samples_every_tick_however_long_the_run() -> None:
    """The grid is t_0 + n T_s, not a running sum of T_s: at 1 kHz a sum of 0.001 drifts
    past k Δt by more than the hold's tolerance (1e-9 Δt) near 8 s, and a frame was held."""
    s = Sensors(noiseless(sample_rate_hz=1000.0), DT)
    n = 20_000
    x = np.zeros(4)
    for k in range(n):
        x[0] = float(k)
        assert s.read(k, x, x, x).q[0] == k, f"tick {k} held the last sample"
    assert s.samples == n
    # the running sum itself: past the tolerance before the run's end
    acc, drift = 0.0, []
    for k in range(1, n):
        acc += 1.0 / 1000.0
        drift.append(acc - k * DT)
    assert max(drift) > 1e-9 * DT


def test_encoder_speed_is_exact_on_a_ramp_without_noise() -> None:
    """Finite difference of a ramp is its slope; the filter starts at the true speed."""
    s = Sensors(noiseless(velocity="encoder"), DT)
    speed = np.array([0.5, -1.0, 2.0, 0.1])
    for k in range(100):
        r = s.read(k, 0.2 + speed * k * DT, speed, np.zeros(4))
        assert np.allclose(r.dq, speed, rtol=1e-9)


def test_encoder_speed_step_response_is_first_order() -> None:
    """A speed step (ramp from rest) is followed as 1 - exp(-2π f t) of the filter."""
    f = 30.0
    s = Sensors(noiseless(velocity="encoder", velocity_filter_hz=f), DT)
    out = []
    for k in range(60):
        q = 1.0 * max(k - 10, 0) * DT  # speed 1 rad/s from t = 10 ms
        out.append(s.read(k, np.full(4, q), np.zeros(4), np.zeros(4)).dq[0])
    n = np.arange(1, 50)
    expected = 1.0 - np.exp(-2 * math.pi * f * DT * n)
    assert np.allclose(np.array(out[11:60]), expected, atol=1e-12)


def test_default_encoder_speed_noise_and_lag() -> None:
    """The default speed: noise ≈ 0.005 rad/s at rest, lag ≈ 1/(2π f_v) on a slow sine."""
    p = SensorParams()
    s = Sensors(p, DT)
    rest = np.array(
        [s.read(k, np.full(4, 0.3), np.zeros(4), np.zeros(4)).dq[0] for k in range(5000)]
    )
    noise = rest[200:].std()
    print(f"\ndefault encoder speed noise at rest: {noise:.4f} rad/s")
    assert 0.002 < noise < 0.008
    s = Sensors(p, DT)
    w = 2 * math.pi * 0.8
    t = np.arange(4000) * DT
    est = np.array(
        [
            s.read(k, np.full(4, 0.5 * math.sin(w * tk)), 0, np.zeros(4)).dq[0]
            for k, tk in enumerate(t)
        ]
    )
    true = 0.5 * w * np.cos(w * t)
    # Best-fitting delay of the estimate [s].
    lags = np.arange(0, 15)
    errs = [np.std(est[1000 + d :] - true[1000 : len(t) - d]) for d in lags]
    lag = lags[int(np.argmin(errs))] * DT
    print(f"default encoder speed lag on a 0.8 Hz sine: {lag * 1e3:.0f} ms")
    assert abs(lag - 1 / (2 * math.pi * p.velocity_filter_hz)) <= 1.5e-3


def test_reads_keep_their_buffers_and_memory_flat() -> None:
    """Every read writes into the same arrays; 2000 reads (two noise blocks) leave no growth."""
    s = Sensors(SensorParams(), DT)
    buffers = (s.readings.q, s.readings.dq, s.readings.tau)
    q, dq, tau = np.full(4, 0.1), np.zeros(4), np.ones(4)
    for k in range(NOISE_BLOCK + 10):  # warm up: first block drawn
        s.read(k, q, dq, tau)
    tracemalloc.start()
    before = tracemalloc.take_snapshot()
    for k in range(NOISE_BLOCK + 10, 3 * NOISE_BLOCK):
        s.read(k, q, dq, tau)
    after = tracemalloc.take_snapshot()
    tracemalloc.stop()
    grown = sum(st.size_diff for st in after.compare_to(before, "filename"))
    assert grown < 4096
    r = s.read(3 * NOISE_BLOCK, q, dq, tau)
    assert all(x is y for x, y in zip((r.q, r.dq, r.tau), buffers, strict=True))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"encoder_resolution_rad": -1e-5}, "encoder_resolution must be >= 0 rad; got -1e-05"),
        ({"encoder_resolution_rad": 0.5}, "encoder_resolution must be in [0, 0.1] rad; got 0.5"),
        (
            {"encoder_noise_std_rad": float("nan")},
            "encoder_noise_std must be a finite number [rad]; got nan",
        ),
        ({"velocity": "gyro"}, "velocity must be 'encoder' or 'true'; got 'gyro'"),
        ({"velocity_filter_hz": 0.0}, "velocity_filter must be > 0 Hz; got 0.0"),
        ({"torque_noise_std_Nm": -0.1}, "torque_noise_std must be >= 0 N·m; got -0.1"),
        ({"torque_resolution_Nm": -1.0}, "torque_resolution must be >= 0 N·m; got -1.0"),
        (
            {"torque_bias_Nm": (1.0, 2.0)},
            "torque_bias must be a finite number or 4 of them [N·m]; got (1.0, 2.0)",
        ),
        (
            {"torque_bias_Nm": (0.0, float("inf"), 0.0, 0.0)},
            "torque_bias must be a finite number [N·m]; got inf",
        ),
        ({"sample_rate_hz": -100.0}, "sample_rate must be > 0 Hz; got -100.0"),
        ({"seed": -1}, "seed must be an integer >= 0; got -1"),
        ({"seed": 1.5}, "seed must be an integer >= 0; got 1.5"),
    ],
)
def test_bad_parameters_are_refused_with_a_clear_message(kwargs, message) -> None:
    with pytest.raises(InvalidParameter) as info:
        SensorParams(**kwargs)
    assert str(info.value) == message


def test_bad_period_is_refused() -> None:
    with pytest.raises(InvalidParameter, match=r"dt must be > 0 s; got 0\.0"):
        Sensors(SensorParams(), 0.0)


def test_bias_is_stored_per_joint() -> None:
    assert SensorParams(torque_bias_Nm=0.7).torque_bias_Nm == (0.7, 0.7, 0.7, 0.7)
    assert np.array_equal(SensorParams(torque_bias_Nm=[1, 2, 3, 4]).bias, [1.0, 2.0, 3.0, 4.0])


def test_readings_of_the_wrong_length_are_refused_by_name() -> None:
    sensors = Sensors(SensorParams(), dt=1e-3)
    before = sensors.record.copy()
    with pytest.raises(InvalidParameter, match=r"^dq_true must be an array of shape \(4,\)"):
        sensors.read(0, np.zeros(4), np.zeros(2), np.zeros(4))
    assert sensors.samples == 0  # no effect:
    for name in before.dtype.names:
        assert np.array_equal(sensors.record[name], before[name]), name


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (
            {"torque_noise_std_Nm": "0.2"},
            "torque_noise_std must be a finite number [N·m]; got '0.2'",
        ),
        ({"torque_bias_Nm": "1"}, "torque_bias must be a finite number [N·m]; got '1'"),
        (
            {"torque_bias_Nm": (0.0, True, 0.0, 0.0)},
            "torque_bias must be a finite number [N·m]; got True",
        ),
    ],
)
def test_numbers_given_as_text_or_truth_values_are_refused(kwargs, message) -> None:
    with pytest.raises(InvalidParameter, match="^" + re.escape(message) + "$"):
        SensorParams(**kwargs)
