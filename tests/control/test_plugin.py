"""A user's controller on the public interface meets the same device as the built-in ones.

Real models and runs, no mocks: a plain-Python PD written on
:class:`exo_ctrl.control.Controller` reproduces the built-in compiled PD;
a torque-commanding impedance controller (examples/impedance.py) stays
within the driver's current and the supply's voltage; a controller that
runs a joint into its limit is stopped by the supervisor as a built-in one
is; the drivers follow a torque controller's current references through
their current loop inside the plant's step (exo_ctrl/plant/current_mode.py),
tick by tick as the closed form says, and the supervisor's drive model reads
the voltage they apply.
"""

from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl import SimConfig, read_recording, simulate
from exo_ctrl.control import Controller, PDGains
from exo_ctrl.control.current_loop import current_reference, reference_params
from exo_ctrl.plant import CURRENT_LOOP_BANDWIDTH_HZ, MotorParams
from exo_ctrl.plant.drive import EFFICIENCY_SMOOTHING_RAD_S
from exo_ctrl.record import RerunRecorder
from exo_ctrl.safety import SafetyLimits
from exo_ctrl.sim import drive_for
from exo_ctrl.sim.setup import build
from exo_ctrl.sim.supervision import ReportingDrives
from exo_ctrl.sim.tick import Runner

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
    assert np.abs(result.signals["voltage_cmd"]).max() <= supply_V + 1e-9  # U_ff is clipped
    summary = result.summary()
    assert max(summary["rms_tracking_error_rad"].values()) < 0.05  # it walks the gait
    assert summary["energy_balance_residual_rel"] <= 1e-12  # the books balance
    assert summary["safety_state"] == "normal"  # the drive model agrees with the drivers


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


def test_the_drives_follow_the_current_references_tick_by_tick() -> None:
    """Each tick's mean current against the lag's closed form from the tick's start."""
    impedance = _example("impedance")
    setup = build(SimConfig(controller=impedance.Impedance(), duration_s=0.3))
    runner = Runner(setup)
    assert isinstance(runner.supervisor, ReportingDrives)
    bank, ref = setup.plant.motors, setup.controller.record["current_ref"][0]
    x = 2.0 * math.pi * CURRENT_LOOP_BANDWIDTH_HZ * setup.config.dt
    phi, eps = -math.expm1(-x) / x, math.exp(-x)
    worst = moved = 0.0
    low, high = np.full(4, np.inf), np.full(4, -np.inf)
    for k in range(runner.chunk):
        start = bank.current_A.copy()
        runner.tick(k, k)
        mean = ref + (start - ref) * phi
        worst = max(worst, np.abs(bank.mean_current_A - mean).max())
        assert np.abs(bank.current_A - (ref + (start - ref) * eps)).max() <= 1e-9
        moved = max(moved, np.abs(ref - start).max())
        low, high = np.minimum(low, ref), np.maximum(high, ref)
    assert worst <= 1e-9  # [A]
    assert moved > 0.1 and np.all(high - low > 0.5)  # [A]: the references do move
    # the log's voltage is the drivers' applied one, not the command
    volts = runner.log["voltage"]
    assert np.abs(volts - runner.log["voltage_cmd"]).max() > 0.1  # [V]


def test_the_driver_limits_a_torque_command_to_its_current() -> None:
    motor = drive_for(MotorParams(), build(SimConfig(duration_s=0.01)).exo)
    ref, u, u_ff = np.zeros(4), np.zeros(4), np.zeros(4)
    omega = np.array([0.0, 0.0, 0.0, 2.0])  # [rad/s]
    torque = np.array([1e4, -1e4, 0.0, 1.0])  # [N·m]
    current_reference(reference_params(motor), torque, omega, ref, u, u_ff)
    limit = motor.current_limit_A
    assert ref[:2].tolist() == [limit, -limit]
    assert ref[2] == 0.0
    gear = motor.gear_efficiency ** math.tanh(2.0 / EFFICIENCY_SMOOTHING_RAD_S)  # η^s, motoring
    assert ref[3] == pytest.approx(1.0 / (motor.torque_per_amp_Nm_per_A * gear), rel=1e-12)
    steady = motor.resistance_ohm * ref + motor.back_emf_V_per_rad_s * omega
    np.testing.assert_allclose(u, np.clip(steady, -24.0, 24.0), rtol=1e-12)
    np.testing.assert_array_equal(u, u_ff)  # the command selects the drivers' current mode
