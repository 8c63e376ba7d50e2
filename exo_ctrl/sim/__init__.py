"""The closed loop: configuration, the tick, the log schema and the run summary."""

from .config import CONTROLLERS, SimConfig
from .loop import simulate
from .result import SimObserver, SimResult
from .schema import SIGNALS, Signal, log_dtype, signal_shapes
from .setup import Setup, build, drive_for, start_on_plan
from .summary import RunStats
from .tick import UNTIMED_TICKS, Runner

__all__ = [
    "CONTROLLERS",
    "SIGNALS",
    "UNTIMED_TICKS",
    "RunStats",
    "Runner",
    "Setup",
    "Signal",
    "SimConfig",
    "SimObserver",
    "SimResult",
    "build",
    "drive_for",
    "log_dtype",
    "signal_shapes",
    "simulate",
    "start_on_plan",
]
