"""Writing a run to a rerun ``.rrd`` file while it goes: :class:`RerunRecorder`.

The recorder is a :class:`~exo_ctrl.sim.SimObserver`.  Per chunk of rows it
packs every signal of the log schema into one float64 vector
(:class:`~.format.Layout`), sends each entity with one
``send_columns`` call (no per-tick ``rr.log``), the 3-D scene at the scene
rate only, and the time series at every tick.  The entity hierarchy is in
:mod:`.format`.

Failure safety.  The file is written in place at its final path, not to a
temporary file renamed at the end: rerun streams each chunk to the file as it
is sent, so a crash (even SIGKILL or ``os._exit``) leaves, at the path the
user asked for, a file readable with every chunk flushed before it.  A temp
file would hide that data under another name, and a run that never reaches
:meth:`~RerunRecorder.finish` would never rename it.  The costs: a previous
recording at the same path is replaced as soon as the run starts, and a file
cut by a crash has no footer (``rerun rrd verify`` rejects it; the viewer and
:func:`~.reader.read_recording` read it).  When :meth:`~RerunRecorder.chunk`
returns, the chunk's exact signals (``raw/``) and its 3-D scene are on disk
(flushed); its human-friendly series (``signals/``, copies of the same
values) are sent after that flush and written by rerun's own threads while
the loop runs on, and are on disk by the next chunk's flush or by
:meth:`~RerunRecorder.finish`.  So a hard crash loses at most the series of
the last chunk, never a signal.  Every way a run ends (normal end,
divergence, Ctrl-C, an error in the loop or in an observer) reaches
:meth:`~RerunRecorder.finish`, which logs the events and the outcome and
writes the footer.

Speed.  Measured here (rerun 0.41, 2 cores), a 2000-tick chunk of the
default run costs the loop about 10-11 ms: rerun's own work per entity and
chunk (about 40 µs at 2000 rows, in the calling thread) for the 61 entities
logged every tick and the 17 of the scene, about 3 ms waiting for the
exact signals to be flushed, and about 2 ms packing and computing the scene
(batched forward kinematics).  Writing the series after the flush keeps
their encoding and writing (about 4-6 ms more) off the loop's path.

Memory.  The recorder keeps no rows between chunks: it packs the chunk it is
given into arrays of pyarrow's memory pool, sends them, and rerun frees them
once written (at most about two chunks' worth in flight).  Rerun's file
sink, however, keeps an index entry per written rerun chunk for the file
footer (about 2 kB per entity and chunk, measured with rerun 0.41), so a
process recording a long run grows by about 0.15 MB per recorded chunk (0.08
MB per simulated second with the default 2000-tick chunks); larger
``chunk_ticks`` shrink that.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import shutil
import sys
import threading
import warnings
from pathlib import Path
from typing import NoReturn

import numpy as np
import rerun as rr

from .._io import is_special, output_problem
from ..exceptions import InvalidParameter, RecordingError
from ..model import BodyModel, load_body, load_patient
from ..sim import SimResult
from .blueprint import make_blueprint
from .columns import SignalColumns
from .format import (
    FORCE_ARROW_M_PER_N,
    FORMAT_VERSION,
    NOT_IN_OUTCOME,
    RECORDING_FORMAT,
    TICK,
    TIME,
    dumps,
    layout,
    params_markdown,
)
from .scene import Skeleton, log_scene_static, send_scene

__all__ = ["DEFAULT_SCENE_RATE_HZ", "RerunRecorder", "find_viewer", "spawn_viewer"]

#: Default rate of the 3-D scene [Hz]: a display rate, far below the control rate.
DEFAULT_SCENE_RATE_HZ = 50.0
#: Estimated file size per tick [B], for the free-space check: the default
#: run (2400 ticks at 1 kHz, 3-D scene at 50 Hz) writes 6.03 MB, 2514 B per
#: tick with the fixed part (blueprint, parameters, geometry) spread over it;
#: 4800 ticks write 11.71 MB (2363 B per tick beyond the first 2400).
BYTES_PER_TICK_ESTIMATE = 2500
#: Longest wait for a flush to reach the disk [s].  A flush of a 2000-tick
#: chunk (about 4 MB) normally takes milliseconds; after a write error (disk
#: full) rerun 0.41's flush blocks until this timeout, or without one forever,
#: and then raises, which becomes a RecordingError.
FLUSH_TIMEOUT_S = 10.0
#: Longest wait for closing a file whose writing failed [s] (see close()).
CLOSE_AFTER_FAILURE_S = 2.0

#: TextLog level of an event or final status by kind.
_LEVELS = {
    "completed": "INFO",
    "diverged": "ERROR",
    "interrupted": "WARN",
    "error": "ERROR",
    "violation": "WARN",
    "estop": "WARN",
    "state": "INFO",
}


def find_viewer() -> Path | None:
    """The rerun viewer executable: the one installed with rerun-sdk, else one on PATH.

    rerun-sdk installs ``rerun`` next to the Python interpreter
    (``.venv/bin/rerun``), which is not on PATH unless the environment is
    activated; that one is looked for first.
    """
    beside = Path(sys.executable).parent / ("rerun.exe" if os.name == "nt" else "rerun")
    if beside.is_file() and os.access(beside, os.X_OK):
        return beside
    found = shutil.which("rerun")
    return Path(found) if found else None


def spawn_viewer(rec: rr.RecordingStream) -> str | None:
    """Start the rerun viewer :func:`find_viewer` finds, listening for ``rec``.

    Returns:
        None when it started, else why not, in one line.

    """
    viewer = find_viewer()
    if viewer is None:
        return (
            f"no rerun viewer found (neither {Path(sys.executable).parent / 'rerun'} nor "
            "'rerun' on PATH; it comes with rerun-sdk)"
        )
    try:
        rr.spawn(connect=False, executable_path=str(viewer), recording=rec)
    except (RuntimeError, OSError) as exc:
        return f"could not start the rerun viewer {viewer}: {' '.join(str(exc).split())}"
    return None


class RerunRecorder:
    """Writes a run to a rerun ``.rrd`` file as it goes (a SimObserver).

    Args:
        path: the ``.rrd`` file to write (replaced if it exists).
        spawn: also stream to a rerun viewer started for the purpose.
        app_id: rerun application id.
        scene_rate_hz: rate of the 3-D scene [Hz] (the ticks k with k mod
            round(f_ctrl / f_scene) = 0, at least every tick); the time
            series are logged at every tick whatever it is.

    Raises:
        InvalidParameter: scene_rate_hz is not a finite rate > 0.
        RecordingError: from :meth:`start` when the file cannot be created
            (missing or read-only directory, not enough free space), and from
            :meth:`chunk` / :meth:`finish` when writing fails (disk full).

    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        spawn: bool = False,
        app_id: str = "exo_ctrl",
        scene_rate_hz: float = DEFAULT_SCENE_RATE_HZ,
    ) -> None:
        ok = isinstance(scene_rate_hz, (int, float)) and not isinstance(scene_rate_hz, bool)
        if not (ok and math.isfinite(scene_rate_hz) and scene_rate_hz > 0):
            raise InvalidParameter("scene_rate", scene_rate_hz, "a finite rate > 0 Hz")
        self.path = Path(path)
        self.spawn = bool(spawn)
        self.app_id = str(app_id)
        self.scene_rate_hz = float(scene_rate_hz)
        self._rec: rr.RecordingStream | None = None
        self._failed = False
        self._next_tick = 0
        self._dt = 0.0
        self._stride = 1
        self._columns = SignalColumns(layout({}))
        self._bodies: tuple[tuple[str, Skeleton, str], ...] = ()
        self._belt: dict[str, float] = {}

    # ------------------------------------------------------------------ protocol

    def start(self, result: SimResult) -> None:
        """Open the file, write the blueprint, parameters and static geometry."""
        if self._rec is not None:
            raise RecordingError(f"recorder for {self.path} is already recording a run")
        config = result.config
        self._check_writable(config.n_ticks)
        self._failed = False
        self._next_tick = 0
        self._dt = config.dt
        self._stride = max(1, round(config.control_rate_hz / self.scene_rate_hz))
        self._columns = SignalColumns(layout())  # the log schema as it is now
        self._columns.prepare(min(config.chunk_ticks, max(config.n_ticks, 1)))  # the loop's chunks
        exo = load_body(result.exo_source, name="exoskeleton")
        patient = load_patient(config.patient)
        hip_e, hip_p = exo.legs["left"].hip_xz, patient.legs["left"].hip_xz
        offset = (hip_e[0] - hip_p[0], hip_e[1] - hip_p[1])
        self._bodies = (
            ("exo", Skeleton(exo), "q"),
            ("patient", Skeleton(patient, offset), "q_patient"),
        )
        rec = rr.RecordingStream(self.app_id)
        blueprint = make_blueprint()
        try:
            if self.spawn and self._spawn_viewer(rec):
                sinks = (rr.FileSink(str(self.path)), rr.GrpcSink())
                rec.set_sinks(*sinks, default_blueprint=blueprint)
            else:
                rec.save(self.path, default_blueprint=blueprint)
        except (RuntimeError, OSError) as exc:
            raise RecordingError(f"cannot write recording {self.path}: {exc}") from None
        self._rec = rec
        try:
            rec.send_recording_name(self.path.stem)
            self._log_static(result, exo, offset)
            rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
        except (RuntimeError, OSError) as exc:
            # The loop never calls finish() when start() fails: close here.
            self._failed = True
            self.close()
            self._fail(exc)

    def chunk(self, result: SimResult, start: int, rows: dict[str, np.ndarray]) -> None:
        """Log rows ``start:start+n`` of every signal.

        The exact signals and the 3-D scene are flushed to disk before this
        returns; the series follow in the background (module docstring).
        Rows already logged are skipped, so a chunk handed over twice is
        logged once.

        Raises:
            RecordingError: writing failed, or ``rows`` lacks a signal of
                the log schema.

        """
        rec = self._rec
        if rec is None or self._failed:
            return
        total = int(next(iter(rows.values())).shape[0])
        skip = max(0, self._next_tick - start)
        if skip >= total:
            return
        n = total - skip
        columns = self._columns
        try:
            source, values = columns.pack(rows, skip, n)
        except RecordingError as exc:
            self._fail(exc)
        ticks = np.arange(start + skip, start + total, dtype=np.int64)
        try:
            columns.send_raw(rec, ticks, self._dt, values)
            self._send_scene(rec, ticks, source, n, result.belt_speed_mps)
            rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
            columns.send_series(rec, ticks, self._dt, source)  # written in the background
        except (RuntimeError, OSError) as exc:
            self._fail(exc)
        self._next_tick = start + total

    def finish(self, result: SimResult) -> None:
        """Log the events and the outcome, then close the file (writes its footer)."""
        rec = self._rec
        if rec is None:
            return
        error: BaseException | None = None
        try:
            if not self._failed:
                self._log_outcome(rec, result)
                rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
        except (RuntimeError, OSError) as exc:
            error = exc
            self._failed = True
        finally:
            self.close()
        if error is not None:
            self._fail(error)

    def close(self) -> None:
        """Flush and close the file (writes the footer); safe to call more than once.

        After a write failure rerun's file writer is dead and closing can block
        (seen with rerun 0.41), so then the close runs in a helper thread that
        is waited for at most CLOSE_AFTER_FAILURE_S.
        """
        rec, self._rec = self._rec, None
        if rec is None:
            return

        def shut() -> None:
            with contextlib.suppress(RuntimeError, OSError):
                rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
            with contextlib.suppress(RuntimeError, OSError):
                rec.disconnect()

        if not self._failed:
            shut()
            return
        closer = threading.Thread(target=shut, name="rerun-recorder-close", daemon=True)
        closer.start()
        closer.join(CLOSE_AFTER_FAILURE_S)

    # ------------------------------------------------------------------ checks

    def _spawn_viewer(self, rec: rr.RecordingStream) -> bool:
        """Start a viewer to stream to; on failure warn and record to the file only."""
        problem = spawn_viewer(rec)
        if problem is not None:
            warnings.warn(f"{problem}; recording to {self.path} only", RuntimeWarning, stacklevel=4)
            return False
        return True

    def _fail(self, exc: BaseException) -> NoReturn:
        """Mark the recording failed and raise RecordingError with the path and reason."""
        self._failed = True
        reason = str(exc)
        with contextlib.suppress(OSError):
            free = shutil.disk_usage(self.path.parent).free
            if free < 1 << 20:
                reason += f"; the disk is full ({free} B free)"
        raise RecordingError(
            f"writing recording {self.path} failed after tick {self._next_tick}: {reason} "
            "(the ticks flushed before remain readable)"
        ) from None

    def _check_writable(self, n_ticks: int) -> None:
        path = self.path
        parent = path.parent
        problem = output_problem(path)  # the check every output of the command line gets
        if problem is not None:
            raise RecordingError(f"cannot write recording {path}: {problem}")
        if is_special(path):
            return  # a device (/dev/null) or a FIFO: no free-space figure applies
        with contextlib.suppress(OSError):
            free = shutil.disk_usage(parent).free
            need = n_ticks * BYTES_PER_TICK_ESTIMATE
            if free < need:
                raise RecordingError(
                    f"cannot write recording {path}: about {need / 1e6:.1f} MB needed for "
                    f"{n_ticks} ticks, {free / 1e6:.1f} MB free"
                )

    # ------------------------------------------------------------------ static

    def _log_static(self, result: SimResult, exo: BodyModel, offset: tuple[float, float]) -> None:
        rec = self._rec
        if rec is None:
            return
        config = result.config
        meta = {
            "format": RECORDING_FORMAT,
            "version": FORMAT_VERSION,
            "config": config.to_dict(),
            "dt": config.dt,
            "n_ticks_planned": config.n_ticks,
            "belt_speed_mps": result.belt_speed_mps,
            "exo_source": result.exo_source,
            "patient_source": result.patient_source,
            "patient_offset_xz": list(offset),
            "decimate_3d_ticks": self._stride,
            "scene_rate_hz": self.scene_rate_hz,
            "force_arrow_m_per_N": FORCE_ARROW_M_PER_N,
            "signals": {name: list(shape) for name, shape in self._columns.layout.shapes.items()},
        }
        text = rr.TextDocument(dumps(meta), media_type=rr.MediaType.TEXT)
        rec.log("raw/meta", text, static=True, strict=True)
        markdown = rr.TextDocument(params_markdown(result, meta), media_type=rr.MediaType.MARKDOWN)
        rec.log("params", markdown, static=True, strict=True)
        for series in self._columns.layout.series:  # legend names and colours of the time series
            lines = rr.SeriesLines(names=series.names, colors=series.colors)
            rec.log(series.entity, lines, static=True, strict=True)
        self._belt = log_scene_static(rec, config.gait, exo)

    # ------------------------------------------------------------------ per chunk

    def _send_scene(
        self, rec: rr.RecordingStream, ticks: np.ndarray, source: np.ndarray, n: int, v: float
    ) -> None:
        picked = np.arange((-int(ticks[0])) % self._stride, n, self._stride)
        if picked.shape[0] == 0:
            return
        signal = self._columns.signal
        bodies = tuple(
            (b, skeleton, signal(source, n, q)[picked]) for b, skeleton, q in self._bodies
        )
        shown = ticks[picked]
        force = signal(source, n, "cuff_force")[picked]
        send_scene(rec, shown, self._dt, bodies, force, self._belt, v)

    # ------------------------------------------------------------------ end

    def _log_outcome(self, rec: rr.RecordingStream, result: SimResult) -> None:
        ticks, dt = self._next_tick, self._dt
        events = [dict(ev) for ev in result.events]
        for ev in events:
            kind = str(ev.get("kind", "event"))
            t = ev.get("t")
            if not (isinstance(t, (int, float)) and math.isfinite(t)):
                t = ticks * dt
            text = f"{kind}: {ev.get('message', '')}"
            self._log_event(rec, t, text, str(ev.get("level", _LEVELS.get(kind, "INFO"))))
        text = f"run {result.status}: {ticks} of {result.config.n_ticks} ticks recorded"
        text += f", t = {ticks * dt:.4f} s" + (f"; {result.error}" if result.error else "")
        self._log_event(rec, ticks * dt, text, _LEVELS.get(result.status, "ERROR"))
        outcome = {
            f.name: getattr(result, f.name)
            for f in dataclasses.fields(result)
            if f.name not in NOT_IN_OUTCOME
        }
        outcome.update(events=events, ticks=ticks)
        document = rr.TextDocument(dumps(outcome), media_type=rr.MediaType.TEXT)
        rec.log("raw/outcome", document, static=True, strict=True)

    def _log_event(self, rec: rr.RecordingStream, t: float, text: str, level: str) -> None:
        rec.set_time(TIME, duration=t)
        rec.set_time(TICK, sequence=max(0, round(t / self._dt)))
        rec.log("events", rr.TextLog(text, level=level), strict=True)
