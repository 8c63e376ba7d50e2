"""The sensors of the device and what they read."""

from .belt_encoder import (
    BeltEncoder,
    BeltEncoderParams,
)
from .readings import (
    SensorReadings,
)
from .sensors import (
    SensorParams,
    Sensors,
)

__all__ = [
    "BeltEncoder",
    "BeltEncoderParams",
    "SensorParams",
    "SensorReadings",
    "Sensors",
]
