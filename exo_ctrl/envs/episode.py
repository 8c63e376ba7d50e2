"""One episode of the environment: the run's ticks, advanced a few at a time.

:class:`Episode` is :func:`~exo_ctrl.sim.simulate`'s loop cut at the
command: it builds the run (:func:`~exo_ctrl.sim.setup.build`, the
:class:`~exo_ctrl.sim.tick.Runner`), reads the sensors of the first tick
(:meth:`~exo_ctrl.sim.tick.Runner.measure`), and :meth:`Episode.advance`
then finishes that tick with the pending command
(:meth:`~exo_ctrl.sim.tick.Runner.act`) and runs on, tick after tick, to
the readings of the next step's first tick.  The log's chunks go to the
run's statistics and observers (the recorder) as in ``simulate``; no
history is kept.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from .._jit import kernel
from ..exceptions import SimulationDiverged
from ..plan.rows import plan_row
from ..sensing.readings import SensorReadings
from ..sim import SimConfig, SimObserver, build
from ..sim.loop import end_result, new_result
from ..sim.tick import Runner
from .reward import drawn_energy_J, log_terms

__all__ = ["Episode"]


class Episode:
    """A run driven from outside, a few ticks at a time (module docstring).

    Args:
        config: the run.
        observers: watchers of its chunks (a :class:`~exo_ctrl.record.RerunRecorder`).
        wrap: replaces the run's controller before the first tick (the
            residual action's wrapper), or None.

    Attributes:
        runner: the run's tick.
        result: its result (statistics, events; no history).
        k: the next tick to act on (its readings are :attr:`readings`).
        readings: the sensor readings of tick :attr:`k`.
        status: ``"running"``, ``"stopped"`` (the supervisor stopped the
            device), ``"diverged"`` or ``"ended"`` (the run's last tick done).

    """

    def __init__(
        self,
        config: SimConfig,
        observers: Sequence[SimObserver] = (),
        wrap: Callable[[Any], Any] | None = None,
    ) -> None:
        setup = build(config)
        if wrap is not None:
            setup.controller = wrap(setup.controller)
        self.config = config
        self.runner = Runner(setup)
        self.result = new_result(setup, 0)
        self.observers = tuple(observers)
        self._started: list[SimObserver] = []
        self._plan = None if setup.online is not None else setup.plan
        self._dt = config.dt
        motors = setup.plant.motors
        self._motors = motors.record if motors is not None else None
        self.k = 0
        self._row = 0
        self._chunk_start = 0
        self.status = "running"
        self._closed = False
        for obs in self.observers:
            obs.start(self.result)
            self._started.append(obs)
        self.readings: SensorReadings = self.runner.measure(0, 0)

    @property
    def stopped(self) -> bool:
        """Whether the supervisor has stopped the device."""
        sup = self.runner.supervisor
        return sup is not None and bool(sup.state_code)

    def advance(self, ticks: int) -> np.ndarray:
        """Act on tick :attr:`k` and run ``ticks`` ticks in all, or fewer if the episode ends.

        The episode ends at the tick the supervisor stops the device (status
        ``"stopped"``), on a divergence (``"diverged"``) or after the run's
        last tick (``"ended"``).

        Returns:
            The reward's terms over the ticks run (E_q, E_f, E_e: :mod:`.reward`), (3,).

        """
        runner, n = self.runner, self.config.n_ticks
        terms = np.zeros(3)
        first = self._row
        motors = self._motors
        drawn = 0.0 if motors is None else drawn_energy_J(motors)
        for _ in range(ticks):
            k, row = self.k, self._row
            try:
                runner.act(k, row, self.readings)
            except SimulationDiverged as exc:
                self._fail(exc)
                break
            self.k, self._row = k + 1, row + 1
            if self._row == runner.chunk:
                self._terms(first, self._row, terms)
                self._flush()
                first = 0
            if self.stopped:
                self.status = "stopped"
                break
            if self.k >= n:
                self.status = "ended"
                break
            self.readings = runner.measure(self.k, self._row)
        if self._row > first:
            self._terms(first, self._row, terms)
        if motors is not None:
            terms[2] = max(drawn_energy_J(motors) - drawn, 0.0)  # a sum's rounding, not < 0
        return terms

    def _terms(self, first: int, end: int, out: np.ndarray) -> None:
        """Add E_q, E_f of the chunk's rows ``first:end`` to ``out`` (their plan rows copied in)."""
        log = self.runner.log
        plan = self._plan
        if plan is not None:  # a precomputed plan: its rows are otherwise logged at the flush
            plan_into_log(log, first, end, self._chunk_start + first, *plan.row_rule, plan.q)
        log_terms(log, first, end, self._dt, out)

    def _fail(self, exc: SimulationDiverged) -> None:
        """End the episode on a divergence, as :func:`~exo_ctrl.sim.simulate` ends the run."""
        self.status = "diverged"
        self.result.status = "diverged"
        self.result.error = str(exc)
        self.result.events.append({"t": exc.time, "kind": "diverged", "message": str(exc)})

    def _flush(self) -> None:
        """Hand the chunk's acted rows to the statistics and the observers."""
        rows = self._row
        if rows == 0:
            return
        runner, start = self.runner, self._chunk_start
        runner.fill_plan(start, rows)
        view = {name: arr[:rows] for name, arr in runner.buf.items()}
        self.result.stats.update(view)
        for obs in self._started:
            obs.chunk(self.result, start, view)
        self._chunk_start += rows
        self._row = 0

    def close(self, reason: str) -> None:
        """End the episode: the last rows flushed, the result's end filled, the observers told.

        Args:
            reason: why it ended, the last event's message.

        An episode closed before the scenario's last tick (the supervisor's
        stop, or the environment reset or closed mid-episode) ends with the
        result's status ``"interrupted"`` and the reason in its ``error``, as
        a run cut short does; one that ran its last tick, ``"completed"``.
        Safe to call more than once (later calls do nothing).

        """
        if self._closed:
            return
        self._closed = True
        t = self.k * self._dt
        if self.status in ("running", "stopped") and self.result.status == "completed":
            # cut before the scenario's last tick: the result and its recording say so
            self.result.status = "interrupted"
            n = self.config.n_ticks
            self.result.error = f"ended after {self.k} of {n} ticks (t = {t:.4f} s): {reason}"
        error: Exception | None = None
        try:
            self._flush()
        except Exception as exc:  # the observers still finish, then it propagates
            error = exc
        end_result(self.result, self.runner)
        self.result.events.append({"t": t, "kind": "episode_end", "message": reason})
        for obs in self._started:
            try:
                obs.finish(self.result)
            except Exception as exc:
                error = error or exc
        if error is not None:
            raise error


@kernel
def plan_into_log(log, first, end, k0, lead, period, tail, plan_q):  # pragma: no cover
    """The plan's q* of ticks k0, k0 + 1, … into the log's rows ``first:end`` (``q_des``)."""
    for i in range(first, end):
        row = plan_row(k0 + i - first, lead, period, tail)
        for j in range(4):
            log[i].q_des[j] = plan_q[row, j]
