"""Controllers: the PD law, the computed-torque feedforward and their closed-loop merit.

The feedforward is checked against an independent evaluation of the same
dynamics: Pinocchio's CRBA mass matrix and its non-linear effects (not RNEA,
which the controller uses; test_plant.py checks RNEA against a hand-derived
Lagrangian), the URDF's joint damping and friction, and the steady-state
motor equation solved for the voltage by hand.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.control import (
    ComputedTorqueController,
    PDController,
    PDGains,
    SensorReadings,
    feedforward_torque,
)
from exo_ctrl.control.lift_off import LIFT_OFF_BLEND_S
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import (
    FRICTION_SMOOTHING_RAD_S,
    JOINT_NAMES,
    BodyModel,
    default_urdf_path,
    load_body,
)
from exo_ctrl.plan.gait import GaitParams, GaitPlan
from exo_ctrl.plan.kinematics import plan_joints
from exo_ctrl.plant.drive import MotorParams
from exo_ctrl.sim import SimConfig, simulate


@pytest.fixture(scope="module")
def patient() -> BodyModel:
    return load_body(default_urdf_path("patient"), name="patient")


@pytest.fixture(scope="module")
def plan(exo):
    """The default gait's joint plan at 1 kHz over one period."""
    t = np.arange(1201) * 1e-3
    return plan_joints(GaitPlan(GaitParams()), exo, t)


def readings(rng: np.random.Generator) -> SensorReadings:
    return SensorReadings(
        q=rng.uniform(-0.5, 1.5, 4), dq=rng.uniform(-3.0, 3.0, 4), tau=rng.uniform(-50, 50, 4)
    )


# --------------------------------------------------------------------------- PD


def test_pd_law_per_joint(plan) -> None:
    kp, kd = (100.0, 80.0, 120.0, 60.0), (2.0, 1.5, 3.0, 0.5)
    ctrl = PDController(plan, PDGains(kp=kp, kd=kd))
    rng = np.random.default_rng(0)
    for k in (0, 1, 317, 1200):
        s = readings(rng)
        u = np.array(ctrl.command(k, s))
        for j in range(4):
            expected = kp[j] * (plan.q[k, j] - s.q[j]) + kd[j] * (plan.dq[k, j] - s.dq[j])
            assert u[j] == pytest.approx(expected, rel=1e-12, abs=1e-12)


def test_pd_is_zero_on_the_plan_and_ignores_the_torque_sensors(plan) -> None:
    ctrl = PDController(plan)
    for k in (0, 600):
        on_plan = SensorReadings(q=plan.q[k].copy(), dq=plan.dq[k].copy(), tau=np.full(4, 99.0))
        np.testing.assert_array_equal(ctrl.command(k, on_plan), np.zeros(4))


def test_pd_gains_broadcast_and_are_stored_as_floats() -> None:
    gains = PDGains(kp=50, kd=1)
    assert gains.kp == (50.0, 50.0, 50.0, 50.0) and gains.kd == (1.0, 1.0, 1.0, 1.0)
    assert all(type(x) is float for x in gains.kp + gains.kd)
    assert PDGains(kd=0.0).kd == (0.0,) * 4  # kd = 0 is allowed (P control)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"kp": 0}, "kp must be > 0 V/rad for every joint; got 0"),
        ({"kp": (1, 2, 0, 3)}, "kp must be > 0 V/rad for every joint; got (1, 2, 0, 3)"),
    ],
)
def test_bad_pd_gains_exact_messages(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        PDGains(**kwargs)
    assert str(info.value) == message


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"kd": -1.0}, "kd must be >= 0 V·s/rad; got -1.0"),
        ({"kp": float("nan")}, "kp must be a finite number [V/rad]; got nan"),
    ],
)
def test_bad_pd_gain_values_name_the_plain_number(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        PDGains(**kwargs)
    assert str(info.value) == message


JOINTS = "left_hip, left_knee, right_hip, right_knee"


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"kp": "100"}, "kp must be a finite number [V/rad]; got '100'"),
        ({"kd": "2"}, "kd must be a finite number [V·s/rad]; got '2'"),
        ({"kp": (100, "90", 80, 70)}, "kp must be a finite number [V/rad]; got '90'"),
        ({"kp": np.array(["1", "2", "3", "4"])}, "kp must be a finite number [V/rad]; got '1'"),
        ({"kp": b"100"}, "kp must be a finite number [V/rad]; got b'100'"),
        ({"kp": True}, "kp must be a finite number [V/rad]; got True"),
        ({"kd": (2, 2, False, 2)}, "kd must be a finite number [V·s/rad]; got False"),
        ({"kd": np.bool_(True)}, "kd must be a finite number [V·s/rad]; got np.True_"),
        ({"kp": None}, "kp must be a finite number [V/rad]; got None"),
        ({"kp": (1, 2)}, f"kp must be a number or 4 numbers (one per joint: {JOINTS}); got (1, 2)"),
        (
            {"kd": [[1, 2], [3, 4]]},
            f"kd must be a number or 4 numbers (one per joint: {JOINTS}); got [[1, 2], [3, 4]]",
        ),
    ],
)
def test_pd_gains_refuse_text_bools_and_wrong_lengths(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        PDGains(**kwargs)
    assert str(info.value) == message
    assert info.value.name == next(iter(kwargs))


def test_pd_gains_take_numpy_numbers() -> None:
    gains = PDGains(kp=np.arange(1.0, 5.0), kd=np.float64(3.0))
    assert gains.kp == (1.0, 2.0, 3.0, 4.0) and gains.kd == (3.0,) * 4
    assert all(type(x) is float for x in gains.kp + gains.kd)


# --------------------------------------------------------------------------- feedforward


def blended(exo: BodyModel, q, dq, ddq, lift) -> np.ndarray:
    """q̈_b = q̈_s + α (q̈* − q̈_s), q̈_s = −J⁻¹ J̇ q̇ (control/lift_off.py), from Pinocchio's
    foot frames: the joint acceleration that scales the plan's foot acceleration by α(u)."""
    model, data = exo.model, exo.model.createData()
    pin.forwardKinematics(model, data, q, dq, np.zeros(4))
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    out = np.array(ddq, dtype=float)
    for leg, name in enumerate(("left_foot", "right_foot")):
        u = lift[leg]
        if not 0.0 <= u < LIFT_OFF_BLEND_S:
            continue
        x = u / LIFT_OFF_BLEND_S
        alpha = x**3 * (10.0 - 15.0 * x + 6.0 * x * x)
        frame = model.getFrameId(name)
        rows = [0, 2]
        cols = slice(2 * leg, 2 * leg + 2)
        jac = pin.getFrameJacobian(model, data, frame, pin.LOCAL_WORLD_ALIGNED)[rows][:, cols]
        bias = pin.getFrameClassicalAcceleration(model, data, frame, pin.LOCAL_WORLD_ALIGNED)
        still = -np.linalg.solve(jac, bias.linear[rows])
        out[cols] = still + alpha * (out[cols] - still)
    return out


def independent_feedforward(
    exo: BodyModel, patient: BodyModel | None, motor: MotorParams, q, dq, ddq, lift=None
) -> np.ndarray:
    """τ_ff = (M_e + i_G² J_r) q̈ + n_e + b q̇ + f tanh(q̇/ε) (+ the patient's, rigidly coupled),
    q̈ the plan's blended over lift-off when ``lift`` (the plan row's times since) is given."""
    if lift is not None:
        ddq = blended(exo, q, dq, ddq, lift)
    tau = np.zeros(4)
    bodies = [(exo, motor.gear_ratio**2 * motor.rotor_inertia_kgm2)]
    if patient is not None:
        bodies.append((patient, 0.0))
    for body, rotor in bodies:
        model = body.model
        data = model.createData()
        mass = pin.crba(model, data, q)
        mass = np.triu(mass) + np.triu(mass, 1).T
        nle = pin.nonLinearEffects(model, data, q, dq)
        tau += (mass + rotor * np.eye(4)) @ ddq + nle
        tau += body.damping * dq + body.friction * np.tanh(dq / FRICTION_SMOOTHING_RAD_S)
    return tau


def test_feedforward_voltage_is_the_steady_state_motor_inverse(exo, patient, plan) -> None:
    motor = MotorParams()
    gains = PDGains(kp=(100, 90, 80, 70), kd=(2, 3, 4, 5))
    ct = ComputedTorqueController(plan, exo, patient, motor, gains)
    pd = PDController(plan, gains)
    rng = np.random.default_rng(1)
    for k in (0, 123, 600, 977):
        s = readings(rng)
        u_pd = np.array(pd.command(k, s))
        u_ct = np.array(ct.command(k, s))
        args = (plan.q[k], plan.dq[k], plan.ddq[k], plan.lift_off_s[k])
        tau = independent_feedforward(exo, patient, motor, *args)
        np.testing.assert_allclose(ct.torque_ff, tau, rtol=1e-9, atol=1e-9)
        # L dI/dt = 0:  U = R I + i_G ω / k_E  with  I = τ_m / (i_G k_m), where the
        # gearbox needs τ_m = τ / η motoring and τ η braking (smoothed over 0.05 rad/s).
        s_dir = np.sign(tau) * np.tanh(plan.dq[k] / 0.05)
        tau_m = tau * motor.gear_efficiency ** (-s_dir)
        i_ff = tau_m / (motor.gear_ratio * motor.torque_constant_Nm_per_A)
        u_ff = motor.resistance_ohm * i_ff + motor.gear_ratio * plan.dq[k] / (
            motor.speed_constant_rad_per_Vs
        )
        np.testing.assert_allclose(u_ct - u_pd, u_ff, rtol=1e-9, atol=1e-9)


def test_feedforward_includes_the_patient_and_the_rotor(exo, patient, plan) -> None:
    motor = MotorParams()
    k = 300  # the right foot's lift-off: its q̈ blended in from q̈_s
    args = (plan.q[k], plan.dq[k], plan.ddq[k], plan.lift_off_s[k])
    with_patient = ComputedTorqueController(plan, exo, patient, motor)
    alone = ComputedTorqueController(plan, exo, None, motor)
    with_patient.command(k, readings(np.random.default_rng(2)))
    alone.command(k, readings(np.random.default_rng(2)))
    np.testing.assert_allclose(
        alone.torque_ff, independent_feedforward(exo, None, motor, *args), rtol=1e-9, atol=1e-9
    )
    # The patient's legs (about three times the exoskeleton's mass) weigh in.
    assert np.max(np.abs(with_patient.torque_ff - alone.torque_ff)) > 5.0
    # With a heavier rotor only the inertial term i_G² J_r q̈ changes.
    heavy = MotorParams(rotor_inertia_kgm2=2 * motor.rotor_inertia_kgm2)
    ctrl = ComputedTorqueController(plan, exo, None, heavy)
    ctrl.command(k, readings(np.random.default_rng(2)))
    np.testing.assert_allclose(
        ctrl.torque_ff - alone.torque_ff,
        motor.gear_ratio**2 * motor.rotor_inertia_kgm2 * blended(exo, *args),
        rtol=1e-9,
        atol=1e-9,
    )


def test_feedforward_along_the_plan_equals_the_controllers(exo, patient, plan) -> None:
    motor = MotorParams()
    whole = feedforward_torque(plan, exo, patient, motor)
    assert whole.shape == plan.q.shape
    ctrl = ComputedTorqueController(plan, exo, patient, motor)
    s = readings(np.random.default_rng(3))
    for k in (0, 450, 1200):
        ctrl.command(k, s)
        np.testing.assert_array_equal(whole[k], ctrl.torque_ff)


# --------------------------------------------------------------------------- closed loop


@pytest.fixture(scope="module")
def runs() -> dict:
    """The default scenario with the paper's PD and with computed torque (same gains)."""
    gains = PDGains()
    return {c: simulate(SimConfig(controller=c, gains=gains)) for c in ("pd", "ct")}


def rms_error(result) -> np.ndarray:
    err = result.signals["q_des"] - result.signals["q"]
    return np.sqrt(np.mean(err**2, axis=0))


def test_computed_torque_tracks_at_least_fifteen_times_better_than_pd(runs) -> None:
    assert all(r.status == "completed" for r in runs.values())
    pd_rms, ct_rms = rms_error(runs["pd"]), rms_error(runs["ct"])
    print("\nRMS joint tracking error [mrad] on the default scenario (3.6 s, ramp included):")
    for j, name in enumerate(JOINT_NAMES):
        ratio = pd_rms[j] / ct_rms[j]
        print(
            f"  {name:10s} PD {1e3 * pd_rms[j]:8.3f}   CT {1e3 * ct_rms[j]:8.4f}   ({ratio:.0f}x)"
        )
    assert np.all(pd_rms >= 15.0 * ct_rms)  # measured 18–26x with the default drive
    # And the errors are real, not an artefact of comparing empty runs.
    assert np.all(pd_rms > 1e-3)
    assert runs["pd"].n_ticks == runs["ct"].n_ticks == 3600  # the ramp-in and two cycles


def test_computed_torque_voltage_stays_within_the_supply(runs) -> None:
    # The drives are not saturated by the CT run: the tracking is not bought
    # by clipping (the command equals the applied voltage).
    ct = runs["ct"].signals
    supply = MotorParams().supply_voltage_V
    assert np.max(np.abs(ct["voltage_cmd"])) < supply
    np.testing.assert_array_equal(ct["voltage_cmd"], ct["voltage"])
    assert math.isfinite(float(np.max(np.abs(ct["drive_torque"]))))


def test_readings_of_the_wrong_length_are_refused_by_name(plan) -> None:
    # The PD law runs in a compiled kernel: a short array must not be read past its end.
    pd = PDController(plan)
    bad = SensorReadings(q=np.zeros(4), dq=np.zeros(3), tau=np.zeros(4))
    with pytest.raises(InvalidParameter, match=r"^sensors_dq must be an array of shape \(4,\)"):
        pd.command(0, bad)
    good = SensorReadings(q=plan.q[0].copy(), dq=plan.dq[0].copy(), tau=np.zeros(4))
    np.testing.assert_array_equal(pd.command(0, good), np.zeros(4))  # on the plan: 0 V


def test_a_tick_beyond_the_plan_is_refused_by_name(exo, patient, plan) -> None:
    # A plan without a period covers ticks 0 .. N-1: tick N is a programming error.
    good = SensorReadings(q=plan.q[0].copy(), dq=plan.dq[0].copy(), tau=np.zeros(4))
    rows = plan.q.shape[0]
    for ctrl in (PDController(plan), ComputedTorqueController(plan, exo, patient, MotorParams())):
        message = rf"^k must be a control tick on the plan's {rows} rows; got {rows}$"
        with pytest.raises(InvalidParameter, match=message):
            ctrl.command(rows, good)
        np.testing.assert_array_equal(ctrl.command(rows - 1, good), ctrl.record["u_cmd"][0])
        assert ctrl.last_row == rows - 1


def test_the_record_holds_the_command_and_is_shared_by_controllers_alike(
    exo, patient, plan
) -> None:
    """``u_cmd`` is what command returned; no QP: no active bounds, no fallbacks.

    Controllers of the same kind share one record dtype object (numba types
    a record argument by its dtype's identity: an equal copy costs a
    re-typing per call).
    """
    motor = MotorParams()
    rng = np.random.default_rng(4)
    for make in (
        lambda: PDController(plan),
        lambda: ComputedTorqueController(plan, exo, patient, motor),
    ):
        first, second = make(), make()
        assert first.record.dtype is second.record.dtype
        for k in (0, 321):
            u = first.command(k, readings(rng))
            np.testing.assert_array_equal(first.record["u_cmd"][0], u)
        assert first.record["active_constraints"][0] == first.record["failures"][0] == 0.0
        assert first.active_constraints == first.failures == 0
