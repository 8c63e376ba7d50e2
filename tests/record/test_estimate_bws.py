"""The offline estimate of a run on the belt with body-weight support equals the live one.

Live, the estimator is given the torque sensors' reading plus the foot plates'
load cells' joint torque (sensing/foot_load.py); the recording logs that torque
(``tau_ground_meas``), so ``exo-ctrl estimate`` adds the same and reproduces the
live estimate, for both estimators.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl.estimation import ESTIMATORS
from exo_ctrl.plan import GaitParams
from exo_ctrl.plant import ContactParams, PelvisParams
from exo_ctrl.record import RerunRecorder, estimate_file
from exo_ctrl.sim import SimConfig, simulate


@pytest.mark.parametrize("estimator", ESTIMATORS)
def test_the_offline_estimate_on_the_belt_equals_the_live_one(tmp_path, estimator) -> None:
    config = SimConfig(
        gait=GaitParams(hip_height=1.0, pelvis_excursion=0.05),
        contact=ContactParams(enabled=True),
        pelvis=PelvisParams(supported=True, bws_fraction=0.5),
        sync=False,
        safety=False,
        duration_s=0.6,
        estimator=estimator,
    )
    path = tmp_path / f"bws_{estimator}.rrd"
    result = simulate(config, observers=[RerunRecorder(path)])
    live = result.signals
    assert np.abs(live["tau_ground_meas"]).max() > 10.0  # the stance legs carry weight
    est = estimate_file(path)
    assert est.series.estimator == estimator
    np.testing.assert_allclose(est.series.force, live["cuff_force_est"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(est.series.tau_ext, live["tau_ext_est"], rtol=0, atol=1e-9)
