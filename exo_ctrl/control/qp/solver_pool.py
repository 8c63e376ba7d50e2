"""proxsuite's dense solvers, one per problem shape and thread, reused from run to run.

proxsuite's vectorised dense solver returns, for the same problems after the
same history, solutions whose last bits depend on the solver object: on
where its buffers were allocated.  Measured with
``.venv/bin/python tools/qp_repeat.py`` (two runs of the ``spastic-qp``
preset in one process, each building its own solver): in about half the
trials the 7th solve of each run got the same problem, bit for bit, and
returned solutions 4.4e-16 N·m apart.  With one solver object reused by
both runs, re-initialised cold by each, every trial was equal.

So :func:`shared_solver` hands out one :class:`SharedSolver` per shape
(n, n_in) and thread, and a workspace holds it only between its own solves:
one that finds that another workspace has used the solver since its own
last solve takes it over (:meth:`SharedSolver.take`: its settings applied,
then a cold re-initialisation on its next solve).  Workspaces that
interleave their solves stay correct, and lose their warm starts.
"""

from __future__ import annotations

import threading
from typing import Any

import proxsuite

__all__ = ["SharedSolver", "shared_solver"]

_LOCAL = threading.local()


class SharedSolver:
    """One proxsuite dense QP with box constraints, and the workspace that used it last.

    Args:
        n: variables.
        n_in: inequality rows.

    Attributes:
        qp: the solver (``proxsuite.proxqp.dense.QP(n, 0, n_in, True)``).

    """

    def __init__(self, n: int, n_in: int) -> None:
        self.qp = proxsuite.proxqp.dense.QP(n, 0, n_in, True)
        self._owner: object | None = None

    def take(self, owner: object, settings: dict[str, Any]) -> bool:
        """Make ``owner`` the solver's user; True if another had used it since (now taken over).

        On a take-over ``settings`` (proxsuite ``Settings`` attribute → value)
        are applied; the caller must then re-initialise before it solves.
        """
        if self._owner is owner:
            return False
        for name, value in settings.items():
            setattr(self.qp.settings, name, value)
        self._owner = owner
        return True


def shared_solver(n: int, n_in: int) -> SharedSolver:
    """The calling thread's solver for problems of ``n`` variables and ``n_in`` rows."""
    solvers: dict[tuple[int, int], SharedSolver] | None = getattr(_LOCAL, "solvers", None)
    if solvers is None:
        solvers = _LOCAL.solvers = {}
    solver = solvers.get((n, n_in))
    if solver is None:
        solver = solvers[(n, n_in)] = SharedSolver(n, n_in)
    return solver
