"""The first run's compile helper (:mod:`exo_ctrl.sim.warmup`), run as a module with a PID.

``python -m exo_ctrl.sim.warmup_helper PID`` reads a pickled
:class:`~exo_ctrl.sim.config.SimConfig` from standard input, builds the run
without starting it and calls the back half of its tick
(:meth:`~exo_ctrl.sim.tick.Runner.compile_back`), so that its kernels are
compiled into numba's cache; ends with its parent, process ``PID``.  It only
compiles: any error ends it quietly (the run's own process compiles what it
did not).
"""

from __future__ import annotations

import contextlib
import pickle
import sys

from .._lifetime import die_with_parent
from .setup import build
from .tick import Runner

__all__ = ["compile_back_half"]


def compile_back_half(parent_pid: int) -> None:
    """Build the run read from standard input; compile its tick's back half."""
    die_with_parent(parent_pid)
    config = pickle.loads(sys.stdin.buffer.read())
    setup = build(config, start=False)
    runner = Runner(setup, start=False)
    runner.compile_back()


if __name__ == "__main__":
    with contextlib.suppress(BaseException):
        compile_back_half(int(sys.argv[1]))
