"""The QP's cuff-force bound over a coarse grid of gaits and bounds ("Load held", issue 19).

The corners of tools/load_held.py's grid: period 0.9 and 1.5 s × step 0.25
and 0.45 m × bound 100 and 150 N, the spastic patient, safety off, the
default 3.6 s run (the peaks come anywhere from the ramp-in's end to the
last cycle, so the run is not shortened).  The real (elastic) peak cuff
force must stay within the margin stated for the point
(:func:`exo_ctrl.control.qp.stated_margin`, the error budget of the
prediction), with no fallback; the full 75-point grid is the tool's.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from exo_ctrl.control.qp import stated_margin
from exo_ctrl.control.qp.margin import MIN_MARGIN, MODEL_ERROR_N
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plan import GaitParams
from exo_ctrl.plant import CuffParams
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.belief import Belief

CORNERS = list(itertools.product((0.9, 1.5), (0.25, 0.45), (100.0, 150.0)))


@pytest.mark.parametrize(("period", "step", "bound"), CORNERS)
def test_load_held_within_the_stated_margin(period, step, bound) -> None:
    result = simulate(
        SimConfig(
            gait=GaitParams(period=period, step_length=step),
            controller="qp",
            patient_torque="spastic",
            cuff_force_limit_N=bound,
            safety=False,
            cuffs=CuffParams.isotropic(),  # the QP's own cuff model (stated margins)
            belief=Belief("truth"),  # and its patient: the margin's model error assumes it
        ),
        keep_history=True,
    )
    peak = float(np.linalg.norm(result.signals["cuff_force"], axis=2).max())
    margin = stated_margin(period, bound)
    print(
        f"\nT {period} s, s {step} m, F_max {bound:g} N: peak {peak:.1f} N "
        f"({100 * (peak / bound - 1):+.1f} %, stated {100 * margin:.1f} %)"
    )
    assert result.status == "completed"
    assert result.qp_failures == 0
    assert peak <= bound * (1.0 + margin)


def test_stated_margin_is_the_error_budget() -> None:
    # (4.6 N + 13 N · 1.2/0.9) / 100 N at the fastest gait, the 10 % floor at the slowest.
    assert stated_margin(0.9, 100.0) == pytest.approx((MODEL_ERROR_N + 13.0 * 1.2 / 0.9) / 100)
    assert stated_margin(1.2, 150.0) == pytest.approx((MODEL_ERROR_N + 13.0) / 150)
    assert stated_margin(1.5, 150.0) == MIN_MARGIN
    with pytest.raises(InvalidParameter, match="period"):
        stated_margin(0.0, 100.0)
    with pytest.raises(InvalidParameter, match="cuff_force_limit"):
        stated_margin(1.2, float("nan"))
