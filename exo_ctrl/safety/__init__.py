"""The safety supervisor: limits, monitors and the controlled stop."""

from .supervisor import (
    STATES,
    SafetyLimits,
    SafetySupervisor,
)

__all__ = [
    "STATES",
    "SafetyLimits",
    "SafetySupervisor",
]
