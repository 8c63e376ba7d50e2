"""The shared proxsuite solvers: one per shape and thread, correct when workspaces interleave.

Workspaces of one shape share one solver object (so that a run repeats bit
for bit: :mod:`exo_ctrl.control.qp.solver_pool`).  A workspace whose solver
another one used since its last solve initialises it again: its answers stay
the KKT optima, and equal, bit for bit, those of a new workspace solving the
same problem from cold.
"""

from __future__ import annotations

import threading

import numpy as np

from exo_ctrl.control.qp import TorqueQP


def drifting_problems(rng: np.random.Generator, n: int, n_in: int, steps: int) -> list[tuple]:
    """A feasible problem drifting as in the loop: (target, C, lower, upper, lo, hi) per step."""
    C = rng.normal(size=(n_in, n))
    x_mid = rng.uniform(-20.0, 20.0, n)
    lo, hi = x_mid - rng.uniform(5.0, 60.0, n), x_mid + rng.uniform(5.0, 60.0, n)
    t = x_mid + rng.normal(0.0, 80.0, n)
    below, above = rng.uniform(0.5, 30.0, (2, n_in))
    out = []
    for _ in range(steps):
        t = t + rng.normal(0.0, 5.0, n)
        C = C + rng.normal(0.0, 0.02, C.shape)
        below = np.abs(below + rng.normal(0.0, 0.5, n_in)) + 0.1
        above = np.abs(above + rng.normal(0.0, 0.5, n_in)) + 0.1
        out.append((t, C.copy(), C @ x_mid - below, C @ x_mid + above, lo, hi))
    return out


def test_interleaved_workspaces_stay_optimal_and_a_take_over_is_a_cold_start(kkt_optimum) -> None:
    rng = np.random.default_rng(3)
    w_a, w_b = rng.uniform(0.3, 3.0, (2, 4))
    a, b = TorqueQP(w_a, 16), TorqueQP(w_b, 16)
    assert a._qp is b._qp  # one solver for the shape
    seq_a, seq_b = drifting_problems(rng, 4, 16, 40), drifting_problems(rng, 4, 16, 40)
    for step, (pa, pb) in enumerate(zip(seq_a, seq_b, strict=True)):
        for qp, w, problem in ((a, w_a, pa), (b, w_b, pb)):
            assert qp.solve(*problem), qp.status
            x_star, residual = kkt_optimum(w, *problem, qp.x)
            assert residual < 1e-6
            np.testing.assert_allclose(qp.x, x_star, atol=1e-6, rtol=0)
        if (
            step % 10 == 9
        ):  # a took the solver over from b: the same as a new workspace's cold start
            fresh = TorqueQP(w_a, 16)
            assert fresh.solve(*pa), fresh.status
            again = a.x.copy()
            assert a.solve(*pa)  # fresh used the solver since: a starts cold again
            np.testing.assert_array_equal(a.x, fresh.x)
            np.testing.assert_allclose(again, a.x, atol=1e-6, rtol=0)


def test_a_workspace_alone_keeps_its_warm_start_and_loses_it_to_another() -> None:
    rng = np.random.default_rng(5)
    w = rng.uniform(0.3, 3.0, 4)
    problem = drifting_problems(rng, 4, 16, 1)[0]
    qp, other = TorqueQP(w, 16), TorqueQP(w, 16)

    def iterations() -> int:
        assert qp.solve(*problem), qp.status
        return int(qp._qp.results.info.iter)

    cold = iterations()
    warm = iterations()  # from the previous optimum
    assert other.solve(*problem)
    again = iterations()  # other used the solver: initialised again, cold
    assert warm < cold and again == cold


def test_each_thread_has_its_own_solver() -> None:
    here = TorqueQP(np.ones(4), 16)
    there: list[TorqueQP] = []
    thread = threading.Thread(target=lambda: there.append(TorqueQP(np.ones(4), 16)))
    thread.start()
    thread.join()
    assert there[0]._qp is not here._qp
    assert TorqueQP(np.ones(4), 16)._qp is here._qp
    assert TorqueQP(np.ones(4), 12)._qp is not here._qp  # another shape, another solver
