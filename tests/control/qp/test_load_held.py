"""The QP's cuff-force bound over a coarse grid of gaits and bounds ("Load held", issue 19).

The corners of tools/load_held.py's grid: period 0.9 and 1.5 s × step 0.25
and 0.45 m × bound 100 and 150 N, the spastic patient, safety off, the
default 3.6 s run (the peaks come anywhere from the ramp-in's end to the
last cycle, so the run is not shortened), the default (split) cuffs.  The
device holds its default knowledge — the nominal patient, the datasheet
drive — plus the split cuff model, with either live force estimator.  The
real (elastic) peak cuff force must stay within the margin stated for the
point and the estimator (:func:`exo_ctrl.control.qp.stated_margin`, the
error budget of the prediction), with no fallback; the full 75-point grid
is the tool's.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from exo_ctrl.control.qp import stated_margin
from exo_ctrl.control.qp.margin import (
    LAG_ERROR_N,
    MIN_MARGIN,
    MODEL_ERROR_N,
    PATIENT_MODEL_ERROR_N,
)
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plan import GaitParams
from exo_ctrl.plant import CuffParams
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.belief import Belief

CORNERS = list(itertools.product((0.9, 1.5), (0.25, 0.45), (100.0, 150.0)))


@pytest.mark.parametrize("estimator", ["momentum", "kalman"])
@pytest.mark.parametrize(("period", "step", "bound"), CORNERS)
def test_load_held_within_the_stated_margin(period, step, bound, estimator) -> None:
    result = simulate(
        SimConfig(
            gait=GaitParams(period=period, step_length=step),
            controller="qp",
            patient_torque="spastic",
            cuff_force_limit_N=bound,
            safety=False,
            estimator=estimator,
            belief=Belief("nominal", cuffs=CuffParams()),  # the truth's cuffs are split
        ),
        keep_history=True,
    )
    peak = float(np.linalg.norm(result.signals["cuff_force"], axis=2).max())
    margin = stated_margin(period, bound, estimator)
    print(
        f"\n{estimator}: T {period} s, s {step} m, F_max {bound:g} N: peak {peak:.1f} N "
        f"({100 * (peak / bound - 1):+.1f} %, stated {100 * margin:.1f} %)"
    )
    assert result.status == "completed"
    assert result.qp_failures == 0
    assert peak <= bound * (1.0 + margin)


def test_stated_margin_is_the_error_budget() -> None:
    model = MODEL_ERROR_N + PATIENT_MODEL_ERROR_N
    # (19.3 N + 18 N · 1.2/0.9) / 100 N at the fastest gait with the momentum observer.
    assert stated_margin(0.9, 100.0, "momentum") == pytest.approx((model + 18.0 * 1.2 / 0.9) / 100)
    assert stated_margin(1.2, 150.0, "momentum") == pytest.approx((model + 18.0) / 150)
    assert stated_margin(1.2, 150.0, "momentum", true_patient=True) == pytest.approx(
        (MODEL_ERROR_N + 18.0) / 150
    )
    # The Kalman filter: a smaller estimate term; the 10 % floor where the budget is below it.
    kalman = LAG_ERROR_N["kalman"]
    assert stated_margin(0.9, 100.0, "kalman") == pytest.approx((model + kalman * 1.2 / 0.9) / 100)
    assert stated_margin(1.5, 150.0, "kalman", true_patient=True) == MIN_MARGIN
    with pytest.raises(InvalidParameter, match="period"):
        stated_margin(0.0, 100.0)
    with pytest.raises(InvalidParameter, match="cuff_force_limit"):
        stated_margin(1.2, float("nan"))
    with pytest.raises(InvalidParameter, match="estimator must be one of momentum, kalman"):
        stated_margin(1.2, 150.0, "ekf")
