"""Misaligned joints in the truth, and what they cost the estimate (exo_ctrl/plant/misalignment.py).

- a static hand calculation of the along-link cuff force a knee offset
  implies, against the plant's cuffs;
- the start's settle with a misaligned patient, against an independent
  minimisation of the patient's potential energy;
- the estimate's whole-force metric and the old normal-over-peak one on the
  default run and under 2 cm of knee misalignment (both printed), against the
  figures computed here from the logged signals;
- exact messages for bad options.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.optimize import minimize

from exo_ctrl.cli import main as cli_main
from exo_ctrl.estimation import ESTIMATORS, MODEL_DRIVEN
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import BodyModel, load_exo, load_patient
from exo_ctrl.plant import CuffParams, Misalignment, misaligned_patient
from exo_ctrl.plant.cuff_scatter import CuffScatter
from exo_ctrl.sim import SimConfig, build, simulate, start_on_plan

K_N, K_U = CuffParams().stiffness_N_per_m, CuffParams().shear_stiffness_N_per_m
KNEE_2CM = Misalignment(knee_xz=(0.0, 0.02))
EXACT = CuffScatter.exact()


def rot(theta: float) -> np.ndarray:
    """R(θ): turns +x towards +z by θ (the link rotations of cuffs.py)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def test_knee_offset_changes_the_thigh_and_moves_the_joint_not_the_cuffs() -> None:
    patient = load_patient(None)
    moved = misaligned_patient(patient, Misalignment((0.01, 0.0), (0.0, 0.02)))
    assert patient.legs["left"].thigh_length == pytest.approx(0.52)
    # Hip → knee: the exo's (0, -0.52) plus d_k - d_h = (-0.01, 0.02).
    assert moved.legs["left"].thigh_length == pytest.approx(np.hypot(0.01, 0.50), rel=1e-12)
    q = np.zeros(4)
    # With the hips aligned by the plant, both cuffs sit -d_h from the exo's (the
    # whole patient is d_h off) and the knee d_k - d_h.
    knee_before = patient.frame_position(q, "left_knee")[[0, 2]]
    knee_after = moved.frame_position(q, "left_knee")[[0, 2]]
    np.testing.assert_allclose(knee_after - knee_before, (-0.01, 0.02), atol=1e-15)
    for frame, shift in (("left_thigh_cuff", (-0.01, 0.0)), ("left_shank_cuff", (-0.01, 0.0))):
        before = patient.frame_position(q, frame)[[0, 2]]
        after = moved.frame_position(q, frame)[[0, 2]]
        np.testing.assert_allclose(after - before, shift, atol=1e-15)  # relative to the hip
    assert misaligned_patient(patient, Misalignment()) is patient


def test_along_shank_force_of_a_knee_offset_is_the_hand_calculation() -> None:
    """Both shanks turned by β from the fit: Δp = (R(θ) - I) d_k, f = -k_n s_n n - k_u s_u u."""
    # The published cuffs exactly (K_N, K_U), not a patient's scattered ones.
    setup = build(SimConfig(misalignment=KNEE_2CM, duration_s=0.1, cuff_scatter=EXACT))
    cuffs, leg = setup.plant.cuffs, setup.exo.legs["left"]
    cuffs.fit(np.zeros(8))
    d_k = np.array([0.0, 0.02])
    for knee in (0.3, 0.8, 1.2):  # flexion [rad]
        q = np.zeros(8)
        q[[1, 3, 5, 7]] = knee
        theta = leg.sign_knee * knee
        u = rot(theta) @ np.array([0.0, -1.0])  # the shank hangs straight at q = 0
        n = np.array([-u[1], u[0]])
        dp = (rot(theta) - np.eye(2)) @ d_k
        hand = -K_N * (n @ dp) * n - K_U * (u @ dp) * u
        force = cuffs.compute(q, np.zeros(8))
        print(
            f"\nknee {knee} rad, 2 cm knee offset: shank cuff along {force[1] @ u:.3f} N "
            f"(hand {-K_U * (u @ dp):.3f}), normal {force[1] @ n:.3f} N; thigh {force[0]} N"
        )
        np.testing.assert_allclose(force[1], hand, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(force[0], 0.0, atol=1e-10)  # thighs unmoved: coaxial hips
        # Along the shank: -k_u u₀ · (I - R(θ)ᵀ) d_k = k_u (0.02)(1 - cos θ) for u₀ = -z.
        assert force[1] @ u == pytest.approx(K_U * 0.02 * (1.0 - np.cos(theta)), rel=1e-12)


def independent_settle(
    exo: BodyModel, patient: BodyModel, q0: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The patient's rest posture and the cuff forces, minimising V = Σ m g z + Σ ½ sᵀ K s.

    Straps fitted with both at q0, the exo held there: each strap holds the
    patient's material point under the exo's cuff at q0 (fixed in the parent
    joint's frame of the patient's cuff frame), s = p_exo(q0) - p_att(q) (exo
    minus patient, from the fit), K = k_n n nᵀ + k_u u uᵀ in the exo link's
    frame at q0.  No CuffSet involved.
    """
    data, exo_data = patient.model.createData(), exo.model.createData()
    pin.framesForwardKinematics(exo.model, exo_data, q0)
    pin.framesForwardKinematics(patient.model, data, q0)
    joints = [patient.model.frames[f].parentJoint for f in patient.cuff_frame_ids]
    exo_at_fit = [exo_data.oMf[f].translation for f in exo.cuff_frame_ids]
    local = [data.oMi[j].actInv(p) for j, p in zip(joints, exo_at_fit, strict=True)]

    def points(body: BodyModel, d: pin.Data, q: np.ndarray) -> np.ndarray:
        pin.framesForwardKinematics(body.model, d, q)
        if body is patient:  # the material points the straps hold
            return np.array([d.oMi[j].act(x)[[0, 2]] for j, x in zip(joints, local, strict=True)])
        return np.array([d.oMf[f].translation[[0, 2]] for f in body.cuff_frame_ids])

    stiff = []
    exo_points = points(exo, exo_data, q0)
    for c in range(4):
        arm = exo_points[c] - exo_data.oMi[exo.joint_ids[c]].translation[[0, 2]]
        u = arm / np.linalg.norm(arm)
        n = np.array([-u[1], u[0]])
        stiff.append(K_N * np.outer(n, n) + K_U * np.outer(u, u))
    stiff = np.array(stiff)
    base = points(patient, data, q0)

    def energy(q: np.ndarray) -> float:
        s = base - points(patient, data, q)
        v = float(pin.computePotentialEnergy(patient.model, data, q))
        return v + 0.5 * float(np.einsum("ci,cij,cj->", s, stiff, s))

    q = minimize(energy, q0, method="BFGS", options={"gtol": 1e-10, "xrtol": 1e-12}).x
    return q, -np.einsum("cij,cj->ci", stiff, base - points(patient, data, q))


def test_settle_with_a_misaligned_knee_is_the_independent_equilibrium() -> None:
    config = SimConfig(misalignment=KNEE_2CM, duration_s=0.1, cuff_scatter=EXACT)  # K_N, K_U
    setup = build(config)
    start_on_plan(setup)
    plant = setup.plant
    q0 = plant.q[:4].copy()
    q_p, force = independent_settle(load_exo(), setup.patient, q0)
    u, _ = plant.cuffs.directions(plant.q)
    along = np.sum(plant.cuff_force * u, axis=-1)
    print("\nsettled with 2 cm knee offset: along-link cuff forces [N]", np.round(along, 3))
    print("  independent [N]", np.round(np.sum(force * u, axis=-1), 3))
    np.testing.assert_allclose(plant.q[4:], q_p, atol=1e-4)
    np.testing.assert_allclose(plant.cuff_force, force, atol=0.2)
    assert np.all(plant.v == 0.0)


def logged_metrics(result, skip: int) -> dict[str, np.ndarray]:
    """The whole-force and normal figures from the logged signals (estimate k vs truth k-1)."""
    s = result.signals
    est, truth = s["cuff_force_est"][skip:], s["cuff_force"][skip - 1 : -1]
    err = np.sqrt(np.mean(np.sum((est - truth) ** 2, axis=-1), axis=0))
    rms_true = np.sqrt(np.mean(np.sum(truth**2, axis=-1), axis=0))
    # Normal: n of the exo link at the estimate's row, from the true angles.
    exo = load_exo()
    geometry_q = s["q"][skip:]
    u = np.zeros((geometry_q.shape[0], 4, 2))
    for c, (side, link) in enumerate((("l", "t"), ("l", "s"), ("r", "t"), ("r", "s"))):
        leg = exo.legs["left" if side == "l" else "right"]
        hip, knee = geometry_q[:, 2 * (c // 2)], geometry_q[:, 2 * (c // 2) + 1]
        theta = leg.sign_hip * hip + (leg.sign_knee * knee if link == "s" else 0.0)
        u[:, c] = np.stack((np.sin(theta), -np.cos(theta)), axis=-1)  # -z turned by θ
    n = np.stack((-u[..., 1], u[..., 0]), axis=-1)
    normal_truth = np.sum(truth * n, axis=-1)
    normal_err = s["cuff_normal_est"][skip:] - normal_truth
    over_peak = np.sqrt(np.mean(normal_err**2, axis=0)) / np.max(np.abs(normal_truth), axis=0)
    return {"vector_N": err, "vector_rel": err / rms_true, "normal_over_peak": over_peak}


@pytest.mark.parametrize("estimator", ESTIMATORS)
@pytest.mark.parametrize("misalignment", [Misalignment(), KNEE_2CM], ids=["default", "knee_2cm"])
def test_new_and_old_estimate_metrics_against_the_logged_signals(misalignment, estimator) -> None:
    config = SimConfig(misalignment=misalignment, estimator=estimator)
    result = simulate(config)
    summary = result.summary()
    mine = logged_metrics(result, skip=round(0.05 / config.dt))
    names = list(summary["cuff_force_estimate_rms_error_rel"])
    new = np.array([summary["cuff_force_estimate_rms_error_rel"][c] for c in names])
    old = np.array([summary["cuff_force_estimate_normal_rms_over_peak"][c] for c in names])
    err = np.array([summary["cuff_force_estimate_rms_error_N"][c] for c in names])
    print(f"\n{misalignment}, {estimator}: per cuff {names}")
    print("  whole-force RMS error / RMS true force", np.round(new, 4))
    print("  normal RMS error / peak (the old metric)", np.round(old, 4))
    np.testing.assert_allclose(new, mine["vector_rel"], rtol=1e-9)
    np.testing.assert_allclose(err, mine["vector_N"], rtol=1e-9)
    np.testing.assert_allclose(old, mine["normal_over_peak"], rtol=1e-9)
    assert np.all(new > old)  # the along-link components the old metric left out
    if estimator == "kalman":  # every component estimated; these from its models
        assert summary["cuff_force_estimate_unobservable"] == MODEL_DRIVEN
    else:
        unobservable = summary["cuff_force_estimate_unobservable"]
        assert unobservable[0].startswith("left_thigh: along the thigh")


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("abc", "--misalignment-knee must be 2 comma-separated numbers; got 'abc'"),
        ("0.01", "--misalignment-knee must be 2 comma-separated numbers; got '0.01'"),
        (
            "0.5,0",
            "scenario preset paper-free-air: misalignment_knee: must be two numbers DX,DZ in "
            "[-0.1, 0.1] m; got (0.5, 0.0)",
        ),
        (
            "nan,0",
            "scenario preset paper-free-air: misalignment_knee: must be two numbers DX,DZ in "
            "[-0.1, 0.1] m; got (nan, 0.0)",
        ),
    ],
)
def test_bad_misalignment_option_exits_2_with_one_line(value, message, capsys) -> None:
    code = cli_main(["simulate", "--misalignment-knee", value, "--no-record", "--duration", "0.1"])
    err = capsys.readouterr().err
    assert code == 2
    assert err == f"exo-ctrl simulate: error: {message}\n"


def test_misalignment_refuses_bad_values() -> None:
    with pytest.raises(InvalidParameter) as e:
        Misalignment(hip_xz=(0.0, 0.2))
    assert (
        str(e.value)
        == "misalignment_hip must be two numbers DX,DZ in [-0.1, 0.1] m; got (0.0, 0.2)"
    )
