"""A run's figures, accumulated chunk by chunk (no need to keep the history)."""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np

from .._jit import kernel, preload
from ..estimation import EstimateErrorStats
from ..model import CUFF_NAMES, JOINT_NAMES
from .config import SimConfig

__all__ = ["RunOutcome", "RunStats"]


class RunOutcome(Protocol):
    """What a summary reads of a run besides its statistics (a :class:`~exo_ctrl.sim.SimResult`)."""

    config: SimConfig
    status: str
    error: str
    belt_speed_mps: float
    qp_failures: int
    energy: dict[str, Any]
    safety_state: str
    events: list[dict[str, Any]]
    wall_time_s: float
    timed_ticks: int


def _keyed(values: np.ndarray, names: tuple[str, ...]) -> dict[str, float]:
    return {name: float(x) for name, x in zip(names, values, strict=True)}


class RunStats:
    """Running sums and peaks of a run's signals.

    Peaks are of absolute values; RMS values are over all ticks seen.
    """

    def __init__(self, estimate: EstimateErrorStats | None = None) -> None:
        self.estimate = estimate
        self.ticks = 0
        # Running sums (Σ err², Σ τ², Σ i²) and peaks (|err|, |τ|, |i|, |U|,
        # |τ q̇|, cuff |f|, |q̇|), a row of 4 each: :func:`_accumulate`'s buffers.
        self._sums = np.zeros((3, 4))
        self._peaks = np.zeros((7, 4))

    def update(self, rows: dict[str, np.ndarray]) -> None:
        """Add a chunk of rows (name → (n, ...) arrays, as in SIGNALS)."""
        if self.estimate is not None:
            self.estimate.update(rows["q"], rows["cuff_force"], rows["cuff_normal_est"])
        self.ticks += rows["q"].shape[0]
        _accumulate(*self._accumulate_args(rows))

    def preload(self, rows: dict[str, np.ndarray]) -> None:
        """Load the compiled kernels for rows of these arrays' types (before a timed run)."""
        if self.estimate is not None:
            self.estimate.preload(rows["q"], rows["cuff_force"], rows["cuff_normal_est"])
        preload(_accumulate, *self._accumulate_args(rows))

    def _accumulate_args(self, rows: dict[str, np.ndarray]) -> tuple[np.ndarray, ...]:
        names = ("q", "q_des", "drive_torque", "current", "voltage", "dq", "cuff_force")
        return (*(rows[name] for name in names), self._sums, self._peaks)

    def summary(self, result: RunOutcome) -> dict[str, Any]:
        """The JSON summary of a run.

        Keys: ``controller``, ``status``, ``error``, ``duration_s``, ``ticks``,
        ``belt_speed_mps``, ``rms_tracking_error_rad`` and
        ``max_tracking_error_rad`` (keyed by joint; error = planned - actual
        exoskeleton angle), ``peak_drive_torque_Nm``, ``rms_drive_torque_Nm``,
        ``peak_motor_current_A``, ``peak_motor_voltage_V``,
        ``peak_mechanical_power_W`` (|τ q̇|; keyed by joint),
        ``peak_cuff_force_N`` (magnitude of the sagittal force, keyed by cuff),
        ``rms_motor_current_A`` (what heats a motor) and
        ``peak_joint_speed_rad_s`` (keyed by joint), ``drive_sizing`` (per
        joint, the figures that size a drive: peak and RMS joint torque,
        peak joint speed, peak mechanical power, peak and RMS motor current,
        peak voltage),
        ``safety_state`` (the supervisor's final state) and ``safety_events``
        (violations and e-stops: t, quantity, value, limit, message),
        ``wall_time_s``, ``real_time_factor`` (simulated / wall time of the
        ticks the wall clock covers, :attr:`SimResult.wall_time_s`); with
        live estimation ``cuff_force_estimate_rms_error_N`` and
        ``cuff_force_estimate_rms_error_rel`` (keyed by cuff: RMS error of
        the estimated normal component, and that over its peak true value).
        """
        n = max(self.ticks, 1)
        sq_err, sq_tau, sq_current = self._sums
        max_err, tau, current, voltage, power, cuff, speed = self._peaks
        rms_tau, rms_current = np.sqrt(sq_tau / n), np.sqrt(sq_current / n)
        duration = self.ticks * result.config.dt
        wall = result.wall_time_s
        out = {
            "controller": result.config.controller,
            "status": result.status,
            "error": result.error,
            "duration_s": duration,
            "ticks": self.ticks,
            "belt_speed_mps": result.belt_speed_mps,
            "rms_tracking_error_rad": _keyed(np.sqrt(sq_err / n), JOINT_NAMES),
            "max_tracking_error_rad": _keyed(max_err, JOINT_NAMES),
            "peak_drive_torque_Nm": _keyed(tau, JOINT_NAMES),
            "rms_drive_torque_Nm": _keyed(rms_tau, JOINT_NAMES),
            "peak_motor_current_A": _keyed(current, JOINT_NAMES),
            "rms_motor_current_A": _keyed(rms_current, JOINT_NAMES),
            "peak_joint_speed_rad_s": _keyed(speed, JOINT_NAMES),
            "peak_motor_voltage_V": _keyed(voltage, JOINT_NAMES),
            "peak_mechanical_power_W": _keyed(power, JOINT_NAMES),
            "peak_cuff_force_N": _keyed(cuff, CUFF_NAMES),
            "qp_failures": result.qp_failures,
            "safety_state": result.safety_state,
            "safety_events": [e for e in result.events if e.get("kind") in ("violation", "estop")],
            "wall_time_s": wall,
            "real_time_factor": (result.timed_ticks * result.config.dt / wall if wall > 0 else 0.0),
            "drive_sizing": {
                joint: {
                    "peak_torque_Nm": float(tau[j]),
                    "rms_torque_Nm": float(rms_tau[j]),
                    "peak_speed_rad_s": float(speed[j]),
                    "peak_power_W": float(power[j]),
                    "peak_current_A": float(current[j]),
                    "rms_current_A": float(rms_current[j]),
                    "peak_voltage_V": float(voltage[j]),
                }
                for j, joint in enumerate(JOINT_NAMES)
            },
        }
        if self.estimate is not None:
            out.update(self.estimate.summary())
        out.update(result.energy)  # energy_J, energy_balance_residual_rel
        return out


@kernel
def _accumulate(q, q_des, tau, current, voltage, dq, cuff_force, sums, peaks):
    """Add rows to the running sums and peaks of :class:`RunStats` (its buffers' layout).

    One pass over the rows in place of a dozen numpy reductions over the
    strided columns of the chunk buffer (1.4 ms → a few µs per 2000 rows).
    """
    for r in range(q.shape[0]):
        for j in range(4):
            err = q_des[r, j] - q[r, j]
            t = tau[r, j]
            sums[0, j] += err * err
            sums[1, j] += t * t
            sums[2, j] += current[r, j] * current[r, j]
            peaks[0, j] = max(peaks[0, j], abs(err))
            peaks[1, j] = max(peaks[1, j], abs(t))
            peaks[2, j] = max(peaks[2, j], abs(current[r, j]))
            peaks[3, j] = max(peaks[3, j], abs(voltage[r, j]))
            peaks[4, j] = max(peaks[4, j], abs(t * dq[r, j]))
            fx, fz = cuff_force[r, j, 0], cuff_force[r, j, 1]
            peaks[5, j] = max(peaks[5, j], math.sqrt(fx * fx + fz * fz))
            peaks[6, j] = max(peaks[6, j], abs(dq[r, j]))
