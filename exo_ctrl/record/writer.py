"""Writing a run to a rerun ``.rrd`` file while it goes: :class:`RerunRecorder`.

The recorder is a :class:`~exo_ctrl.sim.SimObserver`.  Per chunk of rows it
copies the components of every series straight from the rows into one
float64 vector (:class:`~.columns.SignalColumns`), sends each entity with
one ``send_columns`` call (no per-tick ``rr.log``), the 3-D scene at the
scene rate only, and the time series at every tick.  Each value is stored
once, and the signals of the features off in the run are left out
(:mod:`.omitted`); the entity hierarchy is in :mod:`.format`.

Failure safety.  Rerun encodes the recording into memory (a
``BinaryStream``, no file sink of its own); after :meth:`start`, each
:meth:`~RerunRecorder.chunk` and :meth:`~RerunRecorder.finish` the recorder
takes what rerun encoded and writes it to the file itself, whole messages
followed by a footer for the whole file (:class:`~.rrd_file.RrdFile`, through
a small writer process of its own).  So after each write the file is a
complete recording that ``rerun rrd verify`` accepts, whatever happens
next, SIGKILL of this process included (:mod:`.rrd_file` says what can
still cut a write).  By default a chunk is written in a helper thread while
the loop simulates the next one (``write_behind``): it is on disk, with its
series ``signals/`` and its 3-D scene, by the
time the next chunk is handed over, :meth:`~RerunRecorder.sync` or
:meth:`~RerunRecorder.finish` returns, so a hard kill loses at most the
chunk being written; with ``write_behind=False`` it is on disk when
:meth:`~RerunRecorder.chunk` returns.  The file is ``NAME.partial.rrd``
while the run goes, renamed over ``NAME.rrd`` once the run has ended,
unless it was interrupted (Ctrl-C, SIGTERM): a previous recording is never
cut, and a killed run leaves the partial file (:attr:`~RerunRecorder.written`
names it; :mod:`.rrd_file`).  A write error (disk full) is an
``OSError`` of the recorder's, raised as an
:class:`~exo_ctrl.exceptions.OutputError` naming the path and the ticks the
file keeps (the failed write is undone: the file is whole up to them);
nothing of rerun's is left writing to a failed file, so the process also
exits cleanly.  Every way a run ends (normal end, divergence, Ctrl-C,
SIGTERM, an error in the loop or in an observer) reaches
:meth:`~RerunRecorder.finish`, which logs the events and the outcome.

Speed.  Measured here (rerun 0.41, 2 shared cores, CT, default run), a
2000-tick chunk costs the loop's thread 5 ms of CPU (8-10 ms wall, loaded):
55-90 µs per ``send_columns`` call (35 series, 15 scene entities), the copy
(1 ms), the scene's kinematics; the helper thread 12-18 ms (encoding 9-11
ms, footer 3-6 ms), the writer process 2 ms.
Rerun's cost is per entity and row (36 B of row id and timelines against 8
B a value).  While the helper runs, the loop runs at about half speed on a
loaded machine (the helper takes the interpreter lock back, 1-3 ms each
time): 20 ms of the loop's time per chunk.

Memory.  No rows are kept between chunks (copied to pyarrow, sent, freed
once encoded and written); what grows is the footer's index, about 50 rows
of a few hundred bytes per chunk (larger ``chunk_ticks`` shrink it).
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import queue
import shutil
import threading
import warnings
from pathlib import Path
from typing import NoReturn

import numpy as np
import rerun as rr

from .._io import is_special
from .._version import __version__
from ..exceptions import InvalidParameter, OutputError, RecordingError
from ..model import BodyModel, load_body, load_patient
from ..scenario.load import RecordingParams
from ..sim import SimResult
from .blueprint import make_blueprint
from .columns import EntityBatch, SignalColumns, log_styles
from .format import (
    FORCE_ARROW_M_PER_N,
    FORMAT_VERSION,
    RECORDING_FORMAT,
    dumps,
    layout,
    params_markdown,
)
from .omitted import left_out_signals
from .outcome import log_outcome
from .rrd_file import RrdFile, signals_held
from .scene import Skeleton, log_scene_static, send_scene
from .size import BYTES_PER_TICK_ESTIMATE, bytes_per_tick, check_writable
from .viewer import find_viewer, spawn_viewer

__all__ = [
    "BYTES_PER_TICK_ESTIMATE",
    "DEFAULT_SCENE_RATE_HZ",
    "RerunRecorder",
    "bytes_per_tick",
    "find_viewer",
    "spawn_viewer",
]

#: Default rate of the 3-D scene [Hz]: a display rate, far below the control rate.
DEFAULT_SCENE_RATE_HZ = RecordingParams().scene_rate_hz
#: Longest wait for rerun to encode what was sent [s] (a 2000-tick chunk takes
#: milliseconds); past it rerun raises, which becomes a RecordingError.
FLUSH_TIMEOUT_S = 10.0


class RerunRecorder:
    """Writes a run to a rerun ``.rrd`` file as it goes (a SimObserver).

    Args:
        path: the ``.rrd`` file to write (replaced, once the run ends, if it exists).
        spawn: also stream to a rerun viewer started for the purpose.
        app_id: rerun application id.
        scene_rate_hz: rate of the 3-D scene [Hz] (the ticks k with k mod
            round(f_ctrl / f_scene) = 0, at least every tick); the time
            series are logged at every tick whatever it is.
        write_behind: write each chunk in a helper thread while the loop
            runs on (on disk by the next chunk), or before :meth:`chunk`
            returns (module docstring).

    Raises:
        InvalidParameter: scene_rate_hz is not a finite rate > 0.
        RecordingError: from :meth:`start` when the file cannot be created
            (missing or read-only directory, not enough free space).
        OutputError: from :meth:`start`, :meth:`chunk` or :meth:`finish`
            when writing fails (disk full, device error, a FIFO that no
            process opens for reading in time).

    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        spawn: bool = False,
        app_id: str = "exo_ctrl",
        scene_rate_hz: float = DEFAULT_SCENE_RATE_HZ,
        write_behind: bool = True,
    ) -> None:
        ok = isinstance(scene_rate_hz, (int, float)) and not isinstance(scene_rate_hz, bool)
        if not (ok and math.isfinite(scene_rate_hz) and scene_rate_hz > 0):
            raise InvalidParameter("scene_rate", scene_rate_hz, "a finite rate > 0 Hz")
        self.path = Path(path)
        self.spawn = bool(spawn)
        self.app_id = str(app_id)
        self.scene_rate_hz = float(scene_rate_hz)
        self.write_behind = bool(write_behind)
        self._rec: rr.RecordingStream | None = None
        self._stream: rr.BinaryStream | None = None
        self._file: RrdFile | None = None
        self._failed = False
        self._publish = True  # rename the partial file over the path at close()
        #: Where the last run's recording is (the partial file until it is renamed).
        self.written = self.path
        # The helper thread that writes chunks behind the loop, its queue of
        # jobs (the ticks on disk once done; None: stop), and "no job pending".
        self._worker: threading.Thread | None = None
        self._jobs: queue.SimpleQueue[int | None] = queue.SimpleQueue()
        self._idle = threading.Event()
        self._idle.set()
        self._written: int | None = None  # ticks the last write hands over, once on disk
        self._pending_error: BaseException | None = None
        self._on_disk = 0  # ticks whose write has completed
        self._next_tick = 0
        self._dt = 0.0
        self._stride = 1
        self._columns = SignalColumns(layout({}))
        self._bodies: tuple[tuple[str, Skeleton, str], ...] = ()
        self._belt: dict[str, float] = {}
        self._patient_feet = False  # the run's patient feet meet the belt: their arrows

    # ------------------------------------------------------------------ protocol

    def start(self, result: SimResult) -> None:
        """Open the file, write the blueprint, parameters and static geometry."""
        if self._rec is not None:
            raise RecordingError(f"recorder for {self.path} is already recording a run")
        config = result.config
        self._stride = max(1, round(config.control_rate_hz / self.scene_rate_hz))
        lay = layout()  # the log schema as it is now, less the features off in the run
        self._columns = SignalColumns(lay, left_out_signals(config, set(lay.shapes)))
        per_tick = bytes_per_tick(len(self._columns.layout.series), self._stride)
        check_writable(self.path, config.n_ticks, per_tick)
        self._failed = False
        self._pending_error = None
        self._next_tick = self._on_disk = 0
        self._dt = config.dt
        self._columns.prepare(min(config.chunk_ticks, max(config.n_ticks, 1)))  # the loop's chunks
        exo = load_body(result.exo_source, name="exoskeleton")
        patient = load_patient(config.patient)
        hip_e, hip_p = exo.legs["left"].hip_xz, patient.legs["left"].hip_xz
        offset = (hip_e[0] - hip_p[0], hip_e[1] - hip_p[1])
        self._bodies = (
            ("exo", Skeleton(exo), "q"),
            ("patient", Skeleton(patient, offset), "q_patient"),
        )
        try:
            file = RrdFile(self.path)
            self.written, self._publish = file.written, True
        except OSError as exc:
            if exc.errno == errno.ETIMEDOUT:  # a FIFO nobody reads: a failed write (exit 1)
                raise OutputError(self.path, exc.strerror or str(exc)) from None
            raise RecordingError(f"cannot write recording {self.path}: {exc.strerror}") from None
        rec = rr.RecordingStream(self.app_id)
        stream = rr.binary_stream(recording=rec)
        sinks: list = [stream]
        if self.spawn and self._spawn_viewer(rec):
            sinks.append(rr.GrpcSink())
        rec.set_sinks(*sinks)  # the blueprint active: a viewer's own layout replaced (0.41)
        rec.send_blueprint(make_blueprint(self._columns.layout), make_active=True)
        self._rec, self._stream, self._file = rec, stream, file
        chunk = min(config.chunk_ticks, max(config.n_ticks, 1))  # a chunk's bytes, ahead
        file.reserve(chunk * bytes_per_tick(len(self._columns.layout.series), self._stride))
        try:
            rec.send_recording_name(self.path.stem)
            self._log_static(result, exo, offset)
            self._write()
            if self.write_behind:
                self._start_worker()
        except (RecordingError, RuntimeError, OSError) as exc:
            # The loop never calls finish() when start() fails: close here.
            self._failed = True
            self.close()
            self._fail(exc)

    def chunk(self, result: SimResult, start: int, rows: dict[str, np.ndarray]) -> None:
        """Log rows ``start:start+n`` of every signal.

        The chunk is sent to rerun here and written to the file in the
        background; it is on disk, with a footer, by the time the next chunk
        is handed over (this waits for it first), :meth:`finish` or
        :meth:`sync` returns (module docstring).  Rows already logged are
        skipped, so a chunk handed over twice is logged once.

        Raises:
            OutputError: writing this or the previous chunk failed (disk full).
            RecordingError: ``rows`` lacks a signal of the log schema.

        """
        rec = self._rec
        if rec is None or self._failed:
            return
        self.sync()
        total = int(next(iter(rows.values())).shape[0])
        skip = max(0, self._next_tick - start)
        if skip >= total:
            return
        n = total - skip
        columns = self._columns
        try:
            columns.check(rows)
        except RecordingError as exc:
            self._fail(exc)
        ticks = np.arange(start + skip, start + total, dtype=np.int64)
        try:
            log_styles(rec, columns.check_left_out(rows, skip))
            values = columns.series_values(rows, skip, n)
            batch = EntityBatch(ticks, self._dt)
            columns.send_series(rec, batch, values)
            if columns.raw:
                columns.send_raw(rec, EntityBatch(ticks, self._dt), rows, skip)
            self._send_scene(rec, ticks, rows, skip, result.belt_speed_mps)
        except (RecordingError, RuntimeError, OSError) as exc:
            self._fail(exc)
        self._next_tick = start + total
        if self.write_behind:
            self._write_behind(self._next_tick)
        else:
            try:
                self._write()
            except (RecordingError, RuntimeError, OSError) as exc:
                self._fail(exc)
            self._on_disk = self._next_tick

    def finish(self, result: SimResult) -> None:
        """Log the events and the outcome, write them, and close the file."""
        rec = self._rec
        if rec is None:
            return
        error: BaseException | None = None
        try:
            error = self._join()
            self._publish = result.status != "interrupted"  # else the previous file stays
            if error is None and not self._failed:
                log_outcome(rec, result, self._next_tick, self._dt)
                self._write()
        except (RecordingError, RuntimeError, OSError) as exc:
            error = exc
        finally:
            if error is not None:
                self._failed = True
            self.close()
        if error is not None:
            self._fail(error)

    def sync(self) -> None:
        """Wait until every chunk handed over is on disk.

        Raises:
            OutputError: the background write failed (disk full).

        """
        error = self._join()
        if error is not None:
            self._fail(error)

    def close(self) -> None:
        """Close the file (a special file gets its footer now); safe to call more than once.

        What was sent after the last write is not written: every path of the
        loop writes before it closes (:meth:`chunk`, :meth:`finish`).

        Raises:
            OutputError: the footer of a special file could not be written.

        """
        self._join()
        self._stop_worker()
        rec, self._rec, self._stream = self._rec, None, None
        file, self._file = self._file, None
        if rec is not None:
            with contextlib.suppress(RuntimeError, OSError):
                rec.disconnect()  # rerun's sinks are memory and a viewer: nothing to fail
        if file is None:
            return
        if self._failed:
            file.abandon()
            return
        try:
            file.close(self._publish)
        except OSError as exc:
            self._fail(exc)
        finally:
            self.written = file.written

    def _write(self, wait: bool = True) -> None:
        """Write what rerun encoded since the last write (whole messages and a footer).

        ``wait``: for the write's end (else :meth:`_join` waits, see
        :meth:`RrdFile.append <.rrd_file.RrdFile.append>`).
        """
        stream, file = self._stream, self._file
        if stream is None or file is None:
            return
        with signals_held():  # what rerun hands over reaches the file whole
            file.append(stream.read(flush=True, flush_timeout_sec=FLUSH_TIMEOUT_S), wait)

    def _write_behind(self, ticks: int) -> None:
        """:meth:`_write` in the helper thread; ``ticks`` are on disk once it is done.

        Rerun encodes while reading (``BinaryStream.read``, about 10 ms for a
        2000-tick chunk) and releases the interpreter lock meanwhile, as the
        write does: the loop simulates the next chunk in the meantime.  The
        thread lives from :meth:`start` to :meth:`close` (starting one per
        chunk cost the loop about 1 ms here).
        """
        self._start_worker()
        self._idle.clear()
        self._jobs.put(ticks)

    def _start_worker(self) -> None:
        if self._worker is None or not self._worker.is_alive():
            self._worker = threading.Thread(
                target=self._serve,
                args=(self._jobs, self._idle),
                name="exo-ctrl-recorder-write",
                daemon=True,
            )
            self._worker.start()

    def _serve(self, jobs: queue.SimpleQueue[int | None], idle: threading.Event) -> None:
        """The helper thread: each job is a :meth:`_write`; None ends it."""
        while (ticks := jobs.get()) is not None:
            try:
                self._write(wait=False)  # handed to the writer process: _join waits for it
            except (RecordingError, RuntimeError, OSError) as exc:
                self._pending_error = exc
            else:
                self._written = ticks
            finally:
                idle.set()

    def _join(self) -> BaseException | None:
        """Wait for the background write to end; its error, if it failed (cleared)."""
        self._idle.wait()
        error, self._pending_error = self._pending_error, None
        written, self._written = self._written, None
        if error is None and written is not None and self._file is not None:
            try:
                self._file.wait()
            except OSError as exc:
                error = exc
            else:
                self._on_disk = written
        return error

    def _stop_worker(self) -> None:
        worker, self._worker = self._worker, None
        if worker is not None and worker.is_alive():
            self._jobs.put(None)
            worker.join()

    # ------------------------------------------------------------------ checks

    def _spawn_viewer(self, rec: rr.RecordingStream) -> bool:
        """Start a viewer to stream to; on failure warn and record to the file only."""
        problem = spawn_viewer(rec)
        if problem is not None:
            warnings.warn(f"{problem}; recording to {self.path} only", RuntimeWarning, stacklevel=4)
            return False
        return True

    def _fail(self, exc: BaseException) -> NoReturn:
        """Mark the recording failed; raise OutputError (a write error) or RecordingError.

        The message names the path, the reason and the ticks the file keeps.
        """
        self._failed = True
        kept = self._on_disk
        file = self.written if self.written != self.path else "the file"
        held = f"{file} holds ticks 0-{kept - 1}, readable" if kept else "no tick was recorded"
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            reason = exc.strerror or str(exc)
            if not is_special(self.path):
                with contextlib.suppress(OSError):
                    free = shutil.disk_usage(self.path.parent).free
                    if free < 1 << 20:
                        reason += f" ({free} B free)"
            raise OutputError(self.path, f"{reason}; {held}") from None
        raise RecordingError(f"writing recording {self.path} failed: {exc}; {held}") from None

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
            "package_version": __version__,
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
            "columns": self._columns.full.stored(),
            "left_out": dict(self._columns.left_out),
        }
        text = rr.TextDocument(dumps(meta), media_type=rr.MediaType.TEXT)
        rec.log("raw/meta", text, static=True, strict=True)
        markdown = rr.TextDocument(params_markdown(result, meta), media_type=rr.MediaType.MARKDOWN)
        rec.log("params", markdown, static=True, strict=True)
        log_styles(rec, self._columns.layout.series)
        self._patient_feet = config.contact.patient_feet
        ground = "ground_force" not in self._columns.left_out
        self._belt = log_scene_static(rec, config.gait, exo, self._patient_feet, ground)

    # ------------------------------------------------------------------ per chunk

    def _send_scene(
        self,
        rec: rr.RecordingStream,
        ticks: np.ndarray,
        rows: dict[str, np.ndarray],
        skip: int,
        v: float,
    ) -> None:
        """The 3-D scene at the chunk's ticks k with k mod stride = 0 (rows ``skip:``)."""
        picked = skip + np.arange((-int(ticks[0])) % self._stride, ticks.shape[0], self._stride)
        if picked.shape[0] == 0:
            return
        left_out = self._columns.left_out
        bodies = tuple((b, skeleton, rows[q][picked]) for b, skeleton, q in self._bodies)
        shown = ticks[picked - skip]
        force = rows["cuff_force"][picked]
        # Not drawn while left out (zero: the contact off, the pelvis fixed).
        ground = None if "ground_force" in left_out else rows["ground_force"][picked]
        pelvis = None if "pelvis_z" in left_out else rows["pelvis_z"][picked]
        feet = rows["patient_ground_force"][picked] if self._patient_feet else None
        send_scene(rec, shown, self._dt, bodies, force, self._belt, v, ground, pelvis, feet)
