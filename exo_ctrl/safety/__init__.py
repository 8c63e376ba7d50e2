"""The safety supervisor: limits, monitors and the controlled stop.

- :mod:`.limits`: what is allowed (:class:`SafetyLimits`) and its resolution
  against the models and the drive;
- :mod:`.monitor`: the compiled per-tick monitor (which channel exceeds its
  limit, by how much) and its record;
- :mod:`.plausibility`, :mod:`.consistency`, :mod:`.still`, :mod:`.belt_monitor`:
  whether the readings can be true (drive model, encoder step, stuck sensor, command
  age; the torque sensor against the drive's current and the encoder; a still
  encoder against the current a still winding draws; the belt's measured speed
  against the speed its drive's and the feet's forces predict);
- :mod:`.stop_reaction`: how the stop ends: ``hold`` the posture or
  ``yield`` to an active patient (gravity compensation and damping), and
  the default per interaction mode;
- :mod:`.supervisor`: :class:`SafetySupervisor`, the state machine and the
  controlled stop (hold or yield with gravity compensation, ramp, power
  cut), events.
"""

from .limits import (
    CURRENT_LIMIT_FACTOR,
    ISO_TS_15066_CUFF_FORCE_N,
    STATES,
    ResolvedLimits,
    SafetyLimits,
    resolve_limits,
)
from .monitor import MONITOR_FIELDS, Channel, channels, monitor, monitor_record
from .stop_reaction import (
    STOP_REACTIONS,
    default_stop_reaction,
    stop_reaction_schedule,
    yield_damping,
)
from .supervisor import SafetySupervisor

__all__ = [
    "CURRENT_LIMIT_FACTOR",
    "ISO_TS_15066_CUFF_FORCE_N",
    "MONITOR_FIELDS",
    "STATES",
    "STOP_REACTIONS",
    "Channel",
    "ResolvedLimits",
    "SafetyLimits",
    "SafetySupervisor",
    "channels",
    "default_stop_reaction",
    "monitor",
    "monitor_record",
    "resolve_limits",
    "stop_reaction_schedule",
    "yield_damping",
]
