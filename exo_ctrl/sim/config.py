"""What defines a run: :class:`SimConfig`, composed of the packages' own parameters."""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass, field, replace
from typing import Any

from .. import _validate as v
from ..control import PD, Controller, PDGains, controller_name
from ..control.modes import ModeParams, PathParams
from ..control.qp.bounds import cuff_limits
from ..control.qp.controller import RESTORED_BANDWIDTH_PER_S
from ..estimation import DEFAULT_GAIN_PER_S, ESTIMATORS, Estimator, estimator_name
from ..exceptions import InvalidParameter
from ..plan import (
    EXERCISES,
    GaitParams,
    Ramp,
    RowLayout,
    SpeedProfile,
    layout,
)
from ..plant import (
    CompliantJoint,
    ContactParams,
    CuffParams,
    EndStopParams,
    Misalignment,
    MotorParams,
    PelvisParams,
)
from ..plant.cuff_scatter import CuffScatter
from ..plant.patient_active import PATIENT_KINDS, ActiveParams
from ..safety import SafetyLimits, stop_reaction_schedule
from ..safety.stop_reaction import check_stop_reaction
from ..sensing import (
    BeltEncoderParams,
    CuffSensorParams,
    CurrentSensorParams,
    FootLoadParams,
    SensorParams,
)
from . import config_checks as checks
from .belief import Belief
from .config_checks import MAX_DURATION_S, MAX_PLANT_SUBSTEPS, PLAN_ROW_BYTES
from .faults import Fault, faults_of
from .plain import named_copy
from .schema import log_dtype
from .session import SessionParams, check_session

__all__ = [
    "CHUNK_ROW_BYTES",
    "CONTROLLERS",
    "CUFF_FITS",
    "HISTORY_BYTES_PER_TICK",
    "MAX_DURATION_S",
    "MAX_PLANT_SUBSTEPS",
    "PLAN_ROW_BYTES",
    "SimConfig",
]

CONTROLLERS = ("pd", "ct", "qp")

#: How the cuffs are fitted at the start (:func:`~exo_ctrl.sim.setup.start_on_plan`):
#: ``"equilibrium"``, the patient settled into the straps at static
#: equilibrium; ``"slack"``, slack in the exoskeleton's posture (the patient
#: then drops into them).
CUFF_FITS = ("equilibrium", "slack")


#: Memory per row of the log chunk [bytes]: the log row (every signal of
#: :mod:`exo_ctrl.sim.schema`) and, when the planned rows are copied into it,
#: their index and the planned angles and speeds (1 + 4 + 4 numbers).
CHUNK_ROW_BYTES = log_dtype().itemsize + (1 + 2 * 4) * 8

#: Memory per tick of a run's history, kept by
#: :func:`~exo_ctrl.sim.simulate` unless ``keep_history`` is off [bytes]:
#: every signal, the tick time and the tick index it is computed from, and
#: 8 bytes for what else grows with a run (the per-cycle statistics and the
#: events: at most 0.4 bytes per tick measured by tests/cli/test_cli_sizes.py).
HISTORY_BYTES_PER_TICK = log_dtype().itemsize + 2 * 8 + 8


@dataclass(frozen=True)
class SimConfig:
    """Everything that defines a run.

    Attributes:
        gait: the gait (paper §III).
        exo: exoskeleton URDF path (None: the committed default).
        patient: patient URDF path, ``"human"`` (example-robot-data) or None
            (the committed default).
        controller: ``"pd"`` (paper), ``"ct"`` (computed torque + PD),
            ``"qp"`` (CT + PD distributed by a QP under drive limits and
            cuff-force bounds, :mod:`exo_ctrl.control.qp.controller`), or a
            user's: an :class:`exo_ctrl.control.Controller` object or its
            class's path ``"module:Class"`` (:mod:`exo_ctrl.control.interface`; tracking only).
        qp_estimate_bandwidth_per_s: ω_f, the bandwidth the QP brings the
            cuff-force estimate to before it rebuilds the cuff state from it
            [1/s] (:mod:`exo_ctrl.control.qp.observer`; default 200, twice
            the estimator's: its lag halved; ``observer_gain_per_s`` leaves
            the estimate as it is).
        cuff_force_limit_N: the QP's bound on each cuff's force [N]: one for
            every cuff, or two, (thigh, shank), each region's
            (:mod:`exo_ctrl.control.qp.bounds`).  Default 120 N: ISO/TS 15066
            Annex A's quasi-static limit for the lower leg, 130 N, with a
            margin.  The QP holds its prediction within the bound less each
            cuff's margin (:mod:`exo_ctrl.control.qp.margin`).  The presets with
            the belt on (``paper``, ``clinic-bws``, ``clinic-spastic``) set
            200 N on the thighs and 120 N on the shanks: over the belt the QP
            may not leave its plan, and 120 N leaves the thighs less than the
            gait's load plus the margin.
        qp_tighten_bound: tighten the bound by the margin (False: at the bound).
        gains: PD gains (shared by both controllers).
        motor: drive parameters.
        cuffs: the published cuffs the patient's true cuffs scatter around:
            normal and shear stiffness and damping, strap preload
            (:class:`~exo_ctrl.plant.cuffs.CuffParams`; default split, shear
            softer; ``CuffParams.isotropic()`` the cuffs before the split).
            The device's models hold the published cuffs (``belief``).
        cuff_scatter: how far the patient's true cuffs are from ``cuffs``
            (:class:`~exo_ctrl.plant.cuff_scatter.CuffScatter`; default a
            seeded 20 % spread, cited there; ``CuffScatter.exact()``: exactly
            ``cuffs``).  The plant simulates :attr:`true_cuffs`.
        misalignment: the true patient's hip and knee axes offset from the
            exoskeleton's, (DX, DZ) [m] each (:mod:`exo_ctrl.plant.misalignment`;
            default coaxial).  Truth only: the device's models are aligned.
        end_stops: the exoskeleton joints' hard stops at the URDF limits
            (:mod:`exo_ctrl.plant.end_stops`).
        joint_compliance: a torsional spring–damper between each drive and
            its link (:mod:`exo_ctrl.plant.compliance`; default disabled: rigid).
        contact: the treadmill belt with its drive and the foot–belt contact
            (:mod:`exo_ctrl.plant.contact`; default off: the feet in free air).
        pelvis: the pelvis on a vertical guide with body-weight support
            (:mod:`exo_ctrl.plant.pelvis`; default fixed, as the paper); needs
            contact on and the gait exercise.
        foot_load: the foot plates' load cells (:mod:`exo_ctrl.sensing.foot_load`;
            read with contact on, their joint torque given to the estimator).
        belt_encoder: the belt-speed sensor (:mod:`exo_ctrl.sensing.belt_encoder`).
        speed_profile: the session's belt set speed over time
            (:mod:`exo_ctrl.plan.profile`, or its text ``"T1:V1,..."``; None: the
            gait's v_f); with contact on.
        sync: plan online from the measured belt speed (:mod:`exo_ctrl.plan.online`,
            the gait adapting to the speed by :mod:`exo_ctrl.plan.adapt`);
            None: on with contact on, for the QP with the pelvis supported only
            (:attr:`synced`).  Off: the precomputed plan, which assumes the gait's
            v_f whatever the belt does.
        duration_s: simulated time [s], ramps included, from one control
            tick to :data:`MAX_DURATION_S`.  Default 3.6 s: the default
            ramp-in (one 1.2 s gait period) and two gait cycles.
        ramp_in_s: the start's ramp from standing into the gait
            (:mod:`exo_ctrl.plan.ramp`) [s], within the run; None: one gait
            period (a shorter run ends within it; with a ramp-out, at most the
            run less the ramp-out); 0: the run starts on the gait at full
            speed (as before the ramp existed).
        ramp_out_s: the ramp from the gait back to standing over the last
            seconds of the run [s] (default 0: none).
        cuff_fit: how the cuffs are fitted at the start, one of
            :data:`CUFF_FITS` (default ``"equilibrium"``).
        control_rate_hz: control rate [Hz] (default 1 kHz).
        plant_substeps: plant steps per control tick [-] (plant step = Δt / n),
            1 to :data:`MAX_PLANT_SUBSTEPS`.
        chunk_ticks: rows per logging chunk.
        sensors: encoder and joint torque sensor models (defaults: real
            hardware, :mod:`exo_ctrl.sensing.sensors`); ``SensorParams.ideal()`` for
            perfect readings.
        current_sensor: the drives' current sensors the supervisor reads
            (:mod:`exo_ctrl.sensing.current_sensor`).
        cuff_sensors: force sensors in the cuffs, fused by the Kalman filter
            (:mod:`exo_ctrl.sensing.cuff_load`; default mode ``"none"``).
        observer_gain_per_s: bandwidth K_O of the momentum observer [1/s].
        cuff_stiffness_ratio: the estimator's assumption on how the cuffs
            share load (:mod:`exo_ctrl.estimation.observer`).
        estimator: the live cuff-force estimator, ``"kalman"`` (default:
            the filter on the coupled model with the device's patient and
            cuff models, :mod:`exo_ctrl.estimation.kalman`; the better one,
            smaller whole-force error and lag), ``"momentum"`` (the
            momentum observer, :mod:`exo_ctrl.estimation.observer`), or a
            user's :class:`exo_ctrl.estimation.Estimator`: an object, or as
            the scenario key its import path ``"module:Class"`` (tracking only).
        patient_torque: patient joint torques, ``"none"`` (paper §VI),
            ``"spastic"`` (:mod:`exo_ctrl.plant.patient`) or ``"active"``
            (:mod:`exo_ctrl.plant.patient_active`: their own gait, strength,
            delay; spastic on top with ``patient_active.spastic``).
        patient_active: the active patient's parameters (with
            ``patient_torque="active"``).
        mode: the interaction mode, one of :data:`~exo_ctrl.control.modes.MODES`:
            ``"tracking"`` (default: the controller's position control),
            ``"guidance"``, ``"transparent"``, ``"aan"`` or ``"path"``
            (:mod:`exo_ctrl.control.modes.controller`).
        modes: the modes' parameters (G, K_f, aan's f, g, bins, soft PD).
        path: ``path``'s tunnel, wall and support
            (:mod:`exo_ctrl.control.modes.path`).
        session: segments of modes and belt speeds run one after another
            (:mod:`exo_ctrl.sim.session`; None: ``mode`` throughout); their
            durations sum to ``duration_s``, their belt speeds make the
            speed profile.
        safety: run the safety supervisor (:mod:`exo_ctrl.safety.supervisor`).
        safety_limits: its limits.
        safety_use_estimate: the supervisor watches the estimated cuff
            forces, as a real device must (default); False: the true
            (simulated) ones, the ideal comparison of a device with a force
            sensor in every cuff.
        safety_widen: the supervisor watches the estimate with the shanks' along
            force widened by what a knee ``belief.knee_fit_tolerance_m`` off can add
            unseen (:mod:`exo_ctrl.safety.unseen`): its limit holds without 2-axis
            cuff sensors, at the cost of stops.  Not with the QP.
        stop_reaction: how the supervisor's stop ends, ``"hold"`` (the
            posture, stiffly) or ``"yield"`` (gravity compensation and
            damping: an active patient moves the legs;
            :mod:`exo_ctrl.safety.stop_reaction`); None (default): by mode,
            ``hold`` in tracking and guidance with G = 1, ``yield`` in the
            others (with a session: the segment running at the stop).
        estop_at_s: emergency stop at this time [s] (None: none); at most
            the time of the last control tick, (n_ticks - 1) Δt.
        belief: the models the controller, the estimator and the supervisor
            hold (:mod:`exo_ctrl.sim.belief`; default: the nominal patient
            from the paper's stature and mass, the exoskeleton URDF, the
            drive's datasheet, the published split cuffs;
            ``Belief("truth")`` is the ideal comparison).
        faults: faults to inject (:mod:`exo_ctrl.sim.faults`; default none),
            each with its onset within the run.
        exercise: what the run does, one of :data:`~exo_ctrl.plan.EXERCISES`:
            ``"gait"`` (default) or ``"calibration"``, the swing in the air
            for identification (:mod:`exo_ctrl.plan.exercise`; the gait's
            ramps and period then do not apply, the plan holds every tick).

    The arrays a run allocates from these numbers (the plan, the log chunk)
    are checked against the memory cap
    (:data:`~exo_ctrl._validate.MAX_ALLOCATION_BYTES`) when the configuration
    is made; the history kept by :func:`~exo_ctrl.sim.simulate` by
    :meth:`check_history`.

    """

    gait: GaitParams = field(default_factory=GaitParams)
    exo: str | None = None
    patient: str | None = None
    controller: str | Controller = "pd"
    gains: PDGains = field(default_factory=PDGains)
    motor: MotorParams = field(default_factory=MotorParams)
    cuffs: CuffParams = field(default_factory=CuffParams)
    cuff_scatter: CuffScatter = field(default_factory=CuffScatter)
    misalignment: Misalignment = field(default_factory=Misalignment)
    end_stops: EndStopParams = field(default_factory=EndStopParams)
    joint_compliance: CompliantJoint = field(default_factory=CompliantJoint)
    contact: ContactParams = field(default_factory=ContactParams)
    pelvis: PelvisParams = field(default_factory=PelvisParams)
    belt_encoder: BeltEncoderParams = field(default_factory=BeltEncoderParams)
    foot_load: FootLoadParams = field(default_factory=FootLoadParams)
    duration_s: float = 3.6
    ramp_in_s: float | None = None
    ramp_out_s: float = 0.0
    cuff_fit: str = "equilibrium"
    control_rate_hz: float = 1000.0
    plant_substeps: int = 1
    chunk_ticks: int = 2000
    sensors: SensorParams = field(default_factory=SensorParams)
    current_sensor: CurrentSensorParams = field(default_factory=CurrentSensorParams)
    cuff_sensors: CuffSensorParams = field(default_factory=CuffSensorParams)
    observer_gain_per_s: float = DEFAULT_GAIN_PER_S
    cuff_stiffness_ratio: float = 1.0
    estimator: str | Estimator = "kalman"
    cuff_force_limit_N: float | tuple[float, float] = 120.0
    qp_estimate_bandwidth_per_s: float = RESTORED_BANDWIDTH_PER_S
    qp_tighten_bound: bool = True
    patient_torque: str = "none"
    safety: bool = True
    safety_limits: SafetyLimits = field(default_factory=SafetyLimits)
    safety_use_estimate: bool = True
    safety_widen: bool = False
    stop_reaction: str | None = None
    estop_at_s: float | None = None
    belief: Belief = field(default_factory=Belief)
    faults: tuple[Fault, ...] = ()
    exercise: str = "gait"
    speed_profile: SpeedProfile | None = None
    sync: bool | None = None
    mode: str = "tracking"
    modes: ModeParams = field(default_factory=ModeParams)
    path: PathParams = field(default_factory=PathParams)
    session: SessionParams | None = None
    patient_active: ActiveParams = field(default_factory=ActiveParams)

    def __post_init__(self) -> None:
        checks.check_parts(self)
        for name in ("exo", "patient"):
            value = getattr(self, name)
            if value is not None and not isinstance(value, (str, os.PathLike)):
                raise InvalidParameter(name, value, "a URDF path or None")
        for name in ("safety", "safety_use_estimate", "safety_widen", "qp_tighten_bound"):
            object.__setattr__(self, name, v.flag(name, getattr(self, name)))
        v.one_of("exercise", self.exercise, EXERCISES)
        checks.check_controller(self, CONTROLLERS)
        duration = v.positive("duration", self.duration_s, "s")
        rate = v.positive("control_rate", self.control_rate_hz, "Hz")
        if not 10.0 <= rate <= 100_000.0:
            raise InvalidParameter("control_rate", self.control_rate_hz, "in [10, 100000] Hz")
        if not 1.0 / rate - 1e-12 <= duration <= MAX_DURATION_S:
            raise InvalidParameter(
                "duration",
                self.duration_s,
                f"in [{1.0 / rate:g}, {MAX_DURATION_S:g}] s",
                f"at least one control tick at {rate:g} Hz",
            )
        for name, most in (("plant_substeps", MAX_PLANT_SUBSTEPS), ("chunk_ticks", None)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise InvalidParameter(name, value, "an integer >= 1")
            if most is not None and value > most:
                raise InvalidParameter(name, value, f"an integer in [1, {most}]")
        v.one_of("patient_torque", self.patient_torque, PATIENT_KINDS)
        checks.check_mode(self)
        if self.stop_reaction is not None:
            check_stop_reaction(self.stop_reaction)
        cuff_limits(self.cuff_force_limit_N)  # one bound, or (thigh, shank)
        if isinstance(self.cuff_force_limit_N, list):  # a scenario file's pair
            object.__setattr__(self, "cuff_force_limit_N", tuple(self.cuff_force_limit_N))
        checks.check_estimator(self, ESTIMATORS)
        v.positive("qp_estimate_bandwidth", self.qp_estimate_bandwidth_per_s, "1/s")
        v.one_of("cuff_fit", self.cuff_fit, CUFF_FITS)
        Ramp(0.0, self.ramp_out_s, self.duration_s)  # refuses a bad or too long ramp-out
        if self.ramp_in_s is not None:
            checks.check_ramp_in(self)
        if self.estop_at_s is not None:
            checks.check_estop(self)
        checks.check_widen(self)
        object.__setattr__(self, "faults", faults_of(self.faults))
        checks.check_faults(self)
        if self.session is not None:
            object.__setattr__(self, "session", SessionParams.coerce(self.session))
            profile = self.session.speed_profile(self.gait.belt_speed)  # None: no belt speeds
            given = self.speed_profile
            if profile is not None and given is not None and given != profile:
                raise InvalidParameter(
                    "speed_profile", self.speed_profile, "unset with a session's belt speeds"
                )
            if profile is not None and self.contact.enabled:  # else refused by check_session
                object.__setattr__(self, "speed_profile", profile)
        self._check_sync()
        checks.check_pelvis(self)
        if self.session is not None:
            check_session(self)
        checks.check_plan_size(self)  # and the belt's set speeds (check_belt_size)
        chunk = min(self.chunk_ticks, max(self.n_ticks, 1))
        v.allocation(
            "chunk_ticks",
            self.chunk_ticks,
            chunk,
            CHUNK_ROW_BYTES,
            what="log chunk rows",
            limit="smaller",
        )

    @property
    def true_cuffs(self) -> CuffParams:
        """The patient's true cuffs, the plant's: ``cuffs`` scattered by ``cuff_scatter``."""
        return self.cuff_scatter.apply(self.cuffs)

    @property
    def pelvis_resolved(self) -> PelvisParams:
        """The pelvis's parameters, its body mass the one entered at the device when not given.

        The body-weight support is set at the trainer from the patient's body
        mass (``belief.patient_mass_kg`` when given, else the paper patient's
        80 kg); ``pelvis.body_mass_kg`` overrides it.
        """
        pelvis = self.pelvis
        if pelvis.supported and pelvis.body_mass_kg is None and self.belief.patient_mass_kg:
            pelvis = replace(pelvis, body_mass_kg=self.belief.patient_mass_kg)
        return pelvis

    def _check_sync(self) -> None:
        """Normalise the speed profile (text or plain data: a sweep's, ``to_dict``'s form)."""
        profile = self.speed_profile
        if isinstance(profile, str):  # "T1:V1,..." (a sweep's value)
            profile = SpeedProfile.parse(profile)
        elif isinstance(profile, dict) and set(profile) == {"times", "speeds"}:  # to_dict's form
            profile = SpeedProfile(tuple(profile["times"]), tuple(profile["speeds"]))
        object.__setattr__(self, "speed_profile", profile)
        checks.check_sync(self)

    @property
    def stop_reactions(self) -> tuple[tuple[float, str], ...]:
        """The supervisor's stop reaction over the run, ((start [s], reaction), ...)."""
        g = self.modes.guidance
        return stop_reaction_schedule(self.stop_reaction, self.mode, g, self.session)

    @property
    def synced(self) -> bool:
        """Whether the plan follows the measured belt (``sync``; default: contact on, gait).

        The QP's default is the synchronised plan with the pelvis supported (on the
        precomputed one the ramp-in drags the loaded stance feet along the belt) and the
        precomputed plan with it fixed, where the feet skim the belt; its bound holds on
        either (docs/performance.md, the QP's cuff-force bound).
        """
        if self.sync is None:
            return (
                self.contact.enabled
                and self.exercise == "gait"
                and (self.controller != "qp" or self.pelvis.supported)
                and self.ramp_out_s == 0.0
            )
        return bool(self.sync)

    @property
    def plan_periodic(self) -> bool:
        """Whether the gait period is a whole number P ≥ 2 of control ticks."""
        period = self.gait.period / self.dt
        p = round(period)
        return p >= 2 and abs(p - period) <= 1e-9 * period

    @property
    def ramp_in(self) -> float:
        """The ramp-in time T_r [s]: ``ramp_in_s``, or its default (one gait period).

        With a ramp-out the default is at most the run less the ramp-out.
        """
        if self.ramp_in_s is not None:
            return float(self.ramp_in_s)
        if self.ramp_out_s > 0.0:
            return max(min(self.gait.period, self.duration_s - self.ramp_out_s), 0.0)
        return self.gait.period

    @property
    def ramp(self) -> Ramp:
        """The run's ramps (:mod:`exo_ctrl.plan.ramp`), ending at ``duration_s``.

        Raises:
            InvalidParameter: ``ramp_out_s`` not a number >= 0, or the ramps
                longer than the run.

        """
        return Ramp(self.ramp_in, self.ramp_out_s, self.duration_s)

    @property
    def plan_layout(self) -> RowLayout:
        """The rows of the joint plan and the ticks they serve (:func:`~exo_ctrl.plan.layout`).

        The calibration exercise's plan holds every tick.
        """
        if self.exercise == "calibration":
            return RowLayout(self.n_ticks)
        if self.synced:  # one row, overwritten every tick (exo_ctrl.plan.online)
            return RowLayout(rows=1, period=1)
        ramp = self.ramp
        return layout(
            self.n_ticks, self.dt, self.gait.period, ramp.ramp_in_s, ramp.ramp_out_s, ramp.end_s
        )

    @property
    def plan_rows(self) -> int:
        """Rows of the joint plan: the ramps' ticks and one gait period, or every tick.

        The gait is periodic, so after the L ramp-in ticks tick k uses row
        L + (k - L) mod P, then the ramp-out's rows (:mod:`exo_ctrl.plan.rows`);
        with P = T_s / Δt an integer (1200 for the default 1.2 s at 1 kHz) the
        plan's memory does not grow with the run's length.  Otherwise the plan
        covers every tick.
        """
        return self.plan_layout.rows

    def check_history(self) -> None:
        """Refuse a run whose kept history would exceed the memory cap.

        Raises:
            InvalidParameter: naming ``duration``, n_ticks ×
                :data:`HISTORY_BYTES_PER_TICK` beyond
                :data:`~exo_ctrl._validate.MAX_ALLOCATION_BYTES`.

        """
        rate = self.control_rate_hz
        v.allocation(
            "duration",
            self.duration_s,
            self.n_ticks,
            HISTORY_BYTES_PER_TICK,
            what="history rows",
            limit=f"at most {v.max_items(HISTORY_BYTES_PER_TICK) / rate:.4g} s at {rate:g} Hz",
            note="simulate(keep_history=False) keeps none",
        )

    @property
    def dt(self) -> float:
        """Control period Δt [s]."""
        return 1.0 / self.control_rate_hz

    @property
    def n_ticks(self) -> int:
        """Number of control ticks."""
        return math.floor(self.duration_s * self.control_rate_hz + 1e-9)

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (JSON-able), for summaries and recordings (a user's controller named)."""
        names = controller_name(self.controller), estimator_name(self.estimator)
        gains = self.controller.gains if isinstance(self.controller, PD) else self.gains
        return asdict(named_copy(self, controller=names[0], estimator=names[1], gains=gains))
