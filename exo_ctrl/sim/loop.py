"""The closed loop: plan → controller → drives → plant → sensors, and its results.

One control tick k at t_k = k Δt: the sensors read the plant, the controller
turns the plan's row k and the readings into drive voltages, and the plant
advances by Δt (in ``plant_substeps`` equal steps) with the voltages held.
Row k of every logged signal holds the state at t_k and what acted over
[t_k, t_k+1): command, applied voltage, mean current, drive torque, cuff
force (at mid-step).

The loop writes its signals into chunk buffers of ``chunk_ticks`` rows.  Each
full chunk is handed to the observers (the recorder) and, unless
``keep_history`` is off, copied into the result; so a long run that is only
recorded holds one chunk in memory.  A run that diverges or is interrupted
(Ctrl-C) ends with the ticks done so far, its status and its error: nothing
is lost.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any, Protocol

import numpy as np

from .. import _validate as v
from .._jit import kernel
from .._progress import Progress
from ..control import (
    ComputedTorqueController,
    PDController,
    PDGains,
    QPController,
    SensorReadings,
    feedforward_torque,
)
from ..estimation.observer import DEFAULT_GAIN_PER_S, CuffForceEstimator, EstimateErrorStats
from ..exceptions import InvalidParameter, SimulationDiverged
from ..model.body import BodyModel, load_exo, load_patient
from ..plan.gait import GaitParams, GaitPlan
from ..plan.kinematics import JointTrajectory, plan_joints
from ..plant.cuffs import CuffParams
from ..plant.motor import MotorParams
from ..plant.patient import PATIENT_TORQUES, make_patient_torque
from ..plant.plant import Plant
from ..safety.supervisor import SafetyLimits, SafetySupervisor
from ..sensing.sensors import SensorParams, Sensors
from .summary import RunStats

__all__ = [
    "SIGNALS",
    "Runner",
    "Setup",
    "SimConfig",
    "SimObserver",
    "SimResult",
    "build",
    "drive_for",
    "simulate",
    "start_on_plan",
]

CONTROLLERS = ("pd", "ct", "qp")

#: Logged signals: name → (shape of one row, unit, description).
SIGNALS: dict[str, tuple[tuple[int, ...], str, str]] = {
    "q_des": ((4,), "rad", "planned joint angles"),
    "dq_des": ((4,), "rad/s", "planned joint speeds"),
    "q": ((4,), "rad", "exoskeleton joint angles"),
    "dq": ((4,), "rad/s", "exoskeleton joint speeds"),
    "q_patient": ((4,), "rad", "patient joint angles"),
    "dq_patient": ((4,), "rad/s", "patient joint speeds"),
    "voltage_cmd": ((4,), "V", "controller's drive voltage command"),
    "voltage": ((4,), "V", "drive voltage applied (after supply saturation)"),
    "current": ((4,), "A", "mean drive current over the tick"),
    "drive_torque": ((4,), "N·m", "drive torque at the joint"),
    "patient_torque": ((4,), "N·m", "patient joint torque"),
    "cuff_force": ((4, 2), "N", "cuff force on the exoskeleton (x, z)"),
    "safety_state": ((), "", "safety supervisor: 0 normal, 1 stopping, 2 holding, 3 power cut"),
    "q_meas": ((4,), "rad", "encoder reading"),
    "dq_meas": ((4,), "rad/s", "joint speed reading (filtered encoder difference)"),
    "tau_sensor": ((4,), "N·m", "joint torque sensor reading"),
    "tau_ext_est": ((4,), "N·m", "external joint torque estimate (momentum observer)"),
    "cuff_normal_est": ((4,), "N", "estimated cuff force normal to the link"),
    "cuff_force_est": ((4, 2), "N", "estimated cuff force on the exoskeleton (x, z)"),
    "qp_active": ((), "", "QP controller: active constraints"),
    "qp_failures": ((), "", "QP controller: fallbacks so far"),
}


@dataclass(frozen=True)
class SimConfig:
    """Everything that defines a run.

    Attributes:
        gait: the gait (paper §III).
        exo: exoskeleton URDF path (None: the committed default).
        patient: patient URDF path, ``"human"`` (example-robot-data) or None
            (the committed default).
        controller: ``"pd"`` (paper), ``"ct"`` (computed torque + PD) or
            ``"qp"`` (CT + PD distributed by a QP under drive limits and
            cuff-force bounds, :mod:`exo_ctrl.control.qp.controller`).
        cuff_force_limit_N: the QP's bound on each cuff's PREDICTED force [N].
            Default 120 N: ISO/TS 15066 Annex A's quasi-static limit for the
            lower leg, 130 N, with a margin.  The real elastic cuff force can
            exceed it (measured in :mod:`exo_ctrl.control.qp.controller`).
        gains: PD gains (shared by both controllers).
        motor: drive parameters.
        cuffs: cuff parameters.
        duration_s: simulated time [s].
        control_rate_hz: control rate [Hz] (default 1 kHz).
        plant_substeps: plant steps per control tick (plant step = Δt / n).
        chunk_ticks: rows per logging chunk.
        sensors: encoder and joint torque sensor models (defaults: real
            hardware, :mod:`exo_ctrl.sensing.sensors`); ``SensorParams.ideal()`` for
            perfect readings.
        observer_gain_per_s: bandwidth K_O of the momentum observer [1/s].
        cuff_stiffness_ratio: the estimator's assumption on how the cuffs
            share load (:mod:`exo_ctrl.estimation.observer`).
        patient_torque: patient joint torques, ``"none"`` (paper §VI) or
            ``"spastic"`` (:mod:`exo_ctrl.plant.patient`).
        safety: run the safety supervisor (:mod:`exo_ctrl.safety.supervisor`).
        safety_limits: its limits.
        safety_use_estimate: the supervisor watches the estimated cuff
            forces (as a real device must) instead of the simulated ones.
        estop_at_s: emergency stop at this time [s] (None: none).

    """

    gait: GaitParams = field(default_factory=GaitParams)
    exo: str | None = None
    patient: str | None = None
    controller: str = "pd"
    gains: PDGains = field(default_factory=PDGains)
    motor: MotorParams = field(default_factory=MotorParams)
    cuffs: CuffParams = field(default_factory=CuffParams)
    duration_s: float = 2.4
    control_rate_hz: float = 1000.0
    plant_substeps: int = 1
    chunk_ticks: int = 2000
    sensors: SensorParams = field(default_factory=SensorParams)
    observer_gain_per_s: float = DEFAULT_GAIN_PER_S
    cuff_stiffness_ratio: float = 1.0
    cuff_force_limit_N: float = 120.0
    patient_torque: str = "none"
    safety: bool = True
    safety_limits: SafetyLimits = field(default_factory=SafetyLimits)
    safety_use_estimate: bool = False
    estop_at_s: float | None = None

    def __post_init__(self) -> None:
        if self.controller not in CONTROLLERS:
            raise InvalidParameter(
                "controller", self.controller, f"one of {', '.join(CONTROLLERS)}"
            )
        v.positive("duration", self.duration_s, "s")
        rate = v.positive("control_rate", self.control_rate_hz, "Hz")
        if not 10.0 <= rate <= 100_000.0:
            raise InvalidParameter("control_rate", self.control_rate_hz, "in [10, 100000] Hz")
        for name in ("plant_substeps", "chunk_ticks"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise InvalidParameter(name, value, "an integer >= 1")
        if self.patient_torque not in PATIENT_TORQUES:
            raise InvalidParameter(
                "patient_torque", self.patient_torque, f"one of {', '.join(PATIENT_TORQUES)}"
            )
        v.positive("cuff_force_limit", self.cuff_force_limit_N, "N")
        if self.estop_at_s is not None:
            v.non_negative("estop_at", self.estop_at_s, "s")
        if self.duration_s * self.control_rate_hz > 50_000_000:
            raise InvalidParameter(
                "duration", self.duration_s, "at most 5e7 control ticks (duration × rate)"
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
        """Plain-data form (JSON-able), for summaries and recordings."""
        return asdict(self)


class SimObserver(Protocol):
    """Something that watches a run (the recorder)."""

    def start(self, result: SimResult) -> None:
        """Called once before the first tick."""

    def chunk(self, result: SimResult, start: int, rows: dict[str, np.ndarray]) -> None:
        """Called with rows ``start:start+len`` of every signal (views, copy to keep)."""

    def finish(self, result: SimResult) -> None:
        """Called once at the end, whatever the outcome (status and error set)."""


@dataclass
class SimResult:
    """A run's time series and outcome.

    Attributes:
        config: the run's configuration.
        t: tick times [s], (N,).
        signals: name → array (N, *shape) for every entry of :data:`SIGNALS`.
        status: ``"completed"``, ``"interrupted"`` or ``"diverged"``.
        error: the error message when not completed.
        wall_time_s: wall-clock time of the loop after its first
            :data:`UNTIMED_TICKS` ticks [s] (they also load the compiled
            kernels, or compile them on the first run after an install: see
            :mod:`exo_ctrl._jit`).
        timed_ticks: ticks the wall clock covers (all done but the untimed).
        belt_speed_mps: belt speed v_f [m/s].
        exo_source: the exoskeleton URDF used; patient_source likewise.

    """

    config: SimConfig
    t: np.ndarray
    signals: dict[str, np.ndarray]
    status: str = "completed"
    error: str = ""
    wall_time_s: float = 0.0
    timed_ticks: int = 0
    belt_speed_mps: float = 0.0
    exo_source: str = ""
    patient_source: str = ""
    events: list[dict[str, Any]] = field(default_factory=list)
    safety_state: str = "normal"
    qp_failures: int = 0
    stats: RunStats = field(default_factory=RunStats, repr=False)

    def __getattr__(self, name: str) -> np.ndarray:
        signals = self.__dict__.get("signals", {})
        if name in signals:
            return signals[name]
        raise AttributeError(name)

    @property
    def n_ticks(self) -> int:
        """Number of ticks run."""
        return self.stats.ticks

    @property
    def duration_s(self) -> float:
        """Simulated time covered [s]."""
        return self.stats.ticks * self.config.dt

    def summary(self) -> dict[str, Any]:
        """The run's figures (JSON-able); keys in :meth:`RunStats.summary`."""
        return self.stats.summary(self)


@dataclass
class Setup:
    """The pieces of a run, built from a :class:`SimConfig` by :func:`build`."""

    config: SimConfig
    exo: BodyModel
    patient: BodyModel
    plan: JointTrajectory
    plant: Plant
    controller: PDController


def build(config: SimConfig) -> Setup:
    """Load the models, plan the run and build the plant and controller."""
    exo = load_exo(config.exo)
    patient = load_patient(config.patient)
    rows = plan_rows(config)
    plan = plan_joints(GaitPlan(config.gait), exo, np.arange(rows) * config.dt)
    if rows <= config.n_ticks:
        plan = dataclasses.replace(plan, period_ticks=rows)
    motor = drive_for(config.motor, exo)
    plant = Plant(
        exo, patient, dt=config.dt / config.plant_substeps, motors=motor, cuffs=config.cuffs
    )
    controller: PDController
    if config.controller == "ct":
        controller = ComputedTorqueController(plan, exo, patient, motor, config.gains)
    elif config.controller == "qp":
        controller = QPController(
            plan,
            exo,
            patient,
            motor,
            config.gains,
            cuff_force_limit_N=config.cuff_force_limit_N,
            cuffs=config.cuffs,
            dt=config.dt,
        )
    else:
        controller = PDController(plan, config.gains)
    return Setup(config, exo, patient, plan, plant, controller)


def plan_rows(config: SimConfig) -> int:
    """Rows of the joint plan: one gait period if it is a whole number of ticks.

    The gait is periodic, so tick k uses row k mod P; with P = T_s / Δt an
    integer (1200 for the default 1.2 s at 1 kHz) the plan's memory does not
    grow with the run's length.  Otherwise the plan covers every tick.
    """
    period = config.gait.period / config.dt
    p = round(period)
    if p >= 2 and abs(p - period) <= 1e-9 * period:
        return min(p, config.n_ticks + 1)
    return config.n_ticks + 1


def drive_for(motor: MotorParams, exo: BodyModel) -> MotorParams:
    """The drive as configured for this exoskeleton.

    The driver's current limit is capped at the smallest URDF effort limit
    divided by i_G k_m, so that no drive torque ever exceeds its joint's
    rated effort (150 N·m → 8.57 A with the defaults).
    """
    cap = float(np.min(exo.effort_limit)) / motor.torque_per_amp_Nm_per_A
    if motor.current_limit_A <= cap:
        return motor
    return dataclasses.replace(motor, current_limit_A=cap)


_WIDTH = 83
#: Ticks at the start of a run left out of its wall time: they load (or,
#: after an install, compile) the compiled kernels.
UNTIMED_TICKS = 3
#: Limits that never trip: the supervisor then only serves the e-stop.
_NO_LIMITS = SafetyLimits(
    cuff_force_N=(1e12,) * 4,
    position_lower_rad=(-1e12,) * 4,
    position_upper_rad=(1e12,) * 4,
    speed_limit_rad_s=(1e12,) * 4,
    current_limit_A=1e12,
)


def start_on_plan(setup: Setup) -> None:
    """Put the plant on the plan at t = 0, with the planned speed.

    The drive currents carry the feedforward torque of t = 0 (clipped to the
    driver's limit), so the legs do not sag at the start; the patient starts
    in the exoskeleton's posture and the cuffs are fitted there.
    """
    plant, plan = setup.plant, setup.plan
    motor = plant.motor_params
    tau0 = feedforward_torque(plan, setup.exo, setup.patient, motor, rows=1)[0]
    limit = motor.current_limit_A
    i0 = np.clip(tau0 / motor.torque_per_amp_Nm_per_A, -limit, limit)
    plant.reset(plan.q[0], plan.dq[0], current_A=i0)


class Runner:
    """Runs the ticks of a :class:`Setup`, writing each into a chunk buffer.

    :meth:`tick` is the whole per-tick work of a run (sensors, estimator,
    controller, safety supervisor, patient torque, plant steps, logging);
    ``tools/bench.py`` times exactly it.

    Args:
        setup: the run's pieces.

    """

    def __init__(self, setup: Setup) -> None:
        self.setup = setup
        config = setup.config
        plant = setup.plant
        self.chunk = chunk = min(config.chunk_ticks, max(config.n_ticks, 1))
        # One wide row per tick; every signal is a view of it.  Columns: the
        # state [q_exo, q_patient, v_exo, v_patient] as the plant holds it,
        # then what acted over the tick, then the plan.
        self.wide = np.zeros((chunk, _WIDTH))
        w = self.wide
        self.buf = {
            "q": w[:, 0:4],
            "q_patient": w[:, 4:8],
            "dq": w[:, 8:12],
            "dq_patient": w[:, 12:16],
            "voltage_cmd": w[:, 16:20],
            "voltage": w[:, 20:24],
            "current": w[:, 24:28],
            "drive_torque": w[:, 28:32],
            "patient_torque": w[:, 32:36],
            # the cuffs hold (fx of 4 cuffs, fz of 4 cuffs): view as (4, 2)
            "cuff_force": w[:, 36:44].reshape(chunk, 2, 4).transpose(0, 2, 1),
            "q_des": w[:, 44:48],
            "dq_des": w[:, 48:52],
            "safety_state": w[:, 52],
            "q_meas": w[:, 53:57],
            "dq_meas": w[:, 57:61],
            "tau_sensor": w[:, 61:65],
            "tau_ext_est": w[:, 65:69],
            "cuff_normal_est": w[:, 69:73],
            "cuff_force_est": w[:, 73:81].reshape(chunk, 4, 2),
            "qp_active": w[:, 81],
            "qp_failures": w[:, 82],
        }
        self.sensor_model = Sensors(config.sensors, config.dt)
        self.estimator = CuffForceEstimator(
            setup.exo,
            config.dt,
            config.observer_gain_per_s,
            stiffness_ratio=config.cuff_stiffness_ratio,
        )
        self.sensors = self.sensor_model.readings
        self.sensors.cuff_force_est = self.estimator.force  # filled in place
        self._substeps = config.plant_substeps
        self._dt = config.dt
        self._qp = isinstance(setup.controller, QPController)
        self.patient_model = make_patient_torque(config.patient_torque)
        self._tau_p = np.zeros(4)
        self._q_p, self._v_p = plant.q[4:], plant.v[4:]
        self._q_e, self._v_e = plant.q[:4], plant.v[:4]
        self._mean_current = plant.motors.mean_current_A
        # Logged each tick: Sensors.read always fills the same readings object.
        self._measured = (
            plant.state,
            self.sensor_model.readings_flat,
            self.estimator.outputs_flat,
        )
        self.supervisor: SafetySupervisor | None = None
        if config.safety or config.estop_at_s is not None:
            limits = config.safety_limits if config.safety else _NO_LIMITS
            self.supervisor = SafetySupervisor(
                limits,
                setup.exo,
                setup.patient,
                plant.motor_params,
                config.dt,
                estop_at_s=config.estop_at_s,
                use_estimate=config.safety_use_estimate,
            )
        start_on_plan(setup)

    def tick(self, k: int, row: int) -> None:
        """Run control tick ``k``, logging into buffer row ``row``.

        The stages are called through their public methods.
        """
        plant = self.setup.plant
        wide = self.wide
        sensors = self.sensor_model.read(k, self._q_e, self._v_e, plant.sensor_torque)
        self.estimator.update(sensors)
        _log_measured(wide, row, *self._measured)
        controller = self.setup.controller
        u_cmd = controller.command(k, sensors)
        if self._qp:
            self._log_qp(row)
        self._apply(k, row, sensors, u_cmd)

    def _log_qp(self, row: int) -> None:
        """Columns 81-82 of a log row: the QP's active bounds this tick, its failures so far."""
        controller = self.setup.controller
        self.wide[row, 81] = controller.active_constraints
        self.wide[row, 82] = controller.failures

    def _apply(self, k: int, row: int, sensors: SensorReadings, u_cmd: np.ndarray) -> None:
        """The rest of tick k from the command on: supervisor, plant steps, log of the applied."""
        plant = self.setup.plant
        u = u_cmd
        sup = self.supervisor
        if sup is not None:
            force = sensors.cuff_force_est if sup.use_estimate else plant.cuff_force
            u = sup.step(k, k * self._dt, sensors, force, self._mean_current, u)
            self.wide[row, 52] = sup.state_code
        tau_p = None
        for _ in range(self._substeps):
            if self.patient_model is not None:
                tau_p = self.patient_model(plant.t, self._q_p, self._v_p, self._tau_p)
            plant.step(u, tau_p)
        _log_applied(self.wide, row, u_cmd, plant.outputs)

    def fill_plan(self, start: int, rows: int) -> None:
        """Copy the planned rows ``start:start+rows`` into the buffer."""
        plan = self.setup.plan
        index = np.arange(start, start + rows)
        if plan.period_ticks:
            index %= plan.period_ticks
        self.buf["q_des"][:rows] = plan.q[index]
        self.buf["dq_des"][:rows] = plan.dq[index]


def simulate(
    config: SimConfig,
    observers: Sequence[SimObserver] = (),
    progress: bool = False,
    keep_history: bool = True,
) -> SimResult:
    """Run the closed loop.

    Args:
        config: the run.
        observers: watchers called per chunk (see :class:`SimObserver`).
        progress: draw a progress bar on stderr (for runs over ~2 s of wall time).
        keep_history: keep every signal in the result (off: only the
            statistics and the chunk being written are held, for long
            recorded runs; ``result.t`` is then empty).

    Returns:
        The result; ``status`` says whether it completed.  A divergence or
        Ctrl-C ends the run early with the ticks done so far.  Any other
        error (an observer's, say) is recorded as status ``"error"``, every
        observer still gets :meth:`SimObserver.finish`, and then it is raised.

    """
    setup = build(config)
    runner = Runner(setup)
    n = config.n_ticks
    hist_n = n if keep_history else 0
    history = {name: np.zeros((hist_n, *shape)) for name, (shape, _, _) in SIGNALS.items()}
    result = SimResult(
        config=config,
        t=np.arange(hist_n) * config.dt,
        signals=history,
        belt_speed_mps=config.gait.belt_speed,
        exo_source=setup.exo.source,
        patient_source=setup.patient.source,
        stats=RunStats(EstimateErrorStats(setup.exo, config.dt)),
    )
    for obs in observers:
        obs.start(result)
    bar = Progress(n, "simulate", enabled=progress)
    chunk = runner.chunk
    chunk_start = 0
    row = 0
    k = 0

    def flush(start: int, rows: int) -> None:
        runner.fill_plan(start, rows)
        view = {name: arr[:rows] for name, arr in runner.buf.items()}
        result.stats.update(view)
        if keep_history:
            for name, arr in view.items():
                history[name][start : start + rows] = arr
        first: Exception | None = None
        for obs in observers:  # every observer gets the chunk, whoever fails
            try:
                obs.chunk(result, start, view)
            except Exception as exc:
                first = first or exc
        if first is not None:
            raise first

    def fail(status: str, t: float, message: str) -> None:
        if result.status == "completed":
            result.status = status
            result.error = message
            result.events.append({"t": t, "kind": status, "message": message})

    error: Exception | None = None
    result.stats.preload(runner.buf)
    start_wall = time.perf_counter()
    try:
        for k in range(n):
            runner.tick(k, row)
            if k == UNTIMED_TICKS - 1:
                start_wall = time.perf_counter()
            row += 1
            if row == chunk:
                start, row = chunk_start, 0
                chunk_start += chunk
                flush(start, chunk)
                bar.update(chunk_start)
        k = n
    except SimulationDiverged as exc:
        fail("diverged", exc.time, str(exc))
    except KeyboardInterrupt:
        fail("interrupted", k * config.dt, f"interrupted by the user at t = {k * config.dt:.4f} s")
    except Exception as exc:  # recorded, the observers finish, then it propagates
        fail("error", k * config.dt, f"{type(exc).__name__}: {exc}")
        error = exc
    result.wall_time_s = time.perf_counter() - start_wall
    done = chunk_start + row
    result.timed_ticks = max(done - UNTIMED_TICKS, 0)
    if row:
        try:
            flush(chunk_start, row)
        except Exception as exc:
            fail("error", done * config.dt, f"{type(exc).__name__}: {exc}")
            error = error or exc
    bar.close(done)
    if runner._qp:
        result.qp_failures = runner.setup.controller.failures
    if runner.supervisor is not None:
        result.events.extend(runner.supervisor.events)
        result.safety_state = runner.supervisor.state
    if keep_history and done < n:
        result.t = result.t[:done]
        result.signals = {name: arr[:done] for name, arr in history.items()}
    for obs in observers:
        try:
            obs.finish(result)
        except Exception as exc:
            error = error or exc
    if error is not None:
        raise error
    return result


@kernel
def _log_measured(
    wide: np.ndarray, row: int, state: np.ndarray, readings: np.ndarray, estimates: np.ndarray
) -> None:
    """Columns 0-15 (q, v of both bodies) and 53-80 (readings, estimates) of a log row."""
    for i in range(16):
        wide[row, i] = state[i]
        wide[row, 65 + i] = estimates[i]
    for i in range(12):
        wide[row, 53 + i] = readings[i]


@kernel
def _log_applied(wide: np.ndarray, row: int, u_cmd: np.ndarray, outputs: np.ndarray) -> None:
    """Columns 16-19 (commanded voltage) and 20-43 (the plant's outputs) of a log row."""
    for i in range(4):
        wide[row, 16 + i] = u_cmd[i]
    for i in range(24):
        wide[row, 20 + i] = outputs[i]
