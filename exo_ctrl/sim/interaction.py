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
- the RMS tracking error q* − q [rad], per joint, against the CLOCK's plan
  (q* at row k of the plan): in ``path`` mode, whose timing is free, this
  counts a patient who walks the path slower or faster as an error.

In ``path`` mode (:class:`PathReference`; the run's controller a
:class:`~exo_ctrl.control.modes.path.PathController`), the figures that
mean something under free timing, at the device's own phase σ_k (the
plan row the device reached, logged as ``path_phase``):

- ``path_error_rms_m``, ``path_error_max_m`` per foot (left, right): the
  distance d_k = min |p_k − c| of the TRUE exoskeleton's foot p_k (closed-form
  forward kinematics of the plant's exoskeleton legs at the true angles q,
  relative to the hip) from the planned foot path c, the polyline through
  the plan's foot points in rows σ_k − W … σ_k + W (W: the controller's
  search window; rows wrapped in the gait period in the periodic part,
  clamped on the ramps) — the tunnel's distance, measured on the truth;
- ``path_outside_tunnel_share`` per foot: the share of ticks with d_k > w;
- ``path_phase_tracking_error_rad`` per joint: the RMS of q*(σ_k) − q_k,
  the plan's joints at the device's phase (the clock-free analogue of the
  tracking error).

Whole-run figures are over the cycles after the ramp-in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .._jit import kernel
from ..control.modes.path import PathController
from ..model import JOINT_NAMES, SIDES, BodyModel
from ..model.leg_kernels import foot_point, legs_record
from ..plan.kinematics import JointTrajectory
from .config import SimConfig

__all__ = ["InteractionStats", "PathReference", "interaction_stats", "path_distances"]

#: Running sums per cycle, in this order: ticks, Σ|f|², Σ|f̂|², Σ τ_p², W⁺_p, W⁺_d, Σ e².
_SUMS = 7
#: Path mode's per cycle: ticks, Σ d², max d, ticks with d > w (feet in the
#: first two columns), Σ (q*(σ) − q)² (per joint).
_PATH_SUMS = 5


@dataclass(frozen=True)
class PathReference:
    """What ``path`` mode's figures are measured against (module docstring).

    Attributes:
        foot_pos: the planned foot path per plan row, (rows, 2 legs, x/z)
            [m] from the hips.
        q_plan: the planned joint angles per plan row, (rows, 4) [rad].
        legs: the TRUE exoskeleton's legs: a record of
            :data:`~exo_ctrl.model.leg_kernels.LEG_FIELDS`.
        window: W, the controller's search window [rows].
        row_rule: the plan's (lead, period, tail) [rows, ticks].
        width_m: the tunnel's half-width w [m].

    """

    foot_pos: np.ndarray
    q_plan: np.ndarray
    legs: np.ndarray
    window: int
    row_rule: tuple[int, int, int]
    width_m: float

    @classmethod
    def of(cls, controller: PathController, plan: JointTrajectory, exo: BodyModel) -> PathReference:
        """The reference of a path controller on ``plan``, measured on the true ``exo``."""
        rec = controller.record[0]
        legs = legs_record(exo)
        return cls(
            foot_pos=np.asarray(plan.foot_pos, dtype=float),
            q_plan=np.asarray(plan.q, dtype=float),
            legs=legs,
            window=int(rec["window"]),
            row_rule=plan.row_rule,
            width_m=float(rec["width"]),
        )


def path_distances(
    ref: PathReference, q: np.ndarray, phase: np.ndarray, ticks: np.ndarray
) -> np.ndarray:
    """d_k per foot (module docstring), (n, 2) [m]: q (n, 4) [rad], σ_k rows, tick numbers k.

    The least distance over the window's segments, exactly; the compiled
    kernel :func:`_distances` projects onto a segment only where it can beat
    the nearest vertex (|p − c| ≥ max(|p − a|, |p − b|) − L for c on [a, b],
    L the plan's longest segment).
    """
    lead, period, tail = ref.row_rule
    out = np.empty((q.shape[0], 2))
    _distances(
        ref.foot_pos,
        ref.legs,
        np.ascontiguousarray(q, dtype=float),
        np.ascontiguousarray(phase, dtype=np.int64),
        np.ascontiguousarray(ticks, dtype=np.int64),
        ref.window,
        lead,
        max(period, 1),
        tail,
        out,
    )
    return out


@kernel
def _wrap(r, lead, period, last, periodic):  # pragma: no cover - compiled
    """Plan row r wrapped in the gait period (periodic) or clamped to [0, last]."""
    if periodic:
        return lead + (r - lead) % period
    return min(max(r, 0), last)


@kernel
def _distances(pos, legs, q, phase, ticks, window, lead, period, tail, out):  # pragma: no cover
    """:func:`path_distances`' arithmetic into ``out`` (n, 2) [m]."""
    last = pos.shape[0] - 1
    span = 2 * window + 1
    d2 = np.empty(span)
    rows = np.empty(span, dtype=np.int64)
    # The longest segment of the plan's foot path (the period's closing one too) [m].
    longest2 = 0.0
    close = lead + period - 1  # the period's last row, joined to its first (lead)
    for leg in range(2):
        for r in range(last + 1):
            b = lead if r == close else r + 1
            if b > last:
                continue
            dx, dz = pos[b, leg, 0] - pos[r, leg, 0], pos[b, leg, 1] - pos[r, leg, 1]
            longest2 = max(longest2, dx * dx + dz * dz)
            if r == close and r < last:  # and the segment on to the next row
                dx, dz = pos[r + 1, leg, 0] - pos[r, leg, 0], pos[r + 1, leg, 1] - pos[r, leg, 1]
                longest2 = max(longest2, dx * dx + dz * dz)
    longest = np.sqrt(longest2)
    for n in range(q.shape[0]):
        periodic = lead <= ticks[n] < tail
        r = _wrap(phase[n] - window, lead, period, last, periodic)
        for i in range(span):  # the window's rows, wrapped step by step
            rows[i] = r
            if periodic:
                r = r + 1 if r + 1 < lead + period else lead
            else:
                r = min(phase[n] - window + i + 1, last) if phase[n] - window + i + 1 > 0 else 0
        for leg in range(2):
            px, pz, _, _, _, _ = foot_point(legs[0], leg, q[n, 2 * leg], q[n, 2 * leg + 1])
            best = np.inf
            for i in range(span):
                dx, dz = px - pos[rows[i], leg, 0], pz - pos[rows[i], leg, 1]
                d2[i] = dx * dx + dz * dz
                best = min(best, d2[i])
            reach = (np.sqrt(best) + longest) ** 2
            for i in range(span - 1):
                if max(d2[i], d2[i + 1]) >= reach:  # cannot beat the nearest vertex
                    continue
                a, b = rows[i], rows[i + 1]
                ex, ez = pos[b, leg, 0] - pos[a, leg, 0], pos[b, leg, 1] - pos[a, leg, 1]
                length2 = ex * ex + ez * ez
                if length2 <= 0.0:
                    continue
                u = ((px - pos[a, leg, 0]) * ex + (pz - pos[a, leg, 1]) * ez) / length2
                u = min(max(u, 0.0), 1.0)
                gap = (px - pos[a, leg, 0] - u * ex) ** 2 + (pz - pos[a, leg, 1] - u * ez) ** 2
                best = min(best, gap)
            out[n, leg] = np.sqrt(best)


class InteractionStats:
    """Per-cycle sums of the interaction figures (module docstring).

    Args:
        mode: the run's mode (for the block's ``mode``).
        lead: L, the ramp-in ticks.
        period: P, the ticks of a gait cycle.
        dt: the control period Δt [s].

    """

    def __init__(
        self, mode: str, lead: int, period: int, dt: float, path: PathReference | None = None
    ) -> None:
        self.mode = mode
        self.lead, self.period, self.dt = lead, max(period, 1), dt
        self._cycles: dict[int, np.ndarray] = {}
        #: Path mode's reference (None: no path figures) and its sums per cycle.
        self.path = path
        self._path: dict[int, np.ndarray] = {}

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
        if self.path is not None:
            self._update_path(rows, ticks, cycle)

    def _update_path(
        self, rows: dict[str, np.ndarray], ticks: np.ndarray, cycle: np.ndarray
    ) -> None:
        """Path mode's sums of a chunk: the ticks with a device phase (σ ≥ 0)."""
        ref = self.path
        phase = rows["path_phase"]
        ok = np.isfinite(phase) & (phase >= 0)
        if not ok.any():
            return
        q, ticks, cycle, phase = rows["q"][ok], ticks[ok], cycle[ok], phase[ok]
        d = path_distances(ref, q, phase, ticks)
        err = (ref.q_plan[phase.astype(np.int64)] - q) ** 2
        for c in np.unique(cycle):
            m = cycle == c
            sums = self._path.setdefault(int(c), np.zeros((_PATH_SUMS, 4)))
            sums[0] += m.sum()
            sums[1, :2] += (d[m] ** 2).sum(axis=0)
            sums[2, :2] = np.maximum(sums[2, :2], d[m].max(axis=0))
            sums[3, :2] += (d[m] > ref.width_m).sum(axis=0)
            sums[4] += err[m].sum(axis=0)

    def summary(self, support: list[float] | None = None) -> dict[str, Any]:
        """The block: ``mode``, ``run`` (after the ramp-in) and ``cycles`` (each cycle's figures).

        Args:
            support: aan's support level (RMS of its table [N·m]) after each cycle.

        """
        cycles = [
            self._figures(self._cycles[c], c, self._path.get(c)) for c in sorted(self._cycles)
        ]
        after = [self._cycles[c] for c in sorted(self._cycles) if c >= 0]
        path = [self._path[c] for c in sorted(self._path) if c >= 0]
        whole = None
        if path:  # sums add, maxima take the largest
            whole = sum(path)
            whole[2] = np.max([p[2] for p in path], axis=0)
        out: dict[str, Any] = {
            "mode": self.mode,
            "run": self._figures(sum(after), None, whole) if after else None,
            "cycles": cycles,
        }
        if support is not None:
            out["aan_support_rms_Nm"] = [float(x) for x in support]
        return out

    def _figures(
        self, sums: np.ndarray, cycle: int | None, path: np.ndarray | None = None
    ) -> dict[str, Any]:
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
        if path is not None:
            m = max(float(path[0, 0]), 1.0)
            feet = lambda a: {s: float(x) for s, x in zip(SIDES, a[:2], strict=True)}  # noqa: E731
            out.update(
                {
                    "path_error_rms_m": feet(np.sqrt(path[1] / m)),
                    "path_error_max_m": feet(path[2]),
                    "path_outside_tunnel_share": feet(path[3] / m),
                    "path_phase_tracking_error_rad": keyed(np.sqrt(path[4] / m)),
                }
            )
        return out


def interaction_stats(
    config: SimConfig,
    controller: Any = None,
    plan: JointTrajectory | None = None,
    exo: BodyModel | None = None,
) -> InteractionStats | None:
    """The interaction figures of a run in a mode or with an active patient, else None.

    Args:
        config: the run.
        controller: the run's controller; a :class:`PathController` adds
            the path figures (module docstring).
        plan: the run's plan (for the path figures).
        exo: the TRUE exoskeleton, the plant's (for the path figures).

    """
    if config.mode == "tracking" and config.patient_torque != "active":
        return None
    if config.exercise != "gait":
        return None
    lay = config.plan_layout
    period = lay.period if lay.period > 1 else round(config.gait.period / config.dt)
    lead = math.ceil(config.ramp_in / config.dt - 1e-9)
    path = None
    if isinstance(controller, PathController) and plan is not None and exo is not None:
        path = PathReference.of(controller, plan, exo)
    return InteractionStats(config.mode, lead, period, config.dt, path)
