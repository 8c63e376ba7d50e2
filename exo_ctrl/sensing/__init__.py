"""The sensors of the device and what they read."""

from .belt_encoder import (
    BeltEncoder,
    BeltEncoderParams,
)
from .current_sensor import (
    CurrentSensor,
    CurrentSensorParams,
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
    "CurrentSensor",
    "CurrentSensorParams",
    "SensorParams",
    "SensorReadings",
    "Sensors",
]
