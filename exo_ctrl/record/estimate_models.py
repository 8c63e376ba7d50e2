"""Which estimator an offline estimate runs, and the device models it is rebuilt on.

A recording stores its run's whole :class:`~exo_ctrl.sim.config.SimConfig`
(``raw/meta``), the ``estimator`` and the device's beliefs
(:class:`~exo_ctrl.sim.belief.Belief`) included.  The offline estimate
runs the recording's estimator unless the user names another
(:func:`chosen_estimator`), and builds it as the live run did
(:class:`~exo_ctrl.sim.tick.Runner` on :func:`~exo_ctrl.sim.setup.build`'s
device models):

- the momentum observer holds the device's exoskeleton only, its gain K_O
  and its load-sharing assumption κ (:func:`~exo_ctrl.estimation.estimate_series`);
- the Kalman filter (:func:`recorded_kalman`) holds the device's
  exoskeleton, the device's patient rebuilt from the recorded config
  exactly as :func:`~exo_ctrl.sim.setup.build` does it
  (:func:`~exo_ctrl.sim.belief.device_patient` with the fitted, coaxial true
  patient's leg lengths: the nominal de Leva model, the truth or the user's
  URDF), the device's cuff model (``belief.cuff_model_of``), the run's sensor
  datasheet (noise and resolution), its cuff sensors with their logged
  readings (the filter tares and fuses them as live) and its control period; and the
  filter's σ_d as the run's modes set it over time
  (:func:`torque_rate_schedule`: ``transparent`` and ``path`` raise it from
  their first tick, a session's switch from the tick after it).

A CSV log holds readings only, none of these models: it is estimated with
the momentum observer.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np

from ..estimation import ESTIMATORS, CuffForceKalman, estimator_name
from ..exceptions import ExoCtrlError, InvalidParameter, RecordingError
from ..model import BodyModel, load_exo, load_patient
from ..sensing import CuffSensors
from ..sim.belief import device_patient
from ..sim.config import SimConfig

__all__ = [
    "CUFF_READINGS",
    "chosen_estimator",
    "recorded_kalman",
    "torque_rate_schedule",
    "true_exo",
]

#: The logged cuff sensors' readings the offline filter fuses, in
#: :func:`~exo_ctrl.estimation.kalman_series`'s order.
CUFF_READINGS = ("cuff_sensor_normal", "cuff_sensor_along", "cuff_sensor_fresh")


def chosen_estimator(
    estimator: str | None, config: SimConfig | None, gain_per_s: float | None
) -> str:
    """The estimator to run: ``estimator``, else the recording's, else (a CSV log) momentum.

    Args:
        estimator: the user's choice (None: the recording's).
        config: the recording's run (None: a CSV log).
        gain_per_s: the user's observer gain (None: not given).

    Raises:
        InvalidParameter: an unknown estimator; ``kalman`` for a CSV log (it
            holds no device models); a gain with the Kalman filter (it has none).

    """
    if estimator is not None and estimator not in ESTIMATORS:
        raise InvalidParameter("estimator", estimator, f"one of {', '.join(ESTIMATORS)}")
    if config is None:
        if estimator == "kalman":
            raise InvalidParameter(
                "estimator",
                estimator,
                "momentum for a .csv log",
                "the Kalman filter needs the device's patient, cuff and sensor models, "
                "which only a recording holds",
            )
        return "momentum"
    chosen = estimator if estimator is not None else config.estimator
    if chosen not in ESTIMATORS:  # the run's was a user's (exo_ctrl.estimation.plugin)
        raise InvalidParameter(
            "estimator",
            estimator_name(chosen),
            f"one of {', '.join(ESTIMATORS)} for a recording's estimate",
            "the recording's run used a user's estimator: give --estimator",
        )
    if chosen == "kalman" and gain_per_s is not None:
        recorded = "" if estimator is not None else " (the recording's estimator)"
        raise InvalidParameter(
            "gain",
            gain_per_s,
            "given with the momentum observer only",
            f"the kalman estimator{recorded} has no observer gain; add --estimator momentum",
        )
    return chosen


def recorded_kalman(
    path: os.PathLike[str] | str,
    config: SimConfig,
    exo: BodyModel,
    signals: dict[str, np.ndarray] | None = None,
) -> tuple[CuffForceKalman, list[str], tuple[np.ndarray, np.ndarray, np.ndarray] | None]:
    """The Kalman filter of a recorded run, on the device models the run held (module docstring).

    Returns:
        The filter; one line for each patient URDF the recording names
        that was read to build it (a file named by a recording is never
        read without saying so), and one when the run fused cuff sensors
        whose readings the recording does not hold (the offline filter then
        runs without them); and the cuff sensors' readings to fuse
        (:func:`~exo_ctrl.estimation.kalman_series`'s ``cuff_readings``), or None.

    Args:
        path: the recording (for messages).
        config: the recording's run.
        exo: the device's exoskeleton model (the recorded one, or the
            user's, checked by :func:`~.estimate_checks.recorded_exo`).
        signals: the recording's signals (None: none; the cuff sensors'
            readings ``cuff_sensor_normal``, ``…_along``, ``…_fresh`` are taken from them).

    Raises:
        RecordingError: the device's patient cannot be rebuilt (a patient
            URDF the recording names that cannot be loaded here).

    """
    try:
        fitted = load_patient(config.patient)  # as build() does: the coaxial true patient
        patient = device_patient(config.belief, config.patient, fitted)
    except ExoCtrlError as exc:
        raise RecordingError(
            f"cannot estimate from {path} with the kalman estimator: the device's patient "
            f"model cannot be rebuilt ({exc}); --estimator momentum needs none"
        ) from None
    signals = signals if signals is not None else {}
    readings = None
    if config.cuff_sensors.on and all(name in signals for name in CUFF_READINGS):
        readings = tuple(signals[name] for name in CUFF_READINGS)
    kalman = CuffForceKalman(
        exo,
        patient,
        config.dt,
        cuffs=config.belief.cuff_model_of(config.cuffs),
        sensors=config.sensors,
        cuff_sensors=CuffSensors(config.cuff_sensors, config.dt) if readings else None,
    )
    notes = _named_patients(path, config)
    if config.cuff_sensors.on and readings is None:  # a recording made before they were logged
        notes.append(
            f"{path}: the run fused cuff sensors (cuff_sensors.mode = {config.cuff_sensors.mode}),"
            " whose readings the recording does not hold: this estimate is the joint torques' alone"
        )
    return kalman, notes, readings


def _named_patients(path: os.PathLike[str] | str, config: SimConfig) -> list[str]:
    """A line for each patient URDF file the recorded run names (not the default, not human)."""
    named = [config.patient] if config.patient not in (None, "human") else []
    if config.belief.patient not in ("truth", "nominal", "human", config.patient):
        named.append(config.belief.patient)
    return [
        f"{path}: read with the patient URDF it names, {name} (the Kalman filter's device "
        "model; --estimator momentum reads none)"
        for name in named
    ]


def torque_rate_schedule(config: SimConfig) -> list[tuple[int, float | None]]:
    """The rows at which the live run's modes set the Kalman filter's σ_d, with the value.

    ``(row, σ_d [N·m/√s] or None: the filter's own)``: the run's mode from
    row 0 (:meth:`~exo_ctrl.control.modes.ModeParams.torque_rate_for`); in a
    session each segment's from the row after its switch (the live tick
    updates the filter before the controller switches), the first from row 0.
    """
    session = config.session
    if session is None:
        return [(0, config.modes.torque_rate_for(config.mode))]
    schedule = []
    for i, (seg, start) in enumerate(zip(session.segments, session.starts_s, strict=True)):
        row = 0 if i == 0 else round(start / config.dt) + 1
        schedule.append((row, seg.mode_params(config.modes).torque_rate_for(seg.mode)))
    return schedule


def true_exo(result: Any, device_exo: BodyModel) -> BodyModel:
    """The exoskeleton whose geometry the live error figures used: the truth's.

    The device's model when the run gave the device none other (the same
    file), or when the truth's URDF cannot be loaded here.
    """
    if result.config.belief.exo is None:
        return device_exo
    try:
        return load_exo(result.exo_source or result.config.exo or None)
    except ExoCtrlError:
        return device_exo
