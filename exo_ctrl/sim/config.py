"""What defines a run: :class:`SimConfig`, composed of the packages' own parameters."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any

from .. import _validate as v
from ..control import PDGains
from ..estimation import DEFAULT_GAIN_PER_S
from ..exceptions import InvalidParameter
from ..plan import GaitParams
from ..plant import PATIENT_TORQUES, CuffParams, MotorParams
from ..safety import SafetyLimits
from ..sensing import SensorParams

__all__ = ["CONTROLLERS", "SimConfig"]

CONTROLLERS = ("pd", "ct", "qp")


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
