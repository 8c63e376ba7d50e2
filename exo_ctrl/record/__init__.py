"""Rerun recordings of runs: the layout, the default blueprint, the writer, the reader.

- :mod:`.format`: the entity hierarchy, the timelines and the
  series derived from the log schema (:mod:`exo_ctrl.sim.schema`).
- :mod:`.blueprint`: the viewer's default layout.
- :mod:`.scene`: the 3-D scene (both bodies' legs, cuff
  forces, belt, planned foot paths).
- :mod:`.writer`: :class:`RerunRecorder`, the observer that
  writes a run as it goes (:mod:`.columns`: a chunk's series;
  :mod:`.omitted`: the signals of the features off in the run, left out;
  :mod:`.outcome`: the events and the outcome at the end; :mod:`.size`: the
  file's size per tick, for the free-space check).
- :mod:`.rrd_file`, :mod:`.rrd_footer`, :mod:`.write_process`: the file
  itself, written from rerun's in-memory encoding with a footer after
  every chunk, by a process of its own (so that SIGKILL cannot cut it).
- :mod:`.reader`: :func:`read_recording`, the run back from a file
  (:mod:`.stored`: each signal from the entities that store it).
- :mod:`.sizing_plot`: the drives' torque-speed operating points
  against their limits (a PNG).
- :mod:`.estimate`: cuff-force estimation along a recording
  or a CSV log (``exo-ctrl estimate``).
- :mod:`.export`: a recording's time series (or an estimate's) as a CSV
  or Parquet table, columns named from the log schema with their units
  (``exo-ctrl export``).

Nothing in the library below imports this package; the public face
(:mod:`exo_ctrl`), the command line and the tools do.
"""

from .blueprint import blueprint_views, make_blueprint
from .estimate import OfflineEstimate, estimate_file, write_estimate_recording
from .format import FORCE_ARROW_M_PER_N, FORMAT_VERSION, RECORDING_FORMAT
from .reader import read_recording
from .writer import DEFAULT_SCENE_RATE_HZ, RerunRecorder

__all__ = [
    "DEFAULT_SCENE_RATE_HZ",
    "FORCE_ARROW_M_PER_N",
    "FORMAT_VERSION",
    "RECORDING_FORMAT",
    "OfflineEstimate",
    "RerunRecorder",
    "blueprint_views",
    "estimate_file",
    "make_blueprint",
    "read_recording",
    "write_estimate_recording",
]
