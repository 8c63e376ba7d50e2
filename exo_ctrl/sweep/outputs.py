"""What a sweep produces: the output columns of one run, and the files beside the table.

**Files** (for ``--out DIR/NAME.parquet``): ``NAME.parquet`` and ``NAME.csv``
(the table, written atomically at the end and every 30 s),
``NAME.journal.jsonl`` (one JSON line per finished run, flushed and synced
as it arrives), ``NAME.report.txt`` (worst cases, per-joint maxima,
failures), ``NAME.load_<param>.png`` (peak torque and power against each
swept numeric parameter) and ``NAME.urdf_cache/`` (generated patient and exoskeleton URDFs,
named by the SHA-256 of their text so that every worker shares them).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..exceptions import InvalidParameter
from ..model import CUFF_NAMES, JOINT_NAMES

__all__ = ["METRICS", "OUTPUT_COLUMNS", "SweepPaths", "empty_outputs", "flatten"]

#: The per-joint and per-cuff figures of a run: summary key → the names it is given for.
METRICS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("peak_drive_torque_Nm", JOINT_NAMES),
    ("rms_drive_torque_Nm", JOINT_NAMES),
    ("peak_mechanical_power_W", JOINT_NAMES),
    ("peak_motor_current_A", JOINT_NAMES),
    ("rms_motor_current_A", JOINT_NAMES),
    ("peak_joint_speed_rad_s", JOINT_NAMES),
    ("peak_motor_voltage_V", JOINT_NAMES),
    ("share_at_torque_limit", JOINT_NAMES),
    ("share_at_current_limit", JOINT_NAMES),
    ("peak_cuff_force_N", CUFF_NAMES),
    ("rms_tracking_error_rad", JOINT_NAMES),
    ("max_tracking_error_rad", JOINT_NAMES),
)

#: Output columns of the table after the run id and the swept parameters:
#: name → Arrow type name.  Per-joint and per-cuff figures are flat columns
#: ``<summary key>_<joint or cuff>`` (units in the name; ``share_at_*_limit``:
#: fractions of the run's ticks); ``safety_events`` counts the supervisor's
#: violations and e-stops and the monitors' warnings, ``safety_state`` is its
#: final state, ``qp_failures`` the QP controller's fallbacks (0 and "" when
#: the summary has no such key); ``sim_duration_s`` is the simulated time
#: reached; ``wall_time_s`` the run's wall-clock time, set-up included.
OUTPUT_COLUMNS: dict[str, str] = {
    **{f"{key}_{n}": "float64" for key, names in METRICS for n in names},
    "belt_speed_mps": "float64",
    "sim_duration_s": "float64",
    "safety_events": "int64",
    "safety_state": "string",
    "qp_failures": "int64",
    "status": "string",
    "error": "string",
    "wall_time_s": "float64",
}


def empty_outputs() -> dict[str, Any]:
    """The outputs of a run that produced nothing: NaN figures, status ``error``."""
    out: dict[str, Any] = {c: math.nan for c, t in OUTPUT_COLUMNS.items() if t == "float64"}
    out.update(safety_events=0, safety_state="", qp_failures=0, status="error", error="")
    return out


def _count(events: Any) -> int:
    """A summary's safety events as a count (a number, or a list/dict of events)."""
    if events is None:
        return 0
    if isinstance(events, (int, float, np.integer, np.floating)):
        return int(events)
    return len(events)


def flatten(summary: dict[str, Any]) -> dict[str, Any]:
    """A run's summary (:meth:`~exo_ctrl.sim.SimResult.summary`) as output columns."""
    out = {f"{key}_{n}": float(summary[key][n]) for key, names in METRICS for n in names}
    out["belt_speed_mps"] = float(summary["belt_speed_mps"])
    out["sim_duration_s"] = float(summary["duration_s"])
    out["safety_events"] = _count(summary.get("safety_events", 0))
    out["safety_state"] = str(summary.get("safety_state", ""))
    out["qp_failures"] = int(summary.get("qp_failures", 0))
    return out


@dataclass(frozen=True)
class SweepPaths:
    """The files of a sweep, all beside the output table (see the module docstring)."""

    table: Path
    csv: Path
    journal: Path
    report: Path
    cache: Path

    @classmethod
    def for_output(cls, out_path: str | os.PathLike[str]) -> SweepPaths:
        """Paths for an output ``DIR/NAME.parquet``."""
        table = Path(out_path)
        if table.suffix != ".parquet" or not table.stem:
            raise InvalidParameter("out", str(out_path), "a path ending in .parquet")
        stem = table.with_suffix("")
        return cls(
            table=table,
            csv=table.with_suffix(".csv"),
            journal=Path(f"{stem}.journal.jsonl"),
            report=Path(f"{stem}.report.txt"),
            cache=Path(f"{stem}.urdf_cache"),
        )

    def plot(self, name: str) -> Path:
        """The load diagram of a swept parameter."""
        return Path(f"{self.table.with_suffix('')}.load_{name}.png")
