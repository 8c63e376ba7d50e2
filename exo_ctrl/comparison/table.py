"""The comparison table: one row per run, every figure taken from the run's own summary.

A row's figures are read from :meth:`exo_ctrl.sim.SimResult.summary`, never
recomputed, so the table equals each run's summary exactly (:data:`FIGURES`
says where each comes from).  Per-joint and per-cuff figures are
:class:`Keyed` dicts (the summary's, keyed by joint or cuff name) whose
:attr:`Keyed.worst` is the largest value, so a test reads in one line::

    table = exo_ctrl.compare(SimConfig(), controllers=("pd", "ct"))
    assert table["ct"].rms_tracking_error_rad.worst < table["pd"].rms_tracking_error_rad.worst

Files: :meth:`CompareTable.to_csv` (one line per run, one column per figure
and joint or cuff, ``rms_tracking_error_rad.left_knee``; floats written
exactly, ``repr``), :meth:`CompareTable.to_json` and
:meth:`CompareTable.markdown` (the figures down, the runs across).
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._io import atomic_write
from ..exceptions import InvalidParameter
from ..model import CUFF_NAMES, JOINT_NAMES

__all__ = ["FIGURES", "CompareRow", "CompareTable", "CycleTrace", "Figure", "Keyed", "row_from"]


class Keyed(dict):
    """A figure per joint or per cuff (the summary's dict), with its worst value."""

    @property
    def worst(self) -> float:
        """The largest value (of the joint or cuff where the figure is worst); NaN if none."""
        values = [float(x) for x in self.values() if x is not None]
        return max(values) if values else math.nan


@dataclass(frozen=True)
class Figure:
    """One figure of the table.

    Attributes:
        name: the row's attribute and the column's name (SI unit in it).
        title: what it is, in words (the Markdown table's first column).
        unit: its unit ("" for a count or a word).
        keys: JOINT_NAMES or CUFF_NAMES for a figure per joint or cuff, () for one value.
        path: where it is in the summary: key, then sub-keys (``energy_J`` →
            joint → ``electrical``: the joint is taken at ``{}``).
        belt: present only when the run had the belt and contact on (else None).

    """

    name: str
    title: str
    unit: str
    keys: tuple[str, ...]
    path: tuple[str, ...]
    belt: bool = False


#: Every figure of a row, in the table's order, and where the summary has it.
FIGURES: tuple[Figure, ...] = (
    Figure("duration_s", "simulated time", "s", (), ("duration_s",)),
    Figure("rms_tracking_error_rad", "RMS tracking error", "rad", JOINT_NAMES,
           ("rms_tracking_error_rad",)),
    Figure("max_tracking_error_rad", "max tracking error", "rad", JOINT_NAMES,
           ("max_tracking_error_rad",)),
    Figure("peak_drive_torque_Nm", "peak drive torque", "N·m", JOINT_NAMES,
           ("peak_drive_torque_Nm",)),
    Figure("rms_drive_torque_Nm", "RMS drive torque", "N·m", JOINT_NAMES,
           ("rms_drive_torque_Nm",)),
    Figure("peak_motor_current_A", "peak motor current", "A", JOINT_NAMES,
           ("peak_motor_current_A",)),
    Figure("rms_motor_current_A", "RMS motor current", "A", JOINT_NAMES,
           ("rms_motor_current_A",)),
    Figure("electrical_energy_J", "electrical energy drawn (net)", "J", JOINT_NAMES,
           ("energy_J", "{}", "electrical")),
    Figure("peak_cuff_force_N", "peak cuff force (true)", "N", CUFF_NAMES,
           ("peak_cuff_force_N",)),
    Figure("peak_cuff_force_est_N", "peak cuff force (estimated)", "N", CUFF_NAMES,
           ("peak_cuff_force_est_N",)),
    Figure("cuff_force_estimate_rms_error_N", "cuff force estimate's RMS error", "N",
           CUFF_NAMES, ("cuff_force_estimate_rms_error_N",)),
    Figure("slip_speed_rms_mps", "foot slip speed RMS, walking", "m/s", (), ("slip_speed_rms_mps",),
           belt=True),
    Figure("slip_speed_max_mps", "foot slip speed max, walking", "m/s", (), ("slip_speed_max_mps",),
           belt=True),
    Figure("touchdown_speed_mps", "touchdown speed, vertical (worst, walking)", "m/s", (),
           ("touchdown_speed_mps",), belt=True),
    Figure("touchdown_slip_mps", "touchdown speed, horizontal (worst, walking)", "m/s", (),
           ("touchdown_slip_mps",), belt=True),
    Figure("safety_event_count", "safety events", "", (), ("safety_events",)),
    Figure("safety_state", "safety supervisor's final state", "", (), ("safety_state",)),
    Figure("real_time_factor", "real-time factor", "", (), ("real_time_factor",)),
)  # fmt: skip


def _lookup(summary: dict[str, Any], path: tuple[str, ...], key: str) -> Any:
    """The summary's value at ``path`` (``{}`` replaced by ``key``), or None where absent."""
    value: Any = summary
    for part in path:
        part = key if part == "{}" else part
        if not isinstance(value, dict) or part not in value:
            return None
        value = value[part]
    return value


def _figure(summary: dict[str, Any], fig: Figure) -> Any:
    """One figure of a summary: a :class:`Keyed`, a value, or None (absent, or no belt)."""
    if fig.belt and "slip_speed_rms_mps" not in summary:
        return None
    if fig.keys and fig.path[1:]:  # the joint inside the path (energy_J → joint → electrical)
        if not isinstance(summary.get(fig.path[0]), dict):
            return None
        return Keyed({key: _lookup(summary, fig.path, key) for key in fig.keys})
    if fig.keys:  # the summary's own dict, as it is
        block = summary.get(fig.path[0])
        return Keyed(block) if isinstance(block, dict) else None
    value = _lookup(summary, fig.path, "")
    if fig.name == "safety_event_count":
        return None if value is None else len(value)
    return value


@dataclass
class CycleTrace:
    """One gait cycle of a run for the figure (:mod:`.cycle`).

    Attributes:
        t: time since the cycle's start [s], (n,).
        t0_s: the cycle's start in the run [s].
        complete: the ticks are a whole gait cycle at speed (else: the run's last
            period, of a run shorter than the ramp-in and a cycle, a calibration
            exercise, or a run that ended early).
        q: exoskeleton joint angles [rad], (n, 4); q_des the plan's.
        drive_torque: drive torque at the joint [N·m], (n, 4).
        cuff_force: magnitude of the true cuff force [N], (n, 4); cuff_force_est the estimate's.

    """

    t: np.ndarray
    t0_s: float
    complete: bool
    q: np.ndarray
    q_des: np.ndarray
    drive_torque: np.ndarray
    cuff_force: np.ndarray
    cuff_force_est: np.ndarray


@dataclass
class CompareRow:
    """One run of the comparison: its label, its figures (:data:`FIGURES`) and summary.

    Every figure of :data:`FIGURES` is an attribute (``row.peak_drive_torque_Nm``):
    a :class:`Keyed` dict per joint or cuff, a number, a word, or None where the
    run has no such figure (the belt's without the belt).

    Attributes:
        label: the run's name in the table (the controller, or a recording's name).
        controller: the run's controller.
        status: the run's status (``"completed"``, ...).
        source: where the run came from (``"simulated"`` or the recording's path).
        summary: the run's whole summary (:meth:`exo_ctrl.sim.SimResult.summary`).
        config: the run's :meth:`~exo_ctrl.sim.SimConfig.to_dict`.
        cycle: the gait cycle drawn in the figure, or None.

    """

    label: str
    controller: str
    status: str
    source: str
    summary: dict[str, Any] = field(repr=False)
    config: dict[str, Any] = field(repr=False)
    cycle: CycleTrace | None = field(default=None, repr=False)
    figures: dict[str, Any] = field(default_factory=dict, repr=False)

    def __getattr__(self, name: str) -> Any:
        figures = self.__dict__.get("figures", {})
        if name in figures:
            return figures[name]
        raise AttributeError(name)

    def to_dict(self) -> dict[str, Any]:
        """The row as plain data: label, controller, status, source, then every figure."""
        out: dict[str, Any] = {
            "label": self.label,
            "controller": self.controller,
            "status": self.status,
            "source": self.source,
        }
        out.update(
            {name: dict(v) if isinstance(v, Keyed) else v for name, v in self.figures.items()}
        )
        return out


def row_from(
    label: str,
    summary: dict[str, Any],
    config: dict[str, Any],
    source: str,
    cycle: CycleTrace | None = None,
) -> CompareRow:
    """A table row from a run's summary (figures: :data:`FIGURES`, read, not recomputed)."""
    figures = {fig.name: _figure(summary, fig) for fig in FIGURES}
    return CompareRow(
        label=label,
        controller=str(summary.get("controller", config.get("controller", ""))),
        status=str(summary.get("status", "")),
        source=source,
        summary=summary,
        config=config,
        cycle=cycle,
        figures=figures,
    )


class CompareTable:
    """The runs of a comparison, one :class:`CompareRow` each, in order.

    ``table["ct"]`` is the row labelled ``ct``; ``len(table)``, iteration
    and :attr:`labels` go through the rows in order.

    Attributes:
        rows: the rows.
        differences: the configuration keys that differ between the runs,
            dotted key → one value per run (:mod:`.differences`; the compared
            key, the controller, included).

    """

    def __init__(self, rows: list[CompareRow], differences: dict[str, list[Any]]) -> None:
        self.rows = list(rows)
        self.differences = dict(differences)

    def __getitem__(self, label: str) -> CompareRow:
        for row in self.rows:
            if row.label == label:
                return row
        raise InvalidParameter("label", label, f"one of {self.labels}")

    def __len__(self) -> int:
        return len(self.rows)

    def __iter__(self) -> Iterator[CompareRow]:
        return iter(self.rows)

    @property
    def labels(self) -> list[str]:
        """The runs' labels, in order."""
        return [row.label for row in self.rows]

    def columns(self) -> list[str]:
        """The CSV's columns: label, controller, status, source, then each figure (and key)."""
        cols = ["label", "controller", "status", "source"]
        for fig in FIGURES:
            cols += [f"{fig.name}.{k}" for k in fig.keys] if fig.keys else [fig.name]
        return cols

    def _flat(self, row: CompareRow) -> dict[str, Any]:
        out: dict[str, Any] = {
            "label": row.label,
            "controller": row.controller,
            "status": row.status,
            "source": row.source,
        }
        for fig in FIGURES:
            value = row.figures[fig.name]
            if fig.keys:
                for k in fig.keys:
                    out[f"{fig.name}.{k}"] = None if value is None else value.get(k)
            else:
                out[fig.name] = value
        return out

    def csv_text(self) -> str:
        """The CSV text (:meth:`to_csv`)."""
        buf = io.StringIO()
        writer = csv.writer(buf, lineterminator="\n")
        cols = self.columns()
        writer.writerow(cols)
        for row in self.rows:
            flat = self._flat(row)
            writer.writerow(["" if flat[c] is None else _exact(flat[c]) for c in cols])
        return buf.getvalue()

    def to_csv(self, path: str | os.PathLike[str]) -> None:
        """Write one line per run, one column per figure and joint or cuff (atomically).

        Floats are written exactly (``repr``: read back, they equal the
        summary's); a figure the run lacks is an empty field.

        Raises:
            OutputError: the file could not be written.

        """
        text = self.csv_text()
        with atomic_write(path) as handle:
            handle.write(text)

    def as_dict(self) -> dict[str, Any]:
        """The JSON form: the figures' units, the differing keys and the runs' rows."""
        return {
            "figures": {f.name: {"title": f.title, "unit": f.unit} for f in FIGURES},
            "config_differences": self.differences,
            "runs": [row.to_dict() for row in self.rows],
        }

    def to_json(self, path: str | os.PathLike[str]) -> None:
        """Write :meth:`as_dict` as indented JSON (atomically; NaN as null).

        Raises:
            OutputError: the file could not be written.

        """
        text = json.dumps(_no_nan(self.as_dict()), indent=2)
        with atomic_write(path) as handle:
            handle.write(text + "\n")

    def markdown(self) -> str:
        """The table in Markdown: one line per figure (and joint or cuff), one column per run."""
        lines = [
            "| figure | unit | " + " | ".join(self.labels) + " |",
            "|---|---|" + "---:|" * len(self.rows),
            "| status | | " + " | ".join(row.status for row in self.rows) + " |",
        ]
        for fig in FIGURES:
            values = [row.figures[fig.name] for row in self.rows]
            if fig.belt and all(v is None for v in values):
                continue  # no run had the belt
            if fig.keys:
                for k in fig.keys:
                    cells = [_cell(None if v is None else v.get(k)) for v in values]
                    title = f"{fig.title}, {k.replace('_', ' ')}"
                    lines.append(f"| {title} | {fig.unit} | " + " | ".join(cells) + " |")
            else:
                cells = [_cell(v) for v in values]
                lines.append(f"| {fig.title} | {fig.unit} | " + " | ".join(cells) + " |")
        return "\n".join(lines)


def _exact(value: Any) -> str:
    """A CSV field: floats as ``repr`` (exact), the rest as ``str``."""
    return repr(value) if isinstance(value, float) else str(value)


def _cell(value: Any) -> str:
    """A Markdown cell: numbers to 4 significant digits, absent as a dash."""
    if value is None:
        return "–"
    if isinstance(value, float):
        return "NaN" if math.isnan(value) else f"{value:.4g}"
    return str(value)


def _no_nan(data: Any) -> Any:
    """``data`` with NaN and infinite floats as None (strict JSON)."""
    if isinstance(data, float):
        return data if math.isfinite(data) else None
    if isinstance(data, dict):
        return {k: _no_nan(v) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [_no_nan(v) for v in data]
    return data
