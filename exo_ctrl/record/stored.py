"""Where a recording stores each signal's values, and the signals rebuilt from them.

A version 2 recording (:mod:`.format`) stores every value once, in the
series that shows it; ``raw/meta`` says, per stored entity, which signal and
which component of its row each of the entity's components holds
(``"columns"``), and gives the constant of each signal the run left out
(``"left_out"``, :mod:`.omitted`).  A version 1 recording held each signal
whole under ``raw/{signal}``.  :func:`where_stored` reads either layout,
:func:`assemble` rebuilds the signals from the entities' rows.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from ..exceptions import RecordingError
from .format import TICK

__all__ = ["assemble", "scalar_rows", "where_stored"]


def scalar_rows(path: Path, entity: str, batch: pa.RecordBatch) -> tuple[np.ndarray, np.ndarray]:
    """(ticks (n,), values (n, width)) of one chunk of a multi-component Scalars entity."""
    ticks = batch.column(TICK).to_numpy(zero_copy_only=False).astype(np.int64)
    column = batch.column("Scalars:scalars")
    lengths = pc.list_value_length(column).to_numpy(zero_copy_only=False)
    n = ticks.shape[0]
    if n == 0:
        return ticks, np.zeros((0, 0))
    width = int(lengths[0])
    if column.null_count or np.any(lengths != width):
        raise RecordingError(f"cannot read recording {path}: {entity} has rows of unequal width")
    values = column.flatten().to_numpy(zero_copy_only=False).astype(np.float64, copy=False)
    return ticks, values.reshape(n, width)


def where_stored(
    path: Path, meta: dict[str, Any], layout: dict[str, tuple[int, ...]]
) -> tuple[dict[str, list[tuple[str, int] | None]], dict[str, float]]:
    """Where each value is stored, and the constants of the signals left out.

    The first: entity → per component (signal, index), or None (a magnitude).

    Version 2 files say so in ``raw/meta`` (``"columns"``, ``"left_out"``:
    :mod:`.format`); version 1 files hold each signal whole under
    ``raw/{signal}`` and leave nothing out.
    """
    columns = meta.get("columns")
    if columns is None:
        return {f"raw/{k}": [(k, i) for i in range(math.prod(v))] for k, v in layout.items()}, {}
    try:
        where = {
            str(entity): [None if c is None else (str(c[0]), int(c[1])) for c in comps]
            for entity, comps in columns.items()
        }
        left_out = {str(k): float(v) for k, v in (meta.get("left_out") or {}).items()}
    except (AttributeError, TypeError, ValueError, IndexError):
        raise RecordingError(
            f"cannot read recording {path}: raw/meta's columns are malformed"
        ) from None
    return where, left_out


def assemble(
    path: Path,
    layout: dict[str, tuple[int, ...]],
    where: dict[str, list[tuple[str, int] | None]],
    left_out: dict[str, float],
    rows: dict[str, list[tuple[np.ndarray, np.ndarray]]],
) -> dict[str, np.ndarray]:
    """Signal arrays (name → (N, *shape)) over the ticks 0 … N-1 every stored signal has.

    ``where``: entity → what each component holds (:func:`where_stored`);
    ``rows``: entity → (ticks, values) of its chunks.  A left-out signal is
    its constant wherever no entity holds it.
    """
    stored: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    n_common: int | None = None
    for entity, comps in where.items():
        parts = rows.get(entity, [])
        width = len(comps)
        if parts:
            ticks = np.concatenate([t for t, _ in parts])
            values = np.concatenate([v.reshape(-1, width) for _, v in parts if v.size], axis=0)
        else:
            ticks, values = np.zeros(0, dtype=np.int64), np.zeros((0, width))
        if any(v.shape[1:] != (width,) for _, v in parts if v.size) or (
            values.shape[0] != ticks.shape[0]
        ):
            raise RecordingError(f"cannot read recording {path}: {entity} has a bad row width")
        ticks, first = np.unique(ticks, return_index=True)  # sorted; duplicates dropped
        stored[entity] = (ticks, values[first])
        if not any(c is not None and c[0] in layout and c[0] not in left_out for c in comps):
            continue  # holds left-out signals only: from any tick on
        n = ticks.shape[0]
        if n and (ticks[0] != 0 or ticks[-1] != n - 1):
            missing = np.setdiff1d(np.arange(ticks[-1] + 1), ticks)
            raise RecordingError(
                f"cannot read recording {path}: {entity} misses {missing.size} ticks "
                f"(first {int(missing[0])})"
            )
        n_common = n if n_common is None else min(n_common, n)
    n = n_common or 0
    out = {
        name: np.full((n, math.prod(shape)), left_out.get(name, np.nan))
        for name, shape in layout.items()
    }
    found = {name: np.zeros(math.prod(shape), bool) for name, shape in layout.items()}
    for entity, (ticks, values) in stored.items():
        keep = ticks < n
        for k, comp in enumerate(where[entity]):
            if comp is None or comp[0] not in out or not 0 <= comp[1] < found[comp[0]].size:
                continue
            name, i = comp
            found[name][i] = True
            if name in left_out:
                out[name][ticks[keep], i] = values[keep, k]
            else:
                out[name][:, i] = values[:n, k]
    for name, seen in found.items():
        if name not in left_out and not seen.all():
            raise RecordingError(
                f"cannot read recording {path}: raw/meta says nowhere where {name}"
                f"[{int(np.argmin(seen))}] is stored"
            )
    return {name: out[name].reshape(n, *shape) for name, shape in layout.items()}
