r"""The QP's cuff rows: the octagon bound, the clip test, and the screening of rows for proxsuite.

**Octagon rows.**  ``|f_c(t_i)| ≤ F_max`` is replaced by a regular polygon
of :data:`POLYGON_SIDES` = 8 sides inscribed in the circle:
``|n_kᵀ f_c| ≤ r_c = (F_max − m_c) cos(π/8)`` (m_c the cuff's margin,
:mod:`~exo_ctrl.control.qp.margin`) for ``n_k = (cos kπ/4, sin kπ/4)``,
k = 0 … 3, each as two one-sided rows; with f = A τ + b (the horizon
prediction) and one slack s_c per cuff, row ``16 p + 4 c + k`` of the
32 P rows is ``n_kᵀ (A τ + b)_c − s_c ≤ r`` and row ``16 P + 16 p + 4 c + k``
the same with −n_k (:func:`bound_rows`).  The vertices lie on the circle, so
the polygon is at most 7.6 % conservative.

**Clip test** (:func:`clip_if_feasible`).  With W diagonal, the QP without
its cuff rows is solved by clipping τ_cmd into the torque box (slacks zero).
That QP is a relaxation of the full one, so when the clipped τ_cmd meets
every cuff row (exactly, no tolerance) it is the full QP's optimum and
proxsuite is not needed.

**Screening** (:func:`screen`, :func:`widen`).  Only a few of the 32 P rows
can bind at once, and proxsuite's cost grows with its rows (measured on
2,400 recorded ticks of the spastic run: 8 rows ≈ 44 µs, 16 ≈ 51 µs, 160
≈ 148 µs a solve).  proxsuite gets the :data:`SCREENED_ROWS` rows most
nearly binding — the largest ``n_kᵀ f_c(τ) − r`` at τ_cmd or at the last
tick's torque; its answer is checked against every row, and a QP over a
subset of the rows being a relaxation of the full one, an answer that meets
them all is the full problem's optimum.  Otherwise the violated rows
replace the slackest screened ones and the QP is solved again, at most
:data:`SCREEN_ROUNDS` times in all.  A row keeps its slot from tick to tick
while it stays screened, so the warm start's multipliers stay with their
rows.

All are compiled functions on plain arrays, called from the controller's
kernels (:mod:`~exo_ctrl.control.qp.controller`).
"""

from __future__ import annotations

import math

import numpy as np

from ..._jit import kernel
from .workspace import ACTIVE_TOL, FEASIBILITY_TOL

__all__ = [
    "POLYGON_SIDES",
    "SCREENED_ROWS",
    "SCREEN_ROUNDS",
    "bound_rows",
    "clip_if_feasible",
    "copy_rows",
    "polygon_rows",
    "screen",
    "widen",
]

#: Sides of the regular polygon inscribed in each cuff's force circle (even).
POLYGON_SIDES = 8
#: Cuff rows handed to proxsuite each tick (of 32 per horizon point).
SCREENED_ROWS = 16
#: Solves per tick with the screened rows widened by the violated ones, at most.
SCREEN_ROUNDS = 4


def polygon_rows(n_cuffs: int = 4) -> np.ndarray:
    """Row directions of the inscribed polygons, (n_cuffs·S/2, 2·n_cuffs).

    With S = :data:`POLYGON_SIDES`, row ``c·S/2 + k`` holds
    ``n_k = (cos 2πk/S, sin 2πk/S)`` in cuff c's (f_x, f_z) columns
    ``2c, 2c+1``.  Taken with both signs, ``|n_kᵀ f_c| ≤ r`` for
    k = 0 … S/2 − 1 are the S edges of a regular S-gon of apothem r.
    """
    half = POLYGON_SIDES // 2
    rows = np.zeros((n_cuffs * half, 2 * n_cuffs))
    for c in range(n_cuffs):
        for k in range(half):
            angle = k * math.pi / half
            rows[c * half + k, 2 * c] = math.cos(angle)
            rows[c * half + k, 2 * c + 1] = math.sin(angle)
    return rows


@kernel
def bound_rows(
    directions: np.ndarray,
    A: np.ndarray,
    b: np.ndarray,
    radius: np.ndarray,
    rows_C: np.ndarray,
    rows_upper: np.ndarray,
) -> float:  # pragma: no cover - compiled
    """Fill the cuff rows ±n_kᵀ(A τ + b)_c ≤ r_c (τ columns) and their bounds.

    ``radius``: r_c per cuff, (4,) [N] (the tightened bound's apothem,
    :mod:`~exo_ctrl.control.qp.margin`).

    Row ``16 p + 4 c + k`` (and the same plus half the rows, negated) holds
    n_k = ``directions[k]`` on cuff c's (f_x, f_z) rows ``8 p + 2c, +1`` of
    (A, b); only the τ columns (0-3) of ``rows_C`` are written (the slack
    columns are constant).  Returns the sum of every entry written: finite
    iff they all are.
    """
    half = directions.shape[0]
    n_poly = rows_C.shape[0] // 2
    total = 0.0
    for p in range(A.shape[0] // 8):
        for c in range(4):
            ix = 8 * p + 2 * c
            for k in range(half):
                cx, cz = directions[k, 0], directions[k, 1]
                row = p * 4 * half + c * half + k
                for j in range(4):
                    na = cx * A[ix, j] + cz * A[ix + 1, j]
                    rows_C[row, j] = na
                    rows_C[n_poly + row, j] = -na
                    total += na
                nb = cx * b[ix] + cz * b[ix + 1]
                rows_upper[row] = radius[c] - nb
                rows_upper[n_poly + row] = radius[c] + nb
                total += nb
    return total


@kernel
def clip_if_feasible(
    rows: np.ndarray,
    upper: np.ndarray,
    target: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    torque: np.ndarray,
) -> tuple[bool, int]:  # pragma: no cover - compiled
    """τ = τ_cmd clipped into the box [lo, hi], if it meets every cuff row with zero slack.

    Returns (feasible, active): whether it does (exactly: n_kᵀ f_c(τ) ≤ r,
    no tolerance), and then the number of box bounds and rows within
    ACTIVE_TOL of their limit, with τ written to ``torque``.  Not feasible
    (``torque`` untouched) if a row is violated, the box is empty or an
    entry of τ_cmd is not finite.
    """
    for j in range(4):
        if not (lo[j] <= hi[j] and math.isfinite(target[j])):
            return False, 0
    active = 0
    for j in range(4):
        t = min(max(target[j], lo[j]), hi[j])
        if t - lo[j] <= ACTIVE_TOL or hi[j] - t <= ACTIVE_TOL:
            active += 1
    for i in range(rows.shape[0]):
        acc = 0.0
        for j in range(4):
            acc += rows[i, j] * min(max(target[j], lo[j]), hi[j])
        room = upper[i] - acc
        if not room >= 0.0:
            return False, 0
        if room <= ACTIVE_TOL:
            active += 1
    for j in range(4):
        torque[j] = min(max(target[j], lo[j]), hi[j])
    return True, active


@kernel
def screen(
    rows: np.ndarray,
    upper: np.ndarray,
    tau_a: np.ndarray,
    tau_b: np.ndarray,
    value: np.ndarray,
    mark: np.ndarray,
    slots: np.ndarray,
    qp_C: np.ndarray,
    qp_upper: np.ndarray,
) -> None:  # pragma: no cover
    """Put the ``len(slots)`` cuff rows most nearly binding into the QP's rows.

    A row's measure is max over τ ∈ {τ_a, τ_b} of its τ part at τ minus its
    bound (slacks at zero).  A row already in a slot that is chosen again
    keeps that slot; the others take the freed slots in row order.
    ``value`` and ``mark`` are scratch, one entry per cuff row.
    """
    n = rows.shape[0]
    for i in range(n):
        a = 0.0
        b = 0.0
        for j in range(4):
            a += rows[i, j] * tau_a[j]
            b += rows[i, j] * tau_b[j]
        value[i] = max(a, b) - upper[i]
        mark[i] = 0
    for _ in range(slots.shape[0]):
        best = -1
        for i in range(n):
            if mark[i] == 0 and (best < 0 or value[i] > value[best]):
                best = i
        mark[best] = 1
    for s in range(slots.shape[0]):  # chosen and already in place: keep
        if mark[slots[s]] == 1:
            mark[slots[s]] = 2
        else:
            slots[s] = -1
    nxt = 0
    for s in range(slots.shape[0]):
        if slots[s] < 0:
            while mark[nxt] != 1:
                nxt += 1
            slots[s] = nxt
            mark[nxt] = 2
    copy_rows(rows, upper, slots, qp_C, qp_upper)


@kernel
def widen(
    rows: np.ndarray,
    upper: np.ndarray,
    x: np.ndarray,
    value: np.ndarray,
    mark: np.ndarray,
    slots: np.ndarray,
    qp_C: np.ndarray,
    qp_upper: np.ndarray,
) -> int:  # pragma: no cover - compiled
    """Check x against every cuff row; swap violated ones into the QP's rows.

    Returns the number of rows not in the QP that x violates by more than
    FEASIBILITY_TOL (0: x meets every row, and the screened QP's optimum is
    the full QP's).  Those rows, most violated first, replace the screened
    rows with the most room at x (as many as there are slots).
    """
    n = rows.shape[0]
    m = slots.shape[0]
    for i in range(n):
        mark[i] = 0
    for s in range(m):
        mark[slots[s]] = 2
    violated = 0
    for i in range(n):
        acc = 0.0
        for j in range(rows.shape[1]):
            acc += rows[i, j] * x[j]
        value[i] = acc - upper[i]
        if mark[i] == 0 and not value[i] <= FEASIBILITY_TOL:
            mark[i] = 1
            violated += 1
    for _ in range(min(violated, m)):
        worst = -1
        for i in range(n):
            if mark[i] == 1 and (worst < 0 or value[i] > value[worst]):
                worst = i
        roomy = -1
        for s in range(m):
            if mark[slots[s]] == 2 and (roomy < 0 or value[slots[s]] < value[slots[roomy]]):
                roomy = s
        mark[slots[roomy]] = 0
        slots[roomy] = worst
        mark[worst] = 3  # just added: stays
    if violated:
        copy_rows(rows, upper, slots, qp_C, qp_upper)
    return violated


@kernel
def copy_rows(
    rows: np.ndarray, upper: np.ndarray, slots: np.ndarray, qp_C: np.ndarray, qp_upper: np.ndarray
) -> None:  # pragma: no cover - compiled
    """QP row s := cuff row ``slots[s]`` (all columns) and its bound."""
    for s in range(slots.shape[0]):
        r = slots[s]
        for j in range(rows.shape[1]):
            qp_C[s, j] = rows[r, j]
        qp_upper[s] = upper[r]
