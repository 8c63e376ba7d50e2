"""The observer along a logged series: equal to the live estimate, and its input checks."""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl.estimation import InvalidLog, estimate_series

DT = 1e-3


def test_offline_series_equals_the_live_estimate(noisy_run) -> None:
    run = noisy_run
    series = estimate_series(run.t, run.q, run.dq, run.tau, run.exo, run.gain, dt=DT)
    assert np.max(np.abs(series.normal - run.normal)) < 1e-12
    assert np.max(np.abs(series.force - run.force)) < 1e-12
    assert np.max(np.abs(series.tau_ext - run.tau_ext)) < 1e-12


def test_bad_series_are_refused(exo) -> None:
    t = np.arange(5) * DT
    q = np.zeros((5, 4))
    with pytest.raises(InvalidLog, match=r"q must have shape \(5, 4\) like t; got \(5, 3\)"):
        estimate_series(t, q[:, :3], None, q, exo)
    with pytest.raises(InvalidLog, match=r"t must be strictly increasing; t\[2\] = 0.001"):
        estimate_series(np.array([0, 1e-3, 1e-3, 2e-3, 3e-3]), q, None, q, exo)
    bad = q.copy()
    bad[3, 1] = np.nan
    with pytest.raises(InvalidLog, match="tau has a non-finite value in row 3"):
        estimate_series(t, q, None, bad, exo)
    with pytest.raises(InvalidLog, match=r"t is not sampled every dt = 0\.002 s"):
        estimate_series(t, q, None, q, exo, dt=2e-3)
