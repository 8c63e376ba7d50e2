"""Rerun recordings of runs: blueprint, writer, reader."""

from .recorder import (
    FORCE_ARROW_M_PER_N,
    RECORDING_FORMAT,
    RerunRecorder,
    blueprint_views,
    make_blueprint,
    read_recording,
)

__all__ = [
    "FORCE_ARROW_M_PER_N",
    "RECORDING_FORMAT",
    "RerunRecorder",
    "blueprint_views",
    "make_blueprint",
    "read_recording",
]
