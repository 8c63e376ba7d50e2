"""Error statistics of an estimate: the running (chunked) sums equal the offline errors."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.estimation import EstimateErrorStats, normal_component_errors
from exo_ctrl.estimation.errors import REL_FLOOR_N
from exo_ctrl.model import CUFF_NAMES

DT = 1e-3
SKIP_S = 0.05
SKIP = round(SKIP_S / DT)


def test_running_error_stats_match_the_offline_errors(noisy_run) -> None:
    """Fed with simulate()'s rows in chunks (cuff_force row k = force over [t_k, t_k+1))."""
    run = noisy_run
    n = run.t.shape[0] - 1
    q_sim, force_sim, normal_sim = run.q_true[:n], run.force_true[1:], run.normal[:n]
    est_sim = run.force[:n]
    stats = EstimateErrorStats(run.exo, DT, skip_s=SKIP_S)
    for lo, hi in ((0, 30), (30, 700), (700, 1400), (1400, n)):
        stats.update(q_sim[lo:hi], force_sim[lo:hi], normal_sim[lo:hi], est_sim[lo:hi])
    offline = normal_component_errors(
        run.q_true[:n], run.force_true[:n], run.normal[:n], run.exo, skip=SKIP, force_est=est_sim
    )
    lagged = normal_component_errors(
        q_sim, force_sim, normal_sim, run.exo, skip=SKIP, lag=1, force_est=est_sim
    )
    got = stats.result()
    assert got.rows == offline.rows == lagged.rows == n - SKIP
    for ref in (offline, lagged):
        assert np.allclose(got.rms_error_N, ref.rms_error_N, rtol=1e-12)
        assert np.allclose(got.peak_true_N, ref.peak_true_N, rtol=1e-12)
        assert np.allclose(got.max_error_N, ref.max_error_N, rtol=1e-12)
        assert np.allclose(got.vector_rms_error_N, ref.vector_rms_error_N, rtol=1e-12)
        assert np.allclose(got.vector_rms_true_N, ref.vector_rms_true_N, rtol=1e-12)
    summary = stats.summary()
    assert summary["cuff_force_estimate_normal_rms_over_peak"]["left_shank"] == pytest.approx(
        offline.rms_error_rel[1]
    )
    assert summary["cuff_force_estimate_rms_error_rel"]["left_shank"] == pytest.approx(
        offline.vector_rms_error_rel[1]
    )


def test_per_component_errors_over_their_rms(noisy_run) -> None:
    """Normal and along components' RMS errors over their RMS, derived here from the rotation.

    The along direction u = (cos ψ, sin ψ) is rebuilt from the exoskeleton's
    frames through Pinocchio's forward kinematics of the cuff and joint
    frames (an independent path to ψ), and the running sums must agree.
    """
    run = noisy_run
    n = run.t.shape[0] - 1
    # simulate()'s rows: cuff_force row k is the force over [t_k, t_k+1); the
    # estimate of row k is compared with the force of row k - 1 (force_true[k])
    q, logged, est = run.q_true[:n], run.force_true[1:], run.force[:n]
    truth = run.force_true[:n]
    stats = EstimateErrorStats(run.exo, DT, skip_s=SKIP_S)
    for lo, hi in ((0, 400), (400, n)):
        stats.update(q[lo:hi], logged[lo:hi], run.normal[lo:hi], est[lo:hi])
    got = stats.result()
    # ψ per cuff from the frames: the joint → cuff direction in the sagittal (x, z) plane
    model, data = run.exo.model, run.exo.model.createData()
    u = np.zeros((n, 4, 2))
    joint_of = {"thigh": "hip", "shank": "knee"}
    for k in range(SKIP, n):
        pin.framesForwardKinematics(model, data, q[k])
        for c, cuff in enumerate(CUFF_NAMES):
            leg, segment = cuff.split("_")
            cuff_at = data.oMf[model.getFrameId(f"{cuff}_cuff")].translation
            joint_at = data.oMi[model.getJointId(f"{leg}_{joint_of[segment]}")].translation
            d = (cuff_at - joint_at)[[0, 2]]
            u[k, c] = d / np.linalg.norm(d)
    nrm = np.stack((-u[..., 1], u[..., 0]), axis=-1)  # u turned by +90°
    rows = slice(SKIP, n)
    along_true = np.sum(u * truth, axis=-1)[rows]
    along_err = np.sum(u * (est - truth), axis=-1)[rows]
    normal_true = np.sum(nrm * truth, axis=-1)[rows]
    rms = lambda x: np.sqrt(np.mean(x**2, axis=0))  # noqa: E731
    np.testing.assert_allclose(got.along_rms_error_N, rms(along_err), rtol=1e-9)
    np.testing.assert_allclose(got.along_rms_true_N, rms(along_true), rtol=1e-9)
    np.testing.assert_allclose(got.rms_true_N, rms(normal_true), rtol=1e-9)
    summary = stats.summary()
    for c, cuff in enumerate(CUFF_NAMES):
        along_rel = summary["cuff_force_estimate_along_rms_error_over_rms"][cuff]
        if rms(along_true)[c] < REL_FLOOR_N:  # no meaningful denominator
            assert along_rel is None
        else:
            assert along_rel == pytest.approx(rms(along_err)[c] / rms(along_true)[c], rel=1e-9)
        normal_rel = summary["cuff_force_estimate_normal_rms_error_over_rms"][cuff]
        assert normal_rel == pytest.approx(got.rms_error_N[c] / rms(normal_true)[c], rel=1e-9)
    # the whole force splits into its two components: |e|² = e⊥² + e∥²
    np.testing.assert_allclose(
        got.vector_rms_error_N**2,
        rms(np.sum(nrm * (est - truth), axis=-1)[rows]) ** 2 + rms(along_err) ** 2,
        rtol=1e-9,
    )
    offline = normal_component_errors(q, truth, run.normal[:n], run.exo, skip=SKIP, force_est=est)
    np.testing.assert_allclose(offline.along_rms_error_N, got.along_rms_error_N, rtol=1e-12)
    np.testing.assert_allclose(offline.along_rms_true_N, got.along_rms_true_N, rtol=1e-12)
