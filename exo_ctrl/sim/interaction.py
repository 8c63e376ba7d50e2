"""The summary's ``interaction`` block: what the patient and the device did, per gait cycle.

For a run in an interaction mode or with an active patient
(:func:`interaction_stats`), accumulated chunk by chunk from the log rows,
per gait cycle of the plan (cycle c: the ticks L + c P … L + (c + 1) P − 1
after the L ramp-in ticks, P = T_s / Δt; the ramp-in is cycle ``"ramp_in"``):

- RMS interaction force, true and estimated: √(mean over ticks and cuffs of
  |f|²) [N] (the cuff forces on the exoskeleton, ``cuff_force`` and
  ``cuff_force_est``);
- the patient's effort: the RMS of their own joint torques τ_p (passive URDF
  damping and friction excluded: the plant's ``patient_torque``) [N·m] and
  their positive work Σ max(τ_p q̇_p, 0) Δt [J], per joint;
- the device's work: the drives' positive mechanical work at the joints
  Σ max(τ q̇, 0) Δt [J], per joint;
- the RMS tracking error q* − q [rad], per joint.

Whole-run figures are over the cycles after the ramp-in.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..model import JOINT_NAMES
from .config import SimConfig

__all__ = ["InteractionStats", "interaction_stats"]

#: Running sums per cycle, in this order: ticks, Σ|f|², Σ|f̂|², Σ τ_p², W⁺_p, W⁺_d, Σ e².
_SUMS = 7


class InteractionStats:
    """Per-cycle sums of the interaction figures (module docstring).

    Args:
        mode: the run's mode (for the block's ``mode``).
        lead: L, the ramp-in ticks.
        period: P, the ticks of a gait cycle.
        dt: the control period Δt [s].

    """

    def __init__(self, mode: str, lead: int, period: int, dt: float) -> None:
        self.mode = mode
        self.lead, self.period, self.dt = lead, max(period, 1), dt
        self._cycles: dict[int, np.ndarray] = {}

    def update(self, rows: dict[str, np.ndarray], start: int) -> None:
        """Add a chunk of log rows whose first row is tick ``start``."""
        n = rows["q"].shape[0]
        ticks = np.arange(start, start + n)
        cycle = np.where(ticks < self.lead, -1, (ticks - self.lead) // self.period)
        force = np.sum(rows["cuff_force"] ** 2, axis=(1, 2))
        est = np.sum(rows["cuff_force_est"] ** 2, axis=(1, 2))
        tau_p = rows["patient_torque"]
        work_p = np.maximum(tau_p * rows["dq_patient"], 0.0) * self.dt
        work_d = np.maximum(rows["drive_torque"] * rows["dq"], 0.0) * self.dt
        err = (rows["q_des"] - rows["q"]) ** 2
        for c in np.unique(cycle):
            m = cycle == c
            sums = self._cycles.setdefault(int(c), np.zeros((_SUMS, 4)))
            sums[0] += m.sum()
            sums[1] += force[m].sum()
            sums[2] += est[m].sum()
            sums[3] += (tau_p[m] ** 2).sum(axis=0)
            sums[4] += work_p[m].sum(axis=0)
            sums[5] += work_d[m].sum(axis=0)
            sums[6] += err[m].sum(axis=0)

    def summary(self, support: list[float] | None = None) -> dict[str, Any]:
        """The block: ``mode``, ``run`` (after the ramp-in) and ``cycles`` (each cycle's figures).

        Args:
            support: aan's support level (RMS of its table [N·m]) after each cycle.

        """
        cycles = [self._figures(self._cycles[c], c) for c in sorted(self._cycles)]
        after = [self._cycles[c] for c in sorted(self._cycles) if c >= 0]
        out: dict[str, Any] = {
            "mode": self.mode,
            "run": self._figures(sum(after), None) if after else None,
            "cycles": cycles,
        }
        if support is not None:
            out["aan_support_rms_Nm"] = [float(x) for x in support]
        return out

    def _figures(self, sums: np.ndarray, cycle: int | None) -> dict[str, Any]:
        n = max(float(sums[0, 0]), 1.0)
        keyed = lambda a: {j: float(x) for j, x in zip(JOINT_NAMES, a, strict=True)}  # noqa: E731
        out: dict[str, Any] = {} if cycle is None else {"cycle": cycle if cycle >= 0 else "ramp_in"}
        out.update(
            {
                "rms_interaction_force_N": math.sqrt(sums[1, 0] / (4 * n)),
                "rms_interaction_force_estimated_N": math.sqrt(sums[2, 0] / (4 * n)),
                "patient_rms_torque_Nm": keyed(np.sqrt(sums[3] / n)),
                "patient_positive_work_J": keyed(sums[4]),
                "device_positive_work_J": keyed(sums[5]),
                "rms_tracking_error_rad": keyed(np.sqrt(sums[6] / n)),
            }
        )
        return out


def interaction_stats(config: SimConfig) -> InteractionStats | None:
    """The interaction figures of a run in a mode or with an active patient, else None."""
    if config.mode == "tracking" and config.patient_torque != "active":
        return None
    if config.exercise != "gait":
        return None
    lay = config.plan_layout
    period = lay.period if lay.period > 1 else round(config.gait.period / config.dt)
    lead = math.ceil(config.ramp_in / config.dt - 1e-9)
    return InteractionStats(config.mode, lead, period, config.dt)
