"""``compare.png``: the compared runs' last full gait cycle, overlaid.

Three rows of four panels, over the cycle of :mod:`.cycle` (time since its
start [s]): the joint angle against the plan [rad] per joint, the drive
torque at the joint [N·m] per joint, and the magnitude of the true cuff
force [N] per cuff.  One solid line per run in each panel, in the run's
colour (matplotlib's ``gid`` is ``run:<label>``); in the cuff panels the
live estimate's magnitude is a dotted line in the same colour
(``estimate:<label>``); the plan is one black dashed line
(``gid`` ``plan``) when the runs share it, else a dashed line per run in its
colour (``plan:<label>``).  matplotlib is needed (``pip install
"exo-ctrl[plots]"``): :func:`require_matplotlib` says so before any run.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from .._io import atomic_write
from ..exceptions import MissingDependency
from ..model import CUFF_NAMES, JOINT_NAMES
from .table import CompareTable

__all__ = ["PLOTS_HINT", "cycle_figure", "require_matplotlib", "write_compare_png"]

PLOTS_HINT = 'pip install "exo-ctrl[plots]"'

#: The rows of panels: title, the trace's attribute, the y-axis label, the names.
_ROWS = (
    ("angle", "q", "joint angle q [rad]", JOINT_NAMES),
    ("drive torque", "drive_torque", "drive torque τ [N·m]", JOINT_NAMES),
    ("cuff force", "cuff_force", "cuff force |f| [N]", CUFF_NAMES),
)


def require_matplotlib() -> Any:
    """The ``Figure`` class of matplotlib, checked before any work.

    Raises:
        MissingDependency: matplotlib is not installed (with the install hint).

    """
    try:
        from matplotlib.figure import Figure
    except ImportError:
        raise MissingDependency(f"compare.png needs matplotlib: {PLOTS_HINT}") from None
    return Figure


def _shared_plan(table: CompareTable) -> bool:
    """Whether every run drawn has the first's plan over its cycle (one plan line)."""
    traces = [row.cycle for row in table if row.cycle is not None]
    first = traces[0]
    return all(
        t.q_des.shape == first.q_des.shape and np.array_equal(t.q_des, first.q_des)
        for t in traces[1:]
    )


def cycle_figure(table: CompareTable) -> Any:
    """The figure (a matplotlib ``Figure``, not yet saved): module docstring.

    Raises:
        MissingDependency: matplotlib is not installed.

    """
    figure_class = require_matplotlib()
    fig = figure_class(figsize=(16, 10))
    # A fixed layout: matplotlib's constrained layout drew the figure twice (half the time).
    fig.subplots_adjust(left=0.05, right=0.99, bottom=0.1, top=0.93, wspace=0.28, hspace=0.3)
    axes = fig.subplots(len(_ROWS), 4, sharex=True, squeeze=False)
    drawn = [row for row in table if row.cycle is not None]
    colors = [f"C{i % 10}" for i in range(len(table))]
    color = {row.label: colors[i] for i, row in enumerate(table)}
    one_plan = bool(drawn) and _shared_plan(table)
    for r, (what, attribute, ylabel, names) in enumerate(_ROWS):
        for j, name in enumerate(names):
            ax = axes[r, j]
            if r == 0 and drawn and one_plan:
                trace = drawn[0].cycle
                ax.plot(
                    trace.t, trace.q_des[:, j], "k--", lw=1.0, label="plan", gid="plan", zorder=3
                )  # over the runs, which follow it closely
            for row in drawn:
                trace = row.cycle
                c = color[row.label]
                if r == 0 and not one_plan:
                    ax.plot(
                        trace.t, trace.q_des[:, j], "--", color=c, lw=1.0,
                        label=f"plan ({row.label})", gid=f"plan:{row.label}", zorder=3,
                    )  # fmt: skip
                y = getattr(trace, attribute)[:, j]
                ax.plot(trace.t, y, "-", color=c, lw=1.3, label=row.label, gid=f"run:{row.label}")
                if attribute == "cuff_force":
                    ax.plot(
                        trace.t, trace.cuff_force_est[:, j], ":", color=c, lw=1.0,
                        label=f"{row.label} estimate", gid=f"estimate:{row.label}",
                    )  # fmt: skip
            ax.set_title(f"{name.replace('_', ' ')} {what}", fontsize=10)
            ax.set_ylabel(ylabel)
            ax.grid(True, lw=0.3)
            if r == len(_ROWS) - 1:
                ax.set_xlabel("time in the gait cycle t − t₀ [s]")
    handles, labels = axes[0, 0].get_legend_handles_labels()
    more, extra = axes[-1, 0].get_legend_handles_labels()  # the estimates' line style
    handles += [h for h, lab in zip(more, extra, strict=True) if lab.endswith(" estimate")]
    labels += [lab for lab in extra if lab.endswith(" estimate")]
    if handles:
        ncol = min(len(handles), 8)
        fig.legend(handles, labels, loc="lower center", ncol=ncol, frameon=False)
    fig.suptitle(_title(table))
    return fig


def _title(table: CompareTable) -> str:
    """The figure's title: which cycle of which runs."""
    drawn = [row for row in table if row.cycle is not None]
    if not drawn:
        return "no run has a tick to draw"
    starts = sorted({round(row.cycle.t0_s, 6) for row in drawn})
    whole = all(row.cycle.complete for row in drawn)
    what = "last full gait cycle" if whole else "last gait period run (no whole cycle in a run)"
    at = ", ".join(f"{s:g}" for s in starts)
    return f"{' vs '.join(row.label for row in table)}: {what}, from t₀ = {at} s"


def write_compare_png(table: CompareTable, path: str | os.PathLike[str]) -> Path:
    """Draw :func:`cycle_figure` and write it as a PNG (atomically); returns the path.

    Raises:
        MissingDependency: matplotlib is not installed.
        OutputError: the file could not be written.

    """
    fig = cycle_figure(table)
    target = Path(path)
    with atomic_write(path, "wb") as handle:  # path, not target: its kind kept
        fig.savefig(handle, format="png", dpi=100)
    return target
