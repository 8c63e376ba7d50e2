"""Foot–belt contact: foot kinematics, the Hunt–Crossley law, dissipation, the friction cone.

References: Pinocchio's frame placements and Jacobians of the exoskeleton's
foot frames, the static equilibrium J_footᵀ F = g(q) - τ_cuff from
Pinocchio's RNEA, the contact law's penetration (F_n / k)^(1/n), the
passive system's mechanical energy, Coulomb's law |F_t| = μ F_n.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plant import BeltParams, ContactParams, CuffParams, FootContact, Plant
from exo_ctrl.plant.contact import contact_forces

#: The legs bent so that the feet hang 3.6 cm below a belt 0.9 m under the hips.
BENT = np.array([0.45, 0.9, 0.45, 0.9])


def passive(exo, patient, mu: float = 0.8, losses: bool = True, height: float = 0.9) -> Plant:
    contact = ContactParams(enabled=True, friction_coeff=mu)
    return Plant(
        exo,
        patient,
        motors=None,
        cuffs=CuffParams(),
        joint_losses=losses,
        contact=contact,
        belt_height_m=height,
    )


def test_the_foot_points_and_jacobians_are_pinocchios(exo, patient) -> None:
    plant = passive(exo, patient)
    c = plant.contact.record[0]
    rng = np.random.default_rng(3)
    data = exo.model.createData()
    for _ in range(5):
        q = rng.uniform(-0.4, 1.2, 8)
        v = rng.normal(size=8)
        contact_forces(c, q, v, np.zeros(8), 1e-3)
        pin.computeJointJacobians(exo.model, data, q[:4])
        pin.framesForwardKinematics(exo.model, data, q[:4])
        for leg, frame in enumerate(exo.foot_frame_ids):
            p = data.oMf[frame].translation
            np.testing.assert_allclose(c["pos"][leg], [p[0], p[2]], atol=1e-12)
            jac = pin.getFrameJacobian(exo.model, data, frame, pin.LOCAL_WORLD_ALIGNED)
            cols = slice(2 * leg, 2 * leg + 2)
            np.testing.assert_allclose(c["jx"][leg], jac[0, cols], atol=1e-12)
            np.testing.assert_allclose(c["jz"][leg], jac[2, cols], atol=1e-12)
            np.testing.assert_allclose(c["vel"][leg, 0], jac[0, :4] @ v[:4], atol=1e-12)


def test_a_foot_pressed_by_a_known_force_comes_to_the_laws_penetration(exo, patient) -> None:
    """Passive legs settle onto the belt; their static foot force is Pinocchio's statics.

    At rest the belt's force F = (F_t, F_n) on each foot balances gravity and
    the cuffs: J_footᵀ F = g(q) - τ_cuff (J the 2×2 foot Jacobian of the leg).
    The penetration must be (F_n / k)^(1/n) of that statically known F_n.
    """
    plant = passive(exo, patient)
    plant.reset(BENT, np.zeros(4))
    for _ in range(4000):
        plant.step(np.zeros(4))
    assert np.max(np.abs(plant.v)) < 1e-6  # at rest
    c = plant.contact.record[0]
    q = plant.q.copy()
    gravity = pin.computeGeneralizedGravity(exo.model, exo.model.createData(), q[:4])
    plant.cuffs.compute(q, np.zeros(8))
    cuff = plant.cuffs.joint_torque[:4]
    k, n = plant.contact.params.stiffness_N_per_m_n, plant.contact.params.exponent
    depth = plant.contact.penetration(q)
    for leg in range(2):
        cols = slice(2 * leg, 2 * leg + 2)
        jac = np.vstack((c["jx"][leg], c["jz"][leg]))  # rows x, z over (hip, knee)
        ft, fn = np.linalg.solve(jac.T, gravity[cols] - cuff[cols])
        print(f"leg {leg}: static F_n {fn:.3f} N, F_t {ft:.3f} N, penetration {depth[leg]:.6e} m")
        assert fn > 10.0
        assert abs(fn - c["fn"][leg]) < 1e-6 * fn
        assert abs(ft - c["ft"][leg]) < 1e-6 * fn
        assert depth[leg] == pytest.approx((fn / k) ** (1.0 / n), rel=1e-6)
        assert c["state"][leg] == 1.0  # held by friction


def test_a_dropped_leg_loses_energy_on_impact_and_never_pulls(exo, patient) -> None:
    """Legs falling onto the belt: mechanical energy never rises, the force never pulls.

    No joint losses: the only dissipation is the contact's (and the cuffs'
    dampers).  The energy includes the contact springs and the belt.
    """
    plant = passive(exo, patient, losses=False, height=1.0)
    start = np.array([0.45, 0.9, 0.3, 0.7])  # feet 6.4 and 2.4 cm above the belt, at rest
    plant.reset(start, np.zeros(4))
    assert np.all(plant.contact.penetration(plant.q) < 0.0)
    e0 = plant.mechanical_energy()
    energies, forces, depths = [e0], [], []
    for _ in range(1500):
        plant.step(np.zeros(4))
        c = plant.contact.record[0]
        energies.append(plant.mechanical_energy())
        forces.append(c["fn"].copy())
        depths.append(c["pen"].copy())
    energies, forces, depths = np.array(energies), np.array(forces), np.array(depths)
    rise = np.max(np.diff(energies))
    print(f"energy {e0:.3f} J -> {energies[-1]:.3f} J, largest rise in a step {rise:.2e} J")
    assert np.all(forces >= 0.0)
    assert np.all(forces[depths <= 0.0] == 0.0)  # zero at separation
    assert np.any(forces > 10.0)  # the feet did land
    assert rise < 1e-3 * abs(e0 - energies[-1])
    assert energies[-1] < e0 - 1.0


def test_a_sliding_foot_gets_mu_fn_against_the_slip_and_a_held_one_sticks(exo, patient) -> None:
    for mu, belt_speed, sticks in ((0.8, 2.0, False), (0.8, -2.0, False), (5.0, 1e-3, True)):
        plant = passive(exo, patient, mu=mu)
        plant.reset(BENT, np.zeros(4))
        for _ in range(2000):  # settle on the belt at rest
            plant.step(np.zeros(4))
        b = plant.contact.belt
        b["v"] = b["v_set"] = b["v_next"] = belt_speed
        plant.step(np.zeros(4))
        c = plant.contact.record[0]
        for leg in range(2):
            fn, ft = c["fn"][leg], c["ft"][leg]
            assert fn > 10.0
            if sticks:
                assert c["state"][leg] == 1.0
                assert abs(c["slip"][leg]) < 1e-9
                assert abs(ft) < mu * fn
            else:
                assert c["state"][leg] == 2.0
                assert ft == pytest.approx(-np.sign(c["slip"][leg]) * mu * fn, rel=1e-9)
                assert np.sign(c["slip"][leg]) == np.sign(belt_speed)  # slip s = ẋ + v_b


def test_bad_contact_parameters_are_refused(exo) -> None:
    with pytest.raises(InvalidParameter, match="friction coefficient must be > 0; got 0"):
        ContactParams(friction_coeff=0)
    with pytest.raises(InvalidParameter, match=r"contact exponent must be >= 1; got 0\.5"):
        ContactParams(exponent=0.5)
    with pytest.raises(InvalidParameter, match="contact stiffness must be > 0"):
        ContactParams(stiffness_N_per_m_n=-1.0)
    with pytest.raises(InvalidParameter, match=r"belt height must be in \(0, 1.04\) m"):
        FootContact(exo, ContactParams(belt=BeltParams(height_m=1.5)), 0.9)
