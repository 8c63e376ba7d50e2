"""Split cuffs: normal and shear stiffness and damping, strap preload (exo_ctrl/plant/cuffs.py).

Hand calculations at q = 0, where the default legs hang straight down: every
cuff's along-link direction u is -z and its normal n is +x, so a patient
shifted by (dx, dz) stretches each cuff by Δp = exo - patient = (-dx, -dz),
s_n = -dx, s_u = dz.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import load_exo, load_patient
from exo_ctrl.plant import CuffParams, CuffSet, EndStopParams, Plant

K_N, K_U, C_N, C_U = 8000.0, 3700.0, 100.0, 70.0


@pytest.fixture(scope="module")
def bodies():
    return load_exo(), load_patient(None)


def test_defaults_are_split_and_isotropic_stays_available() -> None:
    p = CuffParams()
    assert (p.stiffness_N_per_m, p.shear_stiffness_N_per_m) == (K_N, K_U)
    assert (p.damping_N_s_per_m, p.shear_damping_N_s_per_m, p.preload_N) == (C_N, C_U, 0.0)
    assert not p.is_isotropic
    iso = CuffParams.isotropic(5000.0, 30.0)
    assert iso.is_isotropic and iso.shear_stiffness_N_per_m == 5000.0
    assert CuffParams(shear_stiffness_N_per_m=None).shear_stiffness_N_per_m == K_N


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"shear_stiffness_N_per_m": -1.0}, "cuff shear stiffness must be > 0 N/m; got -1.0"),
        ({"shear_damping_N_s_per_m": -1.0}, "cuff shear damping must be >= 0 N·s/m; got -1.0"),
        ({"preload_N": -2.0}, "cuff preload must be >= 0 N; got -2.0"),
    ],
)
def test_bad_split_parameters_are_refused(kwargs, message) -> None:
    with pytest.raises(InvalidParameter) as err:
        CuffParams(**kwargs)
    assert str(err.value) == message


def test_shift_along_the_link_gives_k_shear_and_across_k_normal(bodies) -> None:
    exo, patient = bodies
    dx, dz = 0.004, -0.007
    cuffs = CuffSet(exo, patient, CuffParams(), (dx, dz))  # not fitted: r₀ = 0
    force = cuffs.compute(np.zeros(8), np.zeros(8)).copy()
    # f = -k_n s_n n - k_u s_u u with s_n = -dx, s_u = dz, n = +x, u = -z.
    expected = np.array([K_N * dx, K_U * dz])
    print("\nshifted patient: force on each exo cuff [N]", force[0], "hand", expected)
    np.testing.assert_allclose(force, np.tile(expected, (4, 1)), rtol=1e-12)
    iso = CuffSet(exo, patient, CuffParams.isotropic(), (dx, dz))
    np.testing.assert_allclose(
        iso.compute(np.zeros(8), np.zeros(8)), np.tile([K_N * dx, K_N * dz], (4, 1)), rtol=1e-12
    )


def test_damping_along_and_across(bodies) -> None:
    exo, patient = bodies
    cuffs = CuffSet(exo, patient, CuffParams())
    cuffs.fit(np.zeros(8))
    # The patient's left hip turns at w: its thigh cuff moves by w × r = (w a, 0)
    # for a = 0.39 m below the hip (the hip turns +x towards +z, s_h = +1, so a
    # point below moves forward); Δṗ = (-w a, 0), purely across the link.
    w = 0.5
    v = np.zeros(8)
    v[4] = w
    force = cuffs.compute(np.zeros(8), v)
    np.testing.assert_allclose(force[0], [C_N * w * 0.39, 0.0], atol=1e-12)
    # Both bodies' knees straight, the patient's left leg moving down at v_z:
    # no joint moves the point along z at q = 0, so use a shifted straight leg.
    q = np.zeros(8)
    q[[0, 4]] = 0.3  # both thighs turned by 0.3 rad: u = (sin 0.3, -cos 0.3)
    cuffs.fit(q)
    v[:] = 0.0
    v[5] = 1.0  # the patient's knee turns: its shank cuff moves across the shank only
    f = cuffs.compute(q, v)
    u, n = cuffs.directions(q)
    rate = 0.45  # m/s: 0.45 m below the knee at 1 rad/s, along -n (s_k = -1) for the patient
    assert float(f[1] @ u[1]) == pytest.approx(0.0, abs=1e-12)
    assert abs(float(f[1] @ n[1])) == pytest.approx(C_N * rate, rel=1e-12)


def test_preload_presses_each_pad_with_p_at_the_fit(bodies) -> None:
    exo, patient = bodies
    preload = 25.0
    params = CuffParams(preload_N=preload)
    cuffs = CuffSet(exo, patient, params)
    q = np.array([0.3, -0.6, -0.2, -0.1, 0.3, -0.6, -0.2, -0.1])
    cuffs.fit(q)
    np.testing.assert_allclose(cuffs.pad_forces(q), preload, rtol=1e-12)
    np.testing.assert_allclose(cuffs.compute(q, np.zeros(8)), 0.0, atol=1e-9)  # net zero
    # Shifted at q = 0 by dx across the links: both pads touch while |s_n| ≤ 2P / k_n
    # (6.25 mm): net k_n dx; beyond, one lifts off: net P + (k_n / 2)|s_n|.
    for dx, net in ((0.004, K_N * 0.004), (0.01, preload + 0.5 * K_N * 0.01)):
        shifted = CuffSet(exo, patient, params, (dx, 0.0))
        force = shifted.compute(np.zeros(8), np.zeros(8))
        print(f"preload {preload} N, shift {dx} m: net normal force {force[0, 0]:.3f} N")
        assert force[0, 0] == pytest.approx(net, rel=1e-12)
        pads = shifted.pad_forces(np.zeros(8))[0]
        assert pads[1] - pads[0] == pytest.approx(net, rel=1e-12)


@pytest.mark.parametrize("preload", [0.0, 25.0])
def test_torques_are_minus_the_gradient_of_the_spring_energy(bodies, preload) -> None:
    """The moment of a split cuff on its exo link makes the spring conservative."""
    exo, patient = bodies
    cuffs = CuffSet(exo, patient, CuffParams(0.0 + K_N, 0.0, K_U, 0.0, preload))
    rng = np.random.default_rng(3)
    q0 = rng.normal(0.0, 0.4, 8)
    cuffs.fit(q0)
    q = q0 + rng.normal(0.0, 0.05, 8)
    cuffs.compute(q, np.zeros(8))
    tau = cuffs.joint_torque.copy()
    h = 1e-6
    grad = np.array(
        [
            (cuffs.spring_energy(q + h * e) - cuffs.spring_energy(q - h * e)) / (2 * h)
            for e in np.eye(8)
        ]
    )
    np.testing.assert_allclose(tau, -grad, atol=1e-6 * np.max(np.abs(tau)))


def test_passive_energy_is_conserved_with_split_cuffs(bodies) -> None:
    """Undamped split cuffs, no drives or losses: energy drift < 0.1 % over 2 s at 1 ms."""
    exo, patient = bodies
    plant = Plant(
        exo,
        patient,
        motors=None,
        cuffs=CuffParams(K_N, 0.0, K_U, 0.0),
        joint_losses=False,
        end_stops=EndStopParams(enabled=False),  # a non-smooth contact: off
    )
    plant.reset(np.zeros(4), np.zeros(4))
    e_rest = plant.mechanical_energy()
    bent = np.array([0.8, 1.2, -0.3, 0.6])  # within the knees' range (flexion +)
    plant.reset(bent, np.zeros(4))  # both bent, straps fitted there, then released
    e0 = plant.mechanical_energy()
    assert e0 - e_rest > 5.0
    worst = stretch = 0.0
    for _ in range(2000):
        plant.step(np.zeros(4))
        worst = max(worst, abs(plant.mechanical_energy() - e0))
        stretch = max(stretch, float(np.max(np.abs(plant.cuffs.link_frame_offsets(plant.q)))))
    assert stretch > 0.002  # the two bodies part by millimetres: the cuffs work
    print(f"\nsplit cuffs, passive: energy above rest {e0 - e_rest:.2f} J, drift {worst:.2e} J")
    assert worst < 1e-3 * (e0 - e_rest)


def test_the_fit_attaches_the_limb_under_the_shell(bodies) -> None:
    """Split cuffs fitted with the bodies apart: slack at the fit, no moment, and the patient's
    point is then the material point of its link that lay under the exoskeleton's cuff (from
    Pinocchio's joint placements, not the CuffSet's matrices); a second fit elsewhere is the
    same as a first one there."""
    exo, patient = bodies
    rng = np.random.default_rng(5)
    q0 = rng.normal(0.0, 0.4, 8)  # exo and patient in different postures: the points apart
    cuffs = CuffSet(exo, patient, CuffParams())
    cuffs.fit(q0)
    np.testing.assert_allclose(cuffs.compute(q0, np.zeros(8)), 0.0, atol=1e-9)
    np.testing.assert_allclose(cuffs.joint_torque, 0.0, atol=1e-9)
    np.testing.assert_allclose(cuffs.rest_along, 0.0, atol=1e-15)
    d_e, d_p = exo.model.createData(), patient.model.createData()
    pin.framesForwardKinematics(exo.model, d_e, q0[:4])
    pin.framesForwardKinematics(patient.model, d_p, q0[4:])
    joints = [patient.model.frames[f].parentJoint for f in patient.cuff_frame_ids]
    at_fit = [d_e.oMf[f].translation for f in exo.cuff_frame_ids]
    local = [d_p.oMi[j].actInv(p) for j, p in zip(joints, at_fit, strict=True)]
    q = q0 + rng.normal(0.0, 0.2, 8)
    pin.framesForwardKinematics(patient.model, d_p, q[4:])
    held = np.array([d_p.oMi[j].act(x)[[0, 2]] for j, x in zip(joints, local, strict=True)])
    np.testing.assert_allclose(cuffs.positions(q)[1], held, atol=1e-12)
    refit = CuffSet(exo, patient, CuffParams())
    refit.fit(q)
    refit.fit(q0)
    np.testing.assert_array_equal(refit.positions(q)[1], cuffs.positions(q)[1])
