"""The sweep's table (Parquet and CSV), its text report and its load diagrams.

The table has one row per run in run order: ``run_index``, ``run_id``, the
swept parameters, then :data:`~exo_ctrl.sweep.outputs.OUTPUT_COLUMNS`; its
schema metadata holds the spec under the key ``exo_ctrl.sweep``.  pyarrow
(the table) and matplotlib (the plots) are optional: each is imported when
needed, with an install hint when missing.
"""

from __future__ import annotations

import importlib
import json
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .._io import DerivedOutput, atomic_write
from ..exceptions import MissingDependency
from ..model import CUFF_NAMES, JOINT_NAMES
from .outputs import OUTPUT_COLUMNS, SweepPaths
from .parameters import PARAMETERS, point_label
from .spec import SweepSpec, SweepTask

__all__ = [
    "PLOTS_HINT",
    "build_table",
    "pyarrow",
    "require",
    "write_plots",
    "write_report",
    "write_table",
]

PLOTS_HINT = 'pip install "exo-ctrl[plots]"'


def require(module: str, message: str) -> Any:
    """Import an optional module, or raise :class:`MissingDependency` with ``message``."""
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingDependency(message) from None


def pyarrow() -> Any:
    """The pyarrow module (the sweep table needs it)."""
    return require("pyarrow", "the sweep table needs pyarrow: pip install pyarrow")


def build_table(spec: SweepSpec, tasks: list[SweepTask], results: dict[str, dict[str, Any]]) -> Any:
    """The table (pyarrow.Table) of the runs of ``tasks`` that have a result, in run order."""
    pa = pyarrow()
    rows = [(t, results[t.run_id]) for t in tasks if t.run_id in results]
    types = {"float64": pa.float64(), "int64": pa.int64(), "string": pa.string()}
    columns: dict[str, Any] = {
        "run_index": pa.array([t.index for t, _ in rows], pa.int64()),
        "run_id": pa.array([t.run_id for t, _ in rows], pa.string()),
    }
    for name in spec.names:
        kind = pa.string() if name == "controller" else pa.float64()
        columns[name] = pa.array([t.point[name] for t, _ in rows], kind)
    for name, kind in OUTPUT_COLUMNS.items():
        columns[name] = pa.array([r[name] for _, r in rows], types[kind])
    meta = {"exo_ctrl.sweep": json.dumps(spec.describe())}
    return pa.table(columns).replace_schema_metadata(meta)


def write_table(table: Any, paths: SweepPaths) -> None:
    """Write ``table`` as Parquet and CSV, each atomically."""
    import pyarrow.csv as pcsv
    import pyarrow.parquet as pq

    with atomic_write(paths.table, "wb") as handle:
        pq.write_table(table, handle)
    with atomic_write(DerivedOutput(paths.csv), "wb") as handle:
        pcsv.write_csv(table, handle)


def _columns(table: Any) -> dict[str, np.ndarray]:
    return {name: np.asarray(table.column(name).to_pylist()) for name in table.column_names}


def _worst(cols: dict[str, np.ndarray], key: str, names: Sequence[str], ok: np.ndarray) -> Any:
    """(row, name, value, ties) of the largest ``key_<name>`` over completed rows."""
    values = np.column_stack([cols[f"{key}_{n}"].astype(float) for n in names])
    per_row = np.where(ok, np.nanmax(np.where(np.isnan(values), -np.inf, values), axis=1), -np.inf)
    row = int(np.argmax(per_row))
    col = int(np.argmax(values[row]))
    return row, names[col], float(values[row, col]), int(np.sum(per_row == per_row[row]))


def _clipped(cols: dict[str, np.ndarray], joint: str, ok: np.ndarray) -> str:
    """How many completed runs clipped ``joint``'s drive at its torque or current limit.

    "–" for a table written before these columns existed (a resumed sweep).
    """
    keys = [f"share_at_{x}_limit_{joint}" for x in ("torque", "current")]
    if any(k not in cols for k in keys):
        return "–"
    shares = np.column_stack([cols[k][ok].astype(float) for k in keys])
    return str(int((np.nan_to_num(shares) > 0.0).any(axis=1).sum()))


def write_report(table: Any, spec: SweepSpec, path: str | os.PathLike[str]) -> Path:
    """Write the text report: worst cases with their parameters, maxima, failures.

    The worst case of a figure is the completed run with its largest value
    over the joints (cuffs); ties go to the first in run order.
    """
    cols = _columns(table)
    status = cols["status"].astype(str) if len(table) else np.array([], dtype=str)
    ok = status == "completed"
    lines = [
        f"exo-ctrl sweep: {len(table)} runs, {int(ok.sum())} completed, "
        f"{int((~ok).sum())} not completed",
        "swept: "
        + ", ".join(f"{n} ({len(v)} values)" for n, v in spec.params)
        + (f"; {spec.samples} random samples, seed {spec.seed}" if spec.samples else "; grid"),
    ]

    def point(row: int) -> str:
        return point_label({n: cols[n][row].item() for n in spec.names})

    if ok.any():
        for title, key, names, unit in (
            ("peak drive torque", "peak_drive_torque_Nm", JOINT_NAMES, "N·m"),
            ("peak cuff force", "peak_cuff_force_N", CUFF_NAMES, "N"),
        ):
            row, name, value, ties = _worst(cols, key, names, ok)
            lines.append(
                f"worst {title}: {value:.6g} {unit} at {name}, run {int(cols['run_index'][row])} "
                f"({cols['run_id'][row]}): {point(row)}"
            )
            if ties > 1:
                lines.append(f"  ({ties} completed runs reach the same value)")
        lines.append("maxima over completed runs:")
        lines.append(
            f"  {'joint':<12}{'torque [N·m]':>14}{'power [W]':>12}{'current [A]':>13}"
            f"{'runs clipped':>14}"
        )
        for j in JOINT_NAMES:
            tau, pw, cur = (
                float(np.nanmax(cols[f"{k}_{j}"][ok].astype(float)))
                for k in ("peak_drive_torque_Nm", "peak_mechanical_power_W", "peak_motor_current_A")
            )
            lines.append(f"  {j:<12}{tau:>14.4g}{pw:>12.4g}{cur:>13.4g}{_clipped(cols, j, ok):>14}")
        flagged = int((cols["safety_events"][ok].astype(int) > 0).sum())
        lines.append(f"completed runs with safety events: {flagged}")
    else:
        lines.append("no run completed: no worst case")
    failed = np.flatnonzero(~ok)
    lines.append(f"failures ({len(failed)}):")
    for row in failed:
        lines.append(
            f"  run {int(cols['run_index'][row])} ({cols['run_id'][row]}): "
            f"{cols['status'][row]}: {cols['error'][row]}"
        )
    with atomic_write(path) as handle:
        handle.write("\n".join(lines) + "\n")
    return Path(path)


def _label(controller: str) -> str:
    """A controller's legend label: a built-in name in capitals, a user's by its class's name."""
    return controller.upper() if controller in ("pd", "ct", "qp") else controller.rpartition(":")[2]


def write_plots(table: Any, spec: SweepSpec, paths: SweepPaths) -> list[Path]:
    """Write one load diagram per swept numeric parameter; returns the files.

    Each figure has peak drive torque [N·m] (top) and peak mechanical power
    [W] (bottom) of the four joints against the parameter, one point per
    completed run, a colour per joint and a marker per controller; with
    several runs per value (other parameters swept too) a line joins the
    largest value at each, the envelope to size against.  The legend sits
    below the panels, off the points.
    """
    require("matplotlib", f"the load plots need matplotlib: {PLOTS_HINT}")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    cols = _columns(table)
    ok = cols["status"].astype(str) == "completed" if len(table) else np.zeros(0, bool)
    controllers = (
        cols["controller"][ok].astype(str) if "controller" in cols else np.full(ok.sum(), "")
    )
    built_in = [c for c in ("pd", "ct", "qp") if c in set(controllers)]
    users = [c for c in dict.fromkeys(controllers) if c not in ("pd", "ct", "qp")]
    kinds = built_in + users or [""]
    markers = dict(zip(("pd", "ct", "qp", ""), "os^o", strict=True))
    markers.update({c: "Dv<>xP*h"[i % 8] for i, c in enumerate(users)})  # a user's own
    colours = dict(
        zip(JOINT_NAMES, ("tab:blue", "tab:orange", "tab:green", "tab:red"), strict=True)
    )
    written = []
    for name in spec.names:
        if name == "controller" or not ok.any():
            continue
        x = cols[name][ok].astype(float)
        fig = Figure(figsize=(9.0, 7.5), layout="constrained")
        FigureCanvasAgg(fig)
        axes = fig.subplots(2, 1, sharex=True)
        for ax, key, ylabel in (
            (axes[0], "peak_drive_torque_Nm", "peak drive torque [N·m]"),
            (axes[1], "peak_mechanical_power_W", "peak mechanical power [W]"),
        ):
            for joint in JOINT_NAMES:
                y = cols[f"{key}_{joint}"][ok].astype(float)
                for kind in kinds:
                    own = controllers == kind if kind else np.ones(len(x), bool)
                    ax.plot(x[own], y[own], markers[kind], ms=6, mfc="none", color=colours[joint])
                xs = np.unique(x)
                if len(xs) < len(x):
                    env = [np.nanmax(y[x == v]) for v in xs]
                    ax.plot(xs, env, "-", color=colours[joint], alpha=0.6)
            ax.set_ylabel(ylabel)
            ax.grid(True, alpha=0.3)
        handles = [
            Line2D([], [], color=colours[j], lw=2, label=j.replace("_", " ")) for j in JOINT_NAMES
        ]
        handles += [
            Line2D([], [], color="0.3", ls="none", marker=markers[k], mfc="none", label=_label(k))
            for k in kinds
            if k
        ]
        handles.append(
            Line2D([], [], color="0.3", alpha=0.6, label="largest at each value (the envelope)")
        )
        fig.legend(handles=handles, loc="outside lower center", ncols=4, frameon=False)
        unit = PARAMETERS[name].unit
        axes[1].set_xlabel(name + (f" [{unit}]" if unit else ""))
        fig.suptitle(
            f"drive loads against {name} ({int(ok.sum())} completed runs); "
            "colour: joint, marker: controller"
        )
        target = paths.plot(name)
        with atomic_write(DerivedOutput(target), "wb") as handle:
            fig.savefig(handle, format="png", dpi=100)
        written.append(target)
    return written
