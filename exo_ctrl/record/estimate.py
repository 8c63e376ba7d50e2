"""Cuff-force estimation after the fact, from a recording or a user's CSV log.

This module reads and writes files; the estimation itself is
:func:`exo_ctrl.estimation.estimate_series`.  :func:`estimate_file` runs the
same momentum observer as the live loop
(:class:`exo_ctrl.estimation.CuffForceEstimator`) along logged sensor readings:

- an ``.rrd`` written by exo_ctrl: the encoder angles ``q_meas``, speeds
  ``dq_meas`` and torque-sensor readings ``tau_sensor`` of every tick, with
  the run's own control period, observer gain and assumption, so the answer
  equals the live estimate; where the recording holds the simulated cuff
  forces, the error of the estimate is reported;
- a ``.csv`` log with the header documented in
  :func:`exo_ctrl.estimation.read_csv_log` (``t`` and, per joint, the angle
  and the torque-sensor reading, speeds optional).

:func:`write_estimate_recording` writes the estimate as a rerun recording
(entities ``estimate/cuff_normal/{cuff}``, ``estimate/cuff_force/{cuff}/{x,z}``
and ``estimate/tau_ext/{joint}``, on the ``sim_time`` timeline).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from ..estimation import (
    DEFAULT_GAIN_PER_S,
    EstimateSeries,
    estimate_series,
    normal_component_errors,
    read_csv_log,
)
from ..exceptions import InvalidParameter, RecordingError
from ..model import CUFF_NAMES, JOINT_NAMES, load_exo
from .format import TIME
from .reader import read_recording

__all__ = ["OfflineEstimate", "estimate_file", "write_estimate_recording"]

#: Observer start-up left out of the error figures: five time constants 5 / K_O [s].
STARTUP_TIME_CONSTANTS = 5.0


@dataclass
class OfflineEstimate:
    """An estimate along a log, and its error where the truth is known.

    Attributes:
        source: the file estimated from.
        series: the estimate (normal components, forces, external torques).
        errors: ``cuff_force_estimate_rms_error_N`` and ``…_rel`` keyed by
            cuff, when the log holds the simulated cuff forces (else empty).

    """

    source: str
    series: EstimateSeries
    errors: dict[str, dict[str, float]] = field(default_factory=dict)

    def summary(self) -> dict[str, Any]:
        """JSON-able figures: source, samples, gain, peaks and errors."""
        s = self.series
        return {
            "source": self.source,
            "samples": int(s.t.shape[0]),
            "observer_gain_per_s": float(s.gain_per_s),
            "peak_cuff_normal_est_N": {
                c: float(np.max(np.abs(s.normal[:, i]))) if s.t.size else 0.0
                for i, c in enumerate(CUFF_NAMES)
            },
            **self.errors,
        }


def estimate_file(
    path: str | os.PathLike[str],
    exo: str | os.PathLike[str] | None = None,
    gain_per_s: float | None = None,
) -> OfflineEstimate:
    """Estimate the cuff forces along a recording (``.rrd``) or a CSV log.

    Args:
        path: the file.
        exo: exoskeleton URDF (default: the recording's own, or the committed
            default for a CSV log).
        gain_per_s: observer gain K_O [1/s] (default: the recording's, or
            :data:`~exo_ctrl.estimation.DEFAULT_GAIN_PER_S`).

    Raises:
        RecordingError: an unreadable recording.
        InvalidLog: a bad CSV log.
        InvalidParameter: an unknown file type.

    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".rrd":
        return _from_recording(p, exo, gain_per_s)
    if suffix == ".csv":
        body = load_exo(exo)
        t, q, dq, tau = read_csv_log(p)
        gain = DEFAULT_GAIN_PER_S if gain_per_s is None else gain_per_s
        series = estimate_series(t, q, dq, tau, body, gain_per_s=gain)
        return OfflineEstimate(str(p), series)
    raise InvalidParameter("file", str(p), "a .rrd recording or a .csv log")


def _from_recording(
    path: Path, exo: str | os.PathLike[str] | None, gain_per_s: float | None
) -> OfflineEstimate:
    result = read_recording(path)
    s = result.signals
    for name in ("q_meas", "dq_meas", "tau_sensor"):
        if name not in s:
            raise RecordingError(f"{path}: no {name!r} in the recording (not a sensor log)")
    config = result.config
    body = load_exo(exo or result.exo_source or config.exo)
    gain = config.observer_gain_per_s if gain_per_s is None else gain_per_s
    series = estimate_series(
        result.t,
        s["q_meas"],
        s["dq_meas"],
        s["tau_sensor"],
        body,
        gain_per_s=gain,
        dt=config.dt,
        stiffness_ratio=config.cuff_stiffness_ratio,
    )
    errors: dict[str, dict[str, float]] = {}
    if "cuff_force" in s and result.t.size:
        skip = round(STARTUP_TIME_CONSTANTS / gain / config.dt)
        errors = normal_component_errors(
            s["q"], s["cuff_force"], series.normal, body, skip=skip, lag=1
        ).summary()
    return OfflineEstimate(str(path), series, errors)


def write_estimate_recording(estimate: OfflineEstimate, path: str | os.PathLike[str]) -> Path:
    """Write an estimate as a rerun recording (entities in the module docstring).

    Raises:
        RecordingError: the file could not be written.

    """
    out = Path(path)
    s = estimate.series
    rec = rr.RecordingStream("exo_ctrl_estimate")
    try:
        rec.save(str(out))
        times = rr.TimeColumn(TIME, duration=s.t)
        for i, cuff in enumerate(CUFF_NAMES):
            rec.send_columns(
                f"estimate/cuff_normal/{cuff}",
                indexes=[times],
                columns=rr.Scalars.columns(scalars=s.normal[:, i]),
            )
            for k, axis in enumerate("xz"):
                rec.send_columns(
                    f"estimate/cuff_force/{cuff}/{axis}",
                    indexes=[times],
                    columns=rr.Scalars.columns(scalars=s.force[:, i, k]),
                )
        for j, joint in enumerate(JOINT_NAMES):
            rec.send_columns(
                f"estimate/tau_ext/{joint}",
                indexes=[times],
                columns=rr.Scalars.columns(scalars=s.tau_ext[:, j]),
            )
        rec.log(
            "estimate/source", rr.TextDocument(f"estimated from {estimate.source}"), static=True
        )
    except Exception as exc:
        raise RecordingError(f"{out}: could not write the estimate ({exc})") from exc
    finally:
        rec.flush()
        rec.disconnect()
    return out
