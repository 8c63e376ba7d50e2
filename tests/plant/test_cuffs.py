"""Cuffs: kinematics against Pinocchio, forces against their definition, energy.

Independent references used here: Pinocchio's frame placements and frame
Jacobians (``LOCAL_WORLD_ALIGNED``, rows x and z), finite differences of the
frame positions, and the spring energy V = ½ K Σ |Δp − r₀|² computed from
Pinocchio's positions.  Forces on the exoskeleton are laid out (4 cuffs, x z)
in :data:`~exo_ctrl.model.CUFF_NAMES` order.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import BodyModel, default_urdf_path, load_body
from exo_ctrl.plant.cuffs import CuffParams, CuffSet
from exo_ctrl.plant.plant import Plant

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
XZ = [0, 2]


@pytest.fixture(scope="module")
def patient() -> BodyModel:
    """The committed default patient."""
    return load_body(default_urdf_path("patient"), name="patient")


def hip_offset(exo: BodyModel, patient: BodyModel) -> np.ndarray:
    """Shift (x, z) putting the patient's left hip on the exoskeleton's, from Pinocchio."""
    hips = []
    for body in (exo, patient):
        data = body.model.createData()
        pin.forwardKinematics(body.model, data, pin.neutral(body.model))
        hips.append(data.oMi[body.joint_ids[0]].translation[XZ])
    return hips[0] - hips[1]


def pin_cuffs(body: BodyModel, q: np.ndarray, offset=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
    """Cuff points (4, 2) and their Jacobians ∂(x, z)/∂q (4, 2, 4) from Pinocchio."""
    model = body.model
    data = model.createData()
    qm = body.to_model_q(q)
    pin.framesForwardKinematics(model, data, qm)
    pos = np.zeros((4, 2))
    jac = np.zeros((4, 2, 4))
    for c, fid in enumerate(body.cuff_frame_ids):
        pos[c] = data.oMf[fid].translation[XZ] + np.asarray(offset)
        full = pin.computeFrameJacobian(model, data, qm, fid, LWA)
        jac[c] = full[XZ][:, body.q_index]
    return pos, jac


def stretch_pin(exo, patient, offset, q_all, rest=None) -> np.ndarray:
    """Δp − r₀ (4, 2) from Pinocchio; r₀ = Δp at the posture ``rest`` (None: r₀ = 0)."""
    d = pin_cuffs(exo, q_all[:4])[0] - pin_cuffs(patient, q_all[4:], offset)[0]
    if rest is not None:
        d -= pin_cuffs(exo, rest[:4])[0] - pin_cuffs(patient, rest[4:], offset)[0]
    return d


def random_q(rng: np.random.Generator, n: int = 8) -> np.ndarray:
    """Joint angles in the flexion ranges: hips in (-0.5, 1.5), knees in (0, 2) rad."""
    lo = np.tile([-0.5, 0.0], n // 2)
    hi = np.tile([1.5, 2.0], n // 2)
    return rng.uniform(lo, hi)


@pytest.fixture(params=["default", "human"])
def pair(request, exo, patient, human):
    """(exo, patient, patient offset) for the default patient and the human model."""
    pat = patient if request.param == "default" else human
    return exo, pat, hip_offset(exo, pat)


def test_plant_puts_the_patients_hips_on_the_exoskeletons(exo, patient, human) -> None:
    for pat in (patient, human):
        plant = Plant(exo, pat, motors=None)
        offset = np.asarray(plant.patient_offset_xz)
        np.testing.assert_allclose(offset, hip_offset(exo, pat), atol=1e-12)
        for side in ("left", "right"):
            hip_e = np.asarray(exo.legs[side].hip_xz)
            hip_p = np.asarray(pat.legs[side].hip_xz) + offset
            np.testing.assert_allclose(hip_p, hip_e, atol=1e-12)
    # The human's hips are not where the exoskeleton's are without the shift.
    assert np.linalg.norm(hip_offset(exo, human)) > 0.05


def test_positions_and_jacobians_match_pinocchio(pair) -> None:
    exo, pat, offset = pair
    cuffs = CuffSet(exo, pat, CuffParams.isotropic(), tuple(offset))
    rng = np.random.default_rng(1)
    for _ in range(10):
        q_all = random_q(rng)
        pos_e, jac_e = pin_cuffs(exo, q_all[:4])
        pos_p, jac_p = pin_cuffs(pat, q_all[4:], offset)
        pos = cuffs.positions(q_all)
        jac = cuffs.jacobians(q_all)
        assert pos.shape == (2, 4, 2) and jac.shape == (2, 4, 2, 8)
        np.testing.assert_allclose(pos[0], pos_e, atol=1e-12)
        np.testing.assert_allclose(pos[1], pos_p, atol=1e-12)
        np.testing.assert_allclose(jac[0, :, :, :4], jac_e, atol=1e-12)
        np.testing.assert_allclose(jac[1, :, :, 4:], jac_p, atol=1e-12)
        # A body's cuff points do not depend on the other body's joints.
        assert not np.any(jac[0, :, :, 4:]) and not np.any(jac[1, :, :, :4])


def test_zero_force_when_the_frames_coincide(exo, patient) -> None:
    # The default exoskeleton and patient have the same link lengths, cuff
    # distances and hips: at equal joint states the cuff frames coincide.
    cuffs = CuffSet(exo, patient, CuffParams.isotropic(), (0.0, 0.0))
    rng = np.random.default_rng(2)
    for _ in range(10):
        q = random_q(rng, 4)
        v = rng.uniform(-5.0, 5.0, 4)
        q_all, v_all = np.concatenate((q, q)), np.concatenate((v, v))
        pos = cuffs.positions(q_all)
        np.testing.assert_allclose(pos[0], pos[1], atol=1e-14)
        f = np.array(cuffs.compute(q_all, v_all))
        np.testing.assert_allclose(f, 0.0, atol=1e-9)
        np.testing.assert_allclose(cuffs.joint_torque, 0.0, atol=1e-9)
    # Fitting at one equal posture keeps every equal posture slack.
    cuffs.fit(np.concatenate((q, q)))
    q2 = random_q(rng, 4)
    f = np.array(cuffs.compute(np.concatenate((q2, q2)), np.zeros(8)))
    np.testing.assert_allclose(f, 0.0, atol=1e-9)


def test_fitting_makes_the_present_posture_slack(exo, human) -> None:
    offset = hip_offset(exo, human)
    cuffs = CuffSet(exo, human, CuffParams.isotropic(), tuple(offset))
    q = np.array([0.4, 0.9, -0.2, 0.3])
    q_all = np.concatenate((q, q))
    # The human's links differ from the exoskeleton's: unfitted, the straps pull.
    assert np.max(np.abs(cuffs.compute(q_all, np.zeros(8)))) > 10.0
    cuffs.fit(q_all)
    np.testing.assert_allclose(cuffs.compute(q_all, np.zeros(8)), 0.0, atol=1e-9)
    other = np.concatenate((q, q + 0.1))
    assert np.max(np.abs(cuffs.compute(other, np.zeros(8)))) > 10.0


def test_spring_force_is_minus_k_times_the_stretch(pair) -> None:
    exo, pat, offset = pair
    params = CuffParams.isotropic(8000.0, 100.0)
    cuffs = CuffSet(exo, pat, params, tuple(offset))
    rng = np.random.default_rng(3)
    fit_q = random_q(rng)
    cuffs.fit(fit_q)
    for _ in range(5):
        q = random_q(rng, 4)
        q_all = np.concatenate((q, q + rng.uniform(-0.1, 0.1, 4)))
        f = np.array(cuffs.compute(q_all, np.zeros(8)))
        expected = -params.stiffness_N_per_m * stretch_pin(exo, pat, offset, q_all, rest=fit_q)
        np.testing.assert_allclose(f, expected, rtol=1e-10, atol=1e-9)
        np.testing.assert_array_equal(cuffs.force, f)


def test_damping_force_is_minus_c_times_the_relative_velocity(pair) -> None:
    exo, pat, offset = pair
    params = CuffParams.isotropic(8000.0, 150.0)
    cuffs = CuffSet(exo, pat, params, tuple(offset))
    rng = np.random.default_rng(4)
    eps = 1e-6
    for _ in range(5):
        q_all = random_q(rng)
        v_all = rng.uniform(-3.0, 3.0, 8)
        f_moving = np.array(cuffs.compute(q_all, v_all))
        f_still = np.array(cuffs.compute(q_all, np.zeros(8)))
        # Δṗ by a central difference of Pinocchio's positions along q + s v.
        d_plus = stretch_pin(exo, pat, offset, q_all + eps * v_all)
        d_minus = stretch_pin(exo, pat, offset, q_all - eps * v_all)
        dp_dot = (d_plus - d_minus) / (2.0 * eps)
        np.testing.assert_allclose(
            f_moving - f_still, -params.damping_N_s_per_m * dp_dot, rtol=1e-6, atol=1e-6
        )


def test_forces_are_equal_and_opposite_through_the_frame_jacobians(pair) -> None:
    exo, pat, offset = pair
    cuffs = CuffSet(exo, pat, CuffParams.isotropic(), tuple(offset))
    rng = np.random.default_rng(5)
    cuffs.fit(random_q(rng))
    for _ in range(5):
        q_all = random_q(rng)
        v_all = rng.uniform(-3.0, 3.0, 8)
        f = np.array(cuffs.compute(q_all, v_all))
        assert np.max(np.abs(f)) > 1.0  # a real force, not a trivial zero
        _, jac_e = pin_cuffs(exo, q_all[:4])
        _, jac_p = pin_cuffs(pat, q_all[4:], offset)
        tau_exo = np.einsum("cki,ck->i", jac_e, f)  # Σ_c J_eᵀ f_c
        tau_pat = -np.einsum("cki,ck->i", jac_p, f)  # Σ_c J_pᵀ (−f_c)
        np.testing.assert_allclose(cuffs.joint_torque[:4], tau_exo, rtol=1e-10, atol=1e-9)
        np.testing.assert_allclose(cuffs.joint_torque[4:], tau_pat, rtol=1e-10, atol=1e-9)


def spring_energy(exo, pat, offset, k, q_all, rest) -> float:
    """V = ½ K Σ |Δp − r₀|² from Pinocchio's frame positions [J]."""
    d = stretch_pin(exo, pat, offset, q_all, rest=rest)
    return 0.5 * k * float(np.sum(d**2))


def test_cuff_torque_is_minus_the_gradient_of_the_spring_energy(pair) -> None:
    exo, pat, offset = pair
    params = CuffParams.isotropic(8000.0, 100.0)
    cuffs = CuffSet(exo, pat, params, tuple(offset))
    rng = np.random.default_rng(6)
    rest = random_q(rng)
    cuffs.fit(rest)
    eps = 1e-6
    for _ in range(3):
        q_all = rest + rng.uniform(-0.2, 0.2, 8)
        cuffs.compute(q_all, np.zeros(8))
        grad = np.zeros(8)
        for i in range(8):
            dq = np.zeros(8)
            dq[i] = eps
            grad[i] = (
                spring_energy(exo, pat, offset, params.stiffness_N_per_m, q_all + dq, rest)
                - spring_energy(exo, pat, offset, params.stiffness_N_per_m, q_all - dq, rest)
            ) / (2.0 * eps)
        assert np.max(np.abs(grad)) > 1.0
        np.testing.assert_allclose(cuffs.joint_torque, -grad, rtol=1e-6, atol=1e-5)


def test_no_net_work_around_a_closed_loop_at_zero_speed_and_loss_with_damping(pair) -> None:
    exo, pat, offset = pair
    params = CuffParams.isotropic(8000.0, 100.0)
    cuffs = CuffSet(exo, pat, params, tuple(offset))
    rng = np.random.default_rng(7)
    centre = random_q(rng)
    cuffs.fit(centre + rng.uniform(-0.05, 0.05, 8))
    a, b = rng.uniform(-0.15, 0.15, (2, 8))
    n = 400
    s = np.arange(n) * 2.0 * np.pi / n
    spring_work = 0.0  # ∮ τ · dq with the cuffs at rest (quasi-static loop)
    spring_scale = 0.0  # ∮ |τ · dq|, for the relative size
    damping_work = 0.0  # the same loop run at one radian of s per second
    for si in s:
        q = centre + a * np.cos(si) + b * np.sin(si)
        dq_ds = -a * np.sin(si) + b * np.cos(si)
        cuffs.compute(q, np.zeros(8))
        tau_still = cuffs.joint_torque.copy()
        cuffs.compute(q, dq_ds)
        power = float(tau_still @ dq_ds)
        spring_work += power
        spring_scale += abs(power)
        damping_work += float((cuffs.joint_torque - tau_still) @ dq_ds)
    ds = 2.0 * np.pi / n  # the periodic trapezoid rule is spectrally accurate
    spring_work *= ds
    spring_scale *= ds
    damping_work *= ds
    assert spring_scale > 1.0
    assert abs(spring_work) < 1e-9 * spring_scale
    # The damper only takes energy out: its power −C |Δṗ|² is never positive.
    assert damping_work < -1e-3


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"stiffness_N_per_m": 0}, "cuff stiffness must be > 0 N/m; got 0"),
        ({"stiffness_N_per_m": -8000.0}, "cuff stiffness must be > 0 N/m; got -8000.0"),
        (
            {"stiffness_N_per_m": float("nan")},
            "cuff stiffness must be a finite number [N/m]; got nan",
        ),
        ({"damping_N_s_per_m": -1}, "cuff damping must be >= 0 N·s/m; got -1"),
        (
            {"damping_N_s_per_m": float("inf")},
            "cuff damping must be a finite number [N·s/m]; got inf",
        ),
    ],
)
def test_bad_cuff_parameters_exact_messages(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        CuffParams(**kwargs)
    assert str(info.value) == message
    assert isinstance(info.value, ValueError)


def test_zero_damping_is_allowed() -> None:
    assert CuffParams(damping_N_s_per_m=0.0).damping_N_s_per_m == 0.0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"stiffness_N_per_m": "8000"}, "cuff stiffness must be a finite number [N/m]; got '8000'"),
        ({"stiffness_N_per_m": b"8e3"}, "cuff stiffness must be a finite number [N/m]; got b'8e3'"),
        ({"stiffness_N_per_m": True}, "cuff stiffness must be a finite number [N/m]; got True"),
        ({"damping_N_s_per_m": "100"}, "cuff damping must be a finite number [N·s/m]; got '100'"),
        ({"damping_N_s_per_m": False}, "cuff damping must be a finite number [N·s/m]; got False"),
        (
            {"damping_N_s_per_m": np.bool_(False)},
            "cuff damping must be a finite number [N·s/m]; got np.False_",
        ),
    ],
)
def test_cuff_parameters_refuse_text_and_bools(kwargs: dict, message: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        CuffParams(**kwargs)
    assert str(info.value) == message


def test_cuff_parameters_are_stored_as_floats() -> None:
    params = CuffParams(stiffness_N_per_m=8000, damping_N_s_per_m=np.float32(50.0))
    assert params == CuffParams(8000.0, 50.0)
    assert type(params.stiffness_N_per_m) is float and type(params.damping_N_s_per_m) is float
