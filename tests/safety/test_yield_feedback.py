"""The yield's force feedback after the QP's departure stop (exo_ctrl/safety/yield_command.py).

The interaction torque against Pinocchio's frame Jacobians of the cuffs; the
gain against the joint's inertia from the kinetic energy of that joint
alone moving (not the mass matrix the code reads); the supervisor feeding
back on a departure stop only, and not once a plausibility monitor doubts a
reading.  The closed loop, point 65 of the load-held campaign, is in
tests/control/qp/test_load_held.py.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl import simulate
from exo_ctrl.estimation.cuff_geometry import CuffGeometry
from exo_ctrl.model import JOINT_NAMES
from exo_ctrl.safety import SafetyLimits, SafetySupervisor
from exo_ctrl.safety.monitor import LIMIT_GROUPS
from exo_ctrl.safety.yield_command import (
    MAX_FORCE_GAIN,
    PATIENT_ACCELERATION_RAD_S2,
    YIELD_FORCE_SHARE,
    YieldCommand,
)
from exo_ctrl.scenario import preset
from exo_ctrl.sensing import SensorParams, SensorReadings

DT = 1e-3
Q = np.array([0.35, 0.8, -0.2, 0.3])


def _jacobian_torque(exo, q: np.ndarray, force: np.ndarray) -> np.ndarray:
    """Σ_c J_cᵀ f_c with the cuff frames' world-aligned linear Jacobians (x, z rows)."""
    model, data = exo.model, exo.model.createData()
    qm = exo.to_model_q(q)
    pin.computeJointJacobians(model, data, qm)
    pin.updateFramePlacements(model, data)
    tau = np.zeros(model.nv)
    for c, frame in enumerate(exo.cuff_frame_ids):
        jac = pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)
        tau += jac[[0, 2]].T @ force[c]
    return tau[exo.q_index]


def _joint_inertia(exo, q: np.ndarray, j: int) -> float:
    """I_j = 2 T / ω² with joint j alone turning at ω (Pinocchio's kinetic energy)."""
    model, data = exo.model, exo.model.createData()
    v = np.zeros(model.nv)
    v[exo.q_index[j]] = 2.0
    return 2.0 * pin.computeKineticEnergy(model, data, exo.to_model_q(q), v) / 4.0


def test_interaction_torque_is_the_cuffs_jacobian_transpose(device) -> None:
    exo = device[0]
    geo = CuffGeometry.from_body(exo)
    rng = np.random.default_rng(4)
    for _ in range(5):
        q, force = rng.uniform(-1.0, 1.2, 4), rng.normal(0.0, 60.0, (4, 2))
        np.testing.assert_allclose(
            geo.joint_torques(q, force), _jacobian_torque(exo, q, force), rtol=1e-12, atol=1e-10
        )


def test_the_gain_keeps_the_inertias_force_within_the_dampings_share(device) -> None:
    """K_j from I_j q̈_p / (r_j (1 − σ) F_j) − 1, clipped to [0, K_max]."""
    exo, patient, motor = device
    cmd = YieldCommand(exo, patient, motor, np.full(4, 5.0), np.full(4, 6.0), DT)
    arms = CuffGeometry.from_body(exo).joint_arms()
    seen = set()
    for bound in (10.0, 130.0, 400.0, 5000.0):
        limit = np.array([bound, 0.8 * bound, bound, 0.8 * bound])
        gain = cmd.gains(Q, limit)
        for j, name in enumerate(JOINT_NAMES):
            inertia = _joint_inertia(exo, Q, j) + motor.reflected_inertia_kgm2
            force = inertia * PATIENT_ACCELERATION_RAD_S2 / arms[j]  # no feedback [N]
            share = (1.0 - YIELD_FORCE_SHARE) * limit[j]
            if gain[j] == 0.0:
                assert force <= share * (1.0 + 1e-9), name
                seen.add("none")
            elif gain[j] == MAX_FORCE_GAIN:
                assert force / (1.0 + MAX_FORCE_GAIN) >= share * (1.0 - 1e-9), name
                seen.add("most")
            else:  # the felt inertia's force exactly the share
                assert force / (1.0 + gain[j]) == pytest.approx(share, rel=1e-9), name
                seen.add("between")
    assert seen == {"none", "most", "between"}


def _supervisor(device, estop: float | None = None) -> SafetySupervisor:
    exo, patient, motor = device
    return SafetySupervisor(
        SafetyLimits(),
        exo,
        patient,
        motor,
        DT,
        estop_at_s=estop,
        sensors=SensorParams.ideal(),
        plausibility_checks=False,
        stop_reaction="yield",
    )


def _stop(sup: SafetySupervisor, force: np.ndarray, request: np.ndarray | None) -> np.ndarray:
    """Two ticks at rest at Q: the stop on the first (asked for with ``request``); τ_y."""
    sensors = SensorReadings(q=Q.copy(), dq=np.zeros(4), tau=np.zeros(4))
    if request is not None:
        cause = {"quantity": "departure_left_knee", "value": 0.1, "limit": 0.09, "message": "off"}
        sup.request_stop(0.0, cause, "yield", request)
    for k in range(2):
        sup.step(k, k * DT, sensors, force, np.zeros(4), np.zeros(4))
    return sup.yield_command.torque.copy()


def test_only_the_departure_stop_feeds_the_cuff_forces_back(device) -> None:
    exo = device[0]
    force = np.array([[30.0, -10.0], [-20.0, 15.0], [45.0, 5.0], [10.0, -25.0]])
    bounds = np.full(4, 120.0)
    plain = _stop(_supervisor(device, estop=0.0), force, None)  # an e-stop: no feedback
    departure = _supervisor(device)
    fed = _stop(departure, force, bounds)
    gain = departure.yield_command.gains(Q, bounds)
    assert np.all(gain > 0.0)
    np.testing.assert_allclose(fed - plain, gain * _jacobian_torque(exo, Q, force), rtol=1e-9)
    # A plausibility monitor doubts a reading: the feedback ends for the rest of the stop.
    sensors = SensorReadings(q=Q.copy(), dq=np.zeros(4), tau=np.zeros(4))
    departure.record["excess"][0][LIMIT_GROUPS] = 1.0
    departure.respond(2 * DT, sensors, force, np.zeros(4))
    np.testing.assert_allclose(departure.yield_command.torque, plain, rtol=1e-9, atol=1e-9)
    departure.record["excess"][0][LIMIT_GROUPS] = 0.0
    departure.respond(3 * DT, sensors, force, np.zeros(4))
    np.testing.assert_allclose(departure.yield_command.torque, plain, rtol=1e-9, atol=1e-9)
    # A non-finite estimate: that tick without.
    other = _supervisor(device)
    _stop(other, force, bounds)
    bad = force.copy()
    bad[2, 0] = np.nan
    other.respond(2 * DT, sensors, bad, np.zeros(4))
    np.testing.assert_allclose(other.yield_command.torque, plain, rtol=1e-9, atol=1e-9)


def test_a_leg_out_of_its_range_loses_its_feedback(device) -> None:
    """The end stop's torque reads as a cuff force: the leg that hit it is fed back no more."""
    exo, patient, motor = device
    cmd = YieldCommand(exo, patient, motor, np.full(4, 5.0), np.full(4, 6.0), DT)
    cmd.start(Q, np.zeros(4), np.full(4, 120.0))
    before = cmd.force_gain.copy()
    assert np.all(before > 0.0)
    lower, upper = np.full(4, -0.5), np.full(4, 2.0)
    q = Q.copy()
    q[1] = -0.6  # the left knee beyond its range
    (breach,) = cmd.brake_outside(q, lower, upper, np.zeros(4))
    assert breach[0] == "yield angle left_knee"
    np.testing.assert_array_equal(cmd.force_gain, [0.0, 0.0, before[2], before[3]])
    cmd.start(Q, np.zeros(4), np.full(4, 120.0))  # the next stop: fed back again
    np.testing.assert_array_equal(cmd.force_gain, before)


def test_a_spastic_leg_straightened_to_its_end_stop_comes_to_rest() -> None:
    """clinic-bws, the QP at 200 / 120 N on the precomputed plan, spastic at 50 % support:
    the departure stop's yield lets the swing knee straighten into its end stop, and the
    legs come to rest and are held with no estimated cuff force past its limit after the
    stop (fed back, the end stop's torque read as a thigh force had driven the estimate
    past 220 N while the true force stayed below 30 N).
    """
    base = preset("clinic-bws").config
    config = dataclasses.replace(
        base,
        controller="qp",
        cuff_force_limit_N=(200.0, 120.0),
        sync=False,
        patient_torque="spastic",
        pelvis=dataclasses.replace(base.pelvis, bws_fraction=0.5),
    )
    result = simulate(config)
    cause = result.events[0]
    assert cause["quantity"] == "departure_left_knee"
    later = [e["quantity"] for e in result.events[1:] if e["kind"] == "violation"]
    assert later == ["angle left_knee", "yield angle left_knee"]  # its end stop; no cuff force
    assert result.safety_state == "holding"
