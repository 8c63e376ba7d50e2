"""The cuff rows: the octagon, the rows the controller builds, the clip test and the screening.

The controller's rows are compared with the soft problem assembled in the
tests' conftest from the cuff model's A and b (octagon, slack columns and
weights written out from the design); the skip decision (clip test) is
checked both ways against it; the screened rows against the measure written
out here; every answer of a screened or widened QP against the KKT optimum
of the FULL soft problem (a relaxation's optimum that meets every row is the
full problem's).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import linprog

from exo_ctrl.control.qp import (
    DEFAULT_HORIZON_TICKS,
    NO_BOUND,
    POLYGON_SIDES,
    SCREEN_ROUNDS,
    SCREENED_ROWS,
    SLACK_WEIGHT,
    QPController,
    polygon_rows,
)

#: ρ, the brief's slack weight [(N·m)²/N²].
RHO = 1e4


def test_slack_weight_and_polygon_are_as_designed(octagon) -> None:
    assert SLACK_WEIGHT == RHO
    assert POLYGON_SIDES == 8
    np.testing.assert_allclose(polygon_rows(4), np.kron(np.eye(4), octagon()), atol=1e-15)


def test_controller_builds_the_soft_cuff_rows(
    exo, patient, motor, plan, on_plan, soft_problem
) -> None:
    ctrl = QPController(plan, exo, patient, motor, cuff_force_limit_N=60.0, tighten=False)
    for k in range(300, 1200, 25):  # the first tick on the plan that calls proxsuite
        ctrl.command(k, on_plan(plan, k))
        if ctrl.screen_rounds:
            break
    assert ctrl.screen_rounds >= 1 and ctrl.solver_ticks == 1
    problem = soft_problem(ctrl)
    qp = ctrl.qp
    points = len(ctrl.cuff_model.horizon_ticks)
    assert points == len(DEFAULT_HORIZON_TICKS)
    assert ctrl.cuff_rows.shape == (32 * points, 8)
    np.testing.assert_allclose(ctrl.cuff_rows, problem.C, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(ctrl.cuff_upper, problem.upper, rtol=1e-12, atol=1e-9)
    # proxsuite holds SCREENED_ROWS distinct rows of the full set.
    assert qp.n == 8 and qp.n_in == SCREENED_ROWS < 32 * points
    assert len(set(ctrl.screened.tolist())) == SCREENED_ROWS
    np.testing.assert_allclose(qp.C, problem.C[ctrl.screened], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(qp.upper, problem.upper[ctrl.screened], rtol=1e-12, atol=1e-9)
    np.testing.assert_array_equal(qp.lower, -NO_BOUND)  # one-sided rows
    np.testing.assert_array_equal(qp.lo[4:], 0.0)
    np.testing.assert_array_equal(qp.hi[4:], NO_BOUND)
    np.testing.assert_array_equal(qp.target[4:], 0.0)
    np.testing.assert_array_equal(qp.target[:4], ctrl.torque_cmd)
    np.testing.assert_array_equal(qp.lo[:4], ctrl.torque_lo)
    np.testing.assert_array_equal(qp.hi[:4], ctrl.torque_hi)
    np.testing.assert_array_equal(qp.x[4:], ctrl.slack)


def screening_measure(problem, *taus: np.ndarray) -> np.ndarray:
    """Per cuff row: max over the given τ of its τ part minus its bound, slack 0 [N]."""
    return np.max([problem.C[:, :4] @ tau - problem.upper for tau in taus], axis=0)


def test_screening_hands_proxsuite_the_rows_nearest_to_binding(
    exo, patient, motor, plan, on_plan, soft_problem
) -> None:
    """A fresh controller (last torque 0): the screened rows are the top SCREENED_ROWS
    of the measure at τ_cmd and at 0, and the answer meets every row."""
    checked = 0
    for k in range(0, 1200, 5):
        ctrl = QPController(plan, exo, patient, motor, cuff_force_limit_N=60.0, tighten=False)
        ctrl.command(k, on_plan(plan, k))
        if ctrl.last_status != "solved" or ctrl.screen_rounds != 1:
            continue
        problem = soft_problem(ctrl)
        measure = screening_measure(problem, ctrl.torque_cmd, np.zeros(4))
        top = np.sort(measure)[::-1]
        chosen = measure[ctrl.screened]
        # The chosen ones are the largest (ties at the threshold either way).
        assert chosen.min() >= top[SCREENED_ROWS - 1] - 1e-12
        assert np.sort(chosen)[::-1][0] == top[0]
        x = np.concatenate((ctrl.torque, ctrl.slack))
        assert np.all(problem.C @ x <= problem.upper + 1e-6)
        checked += 1
    assert checked >= 8


def test_a_tick_whose_clipped_command_meets_every_row_skips_proxsuite(
    exo, patient, motor, plan, near_plan, soft_problem, assert_is_the_soft_optimum
) -> None:
    """The skip decision, checked both ways against the independently built problem.

    A tick without proxsuite (screen_rounds 0) commands τ_cmd clipped into
    the box, which meets every row and is the KKT optimum of the full soft
    problem; a tick with proxsuite is one whose clipped τ_cmd violates a row.
    """
    rng = np.random.default_rng(13)
    ctrl = QPController(plan, exo, patient, motor, cuff_force_limit_N=80.0, tighten=False)
    skipped = clipped = solved = 0
    for i, k in enumerate(rng.integers(0, plan.q.shape[0], 80)):
        # Alternately close to the plan (τ_cmd inside the box) and far (clipped).
        noise = (1e-4, 1e-3) if i % 2 else (0.003, 2.0)
        ctrl.command(int(k), near_plan(plan, rng, int(k), *noise))
        if ctrl.last_status != "solved":
            continue
        problem = soft_problem(ctrl)
        tau_clip = np.clip(ctrl.torque_cmd, ctrl.torque_lo, ctrl.torque_hi)
        x_clip = np.concatenate((tau_clip, np.zeros(4)))
        meets = bool(np.all(problem.C @ x_clip <= problem.upper))
        assert meets == (ctrl.screen_rounds == 0), (int(k), ctrl.screen_rounds)
        if ctrl.screen_rounds == 0:
            skipped += 1
            clipped += not np.array_equal(tau_clip, ctrl.torque_cmd)
            np.testing.assert_array_equal(ctrl.torque, tau_clip)
            np.testing.assert_array_equal(ctrl.slack, 0.0)
        else:
            solved += 1
        assert_is_the_soft_optimum(ctrl, problem)
    print(f"\n{skipped} ticks without proxsuite ({clipped} clipped), {solved} with")
    assert ctrl.solver_ticks == solved + ctrl.failures
    assert skipped >= 10 and clipped >= 3 and solved >= 10  # measured 64 (24 clipped), 16


def test_screened_rows_keep_their_slots_from_tick_to_tick(
    exo, patient, motor, plan, near_plan
) -> None:
    ctrl = QPController(plan, exo, patient, motor, cuff_force_limit_N=60.0, tighten=False)
    rng = np.random.default_rng(8)
    kept = 0
    previous = None
    for k in range(300, 340):
        ctrl.command(k, near_plan(plan, rng, k, q_noise=1e-4, dq_noise=1e-3))
        assert ctrl.last_status == "solved", ctrl.last_status
        now = ctrl.screened.copy()
        if previous is not None:
            for row in set(previous.tolist()) & set(now.tolist()):
                assert np.flatnonzero(previous == row) == np.flatnonzero(now == row)
                kept += 1
        previous = now
    assert kept > 39 * SCREENED_ROWS // 2  # most rows stay screened between ticks


def test_few_screened_rows_are_widened_until_every_row_holds(
    exo, patient, motor, plan, near_plan, soft_problem, assert_is_the_soft_optimum
) -> None:
    """Four rows only: the violated rows must be swapped in and the QP solved again.

    Every tick is still the optimum of the FULL soft problem (the relaxation
    argument of the module docstring): a tick that needs more than
    SCREEN_ROUNDS solves is answered by one solve over every row, not by a
    fallback that gives up the bound.
    """
    rng = np.random.default_rng(5)
    ctrl = QPController(
        plan, exo, patient, motor, cuff_force_limit_N=40.0, screened_rows=4, tighten=False
    )
    assert ctrl.qp.n_in == 4 and ctrl.full_rows.n_in == ctrl.cuff_rows.shape[0]
    widened = every_row = 0
    for k in rng.integers(0, plan.q.shape[0], 60):
        ctrl.command(int(k), near_plan(plan, rng, int(k), dq_noise=0.5))
        assert ctrl.last_status == "solved", ctrl.last_status
        widened += 1 < ctrl.screen_rounds <= SCREEN_ROUNDS
        every_row += ctrl.screen_rounds == SCREEN_ROUNDS + 1
        assert_is_the_soft_optimum(ctrl, soft_problem(ctrl))
    print(f"\n4 screened rows: {widened} of 60 ticks widened, {every_row} solved over every row")
    assert ctrl.failures == 0
    assert widened >= 5 and every_row >= 10  # measured before: 36 solved (28 widened), 24 fell back


def test_a_controller_screening_every_row_has_one_workspace(exo, patient, motor, plan) -> None:
    ctrl = QPController(plan, exo, patient, motor, screened_rows=10_000, tighten=False)
    assert ctrl.full_rows is ctrl.qp and ctrl.qp.n_in == ctrl.cuff_rows.shape[0]


def test_polygon_is_inscribed_in_the_force_circle() -> None:
    """max |f| over the polygon is F_max (at the vertices); min over directions F_max cos(π/S)."""
    rows = polygon_rows(1)
    r = 100.0 * math.cos(math.pi / POLYGON_SIDES)
    a_ub = np.vstack((rows, -rows))
    b_ub = np.full(a_ub.shape[0], r)
    reach = []
    for angle in np.linspace(0.0, 2.0 * math.pi, 97):
        d = np.array([math.cos(angle), math.sin(angle)])
        res = linprog(-d, A_ub=a_ub, b_ub=b_ub, bounds=[(None, None)] * 2)
        reach.append(-res.fun)
    assert max(reach) == pytest.approx(100.0, rel=1e-9)
    assert min(reach) == pytest.approx(r, rel=1e-9)
