"""The stop reactions: yield's command, its ramp, its end, the default per mode, the campaign.

The yield command is checked against an independent computation (gravity
by Pinocchio's RNEA at zero speed and acceleration, the filter and the
drive model written out); the ramp by the applied voltage's per-tick steps
in a closed loop; the benefit by the true cuff forces after a stop of an
active patient in transparent mode, hold against yield.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl import SimConfig, simulate
from exo_ctrl.cli import main as cli_main
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plant import CuffParams
from exo_ctrl.plant.drive import EFFICIENCY_SMOOTHING_RAD_S
from exo_ctrl.safety import (
    ISO_TS_15066_CUFF_FORCE_N,
    SafetyLimits,
    SafetySupervisor,
    resolve_limits,
    stop_reaction_schedule,
    yield_damping,
)
from exo_ctrl.safety.stop_reaction import SPEED_FILTER_HZ, YIELD_FORCE_SHARE, YieldCommand
from exo_ctrl.sensing import SensorParams, SensorReadings
from exo_ctrl.sim import build, start_on_plan
from exo_ctrl.sim.faults import Fault

DT = 1e-3
THIGH, SHANK = ISO_TS_15066_CUFF_FORCE_N[0], ISO_TS_15066_CUFF_FORCE_N[1]


def _rnea_gravity(body, q: np.ndarray) -> np.ndarray:
    model = body.model
    data = model.createData()
    qm = body.to_model_q(q)
    zero = np.zeros(model.nv)
    return pin.rnea(model, data, qm, zero, zero)[body.q_index]


def test_yield_command_is_gravity_compensation_minus_damping(device) -> None:
    exo, patient, motor = device
    d = np.array([7.0, 5.0, 6.0, 4.0])
    limit = np.full(4, 6.0)
    cmd = YieldCommand(exo, patient, motor, d, limit, DT)
    q0 = np.array([0.3, 0.9, -0.1, 0.6])
    dq0 = np.array([1.0, -2.0, 0.5, 3.0])
    q1 = q0 + np.array([1.2e-3, -1.5e-3, 0.4e-3, 2.5e-3])
    cmd.start(q0, dq0)
    u = cmd.command(q1, np.zeros(4))
    # Independent: the filter, RNEA gravity of both bodies, the drive model.
    a = 1.0 - math.exp(-2.0 * math.pi * SPEED_FILTER_HZ * DT)
    w = dq0 + a * ((q1 - q0) / DT - dq0)
    tau = _rnea_gravity(exo, q1) + _rnea_gravity(patient, q1) - d * w
    s = np.sign(tau) * np.tanh(w / EFFICIENCY_SMOOTHING_RAD_S)
    eta_s = motor.gear_efficiency**s
    kt, kb = motor.torque_per_amp_Nm_per_A, motor.back_emf_V_per_rad_s
    expected = motor.resistance_ohm * tau / (kt * eta_s) + kb * w
    np.testing.assert_allclose(cmd.speed, w, rtol=1e-12)
    np.testing.assert_allclose(u, expected, rtol=1e-10, atol=1e-12)
    # The joint torque the drive gives at the estimated speed: η^s k_t (U - k_b ω)/R = τ_y.
    np.testing.assert_allclose(eta_s * kt * (u - kb * w) / motor.resistance_ohm, tau, rtol=1e-10)


def test_yield_damping_from_the_cuff_budget(device) -> None:
    exo, patient, motor = device
    resolved = resolve_limits(SafetyLimits(), exo, patient, motor)
    data = exo.model.createData()
    pin.framesForwardKinematics(exo.model, data, pin.neutral(exo.model))
    hip, knee = data.oMi[exo.joint_ids[0]].translation, data.oMi[exo.joint_ids[1]].translation
    a = np.linalg.norm(data.oMf[exo.cuff_frame_ids[0]].translation - hip)
    c = np.linalg.norm(data.oMf[exo.cuff_frame_ids[1]].translation - knee)
    d = yield_damping(resolved, exo)
    w = resolved.speed_limit
    np.testing.assert_allclose(d[:2], YIELD_FORCE_SHARE * np.array([THIGH * a, SHANK * c]) / w[:2])
    # The damping force at the speed limit is half the cuff's limit.
    np.testing.assert_allclose(d[1] * w[1] / c, 0.5 * SHANK)
    print(f"\nd_y = {d.round(3)} N·m·s/rad (a = {a:.3f} m, c = {c:.3f} m, ω_max = {w[0]:g})")


def _loop(reaction: str, ramp_s: float, duration_s: float = 1.6, estop_s: float = 0.5):
    """Closed loop (CT, passive patient, ideal sensors, the device's models = the truth)."""
    config = SimConfig(controller="ct", duration_s=duration_s, cuffs=CuffParams.isotropic())
    setup = build(config)
    plant, ctrl = setup.plant, setup.controller
    start_on_plan(setup)
    sup = SafetySupervisor(
        SafetyLimits(),
        setup.exo,
        setup.patient,
        plant.motor_params,
        DT,
        estop_at_s=estop_s,
        sensors=SensorParams.ideal(),
        ramp_s=ramp_s,
        stop_reaction=reaction,
    )
    sensors = SensorReadings(q=np.zeros(4), dq=np.zeros(4), tau=np.zeros(4))
    n = config.n_ticks
    u_log, q_log = np.zeros((n, 4)), np.zeros((n, 4))
    for k in range(n):
        np.copyto(sensors.q, plant.q[:4])
        np.copyto(sensors.dq, plant.v[:4])
        np.copyto(sensors.tau, plant.sensor_torque)
        u_cmd = ctrl.command(k, sensors)
        u = sup.step(k, k * DT, sensors, plant.cuff_force, plant.motors.mean_current_A, u_cmd)
        u_log[k], q_log[k] = u, plant.q[:4]
        plant.step(u)
    return sup, u_log, q_log


def test_yield_is_bumpless_and_a_passive_leg_comes_to_rest_and_is_held() -> None:
    sup, u, q = _loop("yield", 0.2, duration_s=3.5)
    steps = np.abs(np.diff(u, axis=0))
    k = 500
    normal = steps[k - 300 : k - 1].max()  # the controller's own largest step before the stop
    ramp = steps[k - 1 : k + 200].max()
    _, u0, _ = _loop("yield", 0.0, duration_s=0.6)
    jump = np.abs(u0[k] - u0[k - 1]).max()
    print(f"\nper-tick step: normal {normal:.3f} V, yield ramp {ramp:.3f} V, no ramp {jump:.3f} V")
    assert ramp <= max(normal, 0.1)
    assert jump > 2.0 * max(normal, 0.1)  # the ramp is what removes the step
    got = [e["value"] for e in sup.events if e["kind"] == "state"]
    assert got == ["stopping", "yielding", "stopping", "holding"]  # at rest: the hold
    rest = next(e for e in sup.events if "legs at rest" in e["message"])
    k_rest = round(rest["t"] / DT)
    # Held from then on: within the hold's tolerance of the posture at rest.
    assert np.abs(q[k_rest:] - sup.hold_posture_rad).max() < sup.hold_tolerance_rad


def test_tracking_keeps_the_hold() -> None:
    assert stop_reaction_schedule(None, "tracking", 1.0) == ((0.0, "hold"),)
    assert stop_reaction_schedule(None, "guidance", 1.0) == ((0.0, "hold"),)
    for mode in ("transparent", "path", "aan"):
        assert stop_reaction_schedule(None, mode, 1.0) == ((0.0, "yield"),)
    assert stop_reaction_schedule(None, "guidance", 0.5) == ((0.0, "yield"),)
    assert stop_reaction_schedule("hold", "transparent", 1.0) == ((0.0, "hold"),)
    by_mode = simulate(SimConfig(duration_s=1.0, estop_at_s=0.5))
    hold = simulate(SimConfig(duration_s=1.0, estop_at_s=0.5, stop_reaction="hold"))
    np.testing.assert_array_equal(by_mode.signals["voltage"], hold.signals["voltage"])
    assert by_mode.safety_state == "holding"


def _after_stop(reaction: str) -> tuple[float, float, str]:
    """Worst true thigh and shank cuff forces from the stop on (active patient, transparent)."""
    overrun = Fault("control_overrun", 2.125, "", 0.005, 0.02, seed=0)  # 5 ms late commands
    config = SimConfig(
        mode="transparent", patient_torque="active", faults=(overrun,), stop_reaction=reaction
    )
    result = simulate(config)
    s = result.signals
    k = int(np.flatnonzero(s["safety_state"] != 0)[0])
    force = np.linalg.norm(s["cuff_force"][k:], axis=-1)
    return float(force[:, 0::2].max()), float(force[:, 1::2].max()), result.safety_state


def test_yield_halves_an_active_patients_forces_against_the_hold() -> None:
    """Transparent, an active patient, commands 5 ms late from 2.125 s: the stop.

    Held, the walking patient loads the cuffs to 167/90 N (thigh/shank); the
    yield lets the limb go on and keeps them at 80/55 N.
    """
    hold, yld = _after_stop("hold"), _after_stop("yield")
    print(f"\nafter the stop, thigh/shank [N]: hold {hold[:2]}, yield {yld[:2]}")
    assert yld[0] < 0.6 * hold[0] and yld[1] < 0.7 * hold[1]
    assert yld[0] < THIGH and yld[1] < SHANK
    assert yld[2] == "yielding"  # an active patient keeps walking: no rest, no cut


def test_bad_stop_reaction_is_refused() -> None:
    with pytest.raises(InvalidParameter) as e:
        SimConfig(stop_reaction="brake")
    assert str(e.value) == "stop_reaction must be one of hold, yield; got 'brake'"


def test_cli_refuses_a_bad_stop_reaction(capsys) -> None:
    with pytest.raises(SystemExit) as e:
        cli_main(["simulate", "--stop-reaction", "brake", "--no-record", "--duration", "0.1"])
    err = capsys.readouterr().err.strip().splitlines()
    assert e.value.code == 2
    assert err[-1] == (
        "exo-ctrl simulate: error: argument --stop-reaction: invalid choice: 'brake' "
        "(choose from 'hold', 'yield')"
    )
