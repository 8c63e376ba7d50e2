"""What defines a run: :class:`SimConfig`, composed of the packages' own parameters."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

from .. import _validate as v
from ..control import PDGains
from ..estimation import DEFAULT_GAIN_PER_S
from ..exceptions import InvalidParameter
from ..plan import PLAN_BYTES_PER_SAMPLE, GaitParams
from ..plant import PATIENT_TORQUES, CuffParams, EndStopParams, MotorParams
from ..safety import SafetyLimits
from ..sensing import SensorParams
from .schema import log_dtype

__all__ = [
    "CHUNK_ROW_BYTES",
    "CONTROLLERS",
    "HISTORY_BYTES_PER_TICK",
    "PLAN_ROW_BYTES",
    "SimConfig",
]

CONTROLLERS = ("pd", "ct", "qp")

#: Memory per row of a run's joint plan [bytes]: its time (8 B), the plan
#: (:data:`~exo_ctrl.plan.PLAN_BYTES_PER_SAMPLE`) and the computed-torque
#: tables of feedforward torque and voltage (4 + 4 numbers).
PLAN_ROW_BYTES = 8 + PLAN_BYTES_PER_SAMPLE + 2 * 4 * 8

#: Memory per row of the log chunk [bytes]: the log row (every signal of
#: :mod:`exo_ctrl.sim.schema`) and, when the planned rows are copied into it,
#: their index and the planned angles and speeds (1 + 4 + 4 numbers).
CHUNK_ROW_BYTES = log_dtype().itemsize + (1 + 2 * 4) * 8

#: Memory per tick of a run's history, kept by
#: :func:`~exo_ctrl.sim.simulate` unless ``keep_history`` is off [bytes]:
#: every signal, the tick time and the tick index it is computed from.
HISTORY_BYTES_PER_TICK = log_dtype().itemsize + 2 * 8


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
        end_stops: the exoskeleton joints' hard stops at the URDF limits
            (:mod:`exo_ctrl.plant.end_stops`).
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
        estop_at_s: emergency stop at this time [s] (None: none); at most
            the time of the last control tick, (n_ticks - 1) Δt.

    The arrays a run allocates from these numbers (the plan, the log chunk)
    are checked against the memory cap
    (:data:`~exo_ctrl._validate.MAX_ALLOCATION_BYTES`) when the configuration
    is made; the history kept by :func:`~exo_ctrl.sim.simulate` by
    :meth:`check_history`.

    """

    gait: GaitParams = field(default_factory=GaitParams)
    exo: str | None = None
    patient: str | None = None
    controller: str = "pd"
    gains: PDGains = field(default_factory=PDGains)
    motor: MotorParams = field(default_factory=MotorParams)
    cuffs: CuffParams = field(default_factory=CuffParams)
    end_stops: EndStopParams = field(default_factory=EndStopParams)
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
            self._check_estop()
        self._check_plan_size()
        chunk = min(self.chunk_ticks, max(self.n_ticks, 1))
        v.allocation(
            "chunk_ticks",
            self.chunk_ticks,
            chunk,
            CHUNK_ROW_BYTES,
            what="log chunk rows",
            limit="smaller",
        )

    def _check_estop(self) -> None:
        """Refuse an e-stop time no control tick reaches (it would be ignored)."""
        v.non_negative("estop_at", self.estop_at_s, "s")
        last = (self.n_ticks - 1) * self.dt  # the time of the last tick, as the loop has it
        if self.estop_at_s <= last:
            return
        if self.n_ticks == 0:
            raise InvalidParameter(
                "estop_at", self.estop_at_s, "unset", f"a {self.duration_s:g} s run has no tick"
            )
        raise InvalidParameter(
            "estop_at",
            self.estop_at_s,
            f"in [0, {last:g}] s, within the run",
            f"the run lasts {self.duration_s:g} s; its last control tick is at t = {last:g} s",
        )

    def _check_plan_size(self) -> None:
        """Refuse a plan beyond the memory cap, naming the period or the duration."""
        rows = self.plan_rows
        most = v.max_items(PLAN_ROW_BYTES)
        rate = self.control_rate_hz
        if self.plan_periodic and rows < self.n_ticks + 1:
            name, value = "period", self.gait.period
            limit, note = f"at most {most / rate:.4g} s at {rate:g} Hz", "the plan holds one period"
        else:
            name, value = "duration", self.duration_s
            limit = f"at most {(most - 1) / rate:.4g} s at {rate:g} Hz"
            note = (
                "the plan holds every tick"
                if self.plan_periodic
                else (
                    "the plan holds every tick, as the period "
                    f"{self.gait.period:g} s is not a whole number of {1e3 * self.dt:g} ms ticks"
                )
            )
        v.allocation(name, value, rows, PLAN_ROW_BYTES, what="plan rows", limit=limit, note=note)

    @property
    def plan_periodic(self) -> bool:
        """Whether the gait period is a whole number P ≥ 2 of control ticks."""
        period = self.gait.period / self.dt
        p = round(period)
        return p >= 2 and abs(p - period) <= 1e-9 * period

    @property
    def plan_rows(self) -> int:
        """Rows of the joint plan: one gait period if it is a whole number of ticks.

        The gait is periodic, so tick k uses row k mod P; with P = T_s / Δt an
        integer (1200 for the default 1.2 s at 1 kHz) the plan's memory does
        not grow with the run's length.  Otherwise the plan covers every tick.
        """
        if self.plan_periodic:
            return min(round(self.gait.period / self.dt), self.n_ticks + 1)
        return self.n_ticks + 1

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
        """Plain-data form (JSON-able), for summaries and recordings."""
        return asdict(self)
