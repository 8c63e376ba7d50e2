"""The patient-torque estimate's bandwidth ω_d follows the live force estimator ("Load held").

d̂ (:class:`~exo_ctrl.control.qp.CuffStateObserver`) is the residual of the
patient's equation through a first-order filter, d̂ ← d̂ + a_d (e − d̂),
a_d = 1 − e^{−h ω_d}: a ramp e = ρ t is followed with a lag of 1/ω_d in the
limit h ω_d → 0.  The spastic reflex torque follows the joint speed, so at the
fastest gait of tools/load_held.py's grid a 33 ms lag (30 1/s) let the real
peak pass the bound by more than 10 % with the Kalman filter's estimate; the
filter's clean estimate takes 60 1/s (17 ms; faster let the estimate's
start-up transient through, tests/sim/test_start.py), the momentum
observer's keeps 30 1/s (:data:`DISTURBANCE_BANDWIDTH_PER_S`).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from exo_ctrl.control.qp import CuffKnowledge, QPController
from exo_ctrl.control.qp.controller import DISTURBANCE_BANDWIDTH_PER_S
from exo_ctrl.estimation import ESTIMATORS
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plan import GaitParams
from exo_ctrl.plant.cuff_scatter import CuffScatter
from exo_ctrl.sim import Runner, SimConfig, build
from exo_ctrl.sim.belief import Belief

#: The bound of the fastest gait's point [N].
BOUND_N = 100.0


def test_every_estimator_has_its_bandwidth() -> None:
    assert set(DISTURBANCE_BANDWIDTH_PER_S) == set(ESTIMATORS)


@pytest.mark.parametrize("estimator", sorted(DISTURBANCE_BANDWIDTH_PER_S))
def test_the_estimators_bandwidth_sets_the_filter(plan, exo, patient, motor, estimator) -> None:
    h = 1e-3
    ctrl = QPController(plan, exo, patient, motor, dt=h, estimator=estimator)
    a_d = float(ctrl.observer.record["a_dist"][0])
    w_d = DISTURBANCE_BANDWIDTH_PER_S[estimator]
    assert a_d == pytest.approx(-math.expm1(-h * w_d), rel=1e-15)
    # The discrete filter's lag behind a ramp: h (1 − a)/a → 1/ω_d as h ω_d → 0.
    assert h * (1 - a_d) / a_d == pytest.approx(1 / w_d, rel=h * w_d)
    # An explicit ω_d wins over the estimator's.
    own = QPController(
        plan, exo, patient, motor, dt=h, estimator=estimator, disturbance_bandwidth_per_s=10.0
    )
    assert float(own.observer.record["a_dist"][0]) == pytest.approx(-math.expm1(-h * 10.0))


def test_a_ramp_is_followed_one_over_omega_behind() -> None:
    """The filter law itself, stepped: the steady lag behind e = ρ t is h (1 − a)/a."""
    h, rho = 1e-3, 2.0  # [s], [N·m/s]
    for w_d in DISTURBANCE_BANDWIDTH_PER_S.values():
        a = -math.expm1(-h * w_d)
        d = 0.0
        t = np.arange(2000) * h
        for tk in t:
            d += a * (rho * tk - d)
        assert (rho * t[-1] - d) / rho == pytest.approx(h * (1 - a) / a, rel=1e-9)


def test_an_unknown_estimator_is_refused(plan, exo, patient, motor) -> None:
    with pytest.raises(
        InvalidParameter, match=r"^estimator must be one of momentum, kalman; got 'ekf'$"
    ):
        QPController(plan, exo, patient, motor, estimator="ekf")


def _peak(bandwidth: float | None) -> tuple[float, int]:
    """The spastic run at 0.9 s, 0.25 m, 100 N: true peak cuff force [N] and fallbacks."""
    config = SimConfig(
        gait=GaitParams(period=0.9, step_length=0.25),
        controller="qp",
        patient_torque="spastic",
        cuff_force_limit_N=BOUND_N,
        safety=False,
        # The published cuffs exactly, as when the bandwidths were compared: with seed 0's
        # scattered cuffs both give 97.59 N (within 5 %), 60 1/s no lower than 30 1/s.
        # The device knows it (no margin for an unknown cuff stiffness).
        cuff_scatter=CuffScatter.exact(),
        belief=Belief(cuff_spread_rel=0.0),
    )
    setup = build(config)
    if bandwidth is not None:
        setup.controller = QPController(
            setup.plan,
            setup.device_exo,
            setup.device_patient,
            setup.device_motor,
            config.gains,
            cuff_force_limit_N=BOUND_N,
            cuffs=config.belief.cuff_model_of(config.cuffs),
            dt=config.dt,
            restored_bandwidth_per_s=config.qp_estimate_bandwidth_per_s,
            disturbance_bandwidth_per_s=bandwidth,
            cuff_knowledge=CuffKnowledge(config.cuffs, spread_rel=0.0),
        )
    runner = Runner(setup)
    peak = 0.0
    for k in range(config.n_ticks):
        row = k % runner.chunk
        runner.tick(k, row)
        peak = max(peak, float(np.linalg.norm(runner.log["cuff_force"][row], axis=1).max()))
    return peak, setup.controller.failures


def test_the_fastest_gaits_worst_point_holds_within_five_percent() -> None:
    """The old grid's worst point with the Kalman filter (0.9 s, 0.25 m, 100 N).

    With d̂ at the filter's 60 1/s the real peak stays within 5 % of the user's
    bound; with the 30 1/s that suits the momentum observer it is higher, by the
    spastic reflex's rise over the extra 25 ms of lag.
    """
    fast, fast_fails = _peak(None)
    slow, slow_fails = _peak(30.0)
    print(f"\nd̂ at 60 1/s: {fast:.1f} N; at 30 1/s: {slow:.1f} N (bound {BOUND_N:g} N)")
    assert fast_fails == slow_fails == 0
    assert fast <= BOUND_N * 1.05
    assert fast < slow
