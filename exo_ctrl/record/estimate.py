"""Cuff-force estimation after the fact, from a recording or a user's CSV log.

This module reads and writes files; the estimation is
:func:`exo_ctrl.estimation.estimate_series` (momentum observer) or
:func:`exo_ctrl.estimation.kalman_series` (Kalman filter on the coupled
model).  :func:`estimate_file` runs the live loop's estimator along logged
sensor readings:

- an ``.rrd`` written by exo_ctrl: the encoder angles ``q_meas``, speeds
  ``dq_meas`` and torque-sensor readings ``tau_sensor`` of every tick, with
  the run's own estimator (or the one the user names), control period and
  device models (:mod:`.estimate_models`: the observer's gain and
  assumption; the filter's nominal patient, cuff model and sensor
  datasheet), so the answer equals the live estimate; where the recording
  holds the simulated cuff forces, the error of the estimate is reported
  (after the checks of :func:`estimate_file`: integrity, length, model,
  plausibility);
- a ``.csv`` log with the header documented in
  :func:`exo_ctrl.estimation.read_csv_log` (``t`` and, per joint, the angle
  and the torque-sensor reading, speeds optional), with the momentum
  observer (a log holds no device models for the filter).

:func:`write_estimate_recording` writes the estimate as a rerun recording
(entities ``estimate/cuff_normal/{cuff}``, ``estimate/cuff_force/{cuff}/{x,z}``
and ``estimate/tau_ext/{joint}``, on the ``sim_time`` timeline).
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import rerun as rr

from .. import _validate as v
from .._io import atomic_write
from ..estimation import (
    DEFAULT_GAIN_PER_S,
    ESTIMATORS,
    EstimateSeries,
    estimate_components,
    estimate_series,
    kalman_series,
    model_driven,
    normal_component_errors,
    read_csv_log,
)
from ..estimation.errors import STARTUP_S
from ..estimation.plausible import implausibility
from ..exceptions import InvalidLog, InvalidParameter, RecordingError
from ..model import CUFF_NAMES, JOINT_NAMES, BodyModel, load_exo
from ..plant import CuffParams
from ..sim.run_models import components_from_s
from .estimate_checks import (
    STARTUP_TIME_CONSTANTS,
    beyond_cuff_stretch,
    recorded_exo,
    startup_ticks,
    worse_than_none,
)
from .estimate_models import chosen_estimator, recorded_kalman, torque_rate_schedule, true_exo
from .format import TIME
from .reader import RecordingIntegrity, read_recording_integrity

__all__ = [
    "OfflineEstimate",
    "SensorLog",
    "estimate_file",
    "read_sensor_log",
    "write_estimate_recording",
]

#: What the text table shows for a figure that is not given (None in JSON).
NOT_GIVEN = "\u2014"
#: Why a CSV log gets no error figures.
NO_TRUTH_CSV = (
    "a CSV log holds the sensor readings only, not the true cuff forces to compare the "
    "estimate with (a simulated run's recording holds them)"
)
#: Why a recording without the simulated cuff forces gets no error figures.
NO_TRUTH_RRD = (
    "the recording holds no simulated cuff forces to compare the estimate with "
    "(cuff_force or q missing or not finite)"
)


@dataclass
class OfflineEstimate:
    """An estimate along a log, and its error where the truth is known.

    Attributes:
        source: the file estimated from.
        series: the estimate (normal components, forces, external torques).
        errors: when the log holds the simulated cuff forces and outlasts
            the observer's start-up (else empty), keyed by cuff:
            ``cuff_force_estimate_rms_error_N`` and ``…_rms_error_rel`` (the
            whole 2-D force's RMS error, and over the RMS true force),
            ``…_normal_rms_error_N`` and ``…_normal_rms_over_peak`` (the
            normal component's, and over its peak), ``…_unobservable``
            (:mod:`exo_ctrl.estimation.errors`); a relative figure whose
            denominator is below :data:`~exo_ctrl.estimation.errors.REL_FLOOR_N`
            is None.
        integrity: how whole the recording was (None for a CSV log).
        warnings: one-line warnings: an incomplete recording, a run too
            short for error figures, another model than the recorded one, an
            estimate the model cannot explain (:mod:`.estimate_checks`).
        no_accuracy: why there are no error figures ("" when there are):
            the log holds no true cuff forces, or is too short.

    """

    source: str
    series: EstimateSeries
    errors: dict[str, dict[str, float | None]] = field(default_factory=dict)
    integrity: RecordingIntegrity | None = None
    warnings: list[str] = field(default_factory=list)
    no_accuracy: str = ""

    def summary(self) -> dict[str, Any]:
        """JSON-able figures: the source, estimator and gain, peaks, errors and warnings.

        ``observer_gain_per_s`` is None for the Kalman filter (it has no gain).
        """
        s = self.series
        whole = self.integrity
        return {
            "source": self.source,
            "samples": int(s.t.shape[0]),
            "estimator": s.estimator,
            "observer_gain_per_s": None if s.gain_per_s is None else float(s.gain_per_s),
            "complete": True if whole is None else whole.complete,
            "ticks_recovered": None if whole is None else whole.ticks_recovered,
            "ticks_planned": None if whole is None else whole.ticks_planned,
            "peak_cuff_normal_est_N": dict(zip(CUFF_NAMES, _peaks(s).tolist(), strict=True)),
            **self.errors,
            "warnings": list(self.warnings),
        }

    def table(self) -> str:
        """The figures as a text table: peak estimate per cuff, and the errors where known.

        Where the truth is known, the summary's error figures (the line under
        the table says which is which) and what the estimator cannot observe or
        takes from models.  A figure not given (below its floor) shows as "—".
        """
        summary = self.summary()
        errors = summary.get("cuff_force_estimate_rms_error_N", {})
        rel = summary.get("cuff_force_estimate_rms_error_rel", {})
        normal = summary.get("cuff_force_estimate_normal_rms_over_peak", {})
        normal_rms = summary.get("cuff_force_estimate_normal_rms_error_over_rms", {})
        along_rms = summary.get("cuff_force_estimate_along_rms_error_over_rms", {})
        head = (
            f"{'rms err [N]':>13}{'rel':>9}{'normal/peak':>13}{'normal/rms':>12}{'along/rms':>11}"
        )
        lines = [f"{'cuff':<13}{'peak normal est [N]':>20}" + (head if errors else "")]
        if not errors and self.no_accuracy:
            lines.insert(0, f"no accuracy figures: {self.no_accuracy}")
        for cuff, peak in summary["peak_cuff_normal_est_N"].items():
            line = f"{cuff:<13}{peak:>20.1f}"
            if errors:
                line += _cell(errors.get(cuff), 13, "{:.2f}")
                line += _cell(None if rel.get(cuff) is None else 100 * rel[cuff], 9, "{:.2f}%")
                for figures, width in ((normal, 13), (normal_rms, 12), (along_rms, 11)):
                    value = figures.get(cuff)
                    line += _cell(None if value is None else 100 * value, width, "{:.2f}%")
            lines.append(line)
        if errors:
            lines.append(
                "rms err, rel: the whole 2-D force against the RMS true force; normal/peak, "
                "normal/rms: the normal component's RMS error against its peak, its RMS; "
                "along/rms: the along-link component's against its RMS (normal/rms, along/rms "
                f"from t = {summary.get('cuff_force_estimate_components_from_s', 0.0):g} s: "
                "after the ramp-in)"
            )
            if self.series.estimator == "kalman":
                lines.append(
                    "from the device's cuff and patient models, not the joint torques: the thigh "
                    "cuffs' along-thigh force, and the split of each hip torque between the "
                    "thigh's normal and the shank's along-shank force"
                )
            else:
                lines.append(
                    "unobservable from the joint torques: the thigh cuffs' along-thigh force "
                    "(assumed 0), the shank cuffs' along-shank force (from the assumption)"
                )
        return "\n".join(lines)


def _peaks(series: EstimateSeries) -> np.ndarray:
    """Peak |estimated normal component| per cuff [N] (zeros for an empty series)."""
    if not series.t.size:
        return np.zeros(len(CUFF_NAMES))
    return np.max(np.abs(series.normal), axis=0)


def _cell(value: float | None, width: int, fmt: str) -> str:
    return f"{NOT_GIVEN if value is None else fmt.format(value):>{width}}"


@dataclass
class SensorLog:
    """A device's sensor readings from a recording or a CSV log, and the model they go with.

    Attributes:
        t: tick times [s], (N,).
        q: encoder angles [rad], (N, 4).
        dq: joint speeds [rad/s], (N, 4) (a CSV log without them: differentiated).
        tau: joint torque sensor readings [N·m], (N, 4).
        exo: the exoskeleton model the readings are interpreted with.
        result: the recording read back (None for a CSV log): its config and
            the simulated truth, where it holds them.
        integrity: how whole the recording was (None for a CSV log).
        notes: one-line warnings (an incomplete recording, another model).

    """

    t: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    tau: np.ndarray
    exo: Any
    result: Any = None
    integrity: RecordingIntegrity | None = None
    notes: list[str] = field(default_factory=list)


def read_sensor_log(
    path: str | os.PathLike[str],
    exo: str | os.PathLike[str] | None = None,
    allow_other_exo: bool = False,
    accept: bool = False,
) -> SensorLog:
    """Read the sensor readings of a recording (``.rrd``) or a CSV log, checked.

    A recording must hold ``q_meas``, ``dq_meas`` and ``tau_sensor`` and at
    least 2 ticks; an incomplete one gives its ticks recovered with a note;
    its exoskeleton is the recorded one unless ``exo`` names another
    (refused unless ``allow_other_exo``, :func:`~.estimate_checks.recorded_exo`).
    A CSV log is read by :func:`~exo_ctrl.estimation.read_csv_log` with
    ``exo`` (default: the committed exoskeleton) and refused if implausible
    for it (:func:`~exo_ctrl.estimation.plausible.implausibility`), or, with
    ``accept``, read with a note saying why it looks wrong.

    Raises:
        RecordingError: an unreadable recording, one without sensor readings
            or of fewer than 2 ticks.
        InvalidLog: a bad CSV log, or an implausible one without ``accept``.
        InvalidParameter: an unknown file type, or an ``exo`` other than the
            recorded one.

    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".csv":
        t, q, dq, tau = read_csv_log(p)
        body = load_exo(exo)
        return SensorLog(t, q, dq, tau, body, notes=plausible(p, t, q, dq, body, accept))
    if suffix != ".rrd":
        raise InvalidParameter("file", str(p), "a .rrd recording or a .csv log")
    result, integrity = read_recording_integrity(p)
    s = result.signals
    for name in ("q_meas", "dq_meas", "tau_sensor"):
        if name not in s:
            raise RecordingError(f"{p}: no {name!r} in the recording (not a sensor log)")
    notes = []
    if not integrity.complete:
        notes.append(f"{p}: {integrity.describe()}; the estimate covers those")
    n = result.t.size
    if n < 2:
        raise RecordingError(
            f"cannot estimate from {p}: it holds {n} tick{'s' * (n != 1)}; "
            "the observer needs at least 2"
        )
    config = result.config
    # The device's exoskeleton model (what the live estimator held): the
    # belief's URDF when the run gave the device another than the truth.
    source = config.belief.exo or result.exo_source or config.exo or ""
    body, model_notes = recorded_exo(p, source, exo, allow_other_exo)
    notes += model_notes
    tau = s["tau_sensor"]
    if "tau_ground_meas" in s:  # the feet's load from the foot plates, as the live estimator had
        tau = tau + s["tau_ground_meas"]
    return SensorLog(result.t, s["q_meas"], s["dq_meas"], tau, body, result, integrity, notes)


def estimate_file(
    path: str | os.PathLike[str],
    exo: str | os.PathLike[str] | None = None,
    gain_per_s: float | None = None,
    allow_other_exo: bool = False,
    estimator: str | None = None,
    accept_implausible: bool = False,
) -> OfflineEstimate:
    """Estimate the cuff forces along a recording (``.rrd``) or a CSV log.

    The estimator is the recording's run's (``config.estimator``) unless
    ``estimator`` names another; a CSV log is estimated with the momentum
    observer (:func:`~.estimate_models.chosen_estimator`).  Each is built as
    the live run built it (:mod:`.estimate_models`), so a recording's
    offline estimate equals its live one to rounding.

    A recording is checked before and after (:mod:`.estimate_checks`):

    - an incomplete one (cut short, or without its end record: the run or
      its writer stopped early) is estimated over the ticks recovered, with a
      warning saying how many of how many (``complete`` false in the summary);
    - one of fewer than 2 ticks is refused; one not longer than the
      observer's start-up (5 / K_O) gets no error figures, with a warning;
    - an ``exo`` that differs from the recorded exoskeleton is refused
      unless ``allow_other_exo``;
    - an estimate worse than none against the recorded forces, or beyond
      what the cuffs can carry, is flagged with a warning.

    Each warning is in :attr:`OfflineEstimate.warnings` (and the summary's
    ``warnings``) and is also issued as a one-line ``RuntimeWarning``
    (``exo-ctrl estimate: warning: …`` on the command line).

    Args:
        path: the file.
        exo: exoskeleton URDF (default: the recording's own, or the committed
            default for a CSV log).
        gain_per_s: observer gain K_O [1/s] (default: the recording's, or
            :data:`~exo_ctrl.estimation.DEFAULT_GAIN_PER_S`).
        allow_other_exo: estimate a recording with an ``exo`` other than the
            one it was recorded with.
        estimator: ``"momentum"`` or ``"kalman"`` (None: the recording's;
            momentum for a CSV log).
        accept_implausible: read a CSV log implausible for the exoskeleton
            with a warning instead of refusing it (:func:`read_sensor_log`).

    Raises:
        RecordingError: an unreadable recording, one without sensor readings
            or of fewer than 2 ticks; a recording whose device patient model
            cannot be rebuilt for the Kalman filter.
        InvalidLog: a bad CSV log.
        InvalidParameter: an unknown file type, a bad gain, an ``exo``
            other than the recorded one, an unknown estimator, ``kalman`` for
            a CSV log, or a gain with the Kalman filter.

    """
    p = Path(path)
    if gain_per_s is not None:
        v.positive("gain", gain_per_s, "1/s")
    if estimator is not None and estimator not in ESTIMATORS:
        raise InvalidParameter("estimator", estimator, f"one of {', '.join(ESTIMATORS)}")
    if p.suffix.lower() == ".csv":
        chosen_estimator(estimator, None, gain_per_s)  # refuses kalman before reading
    log = read_sensor_log(p, exo, allow_other_exo, accept_implausible)
    if log.result is not None:
        chosen = chosen_estimator(estimator, log.result.config, gain_per_s)
        return _warn(_from_recording(p, log, gain_per_s, chosen))
    gain = DEFAULT_GAIN_PER_S if gain_per_s is None else gain_per_s
    try:
        series = estimate_series(log.t, log.q, log.dq, log.tau, log.exo, gain_per_s=gain)
    except InvalidLog as exc:  # the file, not "arrays"
        raise InvalidLog(str(p), exc.reason) from None
    stiffness = CuffParams().stiffness_N_per_m
    notes = log.notes + beyond_cuff_stretch(p, _peaks(series), stiffness, log.exo)
    return _warn(OfflineEstimate(str(p), series, warnings=notes, no_accuracy=NO_TRUTH_CSV))


def _warn(estimate: OfflineEstimate) -> OfflineEstimate:
    """Issue each of the estimate's warnings as a RuntimeWarning (one line each), and return it."""
    for text in estimate.warnings:
        warnings.warn(text, RuntimeWarning, stacklevel=3)
    return estimate


def _from_recording(
    path: Path, log: SensorLog, gain_per_s: float | None, estimator: str
) -> OfflineEstimate:
    result, body, notes = log.result, log.exo, list(log.notes)
    s, n, config = result.signals, result.t.size, result.config
    gain = config.observer_gain_per_s if gain_per_s is None else gain_per_s
    cuffs = None  # the cuff sensors' readings the filter fuses, if any
    if estimator == "kalman":
        kalman, said, cuffs = recorded_kalman(path, config, body, s)
        notes += said
        rates = torque_rate_schedule(config)
        series = kalman_series(log.t, log.q, log.dq, log.tau, kalman, rates, cuffs)
    else:
        series = estimate_series(
            log.t,
            log.q,
            log.dq,
            log.tau,
            body,
            gain_per_s=gain,
            dt=config.dt,
            stiffness_ratio=config.cuff_stiffness_ratio,
        )
    errors: dict[str, dict[str, float | None]] = {}
    why = NO_TRUTH_RRD
    if estimator == "kalman":  # the live run's error figures leave out its first STARTUP_S
        skip = round(STARTUP_S / config.dt)
        startup = f"the start-up the live figures leave out, {skip} ticks ({STARTUP_S:g} s)"
    else:
        skip = startup_ticks(gain, config.dt)
        startup = (
            f"the observer's start-up of {skip} ticks "
            f"(5 / K_O = {STARTUP_TIME_CONSTANTS / gain:.4g} s)"
        )
    truth = s.get("cuff_force")
    if truth is not None and np.all(np.isfinite(truth)) and np.all(np.isfinite(s["q"])):
        if n <= max(skip, 1):
            notes.append(f"{path}: {n} ticks, not more than {startup}: no error figures")
            why = f"{n} ticks, not more than {startup}"
        else:
            found = normal_component_errors(
                s["q"],
                truth,
                series.normal,
                true_exo(result, body),
                skip=skip,
                lag=1,
                force_est=series.force,
                components_from=round(components_from_s(config) / config.dt),
            )
            found.components_from_s = found.components_from_row * config.dt
            errors = found.summary()
            fused = config.cuff_sensors.mode if cuffs is not None else "none"
            components = estimate_components(estimator, fused)
            errors["cuff_force_estimate_components"] = components
            if estimator == "kalman":  # every component estimated; these from the models
                errors["cuff_force_estimate_unobservable"] = model_driven(components)
            notes += worse_than_none(path, found)
    notes += beyond_cuff_stretch(path, _peaks(series), config.cuffs.stiffness_N_per_m, body)
    return OfflineEstimate(str(path), series, errors, log.integrity, notes, "" if errors else why)


def plausible(
    p: Path, t: np.ndarray, q: np.ndarray, dq: np.ndarray | None, exo: BodyModel, accept: bool
) -> list[str]:
    """Refuse a CSV log implausible for ``exo`` (or, with ``accept``, a note saying why).

    Raises:
        InvalidLog: naming the first implausible sample's line and column,
            its value and the limit, unless ``accept``.

    """
    found = implausibility(t, q, dq, exo)
    if found is None:
        return []
    row, column, reason = found
    if not accept:
        line = None if row is None else row + 2  # the header is line 1
        raise InvalidLog(str(p), f"{reason}; --accept-implausible reads it anyway", line, column)
    at = "" if row is None else f", line {row + 2}"
    return [f"{p}{at}, column {column!r}: {reason}; read as it is (--accept-implausible)"]


def write_estimate_recording(estimate: OfflineEstimate, path: str | os.PathLike[str]) -> Path:
    """Write an estimate as a rerun recording (entities in the module docstring).

    Rerun encodes it in memory (a few MB per minute of 1 kHz data); the
    bytes are written whole through a temporary file renamed over ``path``
    (:func:`exo_ctrl._io.atomic_write`): a failure leaves the previous file.

    Raises:
        RecordingError: rerun could not encode the recording.
        OutputError: the file could not be written (disk full).

    """
    out = Path(path)
    s = estimate.series
    rec = rr.RecordingStream("exo_ctrl_estimate")
    stream = rr.binary_stream(recording=rec)
    try:
        times = rr.TimeColumn(TIME, duration=s.t)
        entities = [(f"cuff_normal/{c}", s.normal[:, i]) for i, c in enumerate(CUFF_NAMES)]
        for i, cuff in enumerate(CUFF_NAMES):
            entities += [(f"cuff_force/{cuff}/{x}", s.force[:, i, k]) for k, x in enumerate("xz")]
        entities += [(f"tau_ext/{j}", s.tau_ext[:, i]) for i, j in enumerate(JOINT_NAMES)]
        for entity, values in entities:
            rec.send_columns(
                f"estimate/{entity}", indexes=[times], columns=rr.Scalars.columns(scalars=values)
            )
        rec.log(
            "estimate/source", rr.TextDocument(f"estimated from {estimate.source}"), static=True
        )
        data = stream.read(flush=True)
    except Exception as exc:
        raise RecordingError(f"{out}: could not write the estimate ({exc})") from exc
    finally:
        rec.disconnect()
    with atomic_write(out, "wb") as handle:
        handle.write(data or b"")
    return out
