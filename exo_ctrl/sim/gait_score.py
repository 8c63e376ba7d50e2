r"""How far from normal the device walks the patient: Gait Variable and Gait Profile Scores.

After Baker et al. (2009, Gait & Posture 30:265-269).  For one gait cycle of
one leg and one joint angle x (sampled at the 51 points 0, 2, ..., 100 % of
the cycle, from the leg's initial contact) against the normative mean
x̄ at the same points, the Gait Variable Score is the RMS difference

.. math::

    \mathrm{GVS} = \sqrt{\tfrac{1}{51} \sum_{i=0}^{50} (x_i - \bar x_i)^2}
    \quad [\mathrm{deg}],

and the Gait Profile Score is the RMS of the GVS of the variables scored,
here the four sagittal ones (left and right hip and knee),
GPS = √(Σ_j GVS_j² / 4).  It is a *sagittal hip–knee* GPS: Baker's full
score uses nine variables per side (pelvis, hip in three planes, knee,
ankle, foot progression), so its values are not comparable with published
full GPS figures, only with each other.

**Normative data** (``exo_ctrl/data/normative_gait_schwartz2008.csv``, its
header states source, units and conventions): Schwartz, Rozumalski & Trost
(2008, J Biomech 41:1639-1650), typically developing children at their
self-selected speed, Plug-in Gait conventions, mean and SD at 2 % steps (no
interpolation needed).  This project's joint coordinates are those of the
URDFs (:mod:`exo_ctrl.model.urdfgen`): q = 0 with the leg hanging straight,
flexion positive, the pelvis upright, so the hip coordinate is the thigh's
angle from the vertical (forward positive).  Plug-in Gait's hip flexion h is
the thigh relative to the pelvis, whose anterior tilt α rotates it the other
way in the sagittal plane; so the normative thigh angle from the vertical is
h − α (peak about 25° against the hip flexion's 37°).  The knee is relative
in both (knee flexion = q_knee).

**Cycles.**  The plan's gait cycles after the L ramp-in ticks, of P = T_s/Δt
ticks each (cycle c: ticks L + cP … L + (c+1)P − 1, as in the
``interaction`` block).  Each leg's cycle starts at its planned initial
contact, the point B of :mod:`exo_ctrl.plan.gait` at phase (1 − β) T_s / 2
(the right leg half a period later): point i of leg l in cycle c is the
tick L + cP + ((o_l + i P/50) mod P) rounded to the nearest tick, o_l the
touchdown's offset into the cycle [ticks].  The cycle's samples are thus
taken in the leg's order, wrapped within the cycle's window, which is the
leg's own cycle for a periodic gait.  Scored: the planned angles (``q_des``)
and the patient's true angles (``q_patient``, the plant's: an outcome the
simulation reports, like the true cuff force).  A cycle counts when every
one of its ticks ran and none is in a ramp-out.  A patient walking at a
period other than the plan's (transparent mode) is scored on the plan's
cycles, so their phase drift counts as deviation.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from importlib import resources
from typing import Any

import numpy as np

from ..exceptions import InvalidParameter
from ..model import JOINT_NAMES
from .config import SimConfig

__all__ = [
    "GAIT_POINTS",
    "NORMATIVE_FILE",
    "GaitScoreStats",
    "NormativeGait",
    "contact_offsets",
    "gait_profile_score",
    "gait_score_stats",
    "gait_variable_scores",
    "load_normative",
]

#: Points of a gait cycle the scores are taken at: 0, 2, ..., 100 % (Baker et al. 2009).
GAIT_POINTS = 51
#: The normative data file, in the package's ``data`` folder.
NORMATIVE_FILE = "normative_gait_schwartz2008.csv"


@dataclass(frozen=True)
class NormativeGait:
    """Normative sagittal angles over the gait cycle, in this project's joint coordinates.

    Attributes:
        percent: the points of the cycle, (51,) [%] (0, 2, ..., 100).
        mean_deg: the mean per joint of one leg, (51, 2) [deg]: hip (thigh from
            the vertical, flexion positive) and knee (flexion positive).
        sd_deg: the between-subject SD of the source's angles, (51, 2) [deg]
            (for the hip the SD of the hip flexion relative to the pelvis:
            the source gives no SD of the difference).
        source: the citation.

    """

    percent: np.ndarray
    mean_deg: np.ndarray
    sd_deg: np.ndarray
    source: str

    def per_joint(self) -> np.ndarray:
        """The mean for the four joints of :data:`~exo_ctrl.model.JOINT_NAMES`, (51, 4) [deg]."""
        return np.tile(self.mean_deg, (1, 2))


def load_normative(name: str = NORMATIVE_FILE) -> NormativeGait:
    """Read the normative curves shipped with the package (module docstring).

    Args:
        name: file name in ``exo_ctrl/data``.

    Raises:
        InvalidParameter: no such file, or not 51 points at 2 % steps.

    """
    try:
        text = resources.files("exo_ctrl").joinpath("data", name).read_text(encoding="utf-8")
    except (FileNotFoundError, OSError):
        raise InvalidParameter("normative file", name, "a file in exo_ctrl/data") from None
    rows = list(csv.DictReader(line for line in text.splitlines() if not line.startswith("#")))
    col = lambda key: np.array([float(r[key]) for r in rows])  # noqa: E731
    percent = col("percent_gait_cycle")
    if percent.shape != (GAIT_POINTS,) or not np.allclose(percent, 2.0 * np.arange(GAIT_POINTS)):
        raise InvalidParameter("normative file", name, "51 points at 0, 2, ..., 100 % of the cycle")
    thigh = col("hip_flexion_mean_deg") - col("pelvic_tilt_mean_deg")
    mean = np.column_stack([thigh, col("knee_flexion_mean_deg")])
    sd = np.column_stack([col("hip_flexion_sd_deg"), col("knee_flexion_sd_deg")])
    source = "Schwartz, Rozumalski & Trost 2008, J Biomech 41:1639-1650 (free speed)"
    return NormativeGait(percent, mean, sd, source)


def gait_variable_scores(angles_deg: np.ndarray, normative_deg: np.ndarray) -> np.ndarray:
    """GVS of each variable: RMS over the cycle's points of angle − normative mean [deg].

    Args:
        angles_deg: (51, m) angles at 0, 2, ..., 100 % of the cycle [deg].
        normative_deg: (51, m) normative means at the same points [deg].

    Returns:
        (m,) the GVS [deg].

    Raises:
        InvalidParameter: shapes other than (51, m) alike.

    """
    a, n = np.asarray(angles_deg, float), np.asarray(normative_deg, float)
    if a.ndim != 2 or a.shape[0] != GAIT_POINTS or a.shape != n.shape:
        raise InvalidParameter("angles_deg", a.shape, f"(51, m), the normative's shape {n.shape}")
    return np.sqrt(np.mean((a - n) ** 2, axis=0))


def gait_profile_score(gvs_deg: np.ndarray) -> float:
    """GPS: the RMS of the Gait Variable Scores, √(Σ GVS² / m) [deg]."""
    g = np.asarray(gvs_deg, float)
    return float(math.sqrt(np.mean(g**2)))


class GaitScoreStats:
    """The GVS and GPS per gait cycle of the planned and the true patient angles.

    Args:
        lead: L, the ramp-in ticks.
        period: P, the ticks of a gait cycle.
        offsets: o_l, each leg's initial contact's offset into the cycle [ticks].
        last_tick: the last tick a counted cycle may hold (before a ramp-out).
        normative: the normative curves (default: :func:`load_normative`).

    """

    #: The signals scored: the plan and the patient's true angles [rad].
    KINDS = ("planned", "actual")
    _SIGNALS = ("q_des", "q_patient")

    def __init__(
        self,
        lead: int,
        period: int,
        offsets: tuple[float, float],
        last_tick: int,
        normative: NormativeGait | None = None,
    ) -> None:
        self.lead, self.period, self.last_tick = lead, max(int(period), 1), last_tick
        self.normative = (normative or load_normative()).per_joint()
        steps = np.arange(GAIT_POINTS) * self.period / (GAIT_POINTS - 1)
        #: Tick within the cycle of point i of leg l, (2, 51).
        self.sample = np.array([np.rint(o + steps).astype(np.int64) % self.period for o in offsets])
        self._cycles: dict[int, np.ndarray] = {}  # c -> (2 kinds, 51, 4 joints) [rad]

    def update(self, rows: dict[str, np.ndarray], start: int) -> None:
        """Take the samples a chunk of log rows holds; its first row is tick ``start``."""
        n = rows["q"].shape[0]
        first = max(start, self.lead)
        if first >= start + n:
            return
        c0 = (first - self.lead) // self.period
        for c in range(c0, (start + n - 1 - self.lead) // self.period + 1):
            base = self.lead + c * self.period
            cyc = self._cycles.setdefault(c, np.full((2, GAIT_POINTS, 4), np.nan))
            for leg in range(2):
                k = base + self.sample[leg] - start
                inside = (k >= 0) & (k < n)
                joints = [2 * leg, 2 * leg + 1]
                points = inside.nonzero()[0]
                for s, name in enumerate(self._SIGNALS):
                    cyc[s][np.ix_(points, joints)] = rows[name][k[inside]][:, joints]

    def cycles(self) -> dict[int, np.ndarray]:
        """The complete cycles' angles in degrees: c -> (2 kinds, 51, 4)."""
        done = {}
        for c, a in sorted(self._cycles.items()):
            end = self.lead + (c + 1) * self.period - 1
            if end <= self.last_tick and np.isfinite(a).all():
                done[c] = np.degrees(a)
        return done

    def summary(self) -> dict[str, Any]:
        """The summary's keys.

        ``gait_profile_score_deg`` ({"planned", "actual"}: over the cycles
        after the ramp-in, the RMS of the per-cycle GVS pooled), per joint
        ``gait_variable_scores_deg`` ({"planned", "actual"} → joint → GVS) and
        ``gait_profile_score_cycles`` (per cycle: ``cycle``, ``planned``,
        ``actual`` GPS [deg]); null scores when no cycle is complete.
        """
        cycles = self.cycles()
        per_cycle = []
        squares = np.zeros((2, 4))
        for c, a in cycles.items():
            entry: dict[str, Any] = {"cycle": c}
            for s, kind in enumerate(self.KINDS):
                gvs = gait_variable_scores(a[s], self.normative)
                squares[s] += gvs**2
                entry[kind] = gait_profile_score(gvs)
            per_cycle.append(entry)
        gps: dict[str, float | None] = dict.fromkeys(self.KINDS)
        gvs_out: dict[str, dict[str, float] | None] = dict.fromkeys(self.KINDS)
        if cycles:
            for s, kind in enumerate(self.KINDS):
                gvs = np.sqrt(squares[s] / len(cycles))
                gps[kind] = gait_profile_score(gvs)
                gvs_out[kind] = {j: float(x) for j, x in zip(JOINT_NAMES, gvs, strict=True)}
        return {
            "gait_profile_score_deg": gps,
            "gait_variable_scores_deg": gvs_out,
            "gait_profile_score_cycles": per_cycle,
        }


def contact_offsets(config: SimConfig, lead: int) -> tuple[float, float]:
    """Each leg's planned initial contact's offset into the cycles after the ramp-in [ticks].

    The left foot touches down (point B) at phase (1 − β) T_s / 2, the right
    half a period later (:mod:`exo_ctrl.plan.gait`); the plan's phase is
    t mod T_s, so the offset after the cycle's start L Δt is
    ((t_B − L Δt) mod T_s) / Δt.
    """
    gait, dt = config.gait, config.dt
    t_b = 0.5 * (1.0 - gait.duty_factor) * gait.period
    left, right = (
        (math.fmod(t_b + half * gait.period - lead * dt, gait.period) % gait.period) / dt
        for half in (0.0, 0.5)
    )
    return left, right


def gait_score_stats(config: SimConfig) -> GaitScoreStats | None:
    """The scores of a gait run (None for the calibration exercise)."""
    if config.exercise != "gait":
        return None
    lead = math.ceil(config.ramp_in / config.dt - 1e-9)
    period = round(config.gait.period / config.dt)
    last = config.n_ticks - 1 - math.ceil(config.ramp_out_s / config.dt - 1e-9)
    return GaitScoreStats(lead, period, contact_offsets(config, lead), last)
