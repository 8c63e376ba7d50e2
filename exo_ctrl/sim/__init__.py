"""The closed loop: configuration, the tick, the log and the run summary."""

from .loop import (
    SIGNALS,
    Runner,
    Setup,
    SimConfig,
    SimObserver,
    SimResult,
    build,
    drive_for,
    simulate,
    start_on_plan,
)
from .summary import (
    RunStats,
)

__all__ = [
    "SIGNALS",
    "RunStats",
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
