"""The sensors of the device and what they read."""

from .belt_encoder import (
    BeltEncoder,
    BeltEncoderParams,
)
from .cuff_load import (
    CuffSensorParams,
    CuffSensors,
)
from .current_sensor import (
    CurrentSensor,
    CurrentSensorParams,
)
from .device import (
    DeviceSensors,
)
from .foot_load import (
    FootLoad,
    FootLoadParams,
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
    "CuffSensorParams",
    "CuffSensors",
    "CurrentSensor",
    "CurrentSensorParams",
    "DeviceSensors",
    "FootLoad",
    "FootLoadParams",
    "SensorParams",
    "SensorReadings",
    "Sensors",
]
