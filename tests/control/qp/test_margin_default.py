"""The stated margin and tools/load_held.py follow the run's default estimator (the Kalman filter).

The margin's estimate term is the estimator's (:data:`LAG_ERROR_N`, 18 N for
the momentum observer, 1.5 N for the Kalman filter at 1.2 s), so a margin
stated for one estimator and asserted on a run of the other is wrong by
16 N / F_max.  Left unnamed, the estimator is a default run's
(``SimConfig().estimator``), in the function and in the tool alike.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from exo_ctrl.control.qp import stated_margin
from exo_ctrl.control.qp.margin import (
    LAG_ERROR_N,
    MODEL_ERROR_N,
    PATIENT_MODEL_ERROR_N,
    REFERENCE_PERIOD_S,
)
from exo_ctrl.sim import SimConfig

ROOT = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(ROOT / "tools"))

import load_held as tool  # noqa: E402

DEFAULT = SimConfig().estimator


@pytest.mark.parametrize(("period", "bound"), [(0.9, 100.0), (1.2, 150.0), (1.5, 125.0)])
def test_stated_margin_defaults_to_the_runs_estimator(period: float, bound: float) -> None:
    assert DEFAULT == "kalman"
    budget = MODEL_ERROR_N + PATIENT_MODEL_ERROR_N + 1.5 * REFERENCE_PERIOD_S / period
    assert stated_margin(period, bound) == pytest.approx(max(0.10, budget / bound), rel=1e-12)
    assert stated_margin(period, bound) == stated_margin(period, bound, DEFAULT)


def test_the_estimators_margins_differ_by_their_lag_terms() -> None:
    """At 0.9 s and 100 N both are above the 10 % floor: the gap is the lag terms' alone."""
    gap = stated_margin(0.9, 100.0, "momentum") - stated_margin(0.9, 100.0)
    lag = (LAG_ERROR_N["momentum"] - LAG_ERROR_N["kalman"]) * REFERENCE_PERIOD_S / 0.9
    assert gap == pytest.approx(lag / 100.0, rel=1e-12)
    assert gap > 0.2  # (18 - 1.5) N · 1.2/0.9 over 100 N: 22 points of margin


def test_load_held_runs_and_states_the_default_estimator(tmp_path: Path) -> None:
    """One grid point through the tool: its run and its margin are the Kalman filter's."""
    out = tmp_path / "points.json"
    argv = ["--periods", "0.9", "--steps", "0.25", "--bounds", "100", "--duration", "1.5"]
    code = tool.main([*argv, "--workers", "1", "--json", str(out)])
    (point,) = json.loads(out.read_text())
    assert code == (0 if point["over"] <= point["margin"] else 1)  # exit 1: not held
    assert point["margin"] == stated_margin(0.9, 100.0, "kalman")
    kalman = tool.run_point(0.9, 0.25, 100.0, duration_s=1.5, estimator="kalman")
    momentum = tool.run_point(0.9, 0.25, 100.0, duration_s=1.5, estimator="momentum")
    # The pool's worker process and this one agree to rounding (proxsuite's vectorised
    # arithmetic may differ in the last bits between processes), the estimators do not.
    assert point["peak_N"] == pytest.approx(kalman["peak_N"], rel=1e-9)
    assert abs(kalman["peak_N"] - momentum["peak_N"]) > 1e-3
    assert momentum["margin"] == stated_margin(0.9, 100.0, "momentum")
