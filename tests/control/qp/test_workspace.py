"""The persistent proxsuite workspace: answers against a KKT certificate and scipy, its refusals.

Each answer of :class:`~exo_ctrl.control.qp.workspace.TorqueQP` is checked
against the optimum certified by the KKT conditions on its active set,
built with numpy (the ``kkt_optimum`` fixture), on random feasible
instances, on a warm-started drifting sequence, and against scipy's SLSQP;
bounds out of order, non-finite data and an infeasible problem are refused
without an answer, and the workspace recovers.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from exo_ctrl.control.qp import (
    TorqueQP,
)


def random_instance(rng: np.random.Generator, n: int = 4, n_in: int = 16):
    """A feasible QP: bounds around a random interior point, the target far outside."""
    w = rng.uniform(0.3, 3.0, n)
    C = rng.normal(size=(n_in, n))
    x0 = rng.uniform(-50.0, 50.0, n)
    cx = C @ x0
    lower, upper = cx - rng.uniform(0.5, 40.0, n_in), cx + rng.uniform(0.5, 40.0, n_in)
    lo, hi = x0 - rng.uniform(0.5, 60.0, n), x0 + rng.uniform(0.5, 60.0, n)
    t = x0 + rng.normal(0.0, 80.0, n)
    return w, t, C, lower, upper, lo, hi


def assert_feasible(x, C, lower, upper, lo, hi, tol=1e-7):
    assert np.all(np.isfinite(x))
    assert np.all(x >= lo) and np.all(x <= hi)  # the box is exact (rounded)
    cx = C @ x
    assert np.all(cx >= lower - tol) and np.all(cx <= upper + tol)


@pytest.mark.parametrize("n", [4, 8])
def test_qp_answers_are_kkt_optima_on_random_instances(n, kkt_optimum) -> None:
    rng = np.random.default_rng(7 + n)
    active_seen = 0
    for _ in range(300):
        w, t, C, lower, upper, lo, hi = random_instance(rng, n)
        qp = TorqueQP(w, C.shape[0])
        assert qp.solve(t, C, lower, upper, lo, hi), qp.status
        assert_feasible(qp.x, C, lower, upper, lo, hi)
        x_star, residual = kkt_optimum(w, t, C, lower, upper, lo, hi, qp.x)
        assert residual < 1e-6
        np.testing.assert_allclose(qp.x, x_star, atol=1e-6, rtol=0)
        active_seen += qp.active > 0
    assert active_seen > 200  # the instances do exercise the constraints


def test_warm_started_sequence_matches_the_kkt_optimum_each_time(kkt_optimum) -> None:
    """One workspace, a drifting problem (as in the loop): every answer still optimal."""
    rng = np.random.default_rng(11)
    w, t, C, lower, upper, lo, hi = random_instance(rng)
    x_mid = (lo + hi) / 2  # stays interior
    below, above = rng.uniform(0.5, 30.0, (2, C.shape[0]))
    qp = TorqueQP(w, C.shape[0])
    for _ in range(300):
        t = t + rng.normal(0.0, 5.0, 4)
        C = C + rng.normal(0.0, 0.02, C.shape)
        below = np.abs(below + rng.normal(0.0, 0.5, below.shape)) + 0.1
        above = np.abs(above + rng.normal(0.0, 0.5, above.shape)) + 0.1
        lower, upper = C @ x_mid - below, C @ x_mid + above
        assert qp.solve(t, C, lower, upper, lo, hi), qp.status
        assert_feasible(qp.x, C, lower, upper, lo, hi)
        x_star, residual = kkt_optimum(w, t, C, lower, upper, lo, hi, qp.x)
        assert residual < 1e-6
        np.testing.assert_allclose(qp.x, x_star, atol=1e-6, rtol=0)


def test_qp_agrees_with_scipy_slsqp() -> None:
    """A second, iterative opinion: SLSQP's own accuracy here is ~1e-5, so the 1e-6
    agreement is the KKT test's; here proxsuite must be at least as good as SLSQP."""
    rng = np.random.default_rng(3)
    for _ in range(100):
        w, t, C, lower, upper, lo, hi = random_instance(rng)
        qp = TorqueQP(w, C.shape[0])
        assert qp.solve(t, C, lower, upper, lo, hi)
        rows = np.vstack((C, -C))
        rhs = np.concatenate((lower, -upper))

        def cost(x, w=w, t=t):
            return 1e-3 * 0.5 * (x - t) @ (w * (x - t))

        res = minimize(
            cost,
            (lo + hi) / 2,
            jac=lambda x, w=w, t=t: 1e-3 * w * (x - t),
            bounds=list(zip(lo, hi, strict=True)),
            constraints=[
                {
                    "type": "ineq",
                    "fun": lambda x, r=rows, b=rhs: r @ x - b,
                    "jac": lambda x, r=rows: r,
                }
            ],
            method="SLSQP",
            options={"ftol": 1e-12, "maxiter": 1000},
        )
        assert res.success, res.message
        np.testing.assert_allclose(qp.x, res.x, atol=1e-4, rtol=0)
        assert cost(qp.x) <= cost(res.x) + 1e-9 * abs(cost(res.x))


def test_bounds_out_of_order_fall_back_without_solving() -> None:
    qp = TorqueQP(np.ones(4), 2)
    c = np.eye(2, 4)
    lo, hi = -np.ones(4) * 10, np.ones(4) * 10
    assert not qp.solve(np.ones(4), c, np.array([1.0, 0.0]), np.array([0.0, 1.0]), lo, hi)
    assert "lower > upper" in qp.status
    assert not qp.solve(np.ones(4), c, -np.ones(2), np.ones(2), hi, lo)
    assert not qp.solve(np.full(4, np.nan), c, -np.ones(2), np.ones(2), lo, hi)
    assert qp.status == "non-finite problem data"
    # The workspace still works afterwards.
    assert qp.solve(np.full(4, 5.0), c, -np.ones(2), np.ones(2), lo, hi)
    np.testing.assert_allclose(qp.x, [1.0, 1.0, 5.0, 5.0], atol=1e-7)


def test_infeasible_qp_is_refused_quickly_and_the_workspace_recovers() -> None:
    qp = TorqueQP(np.ones(4), 1, max_iter=100)
    c = np.array([[1.0, 0.0, 0.0, 0.0]])
    lo, hi = -np.ones(4) * 5, np.ones(4) * 5
    assert qp.solve(np.zeros(4), c, np.array([-1.0]), np.array([1.0]), lo, hi)
    # x0 must be ≥ 10 by the row but ≤ 5 by the box: infeasible.
    ok = qp.solve(np.zeros(4), c, np.array([10.0]), np.array([20.0]), lo, hi)
    assert not ok
    assert qp.reinits == 1
    assert "after re-init" in qp.status
    assert qp.solve_time_us < 1e6
    assert qp.solve(np.full(4, 2.0), c, np.array([-1.0]), np.array([1.0]), lo, hi)
    np.testing.assert_allclose(qp.x, [1.0, 2.0, 2.0, 2.0], atol=1e-7)
