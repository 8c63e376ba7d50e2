"""The QP's departure stop (exo_ctrl/safety/departure.py), the supervisor's stop on request, and
the yield of a patient who stands on the belt at a stop.

With the pelvis supported a QP that leaves its plan to hold its cuff bound
lets a leg strike the belt; the device stops the walk (yield) where a leg
leaves its plan by more than the swing foot's lift over the leg's length.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import JOINT_NAMES
from exo_ctrl.plant import ContactParams, PelvisParams
from exo_ctrl.safety import SafetyLimits, SafetySupervisor
from exo_ctrl.safety.departure import DepartureMonitor, departure_limit_rad, harness_arrest_s
from exo_ctrl.sensing import SensorParams, SensorReadings
from exo_ctrl.sim import Runner, SimConfig, build, simulate, start_on_plan
from exo_ctrl.sim.supervision import departure_for


def test_the_limit_is_the_swing_foots_lift_over_the_legs_length() -> None:
    assert departure_limit_rad(0.10, 1.04) == 0.10 / 1.04
    with pytest.raises(InvalidParameter, match=r"lift_height must be > 0 m; got 0"):
        departure_limit_rad(0.0, 1.0)
    with pytest.raises(InvalidParameter, match=r"leg length must be > 0 m; got -1"):
        departure_limit_rad(0.1, -1.0)


def test_the_monitor_names_the_joint_furthest_from_its_plan() -> None:
    monitor = DepartureMonitor(0.1)
    plan, speed = np.array([0.3, 0.6, 0.2, 0.5]), np.array([1.0, -2.0, 0.5, 0.0])
    assert monitor.check(0.5, plan + 0.0999, speed + 5.0, plan, speed) is None  # within δ
    q = plan + np.array([0.05, -0.12, 0.11, 0.0])
    cause = monitor.check(0.5, q, speed + 5.0, plan, speed)  # no look-ahead: speeds unread
    assert cause is not None
    assert cause["quantity"] == "departure_left_knee"
    assert cause["value"] == pytest.approx(0.12)
    assert cause["limit"] == 0.1
    assert cause["message"] == (
        "the left_knee left the plan by 0.120 rad at t = 0.5000 s (limit 0.100 rad, the swing "
        "foot's lift over the leg's length): the QP holds its cuff bound by leaving the plan, "
        "and on the belt a leg off its plan can strike it"
    )
    q[0] = math.nan  # a non-finite reading is the supervisor's own violation, not a departure
    q[1] = plan[1]
    q[2] = plan[2]
    assert monitor.check(0.5, q, speed, plan, speed) is None
    with pytest.raises(InvalidParameter, match=r"departure limit must be > 0 rad; got 0"):
        DepartureMonitor(0.0)
    with pytest.raises(InvalidParameter, match=r"departure look-ahead must be >= 0 s; got -0.01"):
        DepartureMonitor(0.1, -0.01)


def test_the_look_ahead_stops_a_departure_before_it_reaches_the_limit() -> None:
    """d = max(|e|, knees' e + T ė): a knee 0.06 rad beyond its plan folding 2 rad/s faster
    is 0.12 rad off 30 ms on; a joint coming back is judged by where it is."""
    monitor = DepartureMonitor(0.1, 0.03)
    plan, speed = np.array([0.3, 0.6, 0.2, 0.5]), np.array([1.0, -2.0, 0.5, 0.0])
    q = plan + np.array([0.0, 0.06, 0.0, 0.0])
    assert monitor.check(1.0, q, speed, plan, speed) is None  # on its plan's speed
    dq = speed + np.array([0.0, 2.0, 0.0, 0.0])
    cause = monitor.check(1.0, q, dq, plan, speed)
    assert cause["quantity"] == "departure_left_knee"
    assert cause["value"] == pytest.approx(0.06 + 0.03 * 2.0)
    assert cause["message"] == (
        "the left_knee left the plan by 0.060 rad at t = 1.0000 s, 0.120 rad within the "
        "harness's arrest (30 ms) (limit 0.100 rad, the swing foot's lift over the leg's "
        "length): the QP holds its cuff bound by leaving the plan, and on the belt a leg off "
        "its plan can strike it"
    )
    back = plan + np.array([0.0, 0.11, 0.0, 0.0])
    returning = speed + np.array([0.0, -3.0, 0.0, 0.0])  # heading back to the plan
    assert monitor.check(1.0, back, returning, plan, speed)["value"] == pytest.approx(0.11)
    dq[1] = math.nan  # no speed reading: the present departure alone
    assert monitor.check(1.0, q, dq, plan, speed) is None
    # Only a knee folding beyond its plan drops the hip: a knee held short of its plan
    # (a reflex against flexion) or a hip, however fast they go, is judged where it is.
    short = plan + np.array([0.0, 0.0, 0.0, -0.06])
    assert monitor.check(1.0, short, speed + np.array([0, 0, 0, -2.0]), plan, speed) is None
    hip = plan + np.array([0.06, 0.0, 0.0, 0.0])
    assert monitor.check(1.0, hip, speed + np.array([2.0, 0, 0, 0]), plan, speed) is None
    folding = plan + np.array([0.0, 0.0, 0.0, 0.06])
    cause = monitor.check(1.0, folding, speed + np.array([0, 0, 0, 2.0]), plan, speed)
    assert cause["quantity"] == "departure_right_knee"


@pytest.mark.parametrize(
    ("stiffness", "damping", "mass"),
    [(1e5, 2e3, 67.0), (1e5, 2e3, 127.0), (1e5, 0.0, 80.0), (1e4, 2e3, 100.0), (1e4, 3e3, 80.0)],
)
def test_the_harness_arrests_the_pelvis_when_its_speed_first_vanishes(
    stiffness: float, damping: float, mass: float
) -> None:
    """T against an independent integration of M z̈ = −K z − C ż from z = 0, ż = −1 m/s
    (RK4, 1 µs): the first step whose speed is no longer downward; under-, critically
    (1e4 N/m, 2e3 N·s/m, 100 kg) and over-damped (the pelvis then creeps back up)."""
    h, z, w, t = 1e-6, 0.0, -1.0, 0.0

    def acc(z: float, w: float) -> float:
        return (-stiffness * z - damping * w) / mass

    while w < 0.0:
        k1z, k1w = w, acc(z, w)
        k2z, k2w = w + 0.5 * h * k1w, acc(z + 0.5 * h * k1z, w + 0.5 * h * k1w)
        k3z, k3w = w + 0.5 * h * k2w, acc(z + 0.5 * h * k2z, w + 0.5 * h * k2w)
        k4z, k4w = w + h * k3w, acc(z + h * k3z, w + h * k3w)
        z += h * (k1z + 2 * k2z + 2 * k3z + k4z) / 6
        w += h * (k1w + 2 * k2w + 2 * k3w + k4w) / 6
        t += h
    assert harness_arrest_s(stiffness, damping, mass) == pytest.approx(t, abs=2e-6)


def test_the_stop_is_the_qps_with_the_feet_over_the_belt_and_its_bound_tightened(
    supported_qp: SimConfig,
) -> None:
    supported = supported_qp
    setup = build(supported)
    exo = setup.device_exo
    monitor = departure_for(supported, exo)
    assert monitor is not None
    legs = [exo.legs[side] for side in ("left", "right")]
    leg = min(g.thigh_length + g.shank_length for g in legs)
    assert monitor.limit_rad == pytest.approx(supported.gait.lift_height / leg, rel=1e-12)
    pelvis = supported.pelvis  # the look-ahead: the harness's arrest of the guide's mass
    mass = pelvis.body_mass + sum(i.mass for i in exo.model.inertias)  # links and pelvis link
    arrest = harness_arrest_s(pelvis.stop_stiffness_N_per_m, pelvis.stop_damping_N_s_per_m, mass)
    assert monitor.lookahead_s == pytest.approx(arrest, rel=1e-12)
    assert 0.03 < monitor.lookahead_s < 0.05
    fixed = dataclasses.replace(supported, pelvis=PelvisParams())
    assert departure_for(fixed, exo).lookahead_s == 0.0  # the feet skim the belt; nothing falls
    free_air = dataclasses.replace(fixed, contact=dataclasses.replace(fixed.contact, enabled=False))
    assert departure_for(free_air, exo) is None  # the legs swing in the air
    assert departure_for(dataclasses.replace(supported, controller="ct"), exo) is None
    loose = dataclasses.replace(supported, qp_tighten_bound=False)
    assert departure_for(loose, exo) is None
    guided = dataclasses.replace(supported, mode="transparent")  # the plan is not the target
    assert departure_for(guided, exo) is None


def supervisor_on_default_run() -> tuple[SafetySupervisor, SensorReadings, object]:
    config = SimConfig(controller="ct")
    setup = build(config)
    start_on_plan(setup)
    plant = setup.plant
    sup = SafetySupervisor(
        SafetyLimits(),
        setup.exo,
        setup.patient,
        plant.motor_params,
        config.dt,
        sensors=SensorParams.ideal(),
    )
    sensors = SensorReadings(q=plant.q[:4].copy(), dq=plant.v[:4].copy(), tau=np.zeros(4))
    np.copyto(sensors.tau, plant.sensor_torque)
    return sup, sensors, plant


def test_a_requested_stop_starts_at_its_tick_with_its_cause_and_reaction() -> None:
    sup, sensors, plant = supervisor_on_default_run()
    u_cmd = np.full(4, 0.5)
    force, current = plant.cuff_force, plant.motors.mean_current_A
    out = sup.step(0, 0.0, sensors, force, current, u_cmd)
    assert out is u_cmd and sup.state == "normal"
    cause = {"quantity": "departure_right_hip", "value": 0.2, "limit": 0.1, "message": "off"}
    sup.request_stop(0.001, cause, "yield")
    assert not sup.normal_at(0.001)
    out = sup.step(1, 0.001, sensors, force, current, u_cmd)
    assert sup.state == "stopping" and sup.reaction == "yield"
    assert sup.stop_time_s == 0.001
    violation, state = sup.events
    assert violation == {"t": 0.001, "kind": "violation", **cause}
    assert state["value"] == "stopping"
    assert state["message"] == "safety state normal -> stopping: controlled stop (yield): off"
    np.testing.assert_array_equal(sup.hold_posture_rad, sensors.q)
    sup.request_stop(0.002, {**cause, "message": "again"}, "hold")  # once stopped: ignored
    sup.step(2, 0.002, sensors, force, current, u_cmd)
    assert len(sup.events) == 2 and sup.reaction == "yield"
    with pytest.raises(InvalidParameter, match="stop_reaction must be one of"):
        supervisor_on_default_run()[0].request_stop(0.0, cause, "brake")


def test_joint_names_are_the_causes_quantities() -> None:
    monitor = DepartureMonitor(0.05)
    for j, name in enumerate(JOINT_NAMES):
        q = np.zeros(4)
        q[j] = -0.06
        cause = monitor.check(0.0, q, np.zeros(4), np.zeros(4), np.zeros(4))
        assert cause["quantity"] == f"departure_{name}"


def test_at_a_stop_the_standing_patient_is_not_lifted_by_the_yield() -> None:
    """Pelvis supported, the patient's feet on the belt: the yield carries the exoskeleton alone."""
    config = SimConfig(
        controller="ct",
        contact=ContactParams(enabled=True, patient_feet=True),
        pelvis=PelvisParams(supported=True, bws_fraction=0.4),
    )
    q = np.array([0.3, 0.5, 0.1, 0.2])

    def gravity(body) -> np.ndarray:
        model = body.model
        data = model.createData()
        qm = np.zeros(model.nq)
        qm[body.q_index] = q
        return pin.computeGeneralizedGravity(model, data, qm)[body.q_index]

    standing = Runner(build(config))
    exo = gravity(standing.setup.device_exo)
    patient = gravity(standing.setup.device_patient)
    assert np.abs(patient).max() > 5.0  # the patient's legs weigh on the joints
    np.testing.assert_allclose(standing.supervisor.yield_command.gravity(q), exo, rtol=1e-12)
    hanging = Runner(build(dataclasses.replace(config, contact=ContactParams(enabled=True))))
    both = hanging.supervisor.yield_command.gravity(q)
    np.testing.assert_allclose(both, exo + patient, rtol=1e-12)


def test_with_safety_off_the_supervisor_serves_stops_only_with_the_limits_reactions() -> None:
    """``--no-safety`` with an e-stop: no monitor trips, and the yield is the limits' (11 ms)."""
    on = SimConfig(controller="ct", stop_reaction="yield", duration_s=1.2)
    off = dataclasses.replace(on, safety=False, estop_at_s=0.8)
    full, stops = Runner(build(on)).supervisor, Runner(build(off)).supervisor
    np.testing.assert_array_equal(stops.yield_command.damping, full.yield_command.damping)
    assert stops.yield_command.ramp_s == full.yield_command.ramp_s < 0.02
    assert not stops.checks and full.checks  # the plausibility monitors: off
    big = np.finfo(float).max
    assert (stops.record["limit"][0] == big).all()  # no monitor trips
    result = simulate(dataclasses.replace(off, safety_limits=SafetyLimits(cuff_force_N=1.0)))
    assert [e["kind"] for e in result.events][:1] == ["estop"]
    assert result.events[0]["t"] == pytest.approx(0.8)
