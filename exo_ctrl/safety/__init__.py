"""The safety supervisor: limits, monitors and the controlled stop.

- :mod:`.limits`: what is allowed (:class:`SafetyLimits`) and its resolution
  against the models and the drive;
- :mod:`.monitor`: the compiled per-tick monitor (which channel exceeds its
  limit, by how much) and its record;
- :mod:`.plausibility`, :mod:`.belt_monitor`: whether the readings can be
  true (drive model, encoder step, stuck sensor, command age; the belt's
  measured speed against its set speed);
- :mod:`.supervisor`: :class:`SafetySupervisor`, the state machine and the
  controlled stop (hold with gravity compensation, ramp, power cut), events.
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
from .supervisor import SafetySupervisor

__all__ = [
    "CURRENT_LIMIT_FACTOR",
    "ISO_TS_15066_CUFF_FORCE_N",
    "MONITOR_FIELDS",
    "STATES",
    "Channel",
    "ResolvedLimits",
    "SafetyLimits",
    "SafetySupervisor",
    "channels",
    "monitor",
    "monitor_record",
    "resolve_limits",
]
