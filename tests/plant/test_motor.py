"""Tests of exo_ctrl.plant.motor: exact current step, limits, damping, feedforward.

The references below are written from the ODE of paper §V,
``L dI/dt + R I + i_G ω / k_E = U``, with the constants of Table I typed in
here, not taken from the module under test.  The winding's maths is tested
on the paper's printed drive (:meth:`MotorParams.paper_printed`, a lossless
gearbox, so the torque is i_G k_m Ī); the default drive, its consistency and
its gearbox efficiency are tested in test_drive.py.
"""

from __future__ import annotations

import dataclasses
import math
import tracemalloc

import numpy as np
import pytest

from exo_ctrl.exceptions import ExoCtrlError, InvalidParameter
from exo_ctrl.plant.drive import MotorParams
from exo_ctrl.plant.motor import MotorBank

# Paper Table I and the documented choices, typed independently of the module.
L = 0.072e-3  # H
R = 0.103  # Ω
K_M = 0.35  # N·m/A
K_E = 25.9  # rad/(V·s)
I_G = 50.0
U_MAX = 24.0  # V
I_MAX = 10.0  # A
KT = I_G * K_M  # joint torque per ampere [N·m/A]
KB = I_G / K_E  # back-EMF per joint rad/s [V·s/rad]
H = 1e-3  # control period [s]
PRINTED = MotorParams.paper_printed()

# A state well inside the current limit: |I∞| < 10 A for every drive.
I0 = np.array([0.0, 5.0, -8.0, 2.0])
U = np.array([1.6, -1.2, 0.0, 1.2])
W = np.array([0.5, -0.3, 0.2, 0.9])


def i_inf(u: np.ndarray, w: np.ndarray) -> np.ndarray:
    return (u - KB * w) / R


def euler_reference(i0, u, w, h, n_sub):
    """Explicit Euler with n_sub substeps; returns I(h) and the trapezoid time average."""
    i = np.array(i0, dtype=float)
    hf = h / n_sub
    area = np.zeros_like(i)
    for _ in range(n_sub):
        i_next = i + hf * (u - R * i - KB * w) / L
        area += 0.5 * (i + i_next)
        i = i_next
    return i, area / n_sub


def euler_first_order_error(i0, u, w, h, n_sub):
    """Leading error of the n_sub-step Euler reference of I(h) (for L dI/dt = -R (I - I∞)).

    (1 - y)^N = e^{-x} (1 - x y / 2 + O(y²)) with x = h R / L, y = x / N.
    """
    x = h * R / L
    return x * (x / n_sub) / 2 * math.exp(-x) * np.abs(np.asarray(i0) - i_inf(u, w))


# -- parameters ------------------------------------------------------------------------


def test_the_printed_preset_and_its_derived_quantities():
    p = PRINTED
    assert (p.inductance_H, p.resistance_ohm) == (L, R)
    assert (p.torque_constant_Nm_per_A, p.speed_constant_rad_per_Vs) == (K_M, K_E)
    assert (p.gear_ratio, p.supply_voltage_V, p.current_limit_A) == (I_G, U_MAX, I_MAX)
    assert p.rotor_inertia_kgm2 == 6e-5
    assert (p.gear_efficiency, p.energy_consistent) == (1.0, False)
    assert p.electrical_time_constant_s == pytest.approx(0.699e-3, rel=1e-3)
    assert p.torque_per_amp_Nm_per_A == pytest.approx(17.5, rel=1e-15)
    assert p.back_emf_V_per_rad_s == pytest.approx(1.930502, rel=1e-6)
    assert p.reflected_inertia_kgm2 == pytest.approx(0.15, rel=1e-14)
    assert p.peak_torque_Nm == pytest.approx(175.0, rel=1e-15)


def test_params_are_frozen_and_stored_as_float():
    p = MotorParams(gear_ratio=100)
    assert isinstance(p.gear_ratio, float)
    assert p.reflected_inertia_kgm2 == pytest.approx(0.2, rel=1e-14)
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.gear_ratio = 3.0  # type: ignore[misc]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"resistance_ohm": -1}, "resistance_ohm must be > 0 Ω; got -1"),
        ({"inductance_H": math.nan}, "inductance_H must be a finite number [H]; got nan"),
        ({"gear_ratio": 0.0}, "gear_ratio must be > 0; got 0.0"),
        ({"current_limit_A": math.inf}, "current_limit_A must be a finite number [A]; got inf"),
        ({"supply_voltage_V": "24 V"}, "supply_voltage_V must be a finite number [V]; got '24 V'"),
        ({"supply_voltage_V": "24"}, "supply_voltage_V must be a finite number [V]; got '24'"),
        ({"gear_ratio": "50"}, "gear_ratio must be a finite number; got '50'"),
        ({"resistance_ohm": b"0.1"}, "resistance_ohm must be a finite number [Ω]; got b'0.1'"),
        ({"current_limit_A": True}, "current_limit_A must be a finite number [A]; got True"),
        ({"gear_ratio": np.True_}, "gear_ratio must be a finite number; got np.True_"),
        (
            {"speed_constant_rad_per_Vs": -25.9},
            "speed_constant_rad_per_Vs must be > 0 rad/(V·s); got -25.9",
        ),
        ({"rotor_inertia_kgm2": 0}, "rotor_inertia_kgm2 must be > 0 kg·m²; got 0"),
    ],
)
def test_bad_parameters_exact_messages(kwargs, message):
    with pytest.raises(InvalidParameter) as info:
        MotorParams(**kwargs)
    assert str(info.value) == message
    (name,) = kwargs
    assert info.value.name == name
    assert isinstance(info.value, ExoCtrlError)
    assert isinstance(info.value, ValueError)


@pytest.mark.parametrize("n", [0, -2, 2.5, True, "4"])
def test_bad_number_of_drives(n):
    with pytest.raises(InvalidParameter) as info:
        MotorBank(n)
    assert str(info.value) == f"n_drives must be an integer >= 1; got {n!r}"


@pytest.mark.parametrize(
    ("dt", "message"),
    [
        (0.0, "dt_s must be > 0 s; got 0.0"),
        (-1e-3, "dt_s must be > 0 s; got -0.001"),
        (math.nan, "dt_s must be a finite number [s]; got nan"),
        (math.inf, "dt_s must be a finite number [s]; got inf"),
    ],
)
def test_bad_dt(dt, message):
    bank = MotorBank(4, PRINTED)
    bank.step(U, W, H)
    with pytest.raises(InvalidParameter) as info:
        bank.step(U, W, dt)
    assert str(info.value) == message
    # The bank is still usable with a good step afterwards.
    bank.reset(I0)
    bank.step(U, W, H)
    assert np.all(np.isfinite(bank.current_A))


def test_reset_checks_the_current():
    bank = MotorBank(2, PRINTED)
    with pytest.raises(InvalidParameter) as info:
        bank.reset(11.0)
    assert str(info.value) == "current_A must be finite and within ±10 A; got 11.0"
    with pytest.raises(InvalidParameter):
        bank.reset([1.0, math.nan])
    bank.reset([3.0, -10.0])
    np.testing.assert_array_equal(bank.current_A, [3.0, -10.0])
    np.testing.assert_array_equal(bank.torque_Nm, [3.0 * KT, -10.0 * KT])
    assert not bank.saturated.any()


# -- steady state and limits -----------------------------------------------------------


def test_steady_state_current_and_torque():
    bank = MotorBank(4, PRINTED)
    for _ in range(200):
        torque = bank.step(U, W, H)
    expected = (U - I_G * W / K_E) / R
    np.testing.assert_allclose(bank.current_A, expected, rtol=1e-12, atol=0)
    np.testing.assert_allclose(bank.mean_current_A, expected, rtol=1e-12, atol=0)
    np.testing.assert_allclose(torque, I_G * K_M * expected, rtol=1e-12, atol=0)
    np.testing.assert_allclose(bank.steady_state_current(U, W), expected, rtol=1e-14)
    assert not bank.saturated.any()
    np.testing.assert_array_equal(bank.applied_voltage_V, U)


def test_current_limit_at_steady_state():
    bank = MotorBank(4, PRINTED)
    u = np.array([24.0, -24.0, 12.0, 3.0])
    w = np.array([0.0, 0.0, 1.0, -0.5])  # I∞ = 233, -233, 98, 38.5 A: all beyond 10 A
    assert np.all(np.abs(i_inf(u, w)) > I_MAX)
    for _ in range(50):
        bank.step(u, w, H)
    np.testing.assert_array_equal(bank.current_A, [10.0, -10.0, 10.0, 10.0])
    np.testing.assert_array_equal(bank.mean_current_A, [10.0, -10.0, 10.0, 10.0])
    np.testing.assert_array_equal(bank.torque_Nm, [175.0, -175.0, 175.0, 175.0])
    assert bank.saturated.all()
    np.testing.assert_array_equal(bank.steady_state_current(u, w), [10.0, -10.0, 10.0, 10.0])


def test_first_step_into_the_limit_clips_end_and_mean_current():
    bank = MotorBank(2, PRINTED)
    bank.step([24.0, 1.0], [0.0, 0.0], H)  # from rest: I∞ = 233 A and 9.7 A
    assert bank.saturated.tolist() == [True, False]
    assert bank.current_A[0] == I_MAX
    assert bank.mean_current_A[0] == I_MAX
    # The unsaturated drive follows the exact solution from rest.
    x = H * R / L
    i_end = (1.0 / R) * (1 - math.exp(-x))
    i_mean = (1.0 / R) * (1 - (1 - math.exp(-x)) / x)
    assert bank.current_A[1] == pytest.approx(i_end, rel=1e-14)
    assert bank.mean_current_A[1] == pytest.approx(i_mean, rel=1e-14)


def test_voltage_saturation():
    bank = MotorBank(4, PRINTED)
    bank.step([1000.0, -1000.0, 5.0, 24.5], np.zeros(4), H)
    np.testing.assert_array_equal(bank.applied_voltage_V, [24.0, -24.0, 5.0, 24.0])
    ss = bank.steady_state_current([1000.0, 5.0], [12.0, 2.5])
    # 1000 V is applied as 24 V: (24 - 1.9305·12)/R = 8.10 A, not the current limit.
    np.testing.assert_allclose(ss, [(24.0 - KB * 12.0) / R, (5.0 - KB * 2.5) / R], rtol=1e-13)
    assert np.all(np.abs(ss) < I_MAX)


# -- the exact step against a fine reference ------------------------------------------


def test_exact_step_matches_fine_euler_over_one_step():
    bank = MotorBank(4, PRINTED)
    bank.reset(I0)
    bank.step(U, W, H)
    assert not bank.saturated.any()
    i10, _ = euler_reference(I0, U, W, H, 10_000)
    i20, _ = euler_reference(I0, U, W, H, 20_000)
    err10 = i10 - bank.current_A
    err20 = i20 - bank.current_A
    # Measured: max |err10| = 2.70e-4 A, which is the reference's own first-order error
    # (predicted x²/(2N) e^{-x} |I0 - I∞|, same to 5e-5 relative) ...
    np.testing.assert_allclose(
        np.abs(err10), euler_first_order_error(I0, U, W, H, 10_000), rtol=1e-3
    )
    assert np.abs(err10).max() < 3e-4
    # ... halving the reference step halves it (first order, toward the exact step) ...
    np.testing.assert_allclose(err10 / err20, 2.0, rtol=1e-3)
    # ... and the Richardson-extrapolated reference agrees to 6e-9 A (measured).
    assert np.abs(2 * i20 - i10 - bank.current_A).max() < 2e-8


def test_mean_current_is_the_time_average_of_the_fine_reference():
    bank = MotorBank(4, PRINTED)
    bank.reset(I0)
    bank.step(U, W, H)
    _, m10 = euler_reference(I0, U, W, H, 10_000)
    _, m20 = euler_reference(I0, U, W, H, 20_000)
    # Measured: 2.3e-4 A for N = 10_000, halving with N; extrapolated 2.6e-9 A.
    assert np.abs(m10 - bank.mean_current_A).max() < 2.5e-4
    np.testing.assert_allclose(
        (m10 - bank.mean_current_A) / (m20 - bank.mean_current_A), 2.0, rtol=1e-3
    )
    assert np.abs(2 * m20 - m10 - bank.mean_current_A).max() < 1e-8
    # The mean is not the end current nor the start current.
    assert np.abs(bank.mean_current_A - bank.current_A).min() > 0.1
    np.testing.assert_allclose(bank.torque_Nm, KT * bank.mean_current_A, rtol=1e-15)


def test_exact_steps_match_fine_euler_over_a_sequence_of_varying_voltages():
    rng = np.random.default_rng(0)
    u_seq = KB * W + rng.uniform(-0.9, 0.9, size=(20, 4))  # keeps |I| < 10 A
    bank = MotorBank(4, PRINTED)
    i10 = np.zeros(4)
    i20 = np.zeros(4)
    worst = worst_mean = worst_richardson = worst_richardson_mean = 0.0
    for u in u_seq:
        bank.step(u, W, H)
        assert not bank.saturated.any()
        i10, m10 = euler_reference(i10, u, W, H, 10_000)
        i20, m20 = euler_reference(i20, u, W, H, 20_000)
        worst = max(worst, np.abs(i10 - bank.current_A).max())
        worst_mean = max(worst_mean, np.abs(m10 - bank.mean_current_A).max())
        worst_richardson = max(worst_richardson, np.abs(2 * i20 - i10 - bank.current_A).max())
        worst_richardson_mean = max(
            worst_richardson_mean, np.abs(2 * m20 - m10 - bank.mean_current_A).max()
        )
    # Measured over the 20 steps, currents up to 7.7 A: 3.4e-4 A (end) and 2.8e-4 A (mean)
    # against the N = 10_000 reference, 9.6e-9 A and 4.7e-9 A against the extrapolated one.
    assert np.abs(bank.current_A).max() > 3.0
    assert worst < 5e-4
    assert worst_mean < 4e-4
    assert worst_richardson < 2e-8
    assert worst_richardson_mean < 1e-8


def test_plain_euler_at_1ms_rings_and_at_2ms_diverges_but_exact_step_does_not():
    factor_1ms = 1 - H * R / L
    # Euler's error factor at 1 ms is -0.43: stable, but each step overshoots and
    # the sign of the error alternates.  The stability bound is h < 2 L / R = 1.40 ms.
    assert factor_1ms == pytest.approx(-0.4306, abs=1e-4)
    stability_bound = 2 * L / R
    assert stability_bound == pytest.approx(1.398e-3, rel=1e-3)
    factor_2ms = 1 - 2 * H * R / L
    assert abs(factor_2ms) > 1  # -1.86: diverges

    u, w = np.array([1.5]), np.array([0.2])
    target = i_inf(u, w)[0]  # 10.8 A > I_MAX, so raise the limit for this test
    params = MotorParams(current_limit_A=1000.0)
    for h, factor in ((H, factor_1ms), (2 * H, factor_2ms)):
        i_euler = 0.0
        errors = []
        for _ in range(10):
            i_euler = i_euler + h * (u[0] - R * i_euler - KB * w[0]) / L
            errors.append(i_euler - target)
        signs = np.sign(errors)
        assert np.all(signs[1:] == -signs[:-1])  # rings
        np.testing.assert_allclose(np.diff(errors) / np.array(errors[:-1]), factor - 1, rtol=1e-9)

        bank = MotorBank(1, params)
        means = np.array([bank.step(u, w, h)[0] / KT for _ in range(10)])
        # Mean currents rise monotonically toward the target, never overshooting.
        assert np.all(np.diff(means) > 0) and np.all(means < target)
        assert bank.current_A[0] <= target
    # After 10 steps of 2 ms Euler is 1.86**10 ≈ 500 times its first error away.
    assert abs(errors[-1]) > 100 * abs(target)


# -- derivatives and inverse -----------------------------------------------------------


def test_damping_matches_central_difference_of_mean_torque():
    u = np.array([1.6, -1.2, 24.0, -24.0])
    w = np.array([0.5, -0.3, 0.0, 0.0])  # last two saturate
    delta = 1e-3
    bank = MotorBank(4, PRINTED)

    def mean_torque(omega):
        bank.reset(I0)
        return bank.step(u, omega, H).copy()

    fd = (mean_torque(w + delta) - mean_torque(w - delta)) / (2 * delta)
    bank.reset(I0)
    bank.step(u, w, H)
    assert bank.saturated.tolist() == [False, False, True, True]
    d = bank.damping_Nm_s_per_rad
    # The mean torque is affine in ω: measured agreement 5e-15 relative.
    np.testing.assert_allclose(-fd[:2], d[:2], rtol=1e-10)
    assert fd[2:].tolist() == [0.0, 0.0]
    assert d[2:].tolist() == [0.0, 0.0]
    # Closed form: D = i_G k_m (1 - φ) (i_G / k_E) / R with φ = (1 - e^{-x}) / x.
    x = H * R / L
    phi = (1 - math.exp(-x)) / x
    assert d[0] == pytest.approx(KT * (1 - phi) * KB / R, rel=1e-13)
    assert d[0] == pytest.approx(153.556, rel=1e-5)


def test_damping_tends_to_the_steady_state_value_for_long_steps():
    bank = MotorBank(1, PRINTED)
    d_steady = KT * KB / R  # 328 N·m·s/rad
    bank.step([0.1], [0.0], 1.0)
    assert bank.damping_Nm_s_per_rad[0] == pytest.approx(d_steady, rel=1e-3)
    # and to 0 for a step much shorter than τ_e (the current cannot respond).
    bank.step([0.1], [0.0], 1e-7)
    assert bank.damping_Nm_s_per_rad[0] == pytest.approx(d_steady * 1e-7 * R / L / 2, rel=1e-3)


def test_voltage_for_then_steady_state_gives_back_the_torque():
    torque = np.array([50.0, -30.0, 0.0, 120.0])
    w = np.array([1.0, -2.0, 3.0, 0.5])
    bank = MotorBank(4, PRINTED)
    u = bank.voltage_for(torque, w)
    np.testing.assert_allclose(u, R * torque / KT + KB * w, rtol=1e-15)
    for _ in range(100):
        tau = bank.step(u, w, H)
    np.testing.assert_allclose(tau, torque, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(KT * bank.steady_state_current(u, w), torque, rtol=1e-12, atol=1e-12)


# -- in-place behaviour ----------------------------------------------------------------


def test_step_updates_owned_buffers_in_place_and_they_are_read_only():
    bank = MotorBank(4, PRINTED)
    current = bank.current_A
    tau1 = bank.step(U, W, H)
    first = tau1.copy()
    tau2 = bank.step(U, W, H)
    assert np.shares_memory(tau1, tau2)
    assert np.shares_memory(current, bank.current_A)
    assert not np.array_equal(first, tau2)  # overwritten by the next step
    for a in (current, tau2, bank.mean_current_A, bank.applied_voltage_V, bank.saturated):
        with pytest.raises(ValueError):
            a[0] = 0


def test_step_allocates_no_arrays_and_retains_nothing():
    # The step writes into the bank's buffers: after many steps nothing more
    # is retained than by an empty call, and what it holds in passing (the
    # compiled call's argument packing) does not grow with the step count.
    bank = MotorBank(4, PRINTED)
    u, w = U.copy(), W.copy()

    def traced(f, n):
        for _ in range(10):
            f()
        tracemalloc.start()
        try:
            for _ in range(10):
                f()
            before, _ = tracemalloc.get_traced_memory()
            tracemalloc.reset_peak()
            for _ in range(n):
                f()
            after, peak = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
        return peak - before, after - before

    baseline, kept = traced(lambda: None, 500)
    one_array, _ = traced(lambda: np.multiply(u, w), 500)
    assert one_array > baseline  # the probe sees a single small array
    peak, retained = traced(lambda: bank.step(u, w, H), 500)
    assert retained == kept
    assert traced(lambda: bank.step(u, w, H), 5000) == (peak, retained)


def test_changing_the_step_length_between_calls():
    # φ and e^{-h/τ_e} are cached per h: alternating h must still give the
    # closed-form step every time.
    bank = MotorBank(1, PRINTED)
    i = 0.0
    u, w = 1.0, 0.2
    target = (u - KB * w) / R
    for h in (1e-3, 2e-4, 1e-3, 5e-3, 1e-3):
        bank.step([u], [w], h)
        x = h * R / L
        mean = target + (i - target) * (1 - math.exp(-x)) / x
        i = target + (i - target) * math.exp(-x)
        assert bank.current_A[0] == pytest.approx(i, rel=1e-14)
        assert bank.mean_current_A[0] == pytest.approx(mean, rel=1e-14)
