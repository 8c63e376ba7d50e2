r"""A persistent, warm-started proxsuite workspace with an independent check of its answers.

The problem, over x ∈ ℝⁿ with W = diag(w) > 0,

.. math::

    \min_x \tfrac12 (x - x_t)^T W (x - x_t)
    \quad \text{s.t.} \quad l \le C x \le u, \quad x_{lo} \le x \le x_{hi},

is held in one record (:func:`workspace_fields`) and handed to proxsuite's
dense solver, one per problem shape and thread, reused from run to run
(:mod:`.solver_pool`: so that a run repeats bit for bit).  Measured on these
machines: a warm start can come back SOLVED far from the optimum (up to 0.84
on ~1 % of random feasible problems) or falsely infeasible, an infeasible
problem runs to the iteration limit, NaN data runs for seconds, ``l > u``
comes back SOLVED.  Hence the workspace's stated behaviour:

1. before solving, every entry must be finite and every lower bound at most
   its upper bound (else no solve);
2. the iteration limit is bounded (``max_iter``) and the duality gap checked;
3. an answer is accepted only if proxsuite says SOLVED and x, finite, meets
   every row and box bound within :data:`FEASIBILITY_TOL` — checked here, in
   a compiled kernel, independently of the solver; x is then rounded into
   the box exactly;
4. otherwise the QP is re-initialised cold and solved once more; if that
   fails too, :meth:`TorqueQP.solve_in_place` returns False with the reason
   in :attr:`TorqueQP.status`, and the caller falls back.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import proxsuite

from ..._jit import Status, kernel, record
from ...exceptions import InvalidParameter
from .solver_pool import shared_solver

__all__ = ["ACTIVE_TOL", "FEASIBILITY_TOL", "TorqueQP", "workspace_fields"]

#: Feasibility tolerance of the independent check of a QP answer [N·m or N].
FEASIBILITY_TOL = 1e-6
#: A row or box bound within this of its limit counts as active [N·m or N].
ACTIVE_TOL = 1e-6

_Output = proxsuite.proxqp.QPSolverOutput
_SOLVED = _Output.PROXQP_SOLVED
_STATUS = {
    _Output.PROXQP_SOLVED: "solved",
    _Output.PROXQP_MAX_ITER_REACHED: "max_iter_reached",
    _Output.PROXQP_PRIMAL_INFEASIBLE: "primal_infeasible",
    _Output.PROXQP_DUAL_INFEASIBLE: "dual_infeasible",
    _Output.PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE: "closest_primal_feasible",
    _Output.PROXQP_NOT_RUN: "not_run",
}
_WARM = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
_COLD = proxsuite.proxqp.InitialGuess.EQUALITY_CONSTRAINED_INITIAL_GUESS


def workspace_fields(n: int, n_in: int) -> list[tuple[Any, ...]]:
    """The fields of a :class:`TorqueQP`'s record for n variables and n_in rows.

    ``C``: [C; I], (n_in + n, n); ``lower``, ``upper``: the row bounds and
    then the box; ``target`` x_t; ``neg_w`` −w; ``g`` = −W x_t (proxsuite's
    linear term); ``x`` the accepted answer; the verdicts of the kernels:
    ``ordered`` (every lower bound ≤ its upper bound), ``feasible`` (the
    answer met every bound) and ``active`` (the rows and box bounds within
    :data:`ACTIVE_TOL` of a limit).
    """
    m = n_in + n
    f8 = np.float64
    return [
        ("C", f8, (m, n)),
        ("lower", f8, (m,)),
        ("upper", f8, (m,)),
        ("target", f8, (n,)),
        ("neg_w", f8, (n,)),
        ("g", f8, (n,)),
        ("x", f8, (n,)),
        ("ordered", np.bool_),
        ("feasible", np.bool_),
        ("active", np.int64),
    ]


@kernel
def _prepare(state: np.ndarray) -> int:  # pragma: no cover - compiled
    """Check the problem in ``state[0]`` and form g = −W x_t.

    Returns a :class:`~exo_ctrl._jit.Status` value: NOT_FINITE if an entry
    of C, the bounds or x_t is not finite.  Otherwise OK, with ``ordered``
    written, and g if the bounds are ordered.
    """
    p = state[0]
    c_all, lower, upper, target = p.C, p.lower, p.upper, p.target
    for i in range(c_all.shape[0]):
        for j in range(c_all.shape[1]):
            if not math.isfinite(c_all[i, j]):
                return Status.NOT_FINITE.value
    for i in range(lower.shape[0]):
        if not (math.isfinite(lower[i]) and math.isfinite(upper[i])):
            return Status.NOT_FINITE.value
    for j in range(target.shape[0]):
        if not math.isfinite(target[j]):
            return Status.NOT_FINITE.value
    p.ordered = True
    for i in range(lower.shape[0]):
        if not upper[i] >= lower[i]:
            p.ordered = False
            return Status.OK.value
    for j in range(p.g.shape[0]):
        p.g[j] = p.neg_w[j] * target[j]
    return Status.OK.value


@kernel
def _check_answer(state: np.ndarray, x: np.ndarray) -> None:  # pragma: no cover - compiled
    """Check lower ≤ [C; I] x ≤ upper within FEASIBILITY_TOL, independently of the solver.

    Writes ``feasible``; if feasible, also x rounded into the box to ``x``
    and the number of rows and box bounds within ACTIVE_TOL of a limit to
    ``active``.  A non-finite x is not feasible.
    """
    p = state[0]
    c_all, lower_all, upper_all = p.C, p.lower, p.upper
    n_in = c_all.shape[0] - x.shape[0]
    active = 0
    for i in range(c_all.shape[0]):
        acc = 0.0
        for j in range(c_all.shape[1]):
            acc += c_all[i, j] * x[j]
        room = min(acc - lower_all[i], upper_all[i] - acc)
        if not room >= -FEASIBILITY_TOL:
            p.feasible = False
            return
        if room <= ACTIVE_TOL:
            active += 1
    for j in range(x.shape[0]):
        p.x[j] = max(min(x[j], upper_all[n_in + j]), lower_all[n_in + j])
    p.active = active
    p.feasible = True


class TorqueQP:
    """Persistent proxsuite workspace for ``min ½ (x − x_t)ᵀ W (x − x_t)`` (module docstring).

    Subject to ``lower ≤ C x ≤ upper`` and ``lo ≤ x ≤ hi``.  The problem data
    live in :attr:`record`, exposed as writable views (:attr:`target`,
    :attr:`C`, :attr:`lower`, :attr:`upper`, :attr:`lo`, :attr:`hi`); fill
    them and call :meth:`solve_in_place`, or pass arrays to :meth:`solve`.
    Each solve updates g, C, the bounds and the box and solves warm-started
    from the previous result (the first solve, and the first after a
    failure, initialise).

    Args:
        weights: diagonal of W, (n,), each finite and > 0.
        n_in: number of rows of C.
        max_iter: proxsuite's outer iteration limit (bounds a failing solve).
        eps_abs: proxsuite's absolute accuracy.

    Attributes:
        record: the problem and the verdicts (:func:`workspace_fields`).
        x: the accepted solution of the last solve (stale after a failure).
        status: ``"solved"`` or why the last solve failed.
        active: active rows plus active box bounds of the accepted solution.
        solve_time_us: wall time of the last solve, checks included [µs].
        reinits: re-initialisations after a failed warm-started solve.

    Raises:
        InvalidParameter: a weight not finite and > 0, or max_iter not an
            integer in [1, 10000].

    """

    def __init__(
        self, weights: np.ndarray, n_in: int, max_iter: int = 100, eps_abs: float = 1e-9
    ) -> None:
        w = np.asarray(weights, dtype=float)
        if w.ndim != 1 or w.size < 1 or not np.all(np.isfinite(w)) or not np.all(w > 0):
            raise InvalidParameter("torque_weights", weights, "finite and > 0, one per joint")
        if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)):
            raise InvalidParameter("max_iter", max_iter, "an integer in [1, 10000]")
        if not 1 <= max_iter <= 10_000:
            raise InvalidParameter("max_iter", max_iter, "an integer in [1, 10000]")
        n, n_in = w.size, int(n_in)
        self.n, self.n_in = n, n_in
        self.record = record(workspace_fields(n, n_in))
        rec = self.record
        rec["neg_w"] = -w
        self._H = np.diag(w)
        self._c_all = rec["C"][0]
        self._c_all[n_in:] = np.eye(n)
        lower, upper = rec["lower"][0], rec["upper"][0]
        #: Views to fill before :meth:`solve_in_place`.
        self.C = self._c_all[:n_in]
        self.lower = lower[:n_in]
        self.upper = upper[:n_in]
        self.lo = lower[n_in:]
        self.hi = upper[n_in:]
        self.target = rec["target"][0]
        self.x = rec["x"][0]
        self._g = rec["g"][0]
        self._ordered = self.record["ordered"]
        self._feasible = self.record["feasible"]
        self._active = self.record["active"]
        #: proxsuite's settings for this workspace, applied when it takes the solver.
        self._settings = {
            "eps_abs": float(eps_abs),
            "eps_rel": 0.0,
            "max_iter": int(max_iter),
            # proxsuite's inner iterations per outer one: a warm start that stalls in the
            # inner loop ran 200 × 100 of them (50 ms a tick) before failing over to a cold
            # start.  50 gives up sooner: the default QP run 1.32 → 1.14 s and the spastic
            # one 1.11 → 0.66 s for 3,600 ticks; no fallback over tools/load_held.py's 600
            # runs (20: 0.92 and 0.62 s, but three runs fell back on one tick each).
            "max_iter_in": 50,
            "check_duality_gap": True,
            # The slack weight (1e4) scales the duals, so an absolute gap of 1e-8
            # stalled solves already at the optimum; the relative term follows
            # the scale of the cost.
            "eps_duality_gap_abs": 1e-6,
            "eps_duality_gap_rel": 1e-10,
            # The default 1e-4 reported feasible problems of this scale (bounds of
            # ~100 N) as PRIMAL_INFEASIBLE (~0.1 % of random instances).
            "eps_primal_inf": 1e-10,
            "verbose": False,
            "initial_guess": _WARM,
        }
        #: The solver, shared with the workspaces of this shape (:mod:`.solver_pool`).
        self._shared = shared_solver(n, n_in)
        self._qp = self._shared.qp
        self._token = object()  # this workspace, to the shared solver (not a reference to it)
        self._ready = False
        self.status = "not_run"
        self.active = 0
        self.solve_time_us = 0.0
        self.reinits = 0

    def solve(
        self,
        target: np.ndarray,
        C: np.ndarray,
        lower: np.ndarray,
        upper: np.ndarray,
        lo: np.ndarray,
        hi: np.ndarray,
    ) -> bool:
        """Copy the problem into the workspace and :meth:`solve_in_place`.

        Args:
            target: x_t, (n,).
            C: constraint rows, (n_in, n).
            lower: lower row bounds, (n_in,).
            upper: upper row bounds, (n_in,).
            lo: lower box bounds, (n,).
            hi: upper box bounds, (n,).

        Returns:
            Whether :attr:`x` holds an accepted, feasible optimum.

        """
        self.target[:] = target
        self.C[:] = C
        self.lower[:] = lower
        self.upper[:] = upper
        self.lo[:] = lo
        self.hi[:] = hi
        return self.solve_in_place()

    def solve_in_place(self) -> bool:
        """Solve the problem held in the workspace views; True if accepted (module docstring)."""
        start = time.perf_counter_ns()
        ok = self._solve()
        self.solve_time_us = (time.perf_counter_ns() - start) * 1e-3
        return ok

    def _solve(self) -> bool:
        if _prepare(self.record) != Status.OK:
            self.status = "non-finite problem data"
            return False
        if not self._ordered[0]:
            self.status = "infeasible bounds (lower > upper or lo > hi)"
            return False
        qp = self._qp
        if self._shared.take(self._token, self._settings):
            self._ready = False  # another workspace used the solver: initialise it again
        first = ""
        if self._ready:
            self.update_and_solve()
            if self._accept():
                return True
            first = self.status
            self.reinits += 1
        qp.settings.initial_guess = _COLD
        try:
            qp.init(self._H, self._g, None, None, self.C, self.lower, self.upper, self.lo, self.hi)
            qp.solve()
        finally:
            qp.settings.initial_guess = _WARM
        self._ready = self._accept()
        if not self._ready and first:
            self.status = f"{first}; after re-init: {self.status}"
        return self._ready

    def update_and_solve(self) -> None:
        """Warm-update proxsuite with the workspace's data, then solve (no checks).

        The equilibration computed at init is kept (the problem's scale
        changes slowly from tick to tick; recomputing it every tick cost
        about a third of the solve); a re-init recomputes it.
        """
        self._qp.update(
            g=self._g,
            C=self.C,
            l=self.lower,
            u=self.upper,
            l_box=self.lo,
            u_box=self.hi,
            update_preconditioner=False,
        )
        self._qp.solve()

    def _accept(self) -> bool:
        res = self._qp.results
        info_status = res.info.status
        if info_status != _SOLVED:
            self.status = _STATUS.get(info_status, "unknown solver status")
            return False
        _check_answer(self.record, res.x)
        if not self._feasible[0]:
            self.status = "solution violates the constraints or is not finite"
            return False
        self.active = int(self._active[0])
        self.status = "solved"
        return True
