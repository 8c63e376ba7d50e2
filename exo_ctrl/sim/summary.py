"""A run's figures, accumulated chunk by chunk (no need to keep the history)."""

from __future__ import annotations

import math
from typing import Any, Protocol

import numpy as np

from .._jit import kernel, preload
from ..control import controller_name
from ..estimation import EstimateErrorStats, model_driven
from ..estimation.plugin import components_of
from ..model import CUFF_NAMES, JOINT_NAMES, SIDES
from .config import SimConfig
from .gait_score import GaitScoreStats
from .interaction import InteractionStats
from .load_stats import LoadStats
from .run_models import device_belief, true_cuffs

__all__ = [
    "SAFETY_EVENT_KINDS",
    "ContactStats",
    "RunOutcome",
    "RunStats",
    "contact_stats",
    "drive_limits",
    "peak_force_magnitudes",
]

#: The event kinds a summary lists as ``safety_events``: the supervisor's
#: violations and e-stops, and the monitors' warnings (the state left normal).
SAFETY_EVENT_KINDS = ("violation", "estop", "warning")

#: A touchdown's peak normal-force rate is taken over this span after it [s].
TOUCHDOWN_WINDOW_S = 0.05
#: At most this many touchdowns are listed in a summary (the worst values cover all).
MAX_TOUCHDOWNS_LISTED = 200


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


def _estimate_rows(rows: dict[str, np.ndarray], fill: bool) -> tuple[Any, ...]:
    """The arguments of EstimateErrorStats.update from a chunk's rows (errors: None if absent)."""
    names = ("cuff_normal_est_error", "cuff_along_est_error")
    errors = tuple(rows[n] for n in names) if fill and all(n in rows for n in names) else None
    return rows["q"], rows["cuff_force"], rows["cuff_normal_est"], rows["cuff_force_est"], errors


def _margin(result: RunOutcome) -> dict[str, float] | None:
    """The QP's ``cuff_bound_margin_N`` per cuff, or None (another controller, a recording)."""
    margin = getattr(result, "cuff_bound_margin_N", None)
    return None if margin is None else _keyed(margin, CUFF_NAMES)


def _keyed(values: np.ndarray, names: tuple[str, ...]) -> dict[str, float]:
    return {name: float(x) for name, x in zip(names, values, strict=True)}


class RunStats:
    """Running sums and peaks of a run's signals.

    Peaks are of absolute values; RMS values are over all ticks seen.
    """

    def __init__(
        self,
        estimate: EstimateErrorStats | None = None,
        contact: ContactStats | None = None,
        interaction: InteractionStats | None = None,
        limits: np.ndarray | None = None,
    ) -> None:
        self.estimate = estimate
        self.contact = contact
        #: The ``interaction`` block's sums (:mod:`exo_ctrl.sim.interaction`), and
        #: aan's support level per cycle (the controller's list, filled as it runs).
        self.interaction = interaction
        self.support: list[float] | None = None
        #: The gait scores (:mod:`exo_ctrl.sim.gait_score`), set by the loop for a gait run.
        self.gait: GaitScoreStats | None = None
        #: The stance legs' load (:mod:`exo_ctrl.sim.load_stats`), set for a run with the belt.
        self.load: LoadStats | None = None
        self.ticks = 0
        # Running sums (Σ err², Σ τ², Σ i²) and peaks (|err|, |τ|, |i|, |U|,
        # |τ q̇|, cuff |f|, |q̇|), a row of 4 each: :func:`_accumulate`'s buffers.
        self._sums = np.zeros((3, 4))
        self._peaks = np.zeros((7, 4))
        #: The drives' limits (:func:`drive_limits`; none: infinite) and the ticks at each.
        self._limits = np.full((3, 4), np.inf) if limits is None else np.asarray(limits, float)
        self._at_limit = np.zeros((3, 4))
        #: Peak magnitude of each cuff's estimated force [N] (:func:`peak_force_magnitudes`).
        self._peak_est = np.zeros(4)
        #: Fill the rows' per-tick estimate errors (the log's; off for rows read
        #: back from a recording, which hold them already).
        self.fills_errors = True

    def update(self, rows: dict[str, np.ndarray]) -> None:
        """Add a chunk of rows (name → (n, ...) arrays, as in SIGNALS)."""
        if self.estimate is not None:  # and the per-tick errors, into the rows
            self.estimate.update(*_estimate_rows(rows, self.fills_errors))
        if self.contact is not None:
            self.contact.update(rows, self.ticks)
        if self.load is not None:
            self.load.update(rows, self.ticks)
        if self.interaction is not None:
            self.interaction.update(rows, self.ticks)
        if self.gait is not None:
            self.gait.update(rows, self.ticks)
        self.ticks += rows["q"].shape[0]
        _accumulate(*self._accumulate_args(rows))
        np.maximum(
            self._peak_est, peak_force_magnitudes(rows["cuff_force_est"]), out=self._peak_est
        )

    def preload(self, rows: dict[str, np.ndarray]) -> None:
        """Load the compiled kernels for rows of these arrays' types (before a timed run)."""
        if self.estimate is not None:
            self.estimate.preload(*_estimate_rows(rows, self.fills_errors))
        preload(_accumulate, *self._accumulate_args(rows))

    def _accumulate_args(self, rows: dict[str, np.ndarray]) -> tuple[np.ndarray, ...]:
        names = ("q", "q_des", "drive_torque", "current", "voltage", "dq", "cuff_force")
        buffers = (self._sums, self._peaks, self._limits, self._at_limit)
        return (*(rows[name] for name in names), *buffers)

    def summary(self, result: RunOutcome) -> dict[str, Any]:
        """The JSON summary of a run.

        Keys: ``controller``, ``status``, ``error``, ``duration_s``, ``ticks``,
        ``belt_speed_mps``, ``rms_tracking_error_rad`` and
        ``max_tracking_error_rad`` (keyed by joint; error = planned - actual
        exoskeleton angle), ``peak_drive_torque_Nm``, ``rms_drive_torque_Nm``,
        ``peak_motor_current_A``, ``peak_motor_voltage_V``,
        ``peak_mechanical_power_W`` (|τ q̇|; keyed by joint),
        ``share_at_torque_limit`` and ``share_at_current_limit`` (keyed by
        joint: the shares of the ticks the drive was clipped at the rated
        effort or the driver's current limit, as in ``drive_sizing``),
        ``peak_cuff_force_N`` (magnitude of the sagittal force, keyed by cuff),
        ``peak_cuff_force_est_N`` (the same of the live estimate, every tick,
        :func:`peak_force_magnitudes`),
        ``rms_motor_current_A`` (what heats a motor) and
        ``peak_joint_speed_rad_s`` (keyed by joint), ``drive_sizing`` (per
        joint, the figures that size a drive: peak and RMS joint torque,
        peak joint speed, peak mechanical power, peak and RMS motor current,
        peak voltage, and the shares of the ticks at the drive's limits,
        ``share_at_torque_limit`` (the joint's rated effort, the URDF's),
        ``share_at_current_limit`` (the driver's) and
        ``share_at_supply_voltage``: a peak at a limit says the drive was
        clipped there, the share how often),
        ``safety_state`` (the supervisor's final state) and ``safety_events``
        (violations, e-stops and warnings such as the cuff-load monitor's,
        :data:`SAFETY_EVENT_KINDS`: t, kind, quantity, value, limit, message),
        ``wall_time_s``, ``real_time_factor`` (simulated / wall time of the
        ticks the wall clock covers, :attr:`SimResult.wall_time_s`); with
        live estimation ``cuff_force_estimate_rms_error_N`` and
        ``cuff_force_estimate_rms_error_rel`` (keyed by cuff: RMS of the
        whole 2-D force's error, and that over the RMS true force, null below
        1 N), ``cuff_force_estimate_normal_rms_error_N`` and
        ``cuff_force_estimate_normal_rms_over_peak`` (the normal component's
        RMS error, and that over its peak true value) and
        ``cuff_force_estimate_unobservable`` (per cuff, what the joint
        torques cannot see; :mod:`exo_ctrl.estimation.errors`; with the
        Kalman filter, the components its models supply); with the belt
        and contact, :meth:`ContactStats.summary`'s keys; ``device_belief``
        (:func:`device_belief`: what the controller, the estimator and the
        supervisor held, so that a figure made with perfect knowledge says so).
        """
        n = max(self.ticks, 1)
        sq_err, sq_tau, sq_current = self._sums
        max_err, tau, current, voltage, power, cuff, speed = self._peaks
        rms_tau, rms_current = np.sqrt(sq_tau / n), np.sqrt(sq_current / n)
        duration = self.ticks * result.config.dt
        wall = result.wall_time_s
        out = {
            "controller": controller_name(result.config.controller),
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
            "share_at_torque_limit": _keyed(self._at_limit[0] / n, JOINT_NAMES),
            "share_at_current_limit": _keyed(self._at_limit[1] / n, JOINT_NAMES),
            "peak_cuff_force_N": _keyed(cuff, CUFF_NAMES),
            "peak_cuff_force_est_N": _keyed(self._peak_est, CUFF_NAMES),
            "qp_failures": result.qp_failures,
            "cuff_bound_margin_N": _margin(result),
            "safety_state": result.safety_state,
            "safety_events": [e for e in result.events if e.get("kind") in SAFETY_EVENT_KINDS],
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
                    "share_at_torque_limit": float(self._at_limit[0, j] / n),
                    "share_at_current_limit": float(self._at_limit[1, j] / n),
                    "share_at_supply_voltage": float(self._at_limit[2, j] / n),
                }
                for j, joint in enumerate(JOINT_NAMES)
            },
        }
        out["device_belief"] = device_belief(result.config)
        out["true_cuffs"] = true_cuffs(result.config)
        if self.estimate is not None:
            out.update(self.estimate.summary())
            config = result.config
            components = components_of(config.estimator, config.cuff_sensors.mode)
            out["cuff_force_estimate_components"] = components
            if config.estimator == "kalman":
                # The filter estimates every component; these come from its models.
                out["cuff_force_estimate_unobservable"] = model_driven(components)
        if self.contact is not None:
            out.update(self.contact.summary())
        if self.load is not None:  # stance knee torque, the pelvis (exo_ctrl.sim.load_stats)
            out.update(self.load.summary())
        if self.interaction is not None:
            out["interaction"] = self.interaction.summary(self.support)
        if self.gait is not None:  # gait_profile_score_deg, ... (exo_ctrl.sim.gait_score)
            out.update(self.gait.summary())
        out.update(result.energy)  # energy_J, energy_balance_residual_rel
        return out


class ContactStats:
    """The belt's and the feet's figures, chunk by chunk (contact on).

    Slip and touchdowns count from tick ``from_tick`` on (the end of the
    ramp-in: during it the plan's own stance foot slides by σ̇ x,
    :mod:`exo_ctrl.plan.ramp`); forces and the belt's speed error over the
    whole run.  A touchdown is a tick where a foot's contact state leaves 0.
    The walk's figures leave out the ticks where the safety supervisor stops
    (``safety_state`` not normal: the belt runs down, the legs yield or are
    held), which get figures of their own (``stop_*``): a foot that comes down
    on the slowing belt during a stop is not one of the gait's touchdowns.

    Args:
        from_tick: first tick of the slip and touchdown figures.
        dt: control period Δt [s].
        patient_feet: the patient's feet meet the belt too (``ContactParams.patient_feet``):
            their block ``patient_feet`` (:meth:`summary`).

    """

    def __init__(self, from_tick: int, dt: float, patient_feet: bool = False) -> None:
        self.from_tick = int(from_tick)
        self.dt = float(dt)
        #: The patient's feet: peak force, deepest point in contact, Σ slip², ticks in contact.
        self.patient: dict[str, Any] | None = None
        if patient_feet:
            self.patient = {"peak": np.zeros(2), "depth": np.zeros(2), "sq": 0.0, "n": np.zeros(2)}
        self._window = max(round(TOUCHDOWN_WINDOW_S / dt), 1)
        # Σ slip², ticks × feet in contact and the largest slip: [the walk, the stops].
        self._slip_sq = np.zeros(2)
        self._slip_n = np.zeros(2, dtype=np.int64)
        self._slip_max = np.zeros(2)
        self._belt_sq = 0.0
        self._belt_n = 0
        self._peak_force = np.zeros(2)
        self._last_state = np.zeros(2)
        self._open: list[list[float]] = [[], []]  # per foot: [tick, ticks left, peak rate]
        #: Touchdowns: tick, foot, speeds relative to the belt, peak normal-force rate.
        self.touchdowns: list[dict[str, Any]] = []

    def update(self, rows: dict[str, np.ndarray], first_tick: int) -> None:
        """Add a chunk of rows whose first row is tick ``first_tick``."""
        state, slip = rows["contact_state"], rows["foot_slip"]
        n = state.shape[0]
        start = min(max(self.from_tick - first_tick, 0), n)
        stopped = rows["safety_state"] != 0.0
        for phase, ticks in enumerate((~stopped[start:], stopped[start:])):
            s = slip[start:][(state[start:] > 0.0) & ticks[:, None]]
            self._slip_sq[phase] += float(s @ s)
            self._slip_n[phase] += int(s.size)
            if s.size:
                self._slip_max[phase] = max(self._slip_max[phase], float(np.max(np.abs(s))))
        err = rows["belt_speed"] - rows["belt_speed_set"]
        self._belt_sq += float(err @ err)
        self._belt_n += n
        force = np.hypot(rows["ground_force"][..., 0], rows["ground_force"][..., 1])
        if n:
            self._peak_force = np.maximum(self._peak_force, force.max(axis=0))
        rate = np.abs(rows["normal_force_rate"])
        for f in range(2):
            self._extend(f, 0, rate[:, f])
            on = state[:, f] > 0.0
            before = np.concatenate(([self._last_state[f] > 0.0], on[:-1]))
            for r in np.flatnonzero(on & ~before):
                if first_tick + r < self.from_tick:
                    continue
                vx, vz = rows["touchdown_velocity"][r, f]
                self.touchdowns.append(
                    {"tick": first_tick + int(r), "t_s": (first_tick + int(r)) * self.dt,
                     "foot": SIDES[f], "speed_x_mps": float(vx), "speed_z_mps": float(vz),
                     "peak_normal_force_rate_N_per_s": 0.0, "during_stop": bool(stopped[r])}
                )  # fmt: skip
                self._open[f] = [len(self.touchdowns) - 1, self._window]
                self._extend(f, int(r), rate[:, f])
            if n:
                self._last_state[f] = state[-1, f]
        if self.patient is not None:
            self._update_patient(rows, start)

    def _update_patient(self, rows: dict[str, np.ndarray], start: int) -> None:
        """The patient's feet: peak force; depth, slip and ticks in contact from row ``start``."""
        pat = self.patient
        force = rows["patient_ground_force"]
        if force.shape[0]:
            peak = np.hypot(force[..., 0], force[..., 1]).max(axis=0)
            pat["peak"] = np.maximum(pat["peak"], peak)
        on = rows["patient_contact_state"][start:] > 0.0
        depth = np.where(on, rows["patient_foot_penetration"][start:], 0.0)
        if depth.shape[0]:
            pat["depth"] = np.maximum(pat["depth"], depth.max(axis=0))
        slip = rows["patient_foot_slip"][start:][on]
        pat["sq"] += float(slip @ slip)
        pat["n"] += on.sum(axis=0)

    def _extend(self, foot: int, start: int, rate: np.ndarray) -> None:
        """Carry foot ``foot``'s open touchdown window over ``rate[start:]``."""
        if not self._open[foot]:
            return
        index, left = self._open[foot]
        part = rate[start : start + int(left)]
        if part.size:
            event = self.touchdowns[index]
            peak = max(event["peak_normal_force_rate_N_per_s"], float(part.max()))
            event["peak_normal_force_rate_N_per_s"] = peak
        left -= part.size
        self._open[foot] = [index, left] if left > 0 else []

    def summary(self) -> dict[str, Any]:
        """The contact's summary keys.

        While walking (class docstring): ``slip_speed_rms_mps``,
        ``slip_speed_max_mps`` (both feet, in contact), ``touchdown_speed_mps``
        (worst vertical), ``touchdown_slip_mps`` (worst horizontal, relative to
        the belt), ``touchdown_count``; during the supervisor's stops the same
        prefixed ``stop_`` (0 without a stop); over both:
        ``peak_normal_force_rate_N_per_s`` (worst within
        :data:`TOUCHDOWN_WINDOW_S` of a touchdown), ``peak_ground_force_N``
        (keyed by foot), ``belt_speed_error_rms_mps`` (belt - set speed) and
        ``touchdowns`` (the first :data:`MAX_TOUCHDOWNS_LISTED`), all of the
        exoskeleton's feet; with the patient's feet on the belt, their block
        ``patient_feet``: ``peak_ground_force_N`` (keyed by foot, the whole
        run), after the ramp-in ``max_penetration_m`` (deepest point in
        contact, keyed by foot), ``slip_speed_rms_mps`` (both feet, in
        contact) and ``contact_fraction`` (share of the ticks in contact,
        keyed by foot).
        """
        td = self.touchdowns
        out: dict[str, Any] = {}
        for phase, prefix in enumerate(("", "stop_")):
            mine = [e for e in td if e["during_stop"] is bool(phase)]
            rms = math.sqrt(self._slip_sq[phase] / max(int(self._slip_n[phase]), 1))
            out |= {
                f"{prefix}slip_speed_rms_mps": rms,
                f"{prefix}slip_speed_max_mps": float(self._slip_max[phase]),
                f"{prefix}touchdown_speed_mps": max(
                    (abs(e["speed_z_mps"]) for e in mine), default=0.0
                ),
                f"{prefix}touchdown_slip_mps": max(
                    (abs(e["speed_x_mps"]) for e in mine), default=0.0
                ),
                f"{prefix}touchdown_count": len(mine),
            }
        out |= {
            "peak_normal_force_rate_N_per_s": max(
                (e["peak_normal_force_rate_N_per_s"] for e in td), default=0.0
            ),
            "peak_ground_force_N": _keyed(self._peak_force, SIDES),
            "belt_speed_error_rms_mps": math.sqrt(self._belt_sq / max(self._belt_n, 1)),
            "touchdowns": td[:MAX_TOUCHDOWNS_LISTED],
        }
        pat = self.patient
        if pat is not None:
            ticks = max(self._belt_n - self.from_tick, 1)
            out["patient_feet"] = {
                "peak_ground_force_N": _keyed(pat["peak"], SIDES),
                "max_penetration_m": _keyed(pat["depth"], SIDES),
                "slip_speed_rms_mps": math.sqrt(pat["sq"] / max(float(pat["n"].sum()), 1.0)),
                "contact_fraction": _keyed(pat["n"] / ticks, SIDES),
            }
        return out


def contact_stats(config: SimConfig) -> ContactStats | None:
    """The contact figures of a run with the belt (from the end of its ramp-in), else None."""
    if not config.contact.enabled:
        return None
    start = math.ceil(config.ramp_in / config.dt - 1e-9)
    return ContactStats(start, config.dt, config.contact.patient_feet)


@kernel
def _accumulate(q, q_des, tau, current, voltage, dq, cuff_force, sums, peaks, limits, at_limit):
    """Add rows to the running sums and peaks of :class:`RunStats` (its buffers' layout).

    One pass over the rows in place of a dozen numpy reductions over the
    strided columns of the chunk buffer (1.4 ms → a few µs per 2000 rows).
    ``at_limit[i, j]`` counts the rows with |τ|, |I|, |U| (i = 0, 1, 2) at
    ``limits[i, j]`` (within 1e-9 of it: the drive clips to it exactly).
    """
    for r in range(q.shape[0]):
        for j in range(4):
            at_limit[0, j] += abs(tau[r, j]) >= limits[0, j] * (1.0 - 1e-9)
            at_limit[1, j] += abs(current[r, j]) >= limits[1, j] * (1.0 - 1e-9)
            at_limit[2, j] += abs(voltage[r, j]) >= limits[2, j] * (1.0 - 1e-9)
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


def peak_force_magnitudes(force: np.ndarray) -> np.ndarray:
    """Peak magnitude of each force over rows: max over n of √(f_x² + f_z²) [N], (k,).

    Args:
        force: sagittal forces (x, z) [N], (n, k, 2); no rows gives zeros.

    """
    f = np.asarray(force, dtype=float)
    if f.shape[0] == 0:
        return np.zeros(f.shape[1])
    return np.hypot(f[..., 0], f[..., 1]).max(axis=0)


def drive_limits(config: SimConfig, effort: np.ndarray) -> np.ndarray:
    """The true drives' limits per joint, (3, 4): the rated effort [N·m], I_max [A], U_max [V].

    ``effort``: the exoskeleton URDF's joint effort limits [N·m] (not finite
    or not positive: none, infinite), as the plant clips the drive torque.
    """
    effort = np.asarray(effort, dtype=float)
    effort = np.where(np.isfinite(effort) & (effort > 0.0), effort, np.inf)
    m = config.motor
    return np.array([effort, np.full(4, m.current_limit_A), np.full(4, m.supply_voltage_V)])
