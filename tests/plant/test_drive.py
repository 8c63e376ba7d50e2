"""The default drive: energy-consistent, its stall torque and no-load speed, its gearbox losses.

References typed here from the DC motor's equations, not from the module:
U = R I + (i_G/k_E) ω at steady state, τ_m = i_G k_m I, and a gearbox that
passes η of the motor's power to the joint when motoring and takes 1/η of
the joint's power to return the motor's when braking.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plant.drive import EFFICIENCY_SMOOTHING_RAD_S, MotorParams
from exo_ctrl.plant.motor import MotorBank

K_E = 25.9  # rad/(V·s), paper Table I
K_M = 1.0 / K_E  # N·m/A, the SI identity
R = 0.103  # Ω
I_G = 120.0
ETA = 0.85
KT = I_G * K_M  # 4.633 N·m/A
KB = I_G / K_E  # 4.633 V·s/rad


def test_the_default_drive_is_energy_consistent_and_documented() -> None:
    p = MotorParams()
    assert p.torque_constant_Nm_per_A * p.speed_constant_rad_per_Vs == pytest.approx(1.0, abs=1e-15)
    assert (p.gear_ratio, p.gear_efficiency, p.supply_voltage_V, p.current_limit_A) == (
        I_G,
        ETA,
        24.0,
        32.0,
    )
    assert p.reflected_inertia_kgm2 == pytest.approx(I_G**2 * 2e-5, rel=1e-14)
    assert p.torque_per_amp_Nm_per_A == pytest.approx(KT, rel=1e-15)
    assert p.back_emf_V_per_rad_s == pytest.approx(KB, rel=1e-15)
    assert p.energy_consistent


def test_an_inconsistent_pair_is_refused_naming_both_and_the_product() -> None:
    with pytest.raises(InvalidParameter) as info:
        MotorParams(torque_constant_Nm_per_A=0.35)
    assert str(info.value) == (
        "torque_constant_Nm_per_A must be 1/speed_constant_rad_per_Vs = 0.03861 N·m/A within "
        "0.1% (an energy-consistent DC motor); got 0.35 (with speed_constant_rad_per_Vs = 25.9 "
        "the product k_m k_E is 9.065, not 1: the motor would put out 9.06 times the power its "
        "back-EMF takes in; MotorParams.paper_printed() is the paper's printed pair)"
    )
    # A datasheet's rounding passes: 0.0386 N·m/A with 25.9 rad/(V·s) is 0.9997.
    assert MotorParams(torque_constant_Nm_per_A=0.0386).torque_constant_Nm_per_A == 0.0386


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"gear_efficiency": 1.2}, "gear_efficiency must be in (0, 1]; got 1.2"),
        ({"gear_efficiency": 0.0}, "gear_efficiency must be > 0; got 0.0"),
        ({"energy_consistent": "no"}, "energy_consistent must be True or False; got 'no'"),
    ],
)
def test_bad_gearbox_parameters(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        MotorParams(**kwargs)
    assert str(info.value) == message


def test_stall_torque_at_a_held_voltage() -> None:
    """ω = 0: I = U/R (below the limit), τ = i_G k_m U / R (the gearbox passes it whole at rest)."""
    bank = MotorBank(1, MotorParams())
    u = 2.0  # V: 19.4 A, within the 32 A limit
    for _ in range(50):  # 50 ms ≫ τ_e = 0.7 ms
        tau = bank.step([u], [0.0], 1e-3)
    assert bank.current_A[0] == pytest.approx(u / R, rel=1e-12)
    assert tau[0] == pytest.approx(KT * u / R, rel=1e-12)
    # Above U = R I_max the driver holds 32 A: the stall torque is i_G k_m I_max.
    for _ in range(50):
        tau = bank.step([24.0], [0.0], 1e-3)
    assert tau[0] == pytest.approx(KT * 32.0, rel=1e-12)


def test_no_load_speed_at_a_held_voltage() -> None:
    """A free inertia driven at U settles where the back-EMF takes it all: ω₀ = U k_E / i_G."""
    bank = MotorBank(1, MotorParams())
    inertia, h, u = 1.0, 1e-4, 2.0  # kg·m², s, V
    omega = 0.0
    for _ in range(40000):  # 4 s, 30 mechanical time constants J R / (k_t k_b)
        tau = bank.step([u], [omega], h)[0]
        omega += h * tau / inertia
    assert omega == pytest.approx(u * K_E / I_G, rel=1e-6)  # 0.4317 rad/s
    assert abs(bank.current_A[0]) < 1e-4


def _steady(u: float, omega: float) -> tuple[MotorBank, float]:
    bank = MotorBank(1, MotorParams())
    bank.reset((u - KB * omega) / R)  # at the steady current from the start
    for _ in range(100):
        tau = bank.step([u], [omega], 1e-3)[0]
    return bank, tau


def test_motoring_needs_one_over_eta_more_power_at_the_shaft() -> None:
    """Lifting at 1 rad/s: electrical − copper = τ ω / η."""
    omega = 1.0  # rad/s ≫ ω_η: tanh = 1
    bank, tau = _steady(KB * omega + 1.0, omega)
    i = bank.current_A[0]
    assert i > 0.0 and tau > 0.0
    assert tau == pytest.approx(ETA * KT * i, rel=1e-12)
    electrical = (KB * omega + 1.0) * i
    assert electrical - R * i * i == pytest.approx(tau * omega / ETA, rel=1e-12)


def test_braking_returns_eta_of_the_joints_power() -> None:
    """Lowering at 1 rad/s: the load drives the motor; what reaches the winding is η τ ω."""
    omega = 1.0
    u = KB * omega - 1.0  # the back-EMF exceeds the supply: the current reverses
    bank, tau = _steady(u, omega)
    i = bank.current_A[0]
    assert i < 0.0 and tau < 0.0
    assert tau == pytest.approx(KT * i / ETA, rel=1e-12)
    joint_power = -tau * omega  # what the load puts in [W]
    returned = -(u * i) + R * i * i  # what the back-EMF gives the winding [W]
    assert returned == pytest.approx(ETA * joint_power, rel=1e-12)
    books = bank.energy(("j",))["energy_J"]["j"]
    # Over the 0.1 s: (1/η − 1) of what the motor receives, (1/η − 1) |i_G k_m I| ω h.
    assert books["gear_loss"] == pytest.approx(-(1.0 / ETA - 1.0) * KT * i * omega * 0.1, rel=1e-9)
    assert books["regenerated"] > 0.0


def test_at_standstill_the_gearbox_passes_the_motor_torque() -> None:
    bank, tau = _steady(1.0, 0.0)
    assert tau == pytest.approx(KT * bank.current_A[0], rel=1e-15)


@pytest.mark.parametrize("omega", [0.0, 0.3 * EFFICIENCY_SMOOTHING_RAD_S, -0.01, 0.5])
def test_damping_is_minus_the_speed_derivative_of_the_mean_torque(omega: float) -> None:
    """D = −∂τ/∂ω, back-EMF and efficiency terms, against a central difference."""
    bank = MotorBank(1, MotorParams())
    u = KB * omega + 1.5
    delta = 1e-6

    def mean_torque(w: float) -> float:
        bank.reset(5.0)
        return float(bank.step([u], [w], 1e-3)[0])

    fd = (mean_torque(omega + delta) - mean_torque(omega - delta)) / (2 * delta)
    bank.reset(5.0)
    bank.step([u], [omega], 1e-3)
    d = bank.damping_Nm_s_per_rad[0]
    assert d > 0.0
    assert d == pytest.approx(-fd, rel=1e-6)
    # The efficiency's share is largest at standstill: |τ| |ln η| / ω_η.
    if omega == 0.0:
        tau = float(bank.torque_Nm[0])
        emf = d - abs(tau) * abs(math.log(ETA)) / EFFICIENCY_SMOOTHING_RAD_S
        x = 1e-3 * R / 0.072e-3
        assert emf == pytest.approx(KT * (1 - (1 - math.exp(-x)) / x) * KB / R, rel=1e-12)


def test_voltage_for_inverts_the_gearbox() -> None:
    bank = MotorBank(4, MotorParams())
    torque = np.array([50.0, -30.0, 40.0, -20.0])
    w = np.array([1.0, 1.0, -2.0, 0.0])  # motoring, braking, braking, at rest
    u = bank.voltage_for(torque, w)
    for _ in range(100):
        tau = bank.step(u, w, 1e-3)
    np.testing.assert_allclose(tau, torque, rtol=1e-9)
