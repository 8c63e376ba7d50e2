"""The margin the QP tightens each cuff bound by: its terms, the refusal, the filter's σ_c.

The bounds the closed loop must keep are asserted elsewhere against the
user's bound (test_closed_loop.py, test_load_held.py); here the mechanism.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_ctrl import cli
from exo_ctrl.control.qp import QPController
from exo_ctrl.control.qp.margin import PREDICTION_ERROR_N
from exo_ctrl.estimation.kalman import CuffForceKalman
from exo_ctrl.exceptions import CuffBoundTooTight
from exo_ctrl.plant import CuffParams
from exo_ctrl.sim import Runner, SimConfig, build
from exo_ctrl.sim.belief import Belief


def test_margin_terms_on_the_default_gait(exo, patient, motor, plan) -> None:
    published = QPController(plan, exo, patient, motor, cuffs=CuffParams()).margin
    isotropic = QPController(plan, exo, patient, motor, cuffs=CuffParams.isotropic()).margin
    print(
        f"\npublished cuffs: patient {published.patient_N.round(1)}, working "
        f"{published.working_N.round(1)}; isotropic: cuffs {isotropic.cuffs_N.round(1)} N"
    )
    np.testing.assert_array_equal(published.prediction_N, PREDICTION_ERROR_N)
    np.testing.assert_array_equal(published.cuffs_N, 0.0)  # the device holds the published cuffs
    assert np.all(published.patient_N > 0.0) and np.all(published.working_N > 0.0)
    # The isotropic model shares the hip's load otherwise than the published cuffs.
    assert np.all(isotropic.cuffs_N > 10.0)
    total = published.prediction_N + published.patient_N + published.cuffs_N
    np.testing.assert_allclose(published.static_N, total + published.estimate_N)


def test_a_bound_the_margin_cannot_hold_is_refused(exo, patient, motor, plan) -> None:
    with pytest.raises(CuffBoundTooTight) as info:
        QPController(plan, exo, patient, motor, cuffs=CuffParams(), cuff_force_limit_N=50.0)
    err = info.value
    assert err.bound_N == 50.0 and err.margin_N > PREDICTION_ERROR_N
    assert err.bound_N - err.margin_N < err.working_N


def test_cli_refuses_before_the_run_naming_bound_margin_and_gait(capsys) -> None:
    argv = ["simulate", "--controller", "qp", "--no-record"]
    argv += ["--set", "qp.cuff_force_limit_N=55", "--set", "gait.period=1.1"]
    code = cli.main(argv)
    err = capsys.readouterr().err
    assert code == 2
    assert "qp.cuff_force_limit_N = 55 N cannot be held on the gait with period 1.1 s" in err
    assert "cuff's margin of" in err and "raise the bound to at least" in err


def test_kalman_force_std_is_the_covariance_mapped_to_each_cuff() -> None:
    """σ_c = √λ_max(H_c P H_cᵀ), recomputed here from the filter's record."""
    config = SimConfig(controller="qp", belief=Belief(cuffs=CuffParams()))
    setup = build(config)
    runner = Runner(setup)
    for k in range(300):
        runner.tick(k, k % runner.chunk)
    est = runner.estimator
    assert isinstance(est, CuffForceKalman)
    rec, cuffs = est.record[0], est.cuffs.record[0]
    for c in range(4):
        leg = c // 2
        cos, sin = cuffs["cs"][c], cuffs["cs"][8 + c]
        u = np.array(
            [
                cuffs["along0"][c, 0] * cos - cuffs["along0"][c, 1] * sin,
                cuffs["along0"][c, 1] * cos + cuffs["along0"][c, 0] * sin,
            ]
        )
        n = np.array([-u[1], u[0]])
        stiff = cuffs["k"] * np.outer(n, n) + cuffs["k_u"] * np.outer(u, u)
        damp = cuffs["c"] * np.outer(n, n) + cuffs["c_u"] * np.outer(u, u)
        jac = rec["jd"][[c, 4 + c]][:, rec["joints"][leg]]  # (2, 4)
        h = np.hstack((-stiff @ jac, -damp @ jac, np.zeros((2, 2))))
        cov = h @ rec["cov"][leg] @ h.T
        expected = np.sqrt(np.linalg.eigvalsh(cov).max())
        assert rec["cuff_force_std"][c] == pytest.approx(expected, rel=1e-9)
        assert 0.0 < expected < 5.0  # settled: a few newtons at most
    # The controller sees it and tightens each cuff by its three σ_c on top.
    ctrl = setup.controller
    margin = ctrl.record["margin"][0]
    np.testing.assert_allclose(margin, ctrl.margin.static_N + 3.0 * rec["cuff_force_std"])
