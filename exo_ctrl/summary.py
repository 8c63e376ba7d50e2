"""A run's figures: tracking error, peak torques, currents, voltages, cuff forces."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from .model import CUFF_NAMES, JOINT_NAMES

if TYPE_CHECKING:
    from .simulate import SimResult

__all__ = ["summarize"]


def _keyed(values: np.ndarray, names: tuple[str, ...]) -> dict[str, float]:
    return {name: float(x) for name, x in zip(names, values)}


def summarize(result: SimResult) -> dict[str, Any]:
    """The JSON summary of a run.

    Keys: ``controller``, ``status``, ``error``, ``duration_s``,
    ``belt_speed_mps``, ``rms_tracking_error_rad`` and
    ``max_tracking_error_rad`` (keyed by joint), ``peak_drive_torque_Nm``,
    ``rms_drive_torque_Nm``, ``peak_motor_current_A``,
    ``peak_motor_voltage_V``, ``peak_mechanical_power_W`` (keyed by joint),
    ``peak_cuff_force_N`` (keyed by cuff: magnitude of the sagittal force),
    ``wall_time_s``, ``real_time_factor`` (simulated time / wall time),
    ``ticks``.  Peaks are of absolute values; an empty run gives zeros.
    """
    n = result.n_ticks
    s = result.signals
    zeros4 = np.zeros(4)
    if n:
        err = s["q_des"] - s["q"]
        rms = np.sqrt(np.mean(err**2, axis=0))
        mx = np.max(np.abs(err), axis=0)
        torque = s["drive_torque"]
        peak_tau = np.max(np.abs(torque), axis=0)
        rms_tau = np.sqrt(np.mean(torque**2, axis=0))
        peak_i = np.max(np.abs(s["current"]), axis=0)
        peak_u = np.max(np.abs(s["voltage"]), axis=0)
        peak_p = np.max(np.abs(torque * s["dq"]), axis=0)
        peak_f = np.max(np.linalg.norm(s["cuff_force"], axis=2), axis=0)
    else:
        rms = mx = peak_tau = rms_tau = peak_i = peak_u = peak_p = peak_f = zeros4
    duration = result.duration_s
    wall = result.wall_time_s
    return {
        "controller": result.config.controller,
        "status": result.status,
        "error": result.error,
        "duration_s": duration,
        "ticks": n,
        "belt_speed_mps": result.belt_speed_mps,
        "rms_tracking_error_rad": _keyed(rms, JOINT_NAMES),
        "max_tracking_error_rad": _keyed(mx, JOINT_NAMES),
        "peak_drive_torque_Nm": _keyed(peak_tau, JOINT_NAMES),
        "rms_drive_torque_Nm": _keyed(rms_tau, JOINT_NAMES),
        "peak_motor_current_A": _keyed(peak_i, JOINT_NAMES),
        "peak_motor_voltage_V": _keyed(peak_u, JOINT_NAMES),
        "peak_mechanical_power_W": _keyed(peak_p, JOINT_NAMES),
        "peak_cuff_force_N": _keyed(peak_f, CUFF_NAMES),
        "wall_time_s": wall,
        "real_time_factor": duration / wall if wall > 0 else 0.0,
    }
