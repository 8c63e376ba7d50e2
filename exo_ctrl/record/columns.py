"""A chunk of logged rows as rerun columns: the series, and the signals left out.

Per chunk of n ticks, :meth:`SignalColumns.series_values` copies every
component of every series sent straight from the rows handed over into one
new float64 vector (each series' (n, c) block row-major, one after the
other; a magnitude ‖(x, z)‖ = hypot(x, z) computed into its place).  Each
entity's values are a zero-copy slice of that vector, a list column of n
rows of c scalars (``Scalars:scalars``), and each entity goes to rerun as
one ``send_columns`` call (:class:`EntityBatch`), one rerun chunk per
entity.  The rows handed over may be views of any strides; nothing here
assumes them contiguous.

Each value is sent once (:mod:`.format`, version 2): in its series, or whole
under ``raw/{signal}`` for a signal some value of which no series shows.
The signals left out (:mod:`.omitted`) are not sent while every row of
theirs is their constant (:meth:`SignalColumns.check_left_out`).

Cost (rerun 0.41, measured here): rerun's work is per entity and chunk
(``send_columns`` about 70 µs in the calling thread, its encoding about
0.2 ms more) far more than per value, and every entity's rows carry a row
id (16 B) and both timelines (16 B) besides their list offsets (4 B) and
values (8 B each): the number of entities is what a recording costs.

Every array handed to rerun lives in pyarrow's memory pool, not in numpy's
(:func:`pool_array`): rerun's writer threads then free what they have
written without taking the interpreter lock, so they write while the loop
runs, and cannot wait on the lock at exit.
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
import pyarrow as pa
import rerun as rr

from ..exceptions import RecordingError
from .format import TICK, TIME, Layout, Series

__all__ = [
    "EntityBatch",
    "SignalColumns",
    "list_offsets",
    "log_styles",
    "pool_array",
    "pool_vector",
]

_SCALARS = rr.Scalars.descriptor_scalars()


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


@functools.lru_cache(maxsize=64)
def list_offsets(rows: int, per_row: int) -> pa.Array:
    """Offsets 0, w, 2w, … rows·w (int32) of ``rows`` rows of ``per_row`` instances each.

    Cached (a few chunk lengths and widths in use; the series' and the
    scene's alike): the same every chunk, and rerun only reads them.
    """
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
            conversion of ``duration=k Δt``: (k Δt · 10⁹) truncated).

    """

    def __init__(self, ticks: np.ndarray, dt: float) -> None:
        n = ticks.shape[0]
        ns, ns_buffer = pool_vector(n, np.int64)
        ns[:] = ((ticks * dt) * 1e9).astype("timedelta64[ns]").view(np.int64)
        self.n = n
        self.index = [
            _Index(TIME, pa.Array.from_buffers(pa.duration("ns"), n, [None, ns_buffer])),
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


#: One component of a series: (signal, flat index, None, 0) for a value of the
#: signal's row, (x signal, x index, z signal, z index) for the magnitude hypot(x, z).
_Part = tuple[str, int, str | None, int]


class SignalColumns:
    """The signals of a layout, chunk by chunk, as rerun columns.

    Args:
        layout: where each signal sits, and the series built from them.
        left_out: name → constant of the signals not sent while every row of
            theirs is it (:mod:`.omitted`).

    """

    def __init__(self, layout: Layout, left_out: dict[str, float] | None = None) -> None:
        #: Every series of the signals (what ``raw/meta`` describes).
        self.full = layout
        #: Name → constant of the signals not sent while they hold it (:mod:`.omitted`).
        self.left_out = {k: float(v) for k, v in (left_out or {}).items() if k in layout.shapes}
        #: The signals sent whole under ``raw/``.
        self.raw = layout.raw_signals()
        self._widths = {name: math.prod(shape) for name, shape in layout.shapes.items()}
        self._select()

    def _select(self) -> None:
        """The series sent (those showing a signal not left out) and what each component is."""
        #: The series sent.
        self.layout = self.full.without(self.left_out)
        lay = self.layout
        parts: list[list[_Part]] = []
        for s in lay.series:
            comps: list[_Part] = []
            for c in s.columns:
                if c < lay.width:
                    comps.append((*_value_of(lay, c), None, 0))
                else:
                    x, z = lay.magnitudes[c - lay.width]
                    comps.append((*_value_of(lay, x), *_value_of(lay, z)))
            parts.append(comps)
        self._parts = parts
        self._size = sum(len(s.columns) for s in lay.series)

    def prepare(self, n: int) -> None:
        """Build the cached list offsets of chunks of ``n`` ticks ahead of the first one."""
        for w in {*self._widths.values(), *(len(s.columns) for s in self.layout.series)}:
            list_offsets(n, w)

    def check(self, rows: dict[str, np.ndarray]) -> None:
        """Raise RecordingError if ``rows`` lacks a signal of the layout."""
        for name in self.full.shapes:
            if name not in rows:
                raise RecordingError(f"the rows lack the signal {name!r} of the log schema")

    def check_left_out(self, rows: dict[str, np.ndarray], skip: int) -> tuple[Series, ...]:
        """Send from now on every left-out signal whose rows ``skip:`` are not its constant.

        A NaN is not the constant.  Returns the series this adds to :attr:`layout`.
        """
        moved = [name for name, v in self.left_out.items() if not np.all(rows[name][skip:] == v)]
        if not moved:
            return ()
        for name in moved:
            del self.left_out[name]
        before = {s.entity for s in self.layout.series}
        self._select()
        return tuple(s for s in self.layout.series if s.entity not in before)

    def series_values(self, rows: dict[str, np.ndarray], skip: int, n: int) -> pa.Array:
        """Rows ``skip:skip+n`` of every series sent, as one new float64 vector (arrow).

        Each series' (n, c) block, row-major, one after the other in
        :attr:`layout` order; a magnitude is hypot(x, z).  The vector is new
        each chunk (rerun may still be writing the previous one), in
        pyarrow's memory pool.
        """
        flat = {name: self._flat(rows[name], skip) for name in self.full.shapes}
        values, buffer = pool_vector(n * self._size)
        at = 0
        for comps in self._parts:
            w = len(comps)
            block = values[at : at + n * w].reshape(n, w)
            for k, (name, i, z_name, z_i) in enumerate(comps):
                if z_name is None:
                    block[:, k] = flat[name][:, i]
                else:
                    np.hypot(flat[name][:, i], flat[z_name][:, z_i], out=block[:, k])
            at += n * w
        return pa.Array.from_buffers(pa.float64(), n * self._size, [None, buffer])

    def send_series(self, rec: rr.RecordingStream, batch: EntityBatch, values: pa.Array) -> None:
        """Send the series (``values``: :meth:`series_values`).

        ``batch``: an empty batch on the chunk's ticks (it is filled and sent).
        """
        n = batch.n
        at = 0
        for s in self.layout.series:
            w = len(s.columns)
            batch.add(s.entity, _SCALARS, values.slice(at, n * w), list_offsets(n, w))
            at += n * w
        batch.send(rec)

    def send_raw(
        self, rec: rr.RecordingStream, batch: EntityBatch, rows: dict[str, np.ndarray], skip: int
    ) -> None:
        """Send ``raw/{signal}`` of :attr:`raw` (none in the log schema today).

        ``batch``: an empty batch on the chunk's ticks (it is filled and sent).
        """
        n = batch.n
        for name in self.raw:
            values = pool_array(self._flat(rows[name], skip), pa.float64())
            batch.add(f"raw/{name}", _SCALARS, values, list_offsets(n, self._widths[name]))
        batch.send(rec)

    def _flat(self, rows: np.ndarray, skip: int) -> np.ndarray:
        """Rows ``skip:`` of a signal as (n, width) (a view where the strides allow)."""
        return rows[skip:].reshape(rows.shape[0] - skip, -1)


def log_styles(rec: rr.RecordingStream, series: tuple[Series, ...]) -> None:
    """Log the legend names and colours of time series (static)."""
    for s in series:
        lines = rr.SeriesLines(names=s.names, colors=s.colors)
        rec.log(s.entity, lines, static=True, strict=True)


def _value_of(lay: Layout, column: int) -> tuple[str, int]:
    """(signal, flat index) of a signal column of the layout's row."""
    found = lay.column_of(column)
    if found is None:
        raise IndexError(f"column {column} is a magnitude, not a signal's value")
    return found
