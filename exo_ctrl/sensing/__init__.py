"""The sensors of the device and what they read."""

from .readings import (
    SensorReadings,
)
from .sensors import (
    SensorParams,
    Sensors,
)

__all__ = [
    "SensorParams",
    "SensorReadings",
    "Sensors",
]
