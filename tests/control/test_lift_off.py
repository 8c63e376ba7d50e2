"""The swing leg's acceleration feedforward blended in over lift-off (control/lift_off.py).

The blend is checked against Pinocchio's foot frames (not the closed-form leg
of the kernel): the blended joint acceleration moves each foot point with
α(u) times the plan's foot acceleration.  In closed loop, on the default
scenario (pelvis fixed, the belt on), computed torque slips no more than PD:
before the blend its feedforward stepped the hip torque at lift-off while the
foot was still on the belt (0.115 m/s of slip against PD's 0.031 m/s).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.control import ComputedTorqueController, feedforward_torque
from exo_ctrl.control.lift_off import LIFT_OFF_BLEND_S, blend_lift_off
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import BodyModel, default_urdf_path, load_body
from exo_ctrl.model.leg_kernels import legs_record
from exo_ctrl.plan.gait import GaitParams, GaitPlan
from exo_ctrl.plan.kinematics import plan_joints
from exo_ctrl.plant.drive import MotorParams
from exo_ctrl.scenario import load_scenario
from exo_ctrl.sim import simulate

FEET = ("left_foot", "right_foot")


@pytest.fixture(scope="module")
def patient() -> BodyModel:
    return load_body(default_urdf_path("patient"), name="patient")


@pytest.fixture(scope="module")
def plan(exo):
    """The default gait's joint plan at 1 kHz over one period."""
    return plan_joints(GaitPlan(GaitParams()), exo, np.arange(1201) * 1e-3)


def smoothstep(x: float) -> float:
    x = min(max(x, 0.0), 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x * x)


def foot_acceleration(body: BodyModel, q, dq, ddq) -> np.ndarray:
    """Each foot frame's (x, z) acceleration [m/s²] from Pinocchio, (2, 2)."""
    model, data = body.model, body.model.createData()
    pin.forwardKinematics(model, data, q, dq, ddq)
    pin.updateFramePlacements(model, data)
    out = np.zeros((2, 2))
    for leg, name in enumerate(FEET):
        frame = model.getFrameId(name)
        acc = pin.getFrameClassicalAcceleration(model, data, frame, pin.LOCAL_WORLD_ALIGNED)
        out[leg] = acc.linear[[0, 2]]
    return out


def test_the_plan_knows_each_legs_time_since_lift_off(plan) -> None:
    """u = τ − τ_D in swing (the right leg lifts off at 0.3 s, the left at 0.9 s), inf in stance."""
    lift = plan.lift_off_s
    assert lift.shape == (1201, 2)
    assert lift[300, 1] == pytest.approx(0.0, abs=1e-12)
    assert lift[905, 0] == pytest.approx(0.005, abs=1e-12)
    assert np.isinf(lift[300, 0]) and np.isinf(lift[600, 0])
    swing = np.isfinite(lift)
    np.testing.assert_array_equal(swing, ~GaitPlan(GaitParams()).feet(plan.t).stance)


@pytest.mark.parametrize("u", [0.0, 0.3 * LIFT_OFF_BLEND_S, 0.7 * LIFT_OFF_BLEND_S])
def test_the_blend_scales_the_plans_foot_acceleration_by_alpha(exo, plan, u) -> None:
    """J q̈_b + J̇ q̇ = α(u) (J q̈* + J̇ q̇) on the swing leg (Pinocchio's foot frames); the
    other leg's q̈ is the plan's."""
    k = 300  # the right foot's lift-off
    q, dq, ddq = plan.q[k], plan.dq[k], plan.ddq[k]
    out = np.zeros(4)
    lift = np.array([np.inf, u])
    blend_lift_off(legs_record(exo), q, dq, ddq, lift, LIFT_OFF_BLEND_S, out)
    planned = foot_acceleration(exo, q, dq, ddq)
    blended = foot_acceleration(exo, q, dq, out)
    alpha = smoothstep(u / LIFT_OFF_BLEND_S)
    np.testing.assert_allclose(blended[1], alpha * planned[1], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(out[:2], ddq[:2])
    assert np.linalg.norm(planned[1]) > 5.0  # the jump the blend takes out: ≈ 13 m/s²


def test_no_blend_in_stance_after_the_blend_or_when_off(exo, plan) -> None:
    q, dq, ddq = plan.q[300], plan.dq[300], plan.ddq[300]
    out = np.zeros(4)
    for lift, blend in (((np.inf, np.inf), 0.01), ((0.01, 0.02), 0.01), ((0.0, 0.0), 0.0)):
        blend_lift_off(legs_record(exo), q, dq, ddq, np.array(lift), blend, out)
        np.testing.assert_array_equal(out, ddq)


def test_the_feedforward_torque_is_continuous_across_lift_off(exo, patient, plan) -> None:
    """Without the blend the right hip's feedforward jumps by 124 N·m in the tick of lift-off
    (k = 300); blended over T_b = 10 ms its steps are at most the quintic's slope,
    (15/8) Δτ Δt / T_b ≈ 23 N·m a tick.  (The other leg's touchdown at the same tick keeps
    its own step, 21 and 36 N·m at the left hip and knee: the blend is for lift-off.)"""
    motor = MotorParams()
    raw = feedforward_torque(plan, exo, patient, motor, lift_off_blend_s=0.0)
    tau = feedforward_torque(plan, exo, patient, motor)
    window = slice(290, 320)
    jump = np.abs(np.diff(raw[window, 2:], axis=0)).max()
    step = np.abs(np.diff(tau[window, 2:], axis=0)).max()
    print(f"right leg's largest feedforward step per tick: {step:.1f} N·m (unblended {jump:.1f})")
    assert jump > 100.0
    assert step <= 15.0 / 8.0 * jump * 1e-3 / LIFT_OFF_BLEND_S * 1.05
    ctrl = ComputedTorqueController(plan, exo, patient, motor)
    np.testing.assert_array_equal(ctrl.torque_ff_table, tau)


def test_a_bad_blend_time_is_refused(exo, plan) -> None:
    with pytest.raises(InvalidParameter, match="lift_off_blend"):
        ComputedTorqueController(plan, exo, None, MotorParams(), lift_off_blend_s=-0.01)


def test_computed_torque_slips_no_more_than_pd_with_the_pelvis_fixed() -> None:
    """The default scenario (belt on, pelvis fixed, 2 cycles after the ramp-in): CT's worst
    slip at most PD's, and its tracking still sub-milliradian (before: 0.115 m/s against
    0.031 m/s; RMS 0.56-0.74 mrad)."""
    out = {}
    for controller in ("pd", "ct"):
        config = load_scenario(preset="paper", overrides=[f"run.controller={controller}"]).config
        assert config.contact.enabled and not config.pelvis_resolved.supported
        result = simulate(config)
        assert result.status == "completed"
        out[controller] = result.summary()
    ct, pd = out["ct"], out["pd"]
    print(
        f"worst slip: CT {ct['slip_speed_max_mps']:.4f} m/s, PD {pd['slip_speed_max_mps']:.4f} m/s"
    )
    assert ct["slip_speed_max_mps"] <= pd["slip_speed_max_mps"]
    assert max(ct["rms_tracking_error_rad"].values()) < 0.8e-3
