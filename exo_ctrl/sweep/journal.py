"""The journal of a sweep and resuming from it.

The journal is append-only JSON lines, one per finished run (its run id,
point, outputs and resolved run), flushed and synced as each arrives, so a
kill loses at most the run being written; a torn last line is skipped when
read and ended before the next entry.

**Resume.**  On start the journal (and an existing table) give the finished
runs: status ``completed``, ``diverged`` or ``failed`` (a configuration the
library rejects, e.g. an unreachable foot path).  Those are not run again.
Runs that ended in ``error`` (an unexpected exception) or were interrupted
are run again.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
from pathlib import Path
from typing import Any

from ..exceptions import OutputError
from .outputs import OUTPUT_COLUMNS, SweepPaths, empty_outputs
from .spec import SweepTask

__all__ = ["FINISHED_STATUSES", "Journal", "read_previous"]

#: Statuses of runs that are final: a resumed sweep does not run them again.
FINISHED_STATUSES = ("completed", "diverged", "failed")


def read_previous(paths: SweepPaths) -> dict[str, dict[str, Any]]:
    """Results of earlier runs by run id: the old table, then the journal (later wins)."""
    results: dict[str, dict[str, Any]] = {}
    if paths.table.is_file():
        import pyarrow.parquet as pq

        with contextlib.suppress(Exception):  # an unreadable old table: rely on the journal
            old = pq.read_table(paths.table)
            if {"run_id", *OUTPUT_COLUMNS} <= set(old.column_names):
                for row in old.select(["run_id", *OUTPUT_COLUMNS]).to_pylist():
                    results[row.pop("run_id")] = _fill(row)
    if paths.journal.is_file():
        with paths.journal.open(encoding="utf-8") as handle:
            for line in handle:
                try:
                    entry = json.loads(line)
                    results[entry["run_id"]] = _fill(entry["outputs"])
                except (ValueError, KeyError, TypeError):
                    continue  # a line torn by a kill
    return results


def _fill(row: dict[str, Any]) -> dict[str, Any]:
    """A stored row as complete outputs (missing or null columns take the empty value)."""
    out = empty_outputs()
    out.update({k: row[k] for k in OUTPUT_COLUMNS if k in row and row[k] is not None})
    return out


class Journal:
    """Append-only JSON lines, one per finished run, flushed and synced per line."""

    def __init__(self, path: Path) -> None:
        """Open (or create, with the umask's mode) the journal at ``path``.

        Its directory is not created: it is the sweep's output directory.
        The journal is a name the user did not give: it is never followed
        through a symbolic link (``O_NOFOLLOW``).

        Raises:
            OutputError: the file cannot be opened for appending, or is a
                symbolic link.

        """
        flags = os.O_RDWR | os.O_APPEND | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC
        try:
            fd = os.open(path, flags, 0o666)  # the umask applies
        except OSError as exc:
            reason = exc.strerror or str(exc)
            if exc.errno == errno.ELOOP:
                reason = "a symbolic link; a link is followed only when named"
            raise OutputError(path, reason) from None
        size = os.fstat(fd).st_size
        torn = size > 0 and os.pread(fd, 1, size - 1) != b"\n"
        self._handle = os.fdopen(fd, "a", encoding="utf-8")
        if torn:  # end a line torn by a kill, so the next entry starts clean
            self._handle.write("\n")

    def write(self, task: SweepTask, outputs: dict[str, Any]) -> None:
        """Append one finished run and sync it to disk."""
        entry = {"run_id": task.run_id, "point": task.point, "outputs": outputs}
        entry["run"] = task.run
        self._handle.write(json.dumps(entry) + "\n")
        self._handle.flush()
        os.fsync(self._handle.fileno())

    def close(self) -> None:
        """Close the file."""
        self._handle.close()
