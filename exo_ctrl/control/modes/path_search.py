"""The path mode's searches along the planned foot path: the phase ahead and the nearest point.

Both scan the path's rows (:mod:`exo_ctrl.control.modes.path`, steps 2 and 3)
coarse to fine: every :data:`STRIDE`-th row of the window, then the rows
about the best of them.  The plan's rows are a tick apart, about a
millimetre of the foot's path (the feet move at about 1 m/s at most), so
the coarse rows are about a centimetre apart at most and the fine pass
finds the window's nearest row unless two parts of the path lie within
that of the same distance, where either is as near.  Against the scan of
every row it cuts the path mode's tick from 58 to 38 µs
(``tools/bench.py --scenarios path``) with the default window of the whole
period.
"""

from __future__ import annotations

from ..._jit import kernel, leaf

__all__ = ["STRIDE", "nearest_point", "phase_step"]

#: The searches' coarse stride [rows].
STRIDE = 8


@kernel
def _wrap_row(r, lead, period, last, periodic):  # pragma: no cover - compiled
    """Row r kept in the period's loop (periodic) or in [0, last]."""
    if periodic:
        return lead + (r - lead) % period
    if r < 0:
        return 0
    if r > last:
        return last
    return r


@kernel
def nearest_point(pos, leg, px, pz, row, window, lead, period, periodic, out):  # pragma: no cover
    """Nearest point of leg's path polyline to (px, pz) within ``window`` rows of ``row``.

    ``out`` = (cx, cz, d², r*): the closest vertex r* first, then the
    projections on the two segments either side of it.
    """
    last = pos.shape[0] - 1
    best, best_i = 1e300, 0
    for i in range(-window, window + 1, STRIDE):  # coarse, then the rows about the best
        r = _wrap_row(row + i, lead, period, last, periodic)
        dx, dz = px - pos[r, leg, 0], pz - pos[r, leg, 1]
        d2 = dx * dx + dz * dz
        if d2 < best:
            best, best_i = d2, i
    best, best_r = 1e300, row
    for i in range(max(-window, best_i - STRIDE), min(window, best_i + STRIDE) + 1):
        r = _wrap_row(row + i, lead, period, last, periodic)
        dx, dz = px - pos[r, leg, 0], pz - pos[r, leg, 1]
        d2 = dx * dx + dz * dz
        if d2 < best:
            best, best_r = d2, r
    out[0], out[1], out[2], out[3] = pos[best_r, leg, 0], pos[best_r, leg, 1], best, best_r
    for side in (-1, 1):
        r2 = _wrap_row(best_r + side, lead, period, last, periodic)
        ax, az = pos[best_r, leg, 0], pos[best_r, leg, 1]
        ex, ez = pos[r2, leg, 0] - ax, pos[r2, leg, 1] - az
        length2 = ex * ex + ez * ez
        if length2 <= 0.0:
            continue
        u = ((px - ax) * ex + (pz - az) * ez) / length2
        if u <= 0.0 or u >= 1.0:
            continue
        cx, cz = ax + u * ex, az + u * ez
        d2 = (px - cx) ** 2 + (pz - cz) ** 2
        if d2 < out[2]:
            out[0], out[1], out[2] = cx, cz, d2


@leaf
def phase_step(s, pos, lo, hi, stride):  # pragma: no cover - compiled
    """The step i ∈ [lo, hi] (every ``stride``-th) minimising Σ_legs |p − c(σ + i)|².

    ``s``: the path record (its feet, phase σ and the plan's row rule).
    """
    best, step = 1e300, lo
    for i in range(lo, hi + 1, stride):
        r = s.lead + (s.phase + i) % s.period
        cost = 0.0
        for leg in range(2):
            dx = s.foot[leg, 0] - pos[r, leg, 0]
            dz = s.foot[leg, 1] - pos[r, leg, 1]
            cost += dx * dx + dz * dz
        if cost < best:
            best, step = cost, i
    return step
