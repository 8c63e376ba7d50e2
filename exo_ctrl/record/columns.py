"""A chunk of logged rows as rerun columns: packing, the exact signals, the series.

Per chunk of n ticks, :meth:`SignalColumns.pack` copies every signal of the
layout into one new float64 vector (signal s as its (n, w_s) row-major block
at n·offset_s, then the (n, m) block of the magnitudes
‖(x, z)‖ = hypot(x, z)).  Each entity's values are a zero-copy slice of
that vector, a list column of n rows of w scalars (``Scalars:scalars``),
and each entity goes to rerun as one ``send_columns`` call
(:class:`EntityBatch`), one rerun chunk per entity.  The rows handed over
may be views of any strides; nothing here assumes them contiguous.

Every array handed to rerun lives in pyarrow's memory pool, not in numpy's
(:func:`pool_array`): rerun's writer threads then free what they have
written without taking the interpreter lock, so they write while the loop
runs, and cannot wait on the lock at exit.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pyarrow as pa
import rerun as rr

from ..exceptions import RecordingError
from .format import TICK, TIME, Layout

__all__ = ["EntityBatch", "SignalColumns", "list_offsets", "pool_array", "pool_vector"]

_SCALARS = rr.Scalars.descriptor_scalars()
#: Cached list offsets and gather indices kept at most (one per chunk length in use).
_CACHE_MAX = 8


def pool_vector(size: int, dtype: type = np.float64) -> tuple[np.ndarray, pa.Buffer]:
    """A new writable numpy vector of ``size`` items over a buffer of pyarrow's memory pool."""
    buffer = pa.allocate_buffer(size * np.dtype(dtype).itemsize)
    return np.frombuffer(buffer, dtype=dtype), buffer


def pool_array(values: np.ndarray, kind: pa.DataType) -> pa.Array:
    """``values`` flattened (C order) and copied into pyarrow's memory pool, as arrow ``kind``."""
    flat = np.ascontiguousarray(values).reshape(-1)
    vector, buffer = pool_vector(flat.size, flat.dtype.type)
    vector[:] = flat
    return pa.Array.from_buffers(kind, flat.size, [None, buffer])


def list_offsets(rows: int, per_row: int) -> pa.Array:
    """Offsets 0, w, 2w, … rows·w (int32) of ``rows`` rows of ``per_row`` instances each."""
    return pool_array(np.arange(0, rows * per_row + 1, per_row, dtype=np.int32), pa.int32())


class _Index:
    """A timeline's values as an arrow array (rerun's TimeColumnLike protocol)."""

    __slots__ = ("array", "name")

    def __init__(self, name: str, array: pa.Array) -> None:
        self.name, self.array = name, array

    def timeline_name(self) -> str:
        return self.name

    def as_arrow_array(self) -> pa.Array:
        return self.array


class _Batch:
    """An arrow array of components (rerun's ComponentBatchLike protocol)."""

    __slots__ = ("array",)

    def __init__(self, array: pa.Array) -> None:
        self.array = array

    def as_arrow_array(self) -> pa.Array:
        return self.array


class EntityBatch:
    """Columns of many entities on the same ticks: one ``send_columns`` call per entity.

    Args:
        ticks: the ticks k of the rows, (n,).
        dt: the control period Δt [s]; ``sim_time`` is k Δt (whole ns, rerun's
            conversion of ``duration=k Δt``).

    """

    def __init__(self, ticks: np.ndarray, dt: float) -> None:
        ns = rr.TimeColumn(TIME, duration=ticks * dt).as_arrow_array()
        self.index = [
            _Index(TIME, pool_array(ns.cast(pa.int64()).to_numpy(), ns.type)),
            _Index(TICK, pool_array(ticks.astype(np.int64), pa.int64())),
        ]
        self.columns: dict[str, list[rr.ComponentColumn]] = {}

    def add(self, entity: str, descriptor: Any, values: pa.Array, offsets: pa.Array) -> None:
        """Add ``entity``'s component: row i is ``values[offsets[i]:offsets[i + 1]]``."""
        column = rr.ComponentColumn(descriptor, _Batch(values), offsets=offsets)
        self.columns.setdefault(entity, []).append(column)

    def send(self, rec: rr.RecordingStream) -> None:
        """Send every entity's columns (one rerun chunk per entity)."""
        for entity, columns in self.columns.items():
            rec.send_columns(entity, indexes=self.index, columns=columns, strict=True)


class SignalColumns:
    """The signals of a layout, chunk by chunk, as rerun columns.

    Args:
        layout: where each signal sits, and the series built from them.

    """

    def __init__(self, layout: Layout) -> None:
        self.layout = layout
        self._widths = {name: math.prod(shape) for name, shape in layout.shapes.items()}
        self._gather: dict[int, np.ndarray] = {}
        self._offsets: dict[tuple[int, int], pa.Array] = {}

    def prepare(self, n: int) -> None:
        """Build the cached index and offsets of chunks of ``n`` ticks ahead of the first one."""
        self._gather_index(n)
        for w in {*self._widths.values(), *(len(s.columns) for s in self.layout.series)}:
            self._list_offsets(n, w)

    def pack(self, rows: dict[str, np.ndarray], skip: int, n: int) -> tuple[np.ndarray, pa.Array]:
        """Rows ``skip:skip+n`` of every signal, then the magnitudes, as one new float64 vector.

        The vector is new each chunk (rerun may still be writing the previous
        one), in pyarrow's memory pool.

        Returns:
            The vector as numpy (to read) and as arrow (to send) views.

        Raises:
            RecordingError: ``rows`` lacks a signal of the layout.

        """
        lay = self.layout
        extra = len(lay.magnitudes)
        size = n * (lay.width + extra)
        source, buffer = pool_vector(size)
        for name, shape in lay.shapes.items():
            if name not in rows:
                raise RecordingError(f"the rows lack the signal {name!r} of the log schema")
            off = n * lay.offsets[name]
            source[off : off + n * self._widths[name]].reshape(n, *shape)[...] = rows[name][skip:]
        if extra:
            mags = source[n * lay.width :].reshape(n, extra)
            for m, (x, z) in enumerate(lay.magnitudes):
                mags[:, m] = np.hypot(self._column(source, n, x), self._column(source, n, z))
        return source, pa.Array.from_buffers(pa.float64(), size, [None, buffer])

    def signal(self, source: np.ndarray, n: int, name: str) -> np.ndarray:
        """Signal ``name`` of a packed chunk, (n, *shape) (a view)."""
        off = n * self.layout.offsets[name]
        block = source[off : off + n * self._widths[name]]
        return block.reshape(n, *self.layout.shapes[name])

    def send_raw(
        self, rec: rr.RecordingStream, ticks: np.ndarray, dt: float, values: pa.Array
    ) -> None:
        """Send ``raw/{signal}`` of every signal; ``values`` is the packed chunk (arrow)."""
        n, lay = ticks.shape[0], self.layout
        batch = EntityBatch(ticks, dt)
        for name in lay.shapes:
            w = self._widths[name]
            block = values.slice(n * lay.offsets[name], n * w)
            batch.add(f"raw/{name}", _SCALARS, block, self._list_offsets(n, w))
        batch.send(rec)

    def send_series(
        self, rec: rr.RecordingStream, ticks: np.ndarray, dt: float, source: np.ndarray
    ) -> None:
        """Send the human-friendly series; ``source`` is the packed chunk (numpy)."""
        n = ticks.shape[0]
        gather = self._gather_index(n)
        series, buffer = pool_vector(gather.shape[0])
        np.take(source, gather, out=series)
        values = pa.Array.from_buffers(pa.float64(), gather.shape[0], [None, buffer])
        batch = EntityBatch(ticks, dt)
        at = 0
        for s in self.layout.series:
            w = len(s.columns)
            batch.add(s.entity, _SCALARS, values.slice(at, n * w), self._list_offsets(n, w))
            at += n * w
        batch.send(rec)

    def _gather_index(self, n: int) -> np.ndarray:
        gather = self._gather.get(n)
        if gather is None:
            if len(self._gather) >= _CACHE_MAX:
                self._gather.clear()
            gather = self._gather[n] = self.layout.gather_index(n)
        return gather

    def _column(self, source: np.ndarray, n: int, column: int) -> np.ndarray:
        """Column ``column`` of the extended row, as a strided view of ``source``."""
        lay = self.layout
        for name, w in self._widths.items():
            off = lay.offsets[name]
            if off <= column < off + w:
                return source[n * off + column - off : n * (off + w) : w]
        raise IndexError(column)

    def _list_offsets(self, n: int, width: int) -> pa.Array:
        """Offsets of n rows of ``width`` scalars (cached: rerun may hold them)."""
        key = (n, width)
        if key not in self._offsets:
            if len(self._offsets) >= 4 * _CACHE_MAX:
                self._offsets.clear()
            self._offsets[key] = list_offsets(n, width)
        return self._offsets[key]
