"""The stance legs' load in computed torque's feedforward (control/stance_load.py).

References: Pinocchio's foot-frame Jacobian (τ = −J_zᵀ F), the vertical
balance M (g + a_h) = F + F_s with a_h the hip's acceleration over a foot
fixed on the belt (finite differences of the foot's height along the plan),
and the shares' sum and continuity.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.control.stance_load import StanceLoad, stance_load_record, stance_load_torque
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plan import GaitParams, GaitPlan, plan_joints
from exo_ctrl.scenario import load_scenario
from exo_ctrl.sim import build

LOAD = StanceLoad(mass_kg=97.0, support_N=392.0, gravity_mps2=9.81)


def test_standing_on_both_feet_each_leg_holds_half_the_weight(exo) -> None:
    """At rest, both feet level: F = M g − F_s, half on each foot, τ = −J_zᵀ F / 2."""
    rec = stance_load_record(LOAD, exo)
    q = np.array([0.3, 0.6, 0.3, 0.6])
    tau = np.zeros(4)
    stance_load_torque(rec, q, np.zeros(4), np.zeros(4), tau)
    force = 97.0 * 9.81 - 392.0
    assert float(rec["force"][0]) == pytest.approx(force, rel=1e-14)
    np.testing.assert_allclose(rec["share"][0], 0.5, rtol=1e-15)
    data = exo.model.createData()
    pin.computeJointJacobians(exo.model, data, q)
    pin.framesForwardKinematics(exo.model, data, q)
    expected = np.zeros(4)
    for frame in exo.foot_frame_ids:
        jac = pin.getFrameJacobian(exo.model, data, frame, pin.LOCAL_WORLD_ALIGNED)
        expected -= 0.5 * force * jac[2, :4]
    np.testing.assert_allclose(tau, expected, atol=1e-10)


def test_along_the_plan_the_force_balances_the_hips_acceleration(exo) -> None:
    """F = M (g − z̈_stance) − F_s, z̈ from finite differences of the stance foot's height."""
    gait = GaitParams(hip_height=1.0, pelvis_excursion=0.05)
    dt = 1e-3
    t = np.arange(0.0, 2 * gait.period, dt)
    plan = plan_joints(GaitPlan(gait), exo, t)
    rec = stance_load_record(LOAD, exo)
    forces, shares, heights = [], [], []
    for k in range(t.size):
        stance_load_torque(rec, plan.q[k], plan.dq[k], plan.ddq[k], np.zeros(4))
        forces.append(float(rec["force"][0]))
        shares.append(rec["share"][0].copy())
        heights.append(stance_height(exo, plan.q[k]))
    forces, shares, heights = np.array(forces), np.array(shares), np.array(heights)
    np.testing.assert_allclose(shares.sum(axis=1), 1.0, rtol=1e-14)
    assert np.abs(np.diff(shares, axis=0)).max() < 0.1  # the load passes on, no jump
    one = np.flatnonzero(shares.max(axis=1) == 1.0)[5:-5]  # single stance, inside
    leg = np.argmax(shares[one], axis=1)
    z = heights[:, 0]
    z_other = heights[:, 1]
    zs = np.where(leg == 0, z[one], z_other[one])
    zdd_fd = np.where(
        leg == 0,
        (z[one + 1] - 2 * z[one] + z[one - 1]) / dt**2,
        (z_other[one + 1] - 2 * z_other[one] + z_other[one - 1]) / dt**2,
    )
    assert zs.size > 500
    np.testing.assert_allclose(forces[one], 97.0 * (9.81 - zdd_fd) - 392.0, atol=0.5)
    assert forces.min() > 0.0


def stance_height(exo, q: np.ndarray) -> np.ndarray:
    data = exo.model.createData()
    pin.framesForwardKinematics(exo.model, data, q)
    return np.array([data.oMf[f].translation[2] for f in exo.foot_frame_ids])


def test_bad_stance_load_is_refused() -> None:
    with pytest.raises(InvalidParameter, match="stance load mass must be > 0 kg; got -1"):
        StanceLoad(mass_kg=-1.0, support_N=0.0)


def test_the_qp_carries_the_stance_load_as_computed_torque_does() -> None:
    """With the pelvis on its guide the QP's command is CT+PD with the stance legs' load, as
    computed torque's (without it the QP under 40 % support touched down at 0.24-0.27 m/s
    and slid 0.48-0.56 m/s; with it 0.16-0.22 and 0.32-0.43): same feedforward table."""
    from_preset = load_scenario(preset="clinic-bws").config
    tables = {}
    for controller in ("ct", "qp"):
        # (a bound above the plan's load plus its margin: the QP may not leave the plan here;
        # the precomputed plan, whose table holds the whole gait)
        config = dataclasses.replace(
            from_preset, controller=controller, cuff_force_limit_N=300.0, sync=False
        )
        setup = build(config)
        tables[controller] = setup.controller.torque_ff_table
    np.testing.assert_array_equal(tables["qp"], tables["ct"])
    assert np.abs(tables["qp"]).max() > 100.0  # the load: hundreds of newtons at the feet
