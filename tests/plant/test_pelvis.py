"""The pelvis on its vertical guide: mass, free fall, the drop onto the belt, the coupled friction.

References: the equivalence principle (a freely falling system's joints do
not accelerate under gravity alone), Newton's law for the whole moving mass
M z̈ = F_s − M g, the contact law's static penetration ((M g − F_s) / (2 k))^(1/n)
on two feet, the passive system's mechanical energy (no gain), and the
friction solve's result against numpy's dense linear algebra.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.exceptions import InvalidModel, InvalidParameter
from exo_ctrl.plant import ContactParams, CuffParams, PelvisParams, Plant
from exo_ctrl.plant.contact import contact_forces, friction_impulse_coupled

G = 9.81


def guided(exo, patient, bws: float, contact: bool, height: float = 1.0, **kw) -> Plant:
    return Plant(
        exo,
        patient,
        motors=None,
        cuffs=CuffParams(),
        joint_losses=kw.pop("losses", True),
        contact=ContactParams(enabled=contact),
        belt_height_m=height,
        pelvis=PelvisParams(supported=True, bws_fraction=bws, **kw),
    )


def test_the_guide_moves_the_body_mass_and_the_exoskeleton(exo, patient) -> None:
    plant = guided(exo, patient, 0.5, contact=False)
    exo_mass = pin.computeTotalMass(exo.model) + exo.model.inertias[0].mass
    mass = float(plant.pelvis["mass"][0])
    assert mass == pytest.approx(80.0 + exo_mass, rel=1e-12)
    gravity = pin.computeGeneralizedGravity(plant.model, plant.model.createData(), np.zeros(9))
    assert gravity[0] == pytest.approx(mass * G, rel=1e-12)
    assert float(plant.pelvis["support"][0]) == pytest.approx(0.5 * 80.0 * 9.80665, rel=1e-15)


def test_in_free_fall_the_joints_do_not_accelerate_and_the_pelvis_falls_at_g(exo, patient) -> None:
    """Equivalence principle: without support or contact, gravity moves no joint."""
    plant = guided(exo, patient, 0.0, contact=False)
    q = np.array([0.3, 0.6, -0.2, 0.4])
    plant.reset(q, np.zeros(4))
    plant.step(np.zeros(4))
    np.testing.assert_allclose(plant.acceleration, 0.0, atol=1e-9)
    assert float(plant.pelvis["az"][0]) == pytest.approx(-G, rel=1e-12)


def test_the_support_lifts_the_whole_moving_mass(exo, patient) -> None:
    """Legs hanging straight: M z̈ = F_s − M g, the joints still (by symmetry)."""
    plant = guided(exo, patient, 0.7, contact=False)
    plant.reset(np.zeros(4), np.zeros(4))
    plant.step(np.zeros(4))
    mass, support = float(plant.pelvis["mass"][0]), float(plant.pelvis["support"][0])
    assert float(plant.pelvis["az"][0]) == pytest.approx(support / mass - G, rel=1e-12)
    np.testing.assert_allclose(plant.acceleration, 0.0, atol=1e-9)


def test_a_dropped_body_bounces_on_its_legs_loses_energy_and_rests_at_the_laws_depth(
    exo, patient
) -> None:
    """Straight legs (the feet 1.04 m under the hips) dropped 2 cm onto a belt 1.0 m down.

    The normal forces act along the legs, so the joints stay straight and the
    system is one mass M on two Hunt–Crossley springs: it never gains
    energy, the belt never pulls (F_n ≥ 0), and it comes to rest where
    2 k δⁿ = M g − F_s.
    """
    plant = guided(exo, patient, 0.5, contact=True, height=1.0, losses=False)
    plant.reset(np.zeros(4), np.zeros(4), pelvis_z_m=0.06)  # feet 2 cm above the belt
    c = plant.contact.record[0]
    energy0 = plant.mechanical_energy()
    energy, fn_min = [], np.inf
    for _ in range(3000):
        plant.step(np.zeros(4))
        energy.append(plant.mechanical_energy())
        fn_min = min(fn_min, float(c["fn"].min()))
    energy = np.array(energy)
    assert fn_min >= 0.0
    assert np.all(np.diff(energy) <= 1e-6 * abs(energy0))  # never a gain beyond rounding
    assert energy[-1] < energy0 - 1.0  # the impacts dissipated
    mass, support = float(plant.pelvis["mass"][0]), float(plant.pelvis["support"][0])
    depth = ((mass * G - support) / (2 * 5e5)) ** (1 / 1.5)
    np.testing.assert_allclose(c["pen"], depth, rtol=1e-3)
    assert float(c["fn"].sum()) == pytest.approx(mass * G - support, rel=1e-3)
    np.testing.assert_allclose(plant.q, 0.0, atol=1e-9)


def test_the_coupled_friction_solve_sticks_both_feet_exactly(exo, patient) -> None:
    """Both feet loaded, inside the cone: the end-of-step slip is zero against numpy's solve."""
    plant = guided(exo, patient, 0.5, contact=True, height=0.9)
    p = plant.record[0]
    c = p["contact"]
    q = np.array([0.45, 0.9, 0.45, 0.9, 0.45, 0.9, 0.45, 0.9])
    rng = np.random.default_rng(5)
    p["v"][:] = rng.normal(scale=0.02, size=8)
    plant.contact.reset(0.0)
    c["z_pelvis"] = 0.04  # the feet 3.6 cm under a belt 0.9 m down, less 4 cm of pelvis
    contact_forces(c, q, p["v"], np.zeros(8), p["h"])
    c["fn"][:] = 400.0  # loaded feet: a wide cone
    mass = pin.crba(plant.model, plant.data, np.r_[0.04, q])
    full = np.triu(mass) + np.triu(mass, 1).T
    acc_in = rng.normal(size=9)
    friction_impulse_coupled(plant.record, acc_in, mass)
    h = float(p["h"])
    jac = np.zeros((2, 9))
    jac[0, 1:3], jac[1, 3:5] = c["jx"][0], c["jx"][1]
    np.testing.assert_allclose(p["pelvis"]["g9"], np.linalg.solve(full, jac.T).T, rtol=1e-10)
    acc = p["pelvis"]["acc9"]
    np.testing.assert_allclose(acc, acc_in + np.linalg.solve(full, jac.T @ c["imp"]) / h, rtol=1e-9)
    belt_next = c["imp"].sum() / float(c["belt"]["mass"])
    slip = jac[:, 1:] @ (p["v"] + h * acc[1:]) + belt_next
    np.testing.assert_allclose(slip, 0.0, atol=1e-12)
    assert np.all(np.abs(c["imp"]) < 0.8 * 400.0 * h)  # inside the cone: stuck
    assert abs(float(c["w_x"])) > 1e-3 * float(c["w"].min())  # the feet are coupled


def test_bad_pelvis_parameters_are_refused(exo, patient) -> None:
    message = r"bws must be in \[0, 1\] \(a fraction of body weight\); got 1.5"
    with pytest.raises(InvalidParameter, match=message):
        PelvisParams(supported=True, bws_fraction=1.5)
    with pytest.raises(InvalidParameter, match="body_mass"):
        PelvisParams(supported=True, body_mass_kg=-3.0)
    with pytest.raises(InvalidModel, match="body mass 20 kg is not above the patient model's"):
        guided(exo, patient, 0.5, contact=False, body_mass_kg=20.0)
