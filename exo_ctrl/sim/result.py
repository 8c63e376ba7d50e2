"""What a run gives: its time series and outcome, and the observers that watch it."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from .._version import __version__
from .config import SimConfig
from .scenario_file import scenario_toml
from .summary import RunStats

__all__ = ["SimObserver", "SimResult"]


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
        events: violations, e-stops and the run's end (t, kind, message, ...).
        safety_state: the supervisor's final state.
        qp_failures: the QP's fallbacks.
        cuff_bound_margin_N: the QP's largest margin per cuff after the
            estimator's start-up (:mod:`exo_ctrl.control.qp.margin`) [N], (4,);
            None for another controller.
        energy: the drives' energy books (:func:`exo_ctrl.plant.energy.energy_report`):
            ``energy_J`` per joint and ``energy_balance_residual_rel``.
        warnings: what to know before trusting the figures, one sentence each
            (a device that does not fit its patient; :attr:`~exo_ctrl.sim.Setup.warnings`).
        notes: what the run does that its user should know, one sentence each
            (the QP's departure stop over the belt; :attr:`~exo_ctrl.sim.Setup.notes`).

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
    cuff_bound_margin_N: np.ndarray | None = None
    energy: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
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
        """The run's figures (JSON-able); keys in :meth:`RunStats.summary`.

        Also ``warnings`` (:attr:`warnings`), ``notes`` (:attr:`notes`), ``version``
        (exo_ctrl's) and ``scenario``: the complete scenario file of the run, values only
        (:func:`~exo_ctrl.sim.scenario_file.scenario_toml`), which
        ``exo-ctrl simulate`` runs again to the same figures.
        """
        out = self.stats.summary(self)
        out["warnings"] = list(self.warnings)
        out["notes"] = list(self.notes)
        out["version"] = __version__
        out["scenario"] = scenario_toml(self.config, comments=False)
        return out
