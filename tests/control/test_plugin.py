"""A user's controller on the public interface meets the same device as the built-in ones.

Real models and runs, no mocks: a plain-Python PD written on
:class:`exo_ctrl.control.Controller` reproduces the built-in compiled PD;
a torque-commanding impedance controller (examples/impedance.py) stays
within the driver's current and the supply's voltage; a controller that
runs a joint into its limit is stopped by the supervisor as a built-in one
is; the driver's current loop (exo_ctrl/control/current_loop.py) settles on
its reference and does not wind up.
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl import SimConfig, read_recording, simulate
from exo_ctrl.control import Controller, CurrentLoop, PDGains
from exo_ctrl.plant import MotorBank, MotorParams
from exo_ctrl.record import RerunRecorder
from exo_ctrl.safety import SafetyLimits
from exo_ctrl.sim import drive_for
from exo_ctrl.sim.setup import build

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _example(name: str):
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class PlainPD(Controller):
    """The paper's PD law in numpy, on the public interface: U = k_p (q* − q) + k_d (q̇* − q̇)."""

    command_kind = "voltage"

    def __init__(self, gains: PDGains | None = None) -> None:
        gains = gains or PDGains()
        self.kp, self.kd = np.array(gains.kp), np.array(gains.kd)  # [V/rad], [V·s/rad]
        self.setups = 0

    def setup(self, device) -> None:
        self.setups += 1
        self.dt_s = device.dt_s

    def command(self, t_s, plan, sensors, cuff_force_est_N):
        return self.kp * (plan.q - sensors.q) + self.kd * (plan.dq - sensors.dq)


class FullVoltage(Controller):
    """Every drive at +24 V [V] (the default supply): the joints run into their limits."""

    def command(self, t_s, plan, sensors, cuff_force_est_N):
        return np.full(4, 24.0)


@pytest.fixture(scope="module")
def pd_runs():
    """The default run with the built-in PD and with the plain-Python one."""
    user = PlainPD()
    return simulate(SimConfig()), simulate(SimConfig(controller=user)), user


def test_a_plain_python_pd_equals_the_built_in_pd(pd_runs) -> None:
    builtin, mine, user = pd_runs
    assert builtin.status == mine.status == "completed"
    assert mine.t.shape == builtin.t.shape == (SimConfig().n_ticks,)  # the whole default run
    assert np.max(np.abs(mine.signals["q"] - builtin.signals["q"])) <= 1e-9  # [rad]
    assert np.max(np.abs(mine.signals["voltage_cmd"] - builtin.signals["voltage_cmd"])) <= 1e-9
    # the run is not trivial: the PD moves the legs along the gait
    assert np.ptp(builtin.signals["q"], axis=0).min() > 0.3
    assert user.setups == 1 and user.dt_s == SimConfig().dt


def test_the_summary_and_the_plain_data_name_the_class(pd_runs) -> None:
    _, mine, _ = pd_runs
    name = f"{__name__}:PlainPD"
    assert mine.summary()["controller"] == name
    assert mine.config.to_dict()["controller"] == name
    assert mine.config.controller is pd_runs[2]  # the object itself stays in the config
    builtin = {k: v for k, v in pd_runs[0].summary().items() if k not in ("controller",)}
    same = {k: v for k, v in mine.summary().items() if k not in ("controller",)}
    for key in ("rms_tracking_error_rad", "peak_motor_current_A", "peak_cuff_force_N"):
        assert same[key] == pytest.approx(builtin[key], abs=1e-9)


def test_a_recording_names_the_class_and_reads_without_it(tmp_path: Path) -> None:
    def local() -> Controller:  # a class no import path reaches
        class Local(PlainPD):
            pass

        return Local()

    path = tmp_path / "mine.rrd"
    simulate(SimConfig(controller=local(), duration_s=0.05), observers=[RerunRecorder(path)])
    back = read_recording(path)
    name = f"{__name__}:test_a_recording_names_the_class_and_reads_without_it.<locals>.local"
    assert back.config.controller == back.summary()["controller"] == f"{name}.<locals>.Local"


def test_the_same_object_is_set_up_again_for_each_run() -> None:
    user = PlainPD()
    config = SimConfig(controller=user, duration_s=0.05)
    simulate(config)
    simulate(config)
    assert user.setups == 2


def test_an_impedance_controller_stays_within_the_drives_limits() -> None:
    impedance = _example("impedance")
    # stiff enough to ask for more than the driver gives (its current is held at the limit)
    config = SimConfig(controller=impedance.Impedance(2000.0, 60.0), duration_s=2.4)
    setup = build(config)
    assert type(setup.controller).__name__ == "PluginController"
    limit_A = setup.plant.motor_params.current_limit_A
    supply_V = setup.plant.motor_params.supply_voltage_V
    result = simulate(config)
    assert result.status == "completed"
    current = np.abs(result.signals["current"])
    assert current.max() <= limit_A + 1e-9  # [A]: never above the driver's limit
    assert current.max() >= 0.99 * limit_A  # and the test reaches it
    assert np.abs(result.signals["voltage"]).max() <= supply_V + 1e-9  # [V]
    assert np.abs(result.signals["voltage_cmd"]).max() <= supply_V + 1e-9  # the loop clips
    rms = result.summary()["rms_tracking_error_rad"]
    assert max(rms.values()) < 0.05  # it walks the gait


def test_the_supervisor_stops_a_user_controller_as_it_stops_the_built_in() -> None:
    limits = SafetyLimits(position_upper_rad=(0.7, 1.5, 0.7, 1.5))  # the hips pass 0.7 rad
    builtin = simulate(SimConfig(safety_limits=limits, duration_s=1.2))
    mine = simulate(SimConfig(safety_limits=limits, duration_s=1.2, controller=PlainPD()))
    assert builtin.safety_state != "normal"
    assert mine.events == builtin.events  # the same event at the same tick
    state = builtin.signals["safety_state"]
    np.testing.assert_array_equal(mine.signals["safety_state"], state)
    np.testing.assert_array_equal(mine.signals["voltage"], builtin.signals["voltage"])


def test_full_voltage_into_a_joint_limit_is_stopped() -> None:
    # the cuff-force limit out of the way (full voltage drags the patient: it trips first)
    limits = SafetyLimits(cuff_force_N=1e4)
    result = simulate(SimConfig(controller=FullVoltage(), duration_s=1.0, safety_limits=limits))
    assert result.safety_state != "normal"
    first = result.events[0]
    k = int(np.flatnonzero(result.signals["safety_state"])[0])  # the first stopped tick
    assert first["t"] == pytest.approx(k * SimConfig().dt)
    assert first["quantity"] == "angle left_knee"  # into its upper range-of-motion limit
    assert first["value"] > first["limit"]
    assert np.all(result.signals["voltage_cmd"] == 24.0)  # what the controller asked, logged
    assert np.all(result.signals["voltage"][:k] == 24.0)  # applied until the stop
    assert np.all(np.abs(result.signals["voltage"][k:]) < 24.0)  # from it, the stop's ramp


def test_the_current_loop_settles_on_its_reference_and_does_not_wind_up() -> None:
    """The PI of exo_ctrl/control/current_loop.py on the plant's exact drive step."""
    dt = 1e-3  # [s]
    motor = MotorParams()
    loop = CurrentLoop(motor, dt)
    assert loop.omega_c_rad_s == pytest.approx(0.5 / dt)  # capped at the tick
    assert loop.kp_V_per_A == pytest.approx(motor.inductance_H * 500.0)
    assert loop.ki_V_per_A_s == pytest.approx(motor.resistance_ohm * 500.0)
    # a winding 20 % off the datasheet: the integral removes the error
    true = MotorParams(resistance_ohm=motor.resistance_ohm * 1.2)
    bank = MotorBank(4, true)
    omega = np.array([0.0, 1.0, -1.0, 0.5])  # [rad/s]
    torque = np.array([20.0, -30.0, 50.0, 0.0])  # [N·m]
    for _ in range(200):
        u = loop.voltages(torque, omega, bank.mean_current_A.copy())
        bank.step(u, omega, dt)
    np.testing.assert_allclose(bank.mean_current_A, loop.current_ref_A, atol=1e-6)
    # an unreachable current (back-EMF at full speed): the voltage holds the supply,
    # and the integral does not wind up while it does
    loop.reset()
    fast = np.full(4, 6.0)  # [rad/s]: 27.8 V of back-EMF
    for _ in range(500):
        u = loop.voltages(np.full(4, 100.0), fast, bank.mean_current_A.copy())
        bank.step(u, fast, dt)
    assert np.all(u == motor.supply_voltage_V)
    slow = np.zeros(4)
    for _ in range(10):  # the reference drops to 0 A: the current follows within ticks
        u = loop.voltages(np.zeros(4), slow, bank.mean_current_A.copy())
        bank.step(u, slow, dt)
    assert np.abs(bank.mean_current_A).max() < 0.05 * motor.current_limit_A
    assert math.isfinite(float(u.sum()))


def test_the_driver_limits_a_torque_command_to_its_current() -> None:
    motor = drive_for(MotorParams(), build(SimConfig(duration_s=0.01)).exo)
    loop = CurrentLoop(motor, 1e-3)
    loop.voltages(np.array([1e4, -1e4, 0.0, 1.0]), np.zeros(4), np.zeros(4))
    limit = motor.current_limit_A
    assert loop.current_ref_A[:2].tolist() == [limit, -limit]
    assert loop.current_ref_A[3] == pytest.approx(1.0 / motor.torque_per_amp_Nm_per_A)
