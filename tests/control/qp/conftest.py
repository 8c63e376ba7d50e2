"""Independent checks shared by the QP tests, as fixtures (test modules cannot import each other).

- ``kkt_optimum``: the optimum certified by the KKT conditions on an answer's
  active set, with numpy only;
- ``octagon``, ``soft_problem``, ``assert_is_the_soft_optimum``: the
  controller's soft problem assembled here from the cuff model's A and b
  (octagon, slack columns and weights written out from the design, not taken
  from the controller), and the check of the controller's answer against it;
- ``near_plan``, ``on_plan``: readings near or on the plan.

The soft problem, x = (τ, s):  min ½ (τ − τ_cmd)ᵀ W (τ − τ_cmd) + ½ ρ sᵀs  s.t.
±N (A τ + b) − E s ≤ r, τ_lo ≤ τ ≤ τ_hi, s ≥ 0, with r = F_max cos(π/8).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.optimize import nnls

from exo_ctrl.control import SensorReadings
from exo_ctrl.control.qp import QPController

#: ρ, the brief's slack weight [(N·m)²/N²].
RHO = 1e4


def _near_plan(
    plan, rng: np.random.Generator, k: int, q_noise: float = 0.01, dq_noise: float = 0.2
) -> SensorReadings:
    """Readings near the plan (the PD turns 0.01 rad into ~1 V, ~170 N·m at stall)."""
    return SensorReadings(
        q=plan.q[k] + rng.normal(0.0, q_noise, 4),
        dq=plan.dq[k] + rng.normal(0.0, dq_noise, 4),
        tau=np.zeros(4),
    )


def _on_plan(plan, k: int, force=None) -> SensorReadings:
    return SensorReadings(
        q=plan.q[k].copy(), dq=plan.dq[k].copy(), tau=np.zeros(4), cuff_force_est=force
    )


def _kkt_optimum(w, t, C, lower, upper, lo, hi, x, tol=1e-7):
    """The optimum certified by the KKT conditions on x's active set, with numpy only.

    Solves the equality-constrained QP on the rows (and box bounds) that x
    makes active, then checks what makes that point the optimum of the
    convex QP: multipliers ≥ 0 (by NNLS on the stationarity condition),
    every constraint met.  Infinite bounds are allowed.  Returns
    (x*, stationarity residual).
    """
    n = len(t)
    rows = np.vstack((C, np.eye(n)))
    lb = np.concatenate((lower, lo))
    ub = np.concatenate((upper, hi))
    r = rows @ x
    at_ub = r >= ub - tol
    at_lb = (r <= lb + tol) & ~at_ub
    g = np.vstack((rows[at_ub], -rows[at_lb]))  # active as gᵀx ≤ h
    h = np.concatenate((ub[at_ub], -lb[at_lb]))
    W = np.diag(w)
    m = g.shape[0]
    kkt = np.block([[W, g.T], [g, np.zeros((m, m))]])
    sol = np.linalg.lstsq(kkt, np.concatenate((W @ t, h)), rcond=None)[0]
    x_star = sol[:n]
    # Multipliers λ ≥ 0 with W (x* − t) + gᵀ λ = 0.
    if m:
        lam, residual = nnls(g.T, W @ (t - x_star))
    else:
        lam, residual = np.zeros(0), float(np.linalg.norm(W @ (t - x_star)))
    rx = rows @ x_star
    feas = 1e-8 * max(1.0, np.abs(t).max())  # lstsq's accuracy scales with the data
    assert np.all(rx >= lb - feas) and np.all(rx <= ub + feas), "x* not feasible"
    assert np.all(lam >= 0.0)
    return x_star, residual


def _octagon() -> np.ndarray:
    """Edge normals n_k = (cos kπ/4, sin kπ/4), k = 0..3, written out (4, 2)."""
    angles = np.arange(4) * math.pi / 4
    return np.column_stack((np.cos(angles), np.sin(angles)))


@dataclasses.dataclass
class SoftProblem:
    """The controller's QP in x = (τ, s), assembled here from A, b and the design."""

    w: np.ndarray
    t: np.ndarray
    C: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    A: np.ndarray
    b: np.ndarray
    radius: np.ndarray

    def edge_excess(self, tau: np.ndarray) -> np.ndarray:
        """max over horizon points and k of |n_kᵀ f_c| − r per cuff, f = A τ + b [N]."""
        f = (self.A @ tau + self.b).reshape(-1, 4, 2)
        return np.abs(f @ _octagon().T).max(axis=(0, 2)) - self.radius


def _soft_problem(ctrl: QPController, b: np.ndarray | None = None) -> SoftProblem:
    """The soft QP of the last tick, from the cuff model's A and b (or a given b)."""
    A = ctrl.cuff_model.A.copy()
    b = ctrl.cuff_model.b.copy() if b is None else np.asarray(b, dtype=float)
    points = A.shape[0] // 8
    # Row 16p + 4c + k holds n_k at cuff c's columns of horizon point p.
    n_rows = np.kron(np.eye(4 * points), _octagon())
    e = np.kron(np.ones((points, 1)), np.kron(np.eye(4), np.ones((4, 1))))  # → slack c
    # r_c = (F_max − m_c) cos(π/8), the tightened bound of the tick (margin.py), per cuff.
    radius = ctrl.record["radius"][0].copy()
    per_row = np.tile(np.repeat(radius, 4), points)
    na = n_rows @ A
    return SoftProblem(
        w=np.concatenate((np.ones(4), np.full(4, RHO))),
        t=np.concatenate((ctrl.torque_cmd, np.zeros(4))),
        C=np.vstack((np.hstack((na, -e)), np.hstack((-na, -e)))),
        lower=np.full(2 * n_rows.shape[0], -np.inf),
        upper=np.concatenate((per_row - n_rows @ b, per_row + n_rows @ b)),
        lo=np.concatenate((ctrl.torque_lo, np.zeros(4))),
        hi=np.concatenate((ctrl.torque_hi, np.full(4, np.inf))),
        A=A,
        b=b,
        radius=radius,
    )


def _assert_is_the_soft_optimum(ctrl: QPController, problem: SoftProblem) -> None:
    """The controller's x = (τ, s) is the KKT optimum of the independently built problem."""
    x = np.concatenate((ctrl.torque, ctrl.slack))
    x_star, residual = _kkt_optimum(
        problem.w, problem.t, problem.C, problem.lower, problem.upper, problem.lo, problem.hi, x
    )
    assert residual < 1e-6 * max(1.0, np.abs(problem.t).max())
    np.testing.assert_allclose(x, x_star, atol=1e-6, rtol=0)
    # Given τ, the optimal slack is the octagon's excess (or zero).
    np.testing.assert_allclose(
        ctrl.slack, np.maximum(problem.edge_excess(ctrl.torque), 0.0), atol=1e-6, rtol=0
    )


@pytest.fixture(scope="session")
def near_plan():
    """Readings near the plan: ``near_plan(plan, rng, k, q_noise=0.01, dq_noise=0.2)``."""
    return _near_plan


@pytest.fixture(scope="session")
def on_plan():
    """Readings on the plan: ``on_plan(plan, k, force=None)``."""
    return _on_plan


@pytest.fixture(scope="session")
def kkt_optimum():
    """The KKT certificate of a QP answer (:func:`_kkt_optimum`)."""
    return _kkt_optimum


@pytest.fixture(scope="session")
def octagon():
    """The octagon's edge normals, written out (:func:`_octagon`)."""
    return _octagon


@pytest.fixture(scope="session")
def soft_problem():
    """The controller's soft QP of the last tick, assembled here (:func:`_soft_problem`)."""
    return _soft_problem


@pytest.fixture(scope="session")
def assert_is_the_soft_optimum():
    """Check the controller's (τ, s) against the KKT optimum of the soft problem."""
    return _assert_is_the_soft_optimum
