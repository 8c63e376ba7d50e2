"""Error statistics of an estimate: the running (chunked) sums equal the offline errors."""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl.estimation import EstimateErrorStats, normal_component_errors

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
