"""The one gait cycle of a run the comparison draws: which ticks, and keeping only them.

The figure shows the last full gait cycle at speed: with the ramp-in T_r,
the ramp-out T_o, the run's duration D and the gait period T_s, the
steady part [T_r, D − T_o] holds n = ⌊(D − T_o − T_r) / T_s⌋ whole cycles,
and the last starts at t₀ = T_r + (n − 1) T_s (:func:`cycle_ticks`).  A run
too short for one whole cycle, or the calibration exercise (no gait), is
drawn over its last T_s before the ramp-out.  A run that stopped early
(diverged, interrupted) is drawn over the last T_s it ran.  The cycle is
the gait's nominal period: a synchronised plan that changes the period
with the belt speed is drawn over that length all the same.

:class:`CycleKeeper` watches a live run (a :class:`~exo_ctrl.sim.SimObserver`)
and copies only those ticks of the few signals drawn into a ring buffer of
one period, so that a compared run keeps no history (``keep_history`` off);
:func:`trace_from_history` takes the same ticks from a whole history (a
recording read back), so both give the same trace.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..sim import SimConfig, signal_shapes
from .table import CycleTrace

__all__ = ["DRAWN", "CycleKeeper", "cycle_ticks", "trace_from_history"]

#: The signals the figure draws (:data:`exo_ctrl.sim.SIGNALS` names).
DRAWN = ("q", "q_des", "drive_torque", "cuff_force", "cuff_force_est")


def cycle_ticks(config: SimConfig) -> tuple[int, int]:
    """The ticks [k₀, k_end) of the cycle drawn, for a run that ran to its end (module docstring).

    Returns:
        (k₀, k_end): the first tick and one past the last, 0 ≤ k₀ < k_end ≤ n_ticks.

    """
    return _cycle(config)[:2]


def _cycle(config: SimConfig) -> tuple[int, int, bool]:
    """:func:`cycle_ticks`, and whether they are a whole gait cycle at speed."""
    n = config.n_ticks
    dt = config.dt
    period = max(round(config.gait.period / dt), 1)
    end_s = config.duration_s - config.ramp_out_s
    if config.exercise == "gait":
        whole = math.floor((end_s - config.ramp_in) / config.gait.period + 1e-9)
        if whole >= 1:
            start = round((config.ramp_in + (whole - 1) * config.gait.period) / dt)
            return start, min(start + period, n), True
    end = min(max(round(end_s / dt), 1), n)
    return max(end - period, 0), end, False


def _trace(config: SimConfig, window: tuple[int, int, bool], rows: dict) -> CycleTrace:
    """A :class:`CycleTrace` of the ticks ``window`` (:func:`_window`) from their ``rows``."""
    dt = config.dt
    first, last, complete = window
    return CycleTrace(
        t=np.arange(last - first) * dt,
        t0_s=first * dt,
        complete=complete,
        q=rows["q"],
        q_des=rows["q_des"],
        drive_torque=rows["drive_torque"],
        cuff_force=np.hypot(rows["cuff_force"][..., 0], rows["cuff_force"][..., 1]),
        cuff_force_est=np.hypot(rows["cuff_force_est"][..., 0], rows["cuff_force_est"][..., 1]),
    )


def _window(config: SimConfig, done: int) -> tuple[int, int, bool]:
    """(first, last, complete): the ticks drawn of a run that did ``done`` ticks.

    ``complete``: they are the whole gait cycle of :func:`cycle_ticks`.
    """
    start, end, whole = _cycle(config)
    last = min(done, end)
    first = max(last - (end - start), 0)
    return first, last, whole and (first, last) == (start, end)


def trace_from_history(config: SimConfig, signals: dict[str, np.ndarray]) -> CycleTrace | None:
    """The cycle drawn (:func:`cycle_ticks`) from a run's whole history (a recording's).

    None for a history without ticks.
    """
    window = _window(config, signals["q"].shape[0])
    first, last, _ = window
    if last <= first:
        return None
    rows = {name: np.asarray(signals[name][first:last]) for name in DRAWN}
    return _trace(config, window, rows)


class CycleKeeper:
    """Keeps a live run's cycle drawn (:func:`cycle_ticks`), one period of :data:`DRAWN`.

    A ring buffer of the cycle's length per signal holds the last ticks
    before the cycle's end, so a run that stops early still leaves its last
    period.  Use as an observer of :func:`exo_ctrl.sim.simulate`, then
    :meth:`trace`.
    """

    def __init__(self) -> None:
        self._config: SimConfig | None = None
        self._buf: dict[str, np.ndarray] = {}
        self._start = self._end = self._done = 0

    def start(self, result: Any) -> None:
        """Size the ring buffers for the run's cycle."""
        self._config = result.config
        self._start, self._end = cycle_ticks(result.config)
        length = self._end - self._start
        shapes = signal_shapes()
        self._buf = {name: np.zeros((length, *shapes[name])) for name in DRAWN}
        self._done = 0

    def chunk(self, result: Any, start: int, rows: dict[str, np.ndarray]) -> None:
        """Copy the chunk's ticks that may be drawn (the last period before the cycle's end)."""
        m = next(iter(rows.values())).shape[0]
        self._done = start + m
        length = self._end - self._start
        hi = min(start + m, self._end)
        lo = max(start, hi - length)
        if hi <= lo:
            return
        at = np.arange(lo, hi) % length
        for name, buf in self._buf.items():
            buf[at] = rows[name][lo - start : hi - start]

    def finish(self, result: Any) -> None:
        """Nothing to close."""

    def trace(self) -> CycleTrace | None:
        """The cycle drawn, or None before a run (or of a run with no tick)."""
        config = self._config
        if config is None:
            return None
        window = _window(config, self._done)
        first, last, _ = window
        if last <= first:
            return None
        at = np.arange(first, last) % (self._end - self._start)
        rows = {name: buf[at] for name, buf in self._buf.items()}
        return _trace(config, window, rows)
