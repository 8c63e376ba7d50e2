"""What the stance legs carry: the knee's stance torque and, with body-weight support, the pelvis.

With the belt (contact on) a foot in contact is a stance leg; its knee
drive's torque over stance is the figure a drive is sized on
(``stance_knee_torque_rms_Nm``, ``stance_knee_torque_peak_Nm``, keyed by
side, from the end of the ramp-in).  With the pelvis on its guide
(:mod:`exo_ctrl.plant.pelvis`) the ``pelvis`` block checks the vertical
balance: averaged over whole gait cycles the belt's vertical force on both
feet (the patient's feet's too when they meet the belt; and the harness's,
if its travel stops caught the pelvis or its brake locked it after a stop)
equals the weight the support does not carry, M g − F_s (the vertical
momentum returns each cycle), and reports the pelvis's excursion.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..model import SIDES, BodyModel
from ..plant.pelvis import moving_mass_kg
from .config import SimConfig

__all__ = ["LoadStats", "load_stats"]


class LoadStats:
    """Stance knee torque and the pelvis's balance, chunk by chunk.

    Args:
        from_tick: the end of the ramp-in (first tick counted).
        cycle_end_tick: end of the last whole gait cycle after it (the
            vertical force's average spans [from_tick, cycle_end_tick)).
        pelvis: the pelvis block's constants (``bws_fraction``,
            ``support_N``, ``moving_mass_kg``, ``gravity_mps2``), or None
            with the pelvis fixed.
        patient_feet: the patient's feet meet the belt too: their vertical
            force joins the exoskeleton's feet's in the balance.

    """

    def __init__(
        self,
        from_tick: int,
        cycle_end_tick: int,
        pelvis: dict[str, float] | None,
        patient_feet: bool = False,
    ):
        self.from_tick, self.cycle_end_tick = int(from_tick), int(cycle_end_tick)
        self.pelvis = pelvis
        self.patient_feet = bool(patient_feet)
        self._knee_sq = np.zeros(2)
        self._knee_n = np.zeros(2)
        self._knee_peak = np.zeros(2)
        self._fz_sum = 0.0
        self._stop_sum = 0.0
        self._fz_n = 0
        self._z_min, self._z_max = math.inf, -math.inf

    def update(self, rows: dict[str, np.ndarray], first_tick: int) -> None:
        """Add a chunk of rows whose first row is tick ``first_tick``."""
        n = rows["q"].shape[0]
        start = min(max(self.from_tick - first_tick, 0), n)
        state = rows["contact_state"][start:]
        torque = rows["drive_torque"][start:]
        for leg in range(2):
            knee = torque[state[:, leg] > 0.0, 2 * leg + 1]
            self._knee_sq[leg] += float(knee @ knee)
            self._knee_n[leg] += knee.size
            if knee.size:
                self._knee_peak[leg] = max(self._knee_peak[leg], float(np.abs(knee).max()))
        if self.pelvis is None:
            return
        end = min(max(self.cycle_end_tick - first_tick, 0), n)
        if end > start:
            self._fz_sum += float(rows["ground_force"][start:end, :, 1].sum())
            if self.patient_feet:  # the patient's feet carry their share too
                self._fz_sum += float(rows["patient_ground_force"][start:end, :, 1].sum())
            self._stop_sum += float(rows["pelvis_stop_force"][start:end].sum())
            self._fz_n += end - start
        z = rows["pelvis_z"][start:]
        if z.size:
            self._z_min = min(self._z_min, float(z.min()))
            self._z_max = max(self._z_max, float(z.max()))

    def summary(self) -> dict[str, Any]:
        """``stance_knee_torque_rms_Nm``, ``stance_knee_torque_peak_Nm`` and ``pelvis``."""
        rms = np.sqrt(self._knee_sq / np.maximum(self._knee_n, 1))
        out: dict[str, Any] = {
            "stance_knee_torque_rms_Nm": dict(zip(SIDES, rms.tolist(), strict=True)),
            "stance_knee_torque_peak_Nm": dict(zip(SIDES, self._knee_peak.tolist(), strict=True)),
        }
        if self.pelvis is not None:
            p = self.pelvis
            weight = p["moving_mass_kg"] * p["gravity_mps2"] - p["support_N"]
            mean = self._fz_sum / self._fz_n if self._fz_n else None
            stop = self._stop_sum / self._fz_n if self._fz_n else None
            out["pelvis"] = {
                "bws_fraction": p["bws_fraction"],
                "support_N": p["support_N"],
                "moving_mass_kg": p["moving_mass_kg"],
                "unsupported_weight_N": weight,
                "mean_vertical_ground_force_N": mean,
                "mean_harness_stop_force_N": stop,
                "vertical_balance_error_rel": (
                    None if mean is None else (mean + stop - weight) / weight
                ),
                "averaged_ticks": self._fz_n,
                "excursion_m": self._z_max - self._z_min if self._z_max >= self._z_min else None,
                "lowest_m": self._z_min if math.isfinite(self._z_min) else None,
            }
        return out


def load_stats(config: SimConfig, exo: BodyModel) -> LoadStats | None:
    """The load figures of a run with the belt (None without), the pelvis block if supported."""
    if not config.contact.enabled:
        return None
    start = math.ceil(config.ramp_in / config.dt - 1e-9)
    period = config.gait.period / config.dt
    span = config.n_ticks - start - round(config.ramp_out_s / config.dt)
    end = start + math.floor(span / period + 1e-9) * round(period)
    pelvis = None
    params = config.pelvis_resolved
    if params.supported:
        pelvis = {
            "bws_fraction": params.bws_fraction,
            "support_N": params.support_N,
            "moving_mass_kg": moving_mass_kg(params, exo.model),
            "gravity_mps2": -float(exo.model.gravity.linear[2]),
        }
    return LoadStats(start, end, pelvis, config.contact.patient_feet)
