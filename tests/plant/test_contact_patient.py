"""The patient's feet on the belt: kinematics, the law's depth, no pull, the friction's energy.

References: Pinocchio's frame placements and Jacobians of the patient's foot
frames; the patient leg's statics J_pᵀ F = g_p(q) - τ_cuff,p from Pinocchio's
RNEA and the contact law's penetration δ = (F_n / k)^(1/n); the passive
system's mechanical energy (no gain); for the four feet's friction solve,
numpy's dense linear algebra and the kinetic energy balance of an impulse,
ΔT_legs + ΔT_belt = Σ_f P_f (s_f⁻ + s_f⁺) / 2 ≤ 0 (the work the belt's
friction does on the legs is their kinetic change; the belt gives that and
the dissipation).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl import cli
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plant import ContactParams, CuffParams, PelvisParams, Plant
from exo_ctrl.plant.contact import contact_forces, friction_impulse, friction_impulse_coupled
from exo_ctrl.plant.patient_feet import feet_friction, feet_friction_coupled, patient_forces

#: Both bodies' legs bent so that the feet hang 3.6 cm below a belt 0.9 m under the hips.
BENT = np.array([0.45, 0.9, 0.45, 0.9])
FEET = ContactParams(enabled=True, patient_feet=True)


def passive(exo, patient, contact=FEET, losses: bool = True, height: float = 0.9, **pelvis):
    return Plant(
        exo,
        patient,
        motors=None,
        cuffs=CuffParams(),
        joint_losses=losses,
        contact=contact,
        belt_height_m=height,
        pelvis=PelvisParams(**pelvis) if pelvis else None,
    )


def test_the_patient_foot_points_and_jacobians_are_pinocchios(exo, patient) -> None:
    """Positions, Jacobian rows and the normal force's joint torque J_zᵀ F_n of the patient."""
    plant = passive(exo, patient)
    p = plant.record[0]
    c, f = p["contact"], p["patient_feet"]
    assert plant.patient_offset_xz == (0.0, 0.0)  # both hips at the world origin here
    data = patient.model.createData()
    rng = np.random.default_rng(4)
    for _ in range(5):
        q = rng.uniform(-0.4, 1.2, 8)
        v = rng.normal(size=8)
        tau = np.zeros(8)
        patient_forces(c, f, q, v, tau, 1e-3)
        pin.computeJointJacobians(patient.model, data, q[4:])
        pin.framesForwardKinematics(patient.model, data, q[4:])
        for leg, frame in enumerate(patient.foot_frame_ids):
            pos = data.oMf[frame].translation
            np.testing.assert_allclose(f["pos"][leg], [pos[0], pos[2]], atol=1e-12)
            jac = pin.getFrameJacobian(patient.model, data, frame, pin.LOCAL_WORLD_ALIGNED)
            cols = slice(2 * leg, 2 * leg + 2)
            np.testing.assert_allclose(f["jx"][leg], jac[0, cols], atol=1e-12)
            np.testing.assert_allclose(f["jz"][leg], jac[2, cols], atol=1e-12)
            np.testing.assert_allclose(f["vel"][leg], jac[[0, 2]] @ v[4:], atol=1e-12)
        np.testing.assert_allclose(f["pen"], plant.patient_feet.penetration(q), rtol=0, atol=1e-12)
        expected = np.concatenate([f["jz"][leg] * f["fn"][leg] for leg in range(2)])
        np.testing.assert_allclose(tau[4:], expected, rtol=1e-14, atol=0)
        assert not np.any(tau[:4])  # the patient's feet load the patient only


def test_a_patient_foot_pressed_by_a_known_force_comes_to_the_laws_penetration(
    exo, patient
) -> None:
    """Passive legs of both bodies settle onto the belt; the static forces are Pinocchio's statics.

    At rest each patient leg balances gravity, the cuffs and the belt:
    J_pᵀ F = g_p(q_p) - τ_cuff,p (J_p the patient foot's 2×2 Jacobian), and its
    foot sinks δ = (F_n / k)^(1/n) under the F_n that statics gives.
    """
    plant = passive(exo, patient)
    plant.reset(BENT, np.zeros(4))
    for _ in range(5000):
        plant.step(np.zeros(4))
    assert np.max(np.abs(plant.v)) < 1e-6  # at rest
    f = plant.patient_feet.record[0]
    q = plant.q.copy()
    gravity = pin.computeGeneralizedGravity(patient.model, patient.model.createData(), q[4:])
    plant.cuffs.compute(q, np.zeros(8))
    cuff = plant.cuffs.joint_torque[4:]
    k, n = FEET.stiffness_N_per_m_n, FEET.exponent
    depth = plant.patient_feet.penetration(q)
    for leg in range(2):
        cols = slice(2 * leg, 2 * leg + 2)
        jac = np.vstack((f["jx"][leg], f["jz"][leg]))
        ft, fn = np.linalg.solve(jac.T, gravity[cols] - cuff[cols])
        print(f"patient leg {leg}: static F_n {fn:.3f} N, F_t {ft:.3f} N, δ {depth[leg]:.6e} m")
        assert fn > 10.0
        assert abs(fn - f["fn"][leg]) < 1e-6 * fn
        assert abs(ft - f["ft"][leg]) < 1e-6 * fn
        assert depth[leg] == pytest.approx((fn / k) ** (1.0 / n), rel=1e-6)
        assert f["state"][leg] == 1.0  # held by friction
    assert np.all(plant.contact.record["fn"][0] > 10.0)  # the exoskeleton's feet carry theirs


def test_dropped_legs_lose_energy_on_the_patients_feet_too_and_never_pull(exo, patient) -> None:
    """Both bodies' legs fall onto the belt: no energy gain, no pull, the patient's feet land.

    No joint losses: the contact (and the cuffs' dampers) dissipate.  The
    energy holds the four feet's contact springs and the belt.
    """
    plant = passive(exo, patient, losses=False, height=1.0)
    plant.reset(np.array([0.45, 0.9, 0.3, 0.7]), np.zeros(4))
    assert np.all(plant.patient_feet.penetration(plant.q) < 0.0)
    e0 = plant.mechanical_energy()
    energies, forces, depths = [e0], [], []
    for _ in range(1500):
        plant.step(np.zeros(4))
        f = plant.patient_feet.record[0]
        energies.append(plant.mechanical_energy())
        forces.append(f["fn"].copy())
        depths.append(f["pen"].copy())
    energies, forces, depths = np.array(energies), np.array(forces), np.array(depths)
    rise = np.max(np.diff(energies))
    print(f"energy {e0:.3f} J -> {energies[-1]:.3f} J, largest rise in a step {rise:.2e} J")
    print(f"patient feet: peak F_n {forces.max(axis=0)} N, deepest {depths.max(axis=0)} m")
    assert np.all(forces >= 0.0)
    assert np.all(forces[depths <= 0.0] == 0.0)  # zero at separation
    assert np.all(forces.max(axis=0) > 10.0)  # both patient feet did land
    assert rise < 1e-3 * abs(e0 - energies[-1])
    assert energies[-1] < e0 - 1.0


@pytest.mark.parametrize("supported", [False, True], ids=["pelvis fixed", "pelvis supported"])
def test_the_four_feet_friction_solve_balances_the_belts_work(exo, patient, supported) -> None:
    """One friction solve, two feet stuck and two sliding, against numpy and the energy balance.

    g_f = M⁻¹ J_x,fᵀ and the accelerations from numpy's solve; the end-of-step
    slip s⁺ = J_x (v + h a) + v_b⁺ is zero for a stuck foot and |P| = μ F_n h
    against it for a sliding one; and the impulses' work: the legs' kinetic
    energy (M with its armature) changes by the work the belt's friction does
    on them, Σ P_f (ẋ_f⁻ + ẋ_f⁺) / 2, and legs and belt together lose the
    friction's dissipation D = −Σ P_f (s_f⁻ + s_f⁺) / 2, each foot's share ≥ 0
    (s = ẋ + v_b the slip; the belt's surface moves at −v_b).
    """
    kw = {"supported": True, "bws_fraction": 0.5} if supported else {}
    plant = passive(exo, patient, **kw)
    p = plant.record[0]
    c, f = p["contact"], p["patient_feet"]
    off = 1 if supported else 0
    q = np.concatenate((BENT, BENT))
    rng = np.random.default_rng(7)
    p["v"][:] = rng.normal(scale=0.05, size=8)
    plant.contact.reset(0.05)  # a slip the loaded feet's cones can stop within the step
    c["z_pelvis"] = 0.0
    tau = np.zeros(8)
    contact_forces(c, q, p["v"], tau, p["h"])
    patient_forces(c, f, q, p["v"], tau, p["h"])
    c["fn"][:] = (400.0, 2.0)  # exo left loaded (a wide cone), exo right barely
    f["fn"][:] = (3.0, 300.0)  # patient left barely, patient right loaded
    mass = pin.crba(plant.model, plant.data, np.r_[0.0, q] if supported else q)
    full = np.triu(mass) + np.triu(mass, 1).T
    acc_in = rng.normal(size=8 + off)
    solve = feet_friction_coupled if supported else feet_friction
    solve(plant.record, acc_in, mass)
    h, m_b = float(p["h"]), float(c["belt"]["mass"])
    jac = np.zeros((4, 8 + off))
    for foot, row in enumerate((*c["jx"], *f["jx"])):
        jac[foot, off + 2 * foot : off + 2 * foot + 2] = row
    np.testing.assert_allclose(f["g4"][:, : 8 + off], np.linalg.solve(full, jac.T).T, rtol=1e-10)
    imp = f["imp4"].copy()
    acc = p["pelvis"]["acc9"] if supported else c["acc"]
    np.testing.assert_allclose(acc, acc_in + np.linalg.solve(full, jac.T @ imp) / h, rtol=1e-9)
    v_all = np.r_[0.0, p["v"]] if supported else p["v"].copy()  # ż = 0 at the start here
    v_free = v_all + h * acc_in
    v_next = v_all + h * acc
    belt_free = float(c["belt"]["v_free"])
    belt_next = belt_free + imp.sum() / m_b
    assert float(c["belt"]["v_next"]) == pytest.approx(belt_next, rel=1e-14)
    s_before, s_after = jac @ v_free + belt_free, jac @ v_next + belt_next
    fn = np.r_[c["fn"], f["fn"]]
    stuck = fn > 100.0
    np.testing.assert_allclose(s_after[stuck], 0.0, atol=1e-12)
    np.testing.assert_allclose(np.abs(imp[~stuck]), 0.8 * fn[~stuck] * h, rtol=1e-12)
    assert np.all(np.sign(imp[~stuck]) == -np.sign(s_after[~stuck]))
    assert np.all(np.abs(imp[stuck]) < 0.8 * fn[stuck] * h)
    # the energy balance of the impulses, legs (with the armature) and belt
    work_on_legs = float(imp @ (jac @ (v_free + v_next))) / 2.0
    d_legs = 0.5 * (v_next @ full @ v_next - v_free @ full @ v_free)
    d_belt = 0.5 * m_b * (belt_next**2 - belt_free**2)
    dissipated = -imp * (s_before + s_after) / 2.0
    print(f"work on the legs {work_on_legs:.6e} J, belt {d_belt:.6e} J, lost {dissipated} J")
    assert d_legs == pytest.approx(work_on_legs, rel=1e-9, abs=1e-15)
    assert d_legs + d_belt == pytest.approx(-dissipated.sum(), rel=1e-9, abs=1e-15)
    assert np.all(dissipated >= 0.0)
    assert dissipated.sum() > 1e-6  # the sliding feet and the stuck ones' slip did dissipate
    if supported:  # through the pelvis every foot's impulse moves every other foot
        assert np.all(np.abs(f["w4"]) > 0.0)
    else:  # the legs are apart: the feet couple through the belt only
        np.testing.assert_array_equal(f["w4"], np.diag(np.diag(f["w4"])))


def test_off_the_plant_steps_as_before(exo, patient) -> None:
    """Off: the two feet's friction solve, the switch None, the patient's outputs zero."""
    plant = passive(exo, patient, contact=ContactParams(enabled=True))
    assert plant._friction is friction_impulse
    assert plant._friction_coupled is friction_impulse_coupled
    assert plant._switches[4] is None
    plant.reset(BENT, np.zeros(4))
    for _ in range(200):
        plant.step(np.zeros(4))
    f = plant.patient_feet.record[0]
    for name in ("fn", "ft", "pen", "slip", "state", "imp4"):
        assert not np.any(f[name]), name
    assert np.all(plant.patient_feet.penetration(plant.q) > 0.0)  # sunk in, nothing pushing back
    on = passive(exo, patient)
    assert on._friction is feet_friction and on._switches[4] is True


def test_bad_patient_feet_parameters_are_refused(capsys: pytest.CaptureFixture) -> None:
    with pytest.raises(
        InvalidParameter,
        match=r"patient_feet must be False with the contact off \(enabled=False\); got True",
    ):
        ContactParams(patient_feet=True)
    with pytest.raises(InvalidParameter, match="patient_feet must be True or False; got 'on'"):
        ContactParams(enabled=True, patient_feet="on")
    code = cli.main(["simulate", "--patient-feet", "on", "--no-record"])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert code == 2
    assert err == (
        "exo-ctrl simulate: error: --patient-feet: contact.patient_feet: must be False with "
        "the contact off "
        "(enabled=False); got True (the patient's feet meet the belt only with the belt "
        "contact on: --contact on)"
    )
