"""A recording's time series as a table: ``exo-ctrl export`` (CSV or Parquet).

One row per tick, the column ``t`` (k Δt [s], as :func:`~.reader.read_recording`
rebuilds it) first, then one float64 column per scalar component of each
signal of the log schema (:data:`exo_ctrl.sim.schema.SIGNALS`), in log
order, named from the schema and nothing else (:func:`column_names`):

- the item the first axis indexes, by the signal's ``labels``: a joint of
  :data:`~exo_ctrl.model.JOINT_NAMES` (``left_knee``), a cuff of
  :data:`~exo_ctrl.model.CUFF_NAMES` (``left_thigh``), a foot of
  :data:`~exo_ctrl.model.SIDES` (``left``);
- the signal's name (``q``, ``cuff_force``);
- the axis of a force's last axis of two, ``x`` or ``z``;
- the unit (:func:`unit_tag`: ``rad``, ``rad_per_s``, ``Nm``, ``N``;
  none for a count or a code),

joined by ``_``: ``left_knee_q_rad``, ``left_thigh_cuff_force_x_N``,
``left_foot_slip_m_per_s``, ``right_patient_ground_force_z_N``,
``safety_state``.  A signal of another shape, or unlabelled, numbers its
components row-major (``name_0_1_unit``).  The values are the
recording's, bit for bit: a CSV writes each float64 in its shortest form
that reads back to the same number, Parquet stores float64.

The per-sample estimates of ``exo-ctrl estimate`` are written the same way
(:func:`write_table`), their columns named as the log schema's estimate
signals (``cuff_normal_est``, ``cuff_force_est``, ``tau_ext_est``).
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pa_csv
import pyarrow.parquet as pq

from .._io import atomic_write
from ..estimation import EstimateSeries
from ..exceptions import InvalidParameter
from ..model import CUFF_NAMES, JOINT_NAMES, SIDES
from ..sim import SimResult, schema
from .reader import read_recording

__all__ = [
    "TABLE_SUFFIXES",
    "column_names",
    "estimate_table",
    "export_recording",
    "parse_signals",
    "signal_table",
    "table_suffix",
    "unit_tag",
    "write_table",
]

#: The file types a table is written as, by the output's suffix.
TABLE_SUFFIXES = (".csv", ".parquet")
#: The items a signal's first axis indexes, by its ``labels``.
_ITEMS = {"joint": JOINT_NAMES, "cuff": CUFF_NAMES, "foot": SIDES}
#: The last axis of a labelled signal of two components per item (x, z).
_AXES = ("x", "z")


def unit_tag(unit: str) -> str:
    """A unit of the log schema as it ends a column name: ``N·m`` → ``Nm``, ``m/s`` → ``m_per_s``.

    "" (a count or a code) stays "".
    """
    tag = unit.replace("·", "").replace("/", "_per_")
    return re.sub(r"[^0-9A-Za-z_]", "", tag)


def column_names(sig: schema.Signal) -> list[str]:
    """The columns of one signal, one per scalar component in row-major order.

    Named from the signal alone (module docstring): its labels, name, axes and unit.
    """
    unit = unit_tag(sig.unit)
    items = _ITEMS.get(sig.labels)
    shape = tuple(sig.shape)
    parts: list[list[str]]
    if items is not None and shape in ((len(items),), (len(items), len(_AXES))):
        axes = _AXES if len(shape) == 2 else ("",)
        parts = [[item, sig.name, axis] for item in items for axis in axes]
    else:
        parts = [[sig.name, *(str(k) for k in ix)] for ix in np.ndindex(*shape)]
    return ["_".join(p for p in [*part, unit] if p) for part in parts]


def parse_signals(text: str | Sequence[str] | None, option: str = "--signals") -> list[str]:
    """The signals a user names (comma-separated, or a list), checked against the log schema.

    None: every signal of the schema, in log order.  Names are kept in the
    order given, each once.

    Raises:
        InvalidParameter: a name that is not a signal of the log schema, or
            none at all; the message lists every name allowed.

    """
    known = [s.name for s in schema.SIGNALS]
    if text is None:
        return known
    names = text.split(",") if isinstance(text, str) else list(text)
    names = [n.strip() for n in names]
    allowed = f"signal names of the log schema, comma-separated: {', '.join(known)}"
    if not any(names):
        raise InvalidParameter(option, text, allowed)
    chosen: list[str] = []
    for name in names:
        if name not in known:
            raise InvalidParameter(option, name, f"one of the {allowed}")
        if name not in chosen:
            chosen.append(name)
    return chosen


def signal_table(
    t: np.ndarray, values: Mapping[str, np.ndarray], signals: Sequence[str] | None = None
) -> pa.Table:
    """A table of ``t`` [s] and every scalar component of ``signals`` (float64 columns).

    Args:
        t: the rows' times [s], (N,).
        values: signal name → its rows, (N, *shape) as the log schema declares it.
        signals: the names to show, in this order (default: every signal of
            the schema that ``values`` holds, in log order).

    Raises:
        InvalidParameter: a signal not in the log schema (:func:`parse_signals`).
        ValueError: a signal's rows do not have its declared shape or N rows.

    """
    if signals is None:
        names = [s.name for s in schema.SIGNALS if s.name in values]
    else:
        names = parse_signals(list(signals))
    n = int(np.shape(t)[0])
    columns: dict[str, np.ndarray] = {"t": np.asarray(t, dtype=np.float64)}
    for name in names:
        sig = schema.signal(name)
        rows = np.asarray(values[name], dtype=np.float64)
        if rows.shape != (n, *sig.shape):
            raise ValueError(f"signal {name}: rows of shape {rows.shape}, not {(n, *sig.shape)}")
        flat = rows.reshape(n, math.prod(sig.shape))
        for k, column in enumerate(column_names(sig)):
            columns[column] = np.ascontiguousarray(flat[:, k])
    return pa.table(columns)


def estimate_table(series: EstimateSeries) -> pa.Table:
    """An offline estimate's per-sample values as a table, named as the log's estimate signals.

    ``t`` [s], then ``{joint}_tau_ext_est_Nm``, ``{cuff}_cuff_normal_est_N``
    and ``{cuff}_cuff_force_est_{x,z}_N`` (log order): the columns an export
    of a recording gives its live estimate.
    """
    values = {
        "tau_ext_est": series.tau_ext,
        "cuff_normal_est": series.normal,
        "cuff_force_est": series.force,
    }
    return signal_table(series.t, values)


def table_suffix(
    path: str | os.PathLike[str], option: str = "--out", suffixes: Sequence[str] = TABLE_SUFFIXES
) -> str:
    """The suffix of ``path`` (lower case) if it is one of ``suffixes``.

    Raises:
        InvalidParameter: another suffix; the message names ``option``.

    """
    suffix = Path(path).suffix.lower()
    if suffix not in suffixes:
        words = ", ".join(suffixes[:-1]) + f" or {suffixes[-1]}" if len(suffixes) > 1 else ""
        raise InvalidParameter(option, str(path), f"a file name ending in {words or suffixes[0]}")
    return suffix


def write_table(table: pa.Table, path: str | os.PathLike[str]) -> Path:
    """Write ``table`` as CSV or Parquet by the path's suffix, whole or not at all.

    CSV: a header of the column names, then one line per row, every value
    in the shortest form that reads back to the same float64 (Arrow's
    writer).  Parquet: the columns as float64, compressed (Arrow's default,
    Snappy).  Through :func:`exo_ctrl._io.atomic_write`.

    Raises:
        InvalidParameter: the suffix is neither ``.csv`` nor ``.parquet``.
        OutputError: the file could not be written (the old one, or none, is left).

    """
    suffix = table_suffix(path)
    with atomic_write(path, "wb") as handle:
        if suffix == ".csv":
            pa_csv.write_csv(table, handle)
        else:
            pq.write_table(table, handle)
    return Path(path)


def export_recording(
    path: str | os.PathLike[str],
    out: str | os.PathLike[str],
    signals: str | Sequence[str] | None = None,
) -> pa.Table:
    """Write a recording's time series to ``out`` (``.csv`` or ``.parquet``); the table written.

    The run is read by :func:`~.reader.read_recording` (every signal as
    the run logged it; a feature off in the run gives its constant, a signal
    the file predates NaN).

    Args:
        path: the ``.rrd`` recording.
        out: the table file.
        signals: the signals to export, by their log-schema names, as a
            list or comma-separated (default: all, in log order).

    Raises:
        InvalidParameter: an unknown signal or an output of another suffix
            (both checked before the recording is read).
        RecordingError: the recording cannot be read.
        OutputError: ``out`` could not be written.

    """
    table_suffix(out)
    names = parse_signals(signals)
    result: SimResult = read_recording(path)
    table = signal_table(result.t, result.signals, names)
    write_table(table, out)
    return table
