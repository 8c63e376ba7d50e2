"""A run's figures, accumulated chunk by chunk (no need to keep the history)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from .model import CUFF_NAMES, JOINT_NAMES

if TYPE_CHECKING:
    from .estimation import EstimateErrorStats
    from .simulate import SimResult

__all__ = ["RunStats"]


def _keyed(values: np.ndarray, names: tuple[str, ...]) -> dict[str, float]:
    return {name: float(x) for name, x in zip(names, values, strict=True)}


class RunStats:
    """Running sums and peaks of a run's signals.

    Peaks are of absolute values; RMS values are over all ticks seen.
    """

    def __init__(self, estimate: EstimateErrorStats | None = None) -> None:
        self.estimate = estimate
        self.ticks = 0
        self._sq_err = np.zeros(4)
        self._sq_tau = np.zeros(4)
        self._peaks = {
            "max_err": np.zeros(4),
            "tau": np.zeros(4),
            "current": np.zeros(4),
            "voltage": np.zeros(4),
            "power": np.zeros(4),
            "cuff": np.zeros(4),
        }

    def update(self, rows: dict[str, np.ndarray]) -> None:
        """Add a chunk of rows (name → (n, ...) arrays, as in SIGNALS)."""
        n = rows["q"].shape[0]
        if n == 0:
            return
        if self.estimate is not None:
            self.estimate.update(rows["q"], rows["cuff_force"], rows["cuff_normal_est"])
        err = rows["q_des"] - rows["q"]
        tau = rows["drive_torque"]
        self.ticks += n
        self._sq_err += np.sum(err**2, axis=0)
        self._sq_tau += np.sum(tau**2, axis=0)
        p = self._peaks
        for key, values in (
            ("max_err", np.abs(err)),
            ("tau", np.abs(tau)),
            ("current", np.abs(rows["current"])),
            ("voltage", np.abs(rows["voltage"])),
            ("power", np.abs(tau * rows["dq"])),
            ("cuff", np.linalg.norm(rows["cuff_force"], axis=2)),
        ):
            np.maximum(p[key], values.max(axis=0), out=p[key])

    def summary(self, result: SimResult) -> dict[str, Any]:
        """The JSON summary of a run.

        Keys: ``controller``, ``status``, ``error``, ``duration_s``, ``ticks``,
        ``belt_speed_mps``, ``rms_tracking_error_rad`` and
        ``max_tracking_error_rad`` (keyed by joint; error = planned - actual
        exoskeleton angle), ``peak_drive_torque_Nm``, ``rms_drive_torque_Nm``,
        ``peak_motor_current_A``, ``peak_motor_voltage_V``,
        ``peak_mechanical_power_W`` (|τ q̇|; keyed by joint),
        ``peak_cuff_force_N`` (magnitude of the sagittal force, keyed by cuff),
        ``safety_state`` (the supervisor's final state) and ``safety_events``
        (violations and e-stops: t, quantity, value, limit, message),
        ``wall_time_s``, ``real_time_factor`` (simulated / wall time of the
        ticks the wall clock covers, :attr:`SimResult.wall_time_s`); with
        live estimation ``cuff_force_estimate_rms_error_N`` and
        ``cuff_force_estimate_rms_error_rel`` (keyed by cuff: RMS error of
        the estimated normal component, and that over its peak true value).
        """
        n = max(self.ticks, 1)
        p = self._peaks
        duration = self.ticks * result.config.dt
        wall = result.wall_time_s
        out = {
            "controller": result.config.controller,
            "status": result.status,
            "error": result.error,
            "duration_s": duration,
            "ticks": self.ticks,
            "belt_speed_mps": result.belt_speed_mps,
            "rms_tracking_error_rad": _keyed(np.sqrt(self._sq_err / n), JOINT_NAMES),
            "max_tracking_error_rad": _keyed(p["max_err"], JOINT_NAMES),
            "peak_drive_torque_Nm": _keyed(p["tau"], JOINT_NAMES),
            "rms_drive_torque_Nm": _keyed(np.sqrt(self._sq_tau / n), JOINT_NAMES),
            "peak_motor_current_A": _keyed(p["current"], JOINT_NAMES),
            "peak_motor_voltage_V": _keyed(p["voltage"], JOINT_NAMES),
            "peak_mechanical_power_W": _keyed(p["power"], JOINT_NAMES),
            "peak_cuff_force_N": _keyed(p["cuff"], CUFF_NAMES),
            "qp_failures": result.qp_failures,
            "safety_state": result.safety_state,
            "safety_events": [e for e in result.events if e.get("kind") in ("violation", "estop")],
            "wall_time_s": wall,
            "real_time_factor": (result.timed_ticks * result.config.dt / wall if wall > 0 else 0.0),
        }
        if self.estimate is not None:
            out.update(self.estimate.summary())
        return out
