"""Which row of a run's joint plan each control tick reads: one rule, one kernel.

A run's plan holds its rows at the control ticks t_k = k Δt.  A gait whose
period is a whole number P of ticks repeats, so the plan need not grow with
the run: it holds the L ramp-in ticks, then one period, then the ticks of the
ramp-out from tick K (its tail), and tick k reads row

    r(k) = k                        for k < L,
    r(k) = L + (k - L) mod P        for L ≤ k < K,
    r(k) = L + P + (k - K)          for k ≥ K

(:func:`plan_row`; without a period, r(k) = k: the plan holds every tick).
Without a ramp (L = 0, no tail) it is today's k mod P.  :func:`layout` decides
which form a run takes; the controllers' kernels, the log's planned rows and
the plan's Python accessors all call :func:`plan_row`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._jit import kernel

__all__ = ["NO_TAIL", "RowLayout", "fill_rows", "layout", "plan_row"]

#: The tail tick of a plan without a ramp-out: no tick reaches it.
NO_TAIL = 2**62


@kernel
def plan_row(k: int, lead: int, period: int, tail: int) -> int:  # pragma: no cover - compiled
    """The plan row of tick ``k`` (module docstring): L = ``lead``, P = ``period``, K = ``tail``.

    A period of 0 means every tick has its row (r = k).
    """
    if period <= 0 or k < lead:
        return k
    if k < tail:
        return lead + (k - lead) % period
    return lead + period + (k - tail)


@kernel
def fill_rows(
    start: int, out: np.ndarray, lead: int, period: int, tail: int
) -> None:  # pragma: no cover - compiled
    """``out[i]`` = :func:`plan_row` of tick ``start + i``."""
    for i in range(out.shape[0]):
        out[i] = plan_row(start + i, lead, period, tail)


@dataclass(frozen=True)
class RowLayout:
    """The rows of a run's plan and the ticks they belong to.

    Attributes:
        rows: number of plan rows.
        lead: L, ramp-in ticks (t_k < T_r) held before the period.
        period: P, the gait period in ticks; 0: the plan holds every tick.
        tail: K, the first tick of the ramp-out (:data:`NO_TAIL`: none).

    """

    rows: int
    lead: int = 0
    period: int = 0
    tail: int = NO_TAIL

    def ticks(self) -> np.ndarray:
        """The tick index of each row, (rows,)."""
        if not self.period:
            return np.arange(self.rows)
        head = np.arange(self.lead + self.period)
        return np.concatenate((head, self.tail + np.arange(self.rows - head.size)))

    def row(self, k: int) -> int:
        """The row of tick ``k`` (:func:`plan_row`)."""
        return int(plan_row(int(k), self.lead, self.period, self.tail))


def layout(
    n_ticks: int,
    dt: float,
    period_s: float,
    ramp_in_s: float = 0.0,
    ramp_out_s: float = 0.0,
    end_s: float | None = None,
) -> RowLayout:
    """The plan rows of a run of ``n_ticks`` ticks of Δt = ``dt`` [s] (rows for ticks 0..n).

    The compact form (module docstring) when the period [s] is a whole number
    P ≥ 2 of ticks and its L + P + (tail) rows are fewer than the n + 1
    ticks, else every tick.  L counts the ticks before the ramp-in time,
    the tail the ticks after t_e - T_o (t_e: ``end_s``, default n Δt).
    """
    full = RowLayout(rows=n_ticks + 1)
    ticks = period_s / dt
    p = round(ticks)
    if not (p >= 2 and abs(p - ticks) <= 1e-9 * ticks):
        return full
    lead = min(max(math.ceil(ramp_in_s / dt - 1e-9), 0), n_ticks + 1)
    tail = NO_TAIL
    tail_rows = 0
    if ramp_out_s > 0.0:
        end = n_ticks * dt if end_s is None else end_s
        tail = max(math.floor((end - ramp_out_s) / dt + 1e-9) + 1, lead)
        tail_rows = max(n_ticks + 1 - tail, 0)
    rows = lead + p + tail_rows
    if rows > n_ticks:
        return full
    return RowLayout(rows=rows, lead=lead, period=p, tail=tail)
