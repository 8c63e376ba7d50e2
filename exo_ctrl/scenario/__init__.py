"""Scenario files: a run described by one TOML file, and the presets shipped with the package.

A scenario's sections mirror :class:`~exo_ctrl.sim.SimConfig`'s parts
(:mod:`exo_ctrl.sim.scenario_file`) plus ``[recording]``
(:class:`RecordingParams`).  ``exo-ctrl scenario --preset NAME --out FILE``
writes a complete, commented file to edit; ``exo-ctrl simulate FILE`` runs it.
"""

from .load import (
    DEFAULT_PRESET,
    RecordingParams,
    Scenario,
    load_scenario,
    preset,
    scenario_template,
)
from .presets import PRESETS, preset_description, preset_text

__all__ = [
    "DEFAULT_PRESET",
    "PRESETS",
    "RecordingParams",
    "Scenario",
    "load_scenario",
    "preset",
    "preset_description",
    "preset_text",
    "scenario_template",
]
