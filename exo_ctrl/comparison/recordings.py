"""Compare existing recordings: each read back, its summary rebuilt, tabulated as a live run's.

The one module of :mod:`exo_ctrl.comparison` that imports the recorder (and
so rerun): :mod:`exo_ctrl` imports it on first use of
:func:`compare_recordings`.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from pathlib import Path

from .. import _validate as v
from ..exceptions import InvalidParameter
from ..record import read_recording
from .cycle import trace_from_history
from .differences import check_same, config_differences
from .table import CompareRow, CompareTable, row_from

__all__ = ["compare_recordings", "recording_labels"]


def recording_labels(paths: Sequence[str | os.PathLike[str]]) -> list[str]:
    """A label per recording: its file name without ``.rrd``, or its path where names repeat."""
    stems = [Path(p).stem for p in paths]
    return [
        stem if stems.count(stem) == 1 else str(p) for stem, p in zip(stems, paths, strict=True)
    ]


def compare_recordings(
    paths: Sequence[str | os.PathLike[str]],
    *,
    allow_different: bool = False,
    on_run: Callable[[int, int, CompareRow], None] | None = None,
) -> CompareTable:
    """Tabulate recordings (``exo-ctrl simulate --out RUN.rrd``) as :func:`~.runs.compare` does.

    Each file is read back (:func:`exo_ctrl.record.read_recording`, which
    rebuilds the run's statistics, so its summary equals the live run's) and
    its figures taken from that summary; the figure's cycle comes from its
    history (:func:`~.cycle.trace_from_history`).

    Args:
        paths: the recordings, in the table's order (labels: :func:`recording_labels`).
        allow_different: compare runs whose configurations differ in more
            than the controller.
        on_run: called after each file with (its number from 1, the number of files, its row).

    Raises:
        InvalidParameter: no path, a path twice, or the configurations
            differ beyond the controller (naming the keys) without ``allow_different``.
        RecordingError: a file is missing or not a recording.

    """
    allow = v.flag("allow_different", allow_different)
    paths = list(paths)
    if not paths:
        raise InvalidParameter("recordings", paths, "one or more .rrd files")
    real = [os.path.realpath(p) for p in paths]
    if len(set(real)) != len(real):
        raise InvalidParameter("recordings", [str(p) for p in paths], "each file once")
    labels = recording_labels(paths)
    rows: list[CompareRow] = []
    for i, (label, path) in enumerate(zip(labels, paths, strict=True)):
        result = read_recording(path)
        trace = trace_from_history(result.config, result.signals)
        row = row_from(label, result.summary(), result.config.to_dict(), str(path), trace)
        rows.append(row)
        if on_run is not None:
            on_run(i + 1, len(paths), row)
    differences = config_differences([row.config for row in rows])
    check_same(differences, labels, allow)
    return CompareTable(rows, differences)
