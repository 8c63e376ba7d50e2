"""What a therapist sees: the per-cycle figures of a run, logged for the biofeedback panel.

At the end of a run the recorder logs, for each gait cycle after the ramp-in
(cycle c ends at t = (L + (c + 1) P) Δt, :mod:`exo_ctrl.sim.interaction`),
one point per figure under ``biofeedback/``:

==========================================  =====  ==========================================
entity                                      unit   value per cycle
==========================================  =====  ==========================================
``biofeedback/interaction_force/true``      N      RMS true cuff force (the plant's)
``biofeedback/interaction_force/estimated`` N      RMS estimated cuff force (the device's)
``biofeedback/patient_torque``              N·m    patient's RMS joint torque, RMS over joints
``biofeedback/work/patient``                J      patient's positive work, all joints
``biofeedback/work/device``                 J      drives' positive work, all joints
``biofeedback/gait_profile_score/planned``  deg    GPS of the plan (:mod:`~exo_ctrl.sim.gait_score`)
``biofeedback/gait_profile_score/actual``   deg    GPS of the patient's true angles
``biofeedback/aan_support``                 N·m    aan's support level after the cycle
==========================================  =====  ==========================================

The interaction figures exist for a run in a mode or with an active
patient, the GPS for every gait run, the support for ``aan``: an entity
without values holds only its style.  :func:`read_biofeedback` reads them back.
"""

from __future__ import annotations

import math
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr
from rerun.chunk import RrdReader

from ..exceptions import RecordingError
from ..sim import SimResult
from .format import TICK, TIME

__all__ = ["BIOFEEDBACK", "BIOFEEDBACK_SERIES", "biofeedback_points", "log_biofeedback"]

#: The root entity of the per-cycle figures.
BIOFEEDBACK = "biofeedback"
#: entity → (unit, colour RGBA, colour's word, what it is).
BIOFEEDBACK_SERIES: dict[str, tuple[str, tuple[int, ...], str, str]] = {
    "interaction_force/true": ("N", (30, 30, 30, 255), "black", "true"),
    "interaction_force/estimated": ("N", (200, 50, 30, 255), "red", "estimated"),
    "patient_torque": ("N·m", (0, 90, 180, 255), "blue", "patient RMS torque"),
    "work/patient": ("J", (0, 90, 180, 255), "blue", "patient"),
    "work/device": ("J", (240, 160, 40, 255), "orange", "device"),
    "gait_profile_score/planned": ("deg", (40, 160, 60, 255), "green", "planned"),
    "gait_profile_score/actual": ("deg", (0, 90, 180, 255), "blue", "patient"),
    "aan_support": ("N·m", (150, 60, 170, 255), "purple", "aan support"),
}


def biofeedback_points(result: SimResult) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Each figure's points: entity (below ``biofeedback/``) → (cycle end times [s], values).

    Read from the run's statistics (``result.stats``): the ``interaction``
    block's cycles, the gait scores' cycles and aan's support history.
    """
    config, stats = result.config, result.stats
    lead = math.ceil(config.ramp_in / config.dt - 1e-9)
    period = round(config.gait.period / config.dt)
    end = lambda c: (lead + (c + 1) * period) * config.dt  # noqa: E731
    points: dict[str, list[tuple[float, float]]] = {name: [] for name in BIOFEEDBACK_SERIES}
    block = stats.interaction.summary(stats.support) if stats.interaction is not None else None
    for cyc in (block or {}).get("cycles", []):
        c = cyc["cycle"]
        if not isinstance(c, int):
            continue  # the ramp-in
        torque = np.array(list(cyc["patient_rms_torque_Nm"].values()))
        points["interaction_force/true"].append((end(c), cyc["rms_interaction_force_N"]))
        points["interaction_force/estimated"].append(
            (end(c), cyc["rms_interaction_force_estimated_N"])
        )
        points["patient_torque"].append((end(c), float(np.sqrt(np.mean(torque**2)))))
        points["work/patient"].append((end(c), sum(cyc["patient_positive_work_J"].values())))
        points["work/device"].append((end(c), sum(cyc["device_positive_work_J"].values())))
    for k, level in enumerate((block or {}).get("aan_support_rms_Nm", [])):
        points["aan_support"].append((end(k), float(level)))
    gait = stats.gait.summary() if stats.gait is not None else {}
    for cyc in gait.get("gait_profile_score_cycles", []):
        for kind in ("planned", "actual"):
            points[f"gait_profile_score/{kind}"].append((end(cyc["cycle"]), cyc[kind]))
    return {
        name: (np.array([t for t, _ in pts]), np.array([v for _, v in pts], dtype=float))
        for name, pts in points.items()
        if pts
    }


def log_biofeedback(rec: rr.RecordingStream, result: SimResult) -> None:
    """Log :func:`biofeedback_points` as scalar series (lines with a marker per cycle).

    Every entity gets its style (static ``SeriesLines`` and ``SeriesPoints``),
    so that the blueprint's panels name what they would show; values only
    where the run has them.
    """
    dt = result.config.dt
    points = biofeedback_points(result)
    for name, (unit, color, _, what) in BIOFEEDBACK_SERIES.items():
        entity = f"{BIOFEEDBACK}/{name}"
        rec.log(entity, rr.SeriesLines(names=[f"{what} [{unit}]"], colors=[color]), static=True)
        marker = rr.SeriesPoints(colors=[color], markers=["circle"], marker_sizes=[4.0])
        rec.log(entity, marker, static=True)
        if name not in points:
            continue
        times, values = points[name]
        ticks = np.rint(times / dt).astype(np.int64)
        rec.send_columns(
            entity,
            indexes=[rr.TimeColumn(TIME, duration=times), rr.TimeColumn(TICK, sequence=ticks)],
            columns=rr.Scalars.columns(scalars=values),
        )


def read_biofeedback(path: str | os.PathLike[str]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """The biofeedback points of a recording: entity (below ``biofeedback/``) → (times [s], values).

    Raises:
        RecordingError: the file cannot be read.

    """
    p = Path(path)
    found: dict[str, list[Any]] = {}
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*no footer.*")
            chunks = RrdReader(p).stream().to_chunks()
            for chunk in chunks:
                entity = chunk.entity_path.lstrip("/")
                if not entity.startswith(f"{BIOFEEDBACK}/"):
                    continue
                batch = chunk.to_record_batch()
                if "Scalars:scalars" not in batch.schema.names or TIME not in batch.schema.names:
                    continue
                t = batch.column(TIME).to_numpy(zero_copy_only=False).astype("int64") * 1e-9
                v = [row[0] for row in batch.column("Scalars:scalars").to_pylist()]
                found.setdefault(entity[len(BIOFEEDBACK) + 1 :], []).extend(zip(t, v, strict=True))
    except (ValueError, RuntimeError, OSError) as exc:
        raise RecordingError(f"cannot read recording {p}: {exc}") from None
    out = {}
    for name, pts in found.items():
        pts.sort()
        out[name] = (np.array([t for t, _ in pts]), np.array([v for _, v in pts], dtype=float))
    return out
