"""The coupled model's Kalman filter (exo_ctrl/estimation/kalman.py).

- at a static equilibrium the estimated cuff forces, all eight components,
  converge from a wrong start to those of an independent minimisation of the
  patient's potential energy (no CuffSet, no filter);
- there, F and Q are constant and the filter's covariance converges to the
  solution of the discrete algebraic Riccati equation (scipy's);
- the linearised cuff stiffness of F against central differences of the
  cuff forces;
- NaN readings do not poison the filter, bad shapes and parameters are refused.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from scipy.linalg import solve_discrete_are
from scipy.optimize import minimize

from exo_ctrl.estimation import CuffForceKalman, KalmanNoise
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import BodyModel, load_exo, load_patient
from exo_ctrl.plant import CuffParams
from exo_ctrl.sensing import SensorParams

DT = 1e-3
Q0 = np.array([0.3, 0.6, -0.2, 0.4])  # a bent standing posture [rad]
CUFFS = CuffParams()  # the split cuffs: 8 N/mm across, 3.7 N/mm along


def static_truth(exo: BodyModel, patient: BodyModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Patient angles, cuff forces (4, 2) and holding sensor torques, minimising V.

    V = Σ m g z + Σ ½ sᵀ K s, the straps fitted with both at Q0, the exo held
    there: s = p_p(Q0) − p_p(q) (exo minus patient), K = k_n n nᵀ + k_u u uᵀ in
    the exo link's frame.  The sensor torques holding the exo: τ = g_e − J_eᵀ f.
    """
    data, exo_data = patient.model.createData(), exo.model.createData()
    pin.framesForwardKinematics(exo.model, exo_data, Q0)

    def points(body: BodyModel, d: pin.Data, q: np.ndarray) -> np.ndarray:
        pin.framesForwardKinematics(body.model, d, q)
        return np.array([d.oMf[f].translation[[0, 2]] for f in body.cuff_frame_ids])

    stiff = []
    exo_points = points(exo, exo_data, Q0)
    for c in range(4):
        arm = exo_points[c] - exo_data.oMi[exo.joint_ids[c]].translation[[0, 2]]
        u = arm / np.linalg.norm(arm)
        n = np.array([-u[1], u[0]])
        k_u = CUFFS.shear_stiffness_N_per_m
        stiff.append(CUFFS.stiffness_N_per_m * np.outer(n, n) + k_u * np.outer(u, u))
    stiff = np.array(stiff)
    base = points(patient, data, Q0)

    def energy(q: np.ndarray) -> float:
        s = base - points(patient, data, q)
        v = float(pin.computePotentialEnergy(patient.model, data, q))
        return v + 0.5 * float(np.einsum("ci,cij,cj->", s, stiff, s))

    q_p = minimize(energy, Q0, method="BFGS", options={"gtol": 1e-10, "xrtol": 1e-12}).x
    force = -np.einsum("cij,cj->ci", stiff, base - points(patient, data, q_p))
    pin.computeJointJacobians(exo.model, exo_data, Q0)
    pin.framesForwardKinematics(exo.model, exo_data, Q0)
    tau = pin.computeGeneralizedGravity(exo.model, exo_data, Q0).copy()
    for c, frame in enumerate(exo.cuff_frame_ids):
        jac = pin.getFrameJacobian(exo.model, exo_data, frame, pin.LOCAL_WORLD_ALIGNED)
        tau -= jac[[0, 2]].T @ force[c]
    return q_p, force, tau


@pytest.fixture(scope="module")
def models() -> dict:
    exo, patient = load_exo(None), load_patient(None)
    q_p, force, tau = static_truth(exo, patient)
    return {"exo": exo, "patient": patient, "q_p": q_p, "force": force, "tau": tau}


def kalman(models: dict) -> CuffForceKalman:
    return CuffForceKalman(
        models["exo"], models["patient"], DT, cuffs=CUFFS, sensors=SensorParams()
    )


def start_wrong(est: CuffForceKalman, models: dict) -> None:
    """Start at the static readings, then put the patient 0.02 rad and 3 N·m off."""
    est.step(Q0, np.zeros(4), models["tau"])
    est.record["q"][0, 4:] += 0.02
    est.record["d"][0] += 3.0


def test_static_forces_converge_to_the_independent_equilibrium(models) -> None:
    est = kalman(models)
    start_wrong(est, models)
    est.step(Q0, np.zeros(4), models["tau"])
    start_error = np.abs(est.force - models["force"]).max()
    for _ in range(3000):
        est.step(Q0, np.zeros(4), models["tau"])
    u = models["force"]  # components along each exo link, for the print
    along = est.along
    print(f"\nstatic: estimate {np.round(est.force, 3).tolist()} N")
    print(f"  independent {np.round(u, 3).tolist()} N; along-link estimate {np.round(along, 3)}")
    print(f"  largest error {start_error:.2f} N after the wrong start, then "
          f"{np.abs(est.force - u).max():.2e} N")  # fmt: skip
    assert start_error > 5.0
    np.testing.assert_allclose(est.force, models["force"], atol=0.05)
    np.testing.assert_allclose(est.record["q"][0, 4:], models["q_p"], atol=5e-5)
    np.testing.assert_allclose(est.record["d"][0], 0.0, atol=0.05)
    # τ_ext = J_eᵀ f: what holds the exo, g_e − τ_s.
    exo = models["exo"]
    gravity = pin.computeGeneralizedGravity(exo.model, exo.model.createData(), Q0)
    np.testing.assert_allclose(est.tau_ext, gravity - models["tau"], atol=0.02)


def test_covariance_converges_to_the_riccati_solution(models) -> None:
    est = kalman(models)
    start_wrong(est, models)
    rec = est.record
    for _ in range(20000):
        previous = rec["cov"][0].copy()
        est.step(Q0, np.zeros(4), models["tau"])
    h = np.zeros((2, 10))
    h[0, 0] = h[1, 1] = 1.0
    r = float(rec["var_q"][0]) * np.eye(2)
    for leg in range(2):
        f, q = rec["F"][0, leg], rec["Q"][0, leg]
        prior = f @ previous[leg] @ f.T + q  # the filter's P⁻ of the last step
        dare = solve_discrete_are(f.T, h.T, q, r)
        scale = np.sqrt(np.outer(np.diag(dare), np.diag(dare)))
        print(f"\nleg {leg}: largest |P⁻ − DARE| / √(X_ii X_jj) = "
              f"{np.max(np.abs(prior - dare) / scale):.2e}")  # fmt: skip
        np.testing.assert_allclose(prior / scale, dare / scale, atol=1e-6)
        gain = dare @ h.T @ np.linalg.inv(h @ dare @ h.T + r)
        posterior = dare - gain @ h @ dare
        np.testing.assert_allclose(rec["cov"][0, leg] / scale, posterior / scale, atol=1e-6)


def test_linearised_cuff_stiffness_against_central_differences(models) -> None:
    """∂τ_c/∂q of F (links' frames held) against differences of the cuff torques at rest.

    At the fit (no stretch) the links' turning frames add nothing, so the
    linearisation is exact there.
    """
    est = kalman(models)
    q_all = np.concatenate((Q0, Q0))
    est.step(Q0, np.zeros(4), np.zeros(4))  # start (fits the cuffs at Q0, Q0)
    rec = est.record
    cuffs = est.cuffs
    rec["q"][0] = q_all
    rec["v"][0] = 0.0
    est.step(Q0, np.zeros(4), np.zeros(4))
    eps = 1e-7
    for leg in range(2):
        joints = rec["joints"][0, leg]
        a_q = rec["F"][0, leg, 4:8, 0:4] / DT  # h M⁻¹ ∂τ/∂q / h
        exo_mass = pin.crba(est.models[0][0], est.models[0][1], Q0)
        pat_mass = pin.crba(est.models[1][0], est.models[1][1], Q0)
        mass = np.zeros((4, 4))
        mass[:2, :2] = exo_mass[np.ix_(joints[:2], joints[:2])]
        mass[2:, 2:] = pat_mass[np.ix_(joints[2:] - 4, joints[2:] - 4)]
        stiffness = mass @ a_q
        fd = np.zeros((4, 4))
        for j, g in enumerate(joints):
            dq = np.zeros(8)
            dq[g] = eps
            cuffs.compute(q_all + dq, np.zeros(8))
            plus = cuffs.joint_torque[joints].copy()
            cuffs.compute(q_all - dq, np.zeros(8))
            fd[:, j] = (plus - cuffs.joint_torque[joints]) / (2 * eps)
        np.testing.assert_allclose(stiffness, fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())


def test_nan_readings_do_not_poison_the_filter(models) -> None:
    est = kalman(models)
    est.step(Q0, np.zeros(4), models["tau"])
    for _ in range(500):
        est.step(Q0, np.zeros(4), models["tau"])
    settled = est.force.copy()
    bad_q, bad_tau = Q0.copy(), models["tau"].copy()
    bad_q[1] = np.nan
    bad_tau[2] = np.nan
    for _ in range(20):  # 20 ms of a NaN angle (left leg) and a NaN torque (right hip)
        est.step(bad_q, np.zeros(4), bad_tau)
        assert np.all(np.isfinite(est.force))
    assert est.record["skipped"][0] == 20
    for _ in range(500):
        est.step(Q0, np.zeros(4), models["tau"])
    np.testing.assert_allclose(est.force, settled, atol=0.05)


def test_a_nan_start_waits_for_finite_readings(models) -> None:
    est = kalman(models)
    est.step(np.full(4, np.nan), np.zeros(4), models["tau"])
    assert np.all(est.force == 0.0)
    est.step(Q0, np.zeros(4), models["tau"])
    np.testing.assert_allclose(est.force, models["force"], atol=0.05)  # started settled


def test_refuses_bad_shapes_and_parameters(models) -> None:
    est = kalman(models)
    with pytest.raises(InvalidParameter) as e:
        est.step(np.zeros(3), np.zeros(4), np.zeros(4))
    assert str(e.value) == "q must be an array of shape (4,); got array([0., 0., 0.])"
    with pytest.raises(InvalidParameter) as e:
        KalmanNoise(patient_torque_Nm=-1.0)
    assert str(e.value) == "patient_torque must be >= 0 N·m; got -1.0"
    with pytest.raises(InvalidParameter) as e:
        KalmanNoise(initial_angle_rad=0.0)
    assert str(e.value) == "initial_angle must be > 0 rad; got 0.0"


def test_the_torque_rate_sets_the_random_walk_of_d(models) -> None:
    """set_torque_rate: Q's d block h σ_d² from the next step, a faster answer, None restores.

    The exoskeleton held at Q0 and its hip's sensor torque stepped by 5 N·m:
    the filter must put the step into the hip's external torque,
    τ_ext = g − τ_s, so −5 N·m at the end whatever σ_d; a larger σ_d (a
    faster random walk of the patient's torques) gets there sooner.
    """
    rise, h = {}, DT
    for rate in (None, 100.0):
        est = kalman(models)
        est.set_torque_rate(rate)
        for _ in range(3000):
            est.step(Q0, np.zeros(4), models["tau"])
        sigma = est.noise.patient_torque_rate_Nm_per_sqrt_s if rate is None else rate
        np.testing.assert_allclose(est.record["Q"][0, :, 8, 8], h * sigma**2, rtol=1e-15)
        before = est.tau_ext[0]
        answer = []
        for _ in range(400):
            est.step(Q0, np.zeros(4), models["tau"] + np.array([5.0, 0.0, 0.0, 0.0]))
            answer.append(est.tau_ext[0] - before)
        assert answer[-1] == pytest.approx(-5.0, abs=1e-3)
        rise[rate] = int(np.argmax(np.abs(answer) >= 0.632 * 5.0)) + 1
    print(f"\nhip's external torque after a 5 N·m step: 63 % in {rise[None]} ms at σ_d = 10, "
          f"{rise[100.0]} ms at 100 N·m/√s")  # fmt: skip
    assert rise[100.0] < rise[None]
    est, fresh = kalman(models), kalman(models)
    est.set_torque_rate(100.0)
    est.set_torque_rate(None)
    assert est.record["var_rate"][0] == fresh.record["var_rate"][0]
    with pytest.raises(InvalidParameter) as e:
        est.set_torque_rate(-1.0)
    assert str(e.value) == "patient_torque_rate must be >= 0 N·m/√s; got -1.0"
