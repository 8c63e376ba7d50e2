"""The size of a recording per tick, for the free-space check of :class:`~.writer.RerunRecorder`.

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

__all__ = [
    "BYTES_PER_SCENE_FRAME",
    "BYTES_PER_SERIES_TICK",
    "BYTES_PER_TICK_BASE",
    "BYTES_PER_TICK_ESTIMATE",
    "bytes_per_tick",
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
