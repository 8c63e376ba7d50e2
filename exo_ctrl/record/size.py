"""The size of a recording per tick, and the check before a run (:func:`check_writable`).

The file's size per tick is a base (the fixed part, blueprint, parameters,
geometry and footer, spread over the default run's 3600 ticks), a part per
series entity sent (a row a tick: row id, two timelines, list offsets,
values; compressed) and a part per frame of the 3-D scene.  The constants
were fitted to runs of 3600 ticks with 35-55 series (no contact; contact
with the patient's feet and the pelvis on its guide) and a scene at
10-1000 Hz, and match them within 1 % (tests/record/test_writer.py checks
three within 10 %).  Before each value was stored once and the features off
in the run left out (format version 1), the default run wrote 3519 B per
tick.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from pathlib import Path

from .._io import is_special, output_problem
from ..exceptions import RecordingError

__all__ = [
    "BYTES_PER_SCENE_FRAME",
    "BYTES_PER_SERIES_TICK",
    "BYTES_PER_TICK_BASE",
    "BYTES_PER_TICK_ESTIMATE",
    "bytes_per_tick",
    "check_writable",
]

#: B₀, the base [B per tick].
BYTES_PER_TICK_BASE = 425
#: b_s, per series entity sent [B per tick].
BYTES_PER_SERIES_TICK = 29
#: b_f, per frame of the 3-D scene [B].
BYTES_PER_SCENE_FRAME = 870
#: The default run's (37 series, the scene every 20 ticks): 1593 B measured (1484 B
#: with 35 before the estimate's two per-tick error series, issue 31, whose noise
#: compresses less than the fit's series).
BYTES_PER_TICK_ESTIMATE = 1542


def bytes_per_tick(series: int, stride: int) -> int:
    """Estimated file size per tick [B]: ``series`` series entities, a scene frame every ``stride``.

    B₀ + b_s · series + b_f / stride.
    """
    return round(
        BYTES_PER_TICK_BASE + BYTES_PER_SERIES_TICK * series + BYTES_PER_SCENE_FRAME / stride
    )


def check_writable(path: str | os.PathLike[str], n_ticks: int, per_tick: int) -> None:
    """Refuse, before the run, a recording path that cannot be written or lacks the space.

    Args:
        path: the recording.
        n_ticks: ticks the run is planned for.
        per_tick: the file's estimated size per tick [B] (:func:`bytes_per_tick`).

    Raises:
        RecordingError: the check every output of the command line gets
            (:func:`exo_ctrl._io.output_problem`) fails, or a regular
            file's directory has less free space than ``n_ticks · per_tick``.

    """
    problem = output_problem(path)
    if problem is not None:
        raise RecordingError(f"cannot write recording {path}: {problem}")
    if is_special(path):
        return  # a device (/dev/null) or a FIFO: no free-space figure applies
    with contextlib.suppress(OSError):
        free = shutil.disk_usage(Path(path).parent).free
        need = n_ticks * per_tick
        if free < need:
            raise RecordingError(
                f"cannot write recording {path}: about {need / 1e6:.1f} MB needed for "
                f"{n_ticks} ticks, {free / 1e6:.1f} MB free"
            )
