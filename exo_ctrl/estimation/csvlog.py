r"""Sensor logs as CSV files: the format, a reader that names every error, a writer.

A log is a CSV file whose first line is a header naming the columns (in any
order; extra columns are ignored)::

    t,left_hip_q,left_knee_q,right_hip_q,right_knee_q,left_hip_tau,left_knee_tau,right_hip_tau,right_knee_tau

and optionally ``left_hip_dq,left_knee_dq,right_hip_dq,right_knee_dq``
(t [s], q [rad], dq [rad/s], tau: joint torque sensor readings [N·m]), one
row per sample.  :func:`~exo_ctrl.estimation.series.estimate_series` runs
the observer along what :func:`read_csv_log` returns.
"""

from __future__ import annotations

import csv
import math
import os
from pathlib import Path

import numpy as np

from .. import _validate as v
from .._io import atomic_write, not_a_file
from ..exceptions import InvalidLog
from ..model import JOINT_NAMES
from .series import _check_series

__all__ = ["CSV_DQ_COLUMNS", "CSV_REQUIRED_COLUMNS", "read_csv_log", "write_csv_log"]

#: Columns a CSV log must have, in any order (extra columns are ignored).
CSV_REQUIRED_COLUMNS = (
    "t",
    *(f"{j}_q" for j in JOINT_NAMES),
    *(f"{j}_tau" for j in JOINT_NAMES),
)
#: Memory reading a CSV log takes per row [bytes] (the rows' Python numbers
#: and lists, then the arrays): 170 MiB for 300,000 rows, measured.
CSV_ROW_BYTES = 600
#: Memory a field of the header or of the row being read takes as text, beside the line's
#: characters [bytes] (a str and its place in the row's list): 76 B a field of 7 characters
#: with them, measured on lines of 2 million fields.
CSV_FIELD_BYTES = 72
#: Optional joint-speed columns (all four or none).
CSV_DQ_COLUMNS = tuple(f"{j}_dq" for j in JOINT_NAMES)


def read_csv_log(
    path: str | os.PathLike[str],
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """Read a sensor log written as CSV.

    The first line is a header naming the columns, comma-separated, in any
    order; extra columns are ignored.  Required::

        t,left_hip_q,left_knee_q,right_hip_q,right_knee_q,
        left_hip_tau,left_knee_tau,right_hip_tau,right_knee_tau

    (one line), optional: ``left_hip_dq,left_knee_dq,right_hip_dq,right_knee_dq``
    (all four or none).  Units: t [s], *_q [rad], *_dq [rad/s], *_tau [N·m]
    (joint torque sensor readings); joints positive in flexion.

    Args:
        path: the CSV file.

    Returns:
        (t (N,), q (N, 4), dq (N, 4) or None, tau (N, 4)).

    Raises:
        InvalidLog: the file is missing or empty, not CSV text, a column is
            missing, a value is not a finite number, fewer than 2 rows, or t is
            not strictly increasing; the message names the line and column.

    """
    src = str(path)
    p = Path(path)
    if not p.is_file():
        raise InvalidLog(src, not_a_file(p))
    _check_size(src, p)
    try:
        return _read_rows(src, p)
    except UnicodeDecodeError:
        raise InvalidLog(src, "not UTF-8 text: a CSV log is text") from None
    except csv.Error as exc:  # a field longer than the csv module's limit, a NUL byte
        raise InvalidLog(src, f"not a CSV log: {exc}") from None


def _check_size(src: str, p: Path) -> None:
    """Refuse a log whose reading would pass the 1 GiB memory cap, before reading it.

    Reading keeps about :data:`CSV_ROW_BYTES` per row whatever the row's
    length (measured: 170 MiB for 300,000 rows), and holds the header and
    the row being read as text, :data:`CSV_FIELD_BYTES` a field and the
    line's characters each: so the rows are counted and the widest and
    longest line found first (a scan of the file's bytes, nothing kept); a
    file over the cap itself is refused by its size alone.
    """
    cap = v.MAX_ALLOCATION_BYTES
    size = p.stat().st_size
    if size > cap:
        raise InvalidLog(
            src,
            f"the file is {v.format_bytes(size)}; a CSV log is read up to {v.format_bytes(cap)}",
        )
    rows, widest, longest = _scan_lines(p)
    if rows * CSV_ROW_BYTES > cap:
        raise InvalidLog(
            src,
            f"{rows:,} rows would need about {v.format_bytes(rows * CSV_ROW_BYTES)} to read "
            f"({CSV_ROW_BYTES} B a row), beyond the {v.format_bytes(cap)} memory cap: at most "
            f"{cap // CSV_ROW_BYTES:,} rows",
        )
    need = rows * CSV_ROW_BYTES + 2 * (widest * CSV_FIELD_BYTES + longest)
    if need > cap:
        raise InvalidLog(
            src,
            f"a line of {widest:,} fields would need about {v.format_bytes(need)} to read "
            f"(the header and a row held as text, {CSV_FIELD_BYTES} B a field and the line's "
            f"{v.format_bytes(longest)} each; {CSV_ROW_BYTES} B a row for {rows:,} rows), "
            f"beyond the {v.format_bytes(cap)} memory cap",
        )


def _scan_lines(p: Path, block: int = 1 << 20) -> tuple[int, int, int]:
    """(line ends, the most fields on one line, the longest line [B]) of the file ``p``.

    Fields are counted as commas + 1 (a quoted comma counts too: an upper
    bound); a last line without its newline counts for the widest and the
    longest, not as a line end.
    """
    rows = widest = longest = 0
    commas = length = 0  # the line not yet ended: its commas and bytes so far
    with p.open("rb") as handle:
        while data := handle.read(block):
            raw = np.frombuffer(data, dtype=np.uint8)
            ends = np.flatnonzero(raw == ord("\n"))
            counted = np.cumsum(raw == ord(","), dtype=np.int64)
            if ends.size:
                before = np.concatenate(([-1], ends[:-1]))
                fields = counted[ends] - np.concatenate(([0], counted[ends[:-1]]))
                fields[0] += commas
                sizes = ends - before
                sizes[0] += length
                rows += int(ends.size)
                widest = max(widest, int(fields.max()) + 1)
                longest = max(longest, int(sizes.max()))
                commas = int(counted[-1] - counted[ends[-1]])
                length = int(raw.size - ends[-1] - 1)
            else:
                commas += int(counted[-1])
                length += int(raw.size)
    if length:
        widest, longest = max(widest, commas + 1), max(longest, length)
    return rows, widest, longest


def _read_rows(src: str, p: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """:func:`read_csv_log`'s reading and checks (a UTF-8 file, a byte-order mark allowed)."""
    with p.open(newline="", encoding="utf-8-sig") as handle:
        reader = csv.reader(handle)
        header = next(reader, None)
        if header is None:
            raise InvalidLog(src, "the file is empty; expected a header line")
        header = [h.strip() for h in header]
        missing = [c for c in CSV_REQUIRED_COLUMNS if c not in header]
        if missing:
            raise InvalidLog(
                src,
                f"missing column(s) {', '.join(missing)}; the header must name "
                f"{','.join(CSV_REQUIRED_COLUMNS)} (and optionally {','.join(CSV_DQ_COLUMNS)})",
                line=1,
            )
        have_dq = [c for c in CSV_DQ_COLUMNS if c in header]
        if have_dq and len(have_dq) != 4:
            lacking = [c for c in CSV_DQ_COLUMNS if c not in header]
            raise InvalidLog(
                src, f"has {have_dq[0]} but not {lacking[0]}: give all four *_dq or none", line=1
            )
        wanted = list(CSV_REQUIRED_COLUMNS) + (list(CSV_DQ_COLUMNS) if have_dq else [])
        cols = [header.index(c) for c in wanted]
        rows = []
        for line_no, row in enumerate(reader, start=2):
            if not row or all(not x.strip() for x in row):
                continue
            if len(row) < len(header):
                raise InvalidLog(
                    src, f"{len(row)} fields, the header has {len(header)}", line=line_no
                )
            values = []
            for name, col in zip(wanted, cols, strict=True):
                text = row[col].strip()
                try:
                    x = float(text)
                except ValueError:
                    raise InvalidLog(
                        src, f"not a number: {text!r}", line=line_no, column=name
                    ) from None
                if not math.isfinite(x):
                    raise InvalidLog(
                        src, f"not a finite number: {text!r}", line=line_no, column=name
                    )
                values.append(x)
            rows.append((line_no, values))
    if len(rows) < 2:
        raise InvalidLog(src, f"needs at least 2 data rows; got {len(rows)}")
    data = np.array([vals for _, vals in rows])
    t = data[:, 0]
    steps = np.diff(t)
    if not np.all(steps > 0):
        i = int(np.flatnonzero(~(steps > 0))[0])
        raise InvalidLog(
            src,
            f"t must be strictly increasing; t = {float(t[i + 1])!r} s follows "
            f"t = {float(t[i])!r} s",
            line=rows[i + 1][0],
            column="t",
        )
    q = data[:, 1:5]
    tau = data[:, 5:9]
    dq = data[:, 9:13] if have_dq else None
    return t, q, dq, tau


def write_csv_log(
    path: str | os.PathLike[str],
    t: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray | None,
    tau: np.ndarray,
) -> Path:
    """Write a sensor log in the format :func:`read_csv_log` reads (values round-trip exactly).

    Args:
        path: the CSV file to write (replaced atomically).
        t: times [s], (N,).
        q: joint angles [rad], (N, 4).
        dq: joint speeds [rad/s], (N, 4), or None (no *_dq columns).
        tau: joint torque sensor readings [N·m], (N, 4).

    Raises:
        InvalidLog: a shape differs, a value is not finite, or t does not increase.

    """
    t, q, dq, tau = _check_series(t, q, dq, tau)
    header = list(CSV_REQUIRED_COLUMNS) + (list(CSV_DQ_COLUMNS) if dq is not None else [])
    parts = [t[:, None], q, tau] + ([dq] if dq is not None else [])
    data = np.hstack(parts)
    with atomic_write(path) as handle:
        handle.write(",".join(header) + "\n")
        for row in data:
            handle.write(",".join(repr(float(x)) for x in row) + "\n")
    return Path(path)
