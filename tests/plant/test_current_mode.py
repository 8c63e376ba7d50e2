"""The driver's current mode (exo_ctrl/plant/current_mode.py) against its closed forms.

A drive handed a current reference follows it as the first-order lag of
bandwidth ω_c = 2π·1 kHz of a PI with pole-zero cancellation: the current
at several times within a control tick (plant sub-steps) against
I* + (I₀ − I*) e^{−ω_c t}; the applied voltage against the winding's
equation; the supply and the current limit; the energy books against a fine
integration of U I; a voltage command is untouched.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from exo_ctrl.plant import CURRENT_LOOP_BANDWIDTH_HZ, MotorBank, MotorParams

OMEGA_C = 2.0 * math.pi * CURRENT_LOOP_BANDWIDTH_HZ  # [rad/s]
NAMES = ("a", "b", "c", "d")


def _bank(i0: np.ndarray, params: MotorParams | None = None) -> MotorBank:
    bank = MotorBank(4, params)
    bank.reset(i0)
    return bank


def _command(bank: MotorBank, ref: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Write the references and return the voltage command that selects current mode."""
    i_ref, u_ff = bank.current_command
    i_ref[:] = ref
    u_ff[:] = u
    return u


def test_a_reference_step_is_followed_as_the_first_order_lag_within_a_tick() -> None:
    p = MotorParams()
    i0 = np.array([0.0, 2.0, -3.0, 1.0])  # [A]
    ref = np.array([5.0, -4.0, 3.0, 0.0])  # [A]
    omega = np.array([0.0, 1.0, -1.0, 0.5])  # [rad/s]
    n, tick = 8, 1e-3  # eight sub-steps of a 1 ms tick
    h = tick / n
    bank = _bank(i0, p)
    u = np.array([1.0, -2.0, 0.5, 3.0])  # [V]: any number, as long as u_ff is it
    kb, r, ind = p.back_emf_V_per_rad_s, p.resistance_ohm, p.inductance_H
    for k in range(1, n + 1):
        start = bank.current_A.copy()
        bank.step(_command(bank, ref, u), omega, h)
        t = k * h
        expected = ref + (i0 - ref) * math.exp(-OMEGA_C * t)
        np.testing.assert_allclose(bank.current_A, expected, rtol=0, atol=1e-12)
        # the mean over the sub-step: ∫ of the lag over [t − h, t] / h
        mean = ref + (i0 - ref) * (math.exp(-OMEGA_C * (t - h)) - math.exp(-OMEGA_C * t)) / (
            OMEGA_C * h
        )
        np.testing.assert_allclose(bank.mean_current_A, mean, rtol=0, atol=1e-12)
        # the driver's mean voltage: the winding's equation averaged over the sub-step
        volts = kb * omega + r * mean + ind * (expected - start) / h
        np.testing.assert_allclose(bank.applied_voltage_V, volts, rtol=0, atol=1e-12)
        assert np.all(np.abs(bank.applied_voltage_V) <= p.supply_voltage_V)
    # after a tick the step is (1 − e^{−2π}) = 99.8 % done: the cited ~1 ms settling
    assert np.all(np.abs(bank.current_A - ref) <= 2e-3 * np.abs(i0 - ref) + 1e-12)


def test_one_step_equals_its_sub_steps() -> None:
    """The lag is exact: a 1 ms step ends where ten 0.1 ms steps do."""
    i0, ref, omega = np.array([1.0, -1.0, 0.0, 4.0]), np.array([6.0, 2.0, -5.0, 4.0]), np.ones(4)
    one, ten = _bank(i0), _bank(i0)
    one.step(_command(one, ref, np.zeros(4)), omega, 1e-3)
    for _ in range(10):
        ten.step(_command(ten, ref, np.zeros(4)), omega, 1e-4)
    np.testing.assert_allclose(one.current_A, ten.current_A, rtol=0, atol=1e-12)


def test_the_supply_limits_the_driver_and_its_current_never_passes_the_lag() -> None:
    p = MotorParams()
    u_max, r, kb = p.supply_voltage_V, p.resistance_ohm, p.back_emf_V_per_rad_s
    h = 1e-3
    eps = math.exp(-h * r / p.inductance_H)
    omega = np.array([5.0, -5.0, 3.0, -3.0])  # [rad/s]: 23 V, 13.8 V of back-EMF
    ref = np.array([30.0, -30.0, 30.0, -30.0])  # [A]
    bank = _bank(np.zeros(4), p)
    bank.step(_command(bank, ref, np.zeros(4)), omega, h)
    u = bank.applied_voltage_V
    assert np.all(np.abs(u) <= u_max)
    lag = ref * (1.0 - math.exp(-OMEGA_C * h))
    # the first two cannot reach the lag: the supply is applied whole
    assert u[0] == u_max and u[1] == -u_max
    held = (np.array([u_max, -u_max]) - kb * omega[:2]) / r
    np.testing.assert_allclose(bank.current_A[:2], held * (1.0 - eps), rtol=1e-12)
    assert np.all(np.abs(bank.current_A[:2]) < np.abs(lag[:2]))
    # the last two: the lag's start needs e + L ω_c 30 A = 27.4 V, beyond the supply,
    # but a constant voltage within it ends the step on the lag's current
    assert np.all(np.abs(kb * omega[2:] + p.inductance_H * OMEGA_C * ref[2:]) > u_max)
    np.testing.assert_allclose(bank.current_A[2:], lag[2:], rtol=1e-12)
    np.testing.assert_allclose(u[2:], kb * omega[2:] + r * lag[2:] / (1.0 - eps), rtol=1e-12)


def test_the_current_never_exceeds_the_drivers_limit() -> None:
    p = MotorParams()
    rng = np.random.default_rng(3)
    bank = _bank(np.zeros(4), p)
    peak = 0.0
    for _ in range(400):
        ref = rng.uniform(-3.0, 3.0, 4) * p.current_limit_A  # [A], mostly beyond the limit
        omega = rng.uniform(-6.0, 6.0, 4)  # [rad/s]
        bank.step(_command(bank, ref, np.zeros(4)), omega, rng.choice([1e-4, 1e-3, 2e-3]))
        peak = max(peak, np.abs(bank.current_A).max(), np.abs(bank.mean_current_A).max())
        assert np.all(np.abs(bank.applied_voltage_V) <= p.supply_voltage_V)
    assert peak <= p.current_limit_A
    assert peak >= 0.99 * p.current_limit_A  # and the test reaches it


def test_the_books_equal_a_fine_integration_of_u_times_i() -> None:
    """One step in current mode: electrical ∫U I dt and copper R ∫I² dt, by the midpoint rule."""
    p = MotorParams(gear_efficiency=1.0)
    i0, ref, omega, h = 1.0, 7.0, 0.4, 1e-3  # [A], [A], [rad/s], [s]
    bank = MotorBank(1, p)
    bank.reset(i0)
    i_ref, u_ff = bank.current_command
    i_ref[0], u_ff[0] = ref, 0.0
    bank.step(np.zeros(1), np.array([omega]), h)
    books = bank.energy(("j",))["energy_J"]["j"]
    n = 20000
    t = (np.arange(n) + 0.5) * (h / n)
    i = ref + (i0 - ref) * np.exp(-OMEGA_C * t)
    u = p.back_emf_V_per_rad_s * omega + p.resistance_ohm * i - p.inductance_H * OMEGA_C * (i - ref)
    assert books["electrical"] == pytest.approx(float(np.sum(u * i) * h / n), rel=1e-8)
    assert books["copper_loss"] == pytest.approx(
        float(np.sum(p.resistance_ohm * i * i) * h / n), rel=1e-8
    )
    assert abs(books["residual"]) <= 1e-15 * books["electrical"] + 1e-18


def test_a_run_of_references_balances_to_rounding() -> None:
    p = MotorParams()  # a consistent motor: k_b = k_t
    rng = np.random.default_rng(7)
    bank = _bank(np.zeros(4), p)
    for k in range(2000):
        ref = rng.uniform(-1.2, 1.2, 4) * p.current_limit_A
        omega = rng.uniform(-6.0, 6.0, 4)
        u = _command(bank, ref, np.zeros(4))
        bank.step(u if k % 3 else u + 1.0, omega, 1e-3)  # every third step a voltage step
    report = bank.energy(NAMES)
    assert report["energy_balance_residual_rel"] <= 1e-12


def test_a_voltage_command_is_not_a_current_reference() -> None:
    """A command other than u_ff (NaN after a reset) is applied as a voltage, bit for bit."""
    u, omega = np.array([3.0, -2.0, 12.0, 0.0]), np.array([0.5, 0.0, -1.0, 2.0])
    plain, tagged = _bank(np.ones(4)), _bank(np.ones(4))
    i_ref, u_ff = tagged.current_command
    assert np.all(np.isnan(u_ff))
    i_ref[:] = 20.0
    u_ff[:] = u + 1e-9  # close, but not the command
    for _ in range(5):
        plain.step(u, omega, 1e-3)
        tagged.step(u, omega, 1e-3)
    for name in ("current_A", "mean_current_A", "applied_voltage_V", "torque_Nm"):
        np.testing.assert_array_equal(getattr(plain, name), getattr(tagged, name))
    np.testing.assert_array_equal(plain.damping_Nm_s_per_rad, tagged.damping_Nm_s_per_rad)


def test_a_drive_in_current_mode_has_no_back_emf_damping() -> None:
    p = MotorParams()
    bank = _bank(np.zeros(4), p)
    omega = np.zeros(4)
    bank.step(_command(bank, np.array([5.0, -5.0, 0.0, 1.0]), np.zeros(4)), omega, 1e-3)
    # at ω = 0 only the gearbox's smoothing term is left: |τ| |ln η| / ω_η
    tau = np.abs(bank.torque_Nm)
    from_gear = tau * abs(math.log(p.gear_efficiency)) * bank.record[0]["inv_w_eta"]
    np.testing.assert_allclose(bank.damping_Nm_s_per_rad, from_gear, rtol=1e-12, atol=0)
    volt = _bank(np.zeros(4), p)
    volt.step(np.ones(4), omega, 1e-3)
    assert np.all(volt.damping_Nm_s_per_rad > 10.0)  # [N·m·s/rad]: a voltage step's
