"""Rerun recordings of simulated runs: written while the run goes, read back exactly.

:class:`RerunRecorder` is a :class:`~exo_ctrl.sim.loop.SimObserver`.  It writes
one ``.rrd`` file per run, viewable offline (``rerun run.rrd``) with a default
blueprint, and :func:`read_recording` rebuilds the run's
:class:`~exo_ctrl.sim.loop.SimResult` from it.

Entity hierarchy (the one place it is defined)::

    params                                   TextDocument, static: the run's parameters (markdown)
    events                                   TextLog: run events and the final status
    world/belt                               Boxes3D, static: treadmill belt; its top is the
                                             stance-foot height (exo hip z - hip_height)
    world/belt/stripes                       LineStrips3D: belt markings moving at belt speed
    world/plan/foot_path/{left,right}        LineStrips3D, static: planned foot path over one
                                             gait period (path relative to the hip + hip)
    world/{exo,patient}/{left,right}/leg     LineStrips3D: hip → knee → foot
    world/{exo,patient}/{left,right}/joints  Points3D: hip, knee, foot
    world/{exo,patient}/{left,right}/cuffs   Points3D: thigh cuff, shank cuff
    world/cuff_force/{cuff}                  Arrows3D: cuff force on the exoskeleton, drawn at
                                             the exo cuff, FORCE_ARROW_M_PER_N metres per newton
    signals/joint_angle/{joint}              Scalars (desired, actual, patient) [rad]
    signals/joint_speed/{joint}              Scalars (desired, actual, patient) [rad/s]
    signals/drive_torque/{joint}             Scalars [N·m]
    signals/patient_torque/{joint}           Scalars [N·m]
    signals/current/{joint}                  Scalars [A] (mean over the tick)
    signals/voltage/{joint}                  Scalars (command, applied) [V]
    signals/cuff_force/{cuff}                Scalars (x, z, magnitude) [N]
    signals/safety_state                     Scalars: 0 normal, 1 stopping, 2 holding, 3 power cut
    signals/{name}[/{cuff}]                  Scalars: every other entry of SIGNALS: (4, 2) as
                                             .../{cuff} (x, z, magnitude), e.g. cuff_force_est;
                                             others as one entity, components flattened
    raw/{signal}                             Scalars: one row per tick holding the signal's
                                             whole row (row-major), for every entry of SIGNALS
    raw/meta                                 TextDocument, static: JSON (format marker, config,
                                             model sources, Δt, signal layout)
    raw/outcome                              TextDocument, static: JSON written at the end
                                             (status, error, events, ticks, and the other
                                             plain fields of SimResult)

``{joint}`` is one of :data:`~exo_ctrl.model.body.JOINT_NAMES`, ``{cuff}`` one of
:data:`~exo_ctrl.model.body.CUFF_NAMES`.  Time-varying data sits on two timelines:
``sim_time`` (a duration, t_k = k Δt, stored in whole nanoseconds) and
``tick`` (the sequence k).  Everything under ``signals/`` and ``raw/`` is
logged at every tick; the 3-D entities every ``decimate_3d_s`` of simulated
time (ticks k with k mod round(decimate_3d_s / Δt) = 0).

Exactness.  Rerun stores scalars as float64, so ``raw/`` holds every signal
bit for bit; :func:`read_recording` rebuilds ``t`` as ``k Δt`` from the
``tick`` timeline (exactly as :func:`~exo_ctrl.sim.loop.simulate` computes
it), not from the nanosecond ``sim_time``.  3-D positions are float32
(rerun's Vec3D), so they are within about 1e-7 m of Pinocchio's.

The 3-D pose comes from the logged joint angles through Pinocchio forward
kinematics of the two models, loaded once in :meth:`RerunRecorder.start`.
The patient's world is shifted in x and z so that its left hip sits on the
exoskeleton's (as the plant's ``patient_offset_xz`` does); y is the model's.

Failure safety.  The file is written in place at its final path, not to a
temporary file renamed at the end: rerun streams each chunk to the file as it
is sent, so a crash (even SIGKILL or ``os._exit``) leaves, at the path the
user asked for, a file readable with every chunk flushed before it.  A temp
file would hide that data under another name, and a run that never reaches
:meth:`~RerunRecorder.finish` would never rename it.  The costs: a previous
recording at the same path is replaced as soon as the run starts, and a file
cut by a crash has no footer (``rerun rrd verify`` rejects it; the viewer and
:func:`read_recording` read it).  The recorder flushes after every chunk, so
at most the chunk being written is at risk.  Every way a run ends (normal
end, divergence, Ctrl-C, an error in the loop or in an observer) reaches
:meth:`~RerunRecorder.finish`, which logs the events and the outcome and
writes the footer.  A file without ``raw/outcome`` (the process died) reads
back with status ``"interrupted"``; a file whose last message was cut short
(disk full) is read up to its last complete message.

Memory.  The recorder keeps no rows between chunks (it copies the chunk it
is given, sends it and drops it).  Rerun's file sink, however, keeps an index
entry per written rerun chunk for the file footer (about 2 kB per entity and
chunk, measured with rerun 0.41), so a process recording a long run grows
by about 0.15 MB per recorded chunk (0.08 MB per simulated second with
the default 2000-tick chunks); larger ``chunk_ticks`` shrink that.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import shutil
import struct
import tempfile
import threading
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from ..exceptions import ExoCtrlError, InvalidParameter, RecordingError
from ..model.body import CUFF_NAMES, JOINT_NAMES, SIDES, BodyModel, load_body, load_patient
from ..plan.gait import GaitPlan

try:
    import pyarrow as pa
    import pyarrow.compute as pc
    import rerun as rr
    import rerun.blueprint as rrb
    from rerun.chunk import RrdReader
except ImportError as _exc:  # pragma: no cover - rerun-sdk is a dependency
    raise ImportError(
        "exo_ctrl.record needs rerun-sdk (and pyarrow): pip install 'rerun-sdk>=0.24'"
    ) from _exc

if TYPE_CHECKING:
    from ..sim.loop import SimConfig, SimResult

__all__ = [
    "FORCE_ARROW_M_PER_N",
    "RECORDING_FORMAT",
    "RerunRecorder",
    "blueprint_views",
    "make_blueprint",
    "read_recording",
]

#: Marker stored in ``raw/meta``; :func:`read_recording` refuses files without it.
RECORDING_FORMAT = "exo_ctrl.recording"
#: Version of the layout described in the module docstring.
FORMAT_VERSION = 1
#: Length of a cuff-force arrow per newton of force [m/N] (1 mm per N).
FORCE_ARROW_M_PER_N = 1e-3
#: Estimated file size per tick [B], for the free-space check (measured about
#: 2.2 kB per tick at 1 kHz with the default 3-D rate; taken lower on purpose
#: so the check only refuses when the disk surely cannot hold the run).
BYTES_PER_TICK_ESTIMATE = 1500

#: Longest wait for a flush to reach the disk [s].  A flush of a 2000-tick
#: chunk (about 4 MB) normally takes milliseconds; after a write error (disk
#: full) rerun 0.41's flush blocks until this timeout, or without one forever,
#: and then raises, which becomes a RecordingError.
FLUSH_TIMEOUT_S = 10.0
#: Longest wait for closing a file whose writing failed [s] (see close()).
CLOSE_AFTER_FAILURE_S = 2.0

TIME = "sim_time"
TICK = "tick"

_COLORS = {
    "exo": (70, 130, 220, 255),
    "patient": (235, 150, 80, 150),
    "cuff": (30, 30, 30, 255),
    "force": (220, 40, 40, 255),
    "plan": (60, 180, 75, 255),
    "belt": (60, 60, 64, 255),
    "stripe": (200, 200, 200, 255),
    "series_desired": (60, 180, 75, 255),
    "series_actual": (70, 130, 220, 255),
    "series_patient": (235, 150, 80, 255),
}
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
#: Human-friendly series of the per-joint signals: one entity per quantity and
#: joint, signals/{quantity}/{joint}, whose components are these signals.
_JOINT_GROUPS = {
    "joint_angle": (("q_des", "desired"), ("q", "actual"), ("q_patient", "patient")),
    "joint_speed": (("dq_des", "desired"), ("dq", "actual"), ("dq_patient", "patient")),
    "drive_torque": (("drive_torque", ""),),
    "patient_torque": (("patient_torque", ""),),
    "current": (("current", ""),),
    "voltage": (("voltage_cmd", "command"), ("voltage", "applied")),
}
#: SimResult fields not stored in raw/outcome (they have their own entities).
_NOT_IN_OUTCOME = ("config", "t", "signals", "stats")
_STRIPE_SPACING_M = 0.1
_EST = "signals/cuff_force_est"


# --------------------------------------------------------------------------- blueprint


def make_blueprint() -> rrb.Blueprint:
    """The default layout: 3-D view beside time series grouped by quantity.

    Left: the 3-D scene (``world``) above tabs with the event log (``events``)
    and the parameters (``params``).  Right: time series of joint angles,
    drive torques, currents, voltages and cuff forces (with their estimate,
    ``signals/cuff_force_est``, when logged), and tabs with joint speeds,
    patient torques, the safety state and every other signal.  The time
    panel shows ``sim_time``.
    """
    series = [
        ("signals/joint_angle", "Joint angles [rad]"),
        ("signals/drive_torque", "Drive torques [N·m]"),
        ("signals/current", "Drive currents [A]"),
        ("signals/voltage", "Drive voltages [V]"),
        ("signals/cuff_force", "Cuff forces on the exo [N]"),
    ]
    views = [rrb.TimeSeriesView(origin=origin, name=name) for origin, name in series[:-1]]
    # Cuff forces beside their estimate from the joint torque sensors.
    views.append(
        rrb.TimeSeriesView(
            origin=series[-1][0], name=series[-1][1], contents=["$origin/**", f"/{_EST}/**"]
        )
    )
    tabs = [
        ("signals/joint_speed", "Joint speeds [rad/s]"),
        ("signals/patient_torque", "Patient torques [N·m]"),
        ("signals/safety_state", "Safety state"),
    ]
    shown = [origin for origin, _ in series + tabs] + [_EST]
    rest = ["+ /signals/**"] + [f"- /{o}" for o in shown] + [f"- /{o}/**" for o in shown]
    extra = rrb.Tabs(
        *(rrb.TimeSeriesView(origin=origin, name=name) for origin, name in tabs),
        rrb.TimeSeriesView(origin="signals", name="Other signals", contents=rest),
    )
    left = rrb.Vertical(
        rrb.Spatial3DView(origin="world", name="Exoskeleton, patient and belt"),
        rrb.Tabs(
            rrb.TextLogView(origin="events", name="Events"),
            rrb.TextDocumentView(origin="params", name="Parameters"),
        ),
        row_shares=[3, 1],
    )
    return rrb.Blueprint(
        rrb.Horizontal(left, rrb.Vertical(*views, extra), column_shares=[1, 1]),
        rrb.TimePanel(timeline=TIME),
        collapse_panels=False,
    )


# --------------------------------------------------------------------------- series


@dataclasses.dataclass(frozen=True)
class _Series:
    """One human-friendly time-series entity: its components and their legend."""

    entity: str
    names: list[str]
    colors: list[tuple[int, int, int, int]] | None
    picks: list[Callable[[dict[str, np.ndarray]], np.ndarray]]


def _pick(signal: str, index: tuple[int, ...]) -> Callable[[dict[str, np.ndarray]], np.ndarray]:
    return lambda data: data[signal][(slice(None), *index)]


def _norm(signal: str, cuff: int) -> Callable[[dict[str, np.ndarray]], np.ndarray]:
    return lambda data: np.hypot(data[signal][:, cuff, 0], data[signal][:, cuff, 1])


def _series_layout(shapes: dict[str, tuple[int, ...]]) -> list[_Series]:
    """The series logged under ``signals/`` for the signals present (name → row shape).

    The per-joint quantities of ``_JOINT_GROUPS`` give one entity per joint;
    any other signal: a scalar as is, (4, 2) as one entity per cuff with
    (x, z, magnitude), anything else as one entity with its components
    flattened ((4,): named by joint, or by cuff if the name has "cuff").
    """
    out = []
    used = set()
    for quantity, parts in _JOINT_GROUPS.items():
        present = [(sig, label) for sig, label in parts if shapes.get(sig) == (4,)]
        used.update(sig for sig, _ in present)
        keys = [f"series_{label}" for _, label in present]
        colors = [_COLORS[k] for k in keys] if all(k in _COLORS for k in keys) else None
        for j, joint in enumerate(JOINT_NAMES if present else ()):
            names = [f"{joint} {label}".rstrip() for _, label in present]
            picks = [_pick(sig, (j,)) for sig, _ in present]
            out.append(_Series(f"signals/{quantity}/{joint}", names, colors, picks))
    for name, shape in shapes.items():
        if name in used:
            continue
        if shape == (4, 2):
            for c, cuff in enumerate(CUFF_NAMES):
                tag = "" if name == "cuff_force" else f" ({name})"
                names = [f"{cuff} {part}{tag}" for part in ("x", "z", "magnitude")]
                picks = [_pick(name, (c, 0)), _pick(name, (c, 1)), _norm(name, c)]
                out.append(_Series(f"signals/{name}/{cuff}", names, None, picks))
        elif shape == (4,):
            labels = CUFF_NAMES if "cuff" in name else JOINT_NAMES
            names = [f"{name} {label}" for label in labels]
            picks = [_pick(name, (i,)) for i in range(4)]
            out.append(_Series(f"signals/{name}", names, None, picks))
        else:
            idx = list(np.ndindex(*shape))
            names = [name + "".join(f"[{i}]" for i in ix) for ix in idx]
            out.append(_Series(f"signals/{name}", names, None, [_pick(name, ix) for ix in idx]))
    return out


# --------------------------------------------------------------------------- kinematics


class _Skeleton:
    """World points of one body's legs from its joint angles (Pinocchio FK).

    Args:
        body: the body.
        offset_xz: shift of the body's world in (x, z) [m].

    """

    def __init__(self, body: BodyModel, offset_xz: tuple[float, float] = (0.0, 0.0)) -> None:
        self.model = body.model
        self.data = body.model.createData()
        self.q_index = body.q_index
        self.q_model = pin.neutral(body.model)
        self.hips = body.joint_ids[0::2]
        self.knees = body.joint_ids[1::2]
        self.feet = body.foot_frame_ids
        self.cuffs = body.cuff_frame_ids
        self.offset = np.array([offset_xz[0], 0.0, offset_xz[1]])

    def points(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Leg points and cuff points for joint angles q, (m, 4) in JOINT_NAMES order.

        Returns:
            legs (m, 2, 3, 3): side, (hip, knee, foot), xyz [m];
            cuffs (m, 4, 3): cuff in CUFF_NAMES order, xyz [m].

        """
        m = q.shape[0]
        legs = np.empty((m, 2, 3, 3))
        cuffs = np.empty((m, 4, 3))
        model, data, qm = self.model, self.data, self.q_model
        for i in range(m):
            qm[self.q_index] = q[i]
            pin.framesForwardKinematics(model, data, qm)
            for s in range(2):
                legs[i, s, 0] = data.oMi[self.hips[s]].translation
                legs[i, s, 1] = data.oMi[self.knees[s]].translation
                legs[i, s, 2] = data.oMf[self.feet[s]].translation
            for c in range(4):
                cuffs[i, c] = data.oMf[self.cuffs[c]].translation
        legs += self.offset
        cuffs += self.offset
        return legs, cuffs


# --------------------------------------------------------------------------- recorder


class RerunRecorder:
    """Writes a run to a rerun ``.rrd`` file as it goes (a SimObserver).

    Each chunk of rows is logged with one ``send_columns`` call per entity and
    flushed to disk before :meth:`chunk` returns; the recorder keeps no rows
    between chunks.  See the module docstring for the entity hierarchy.

    Args:
        path: the ``.rrd`` file to write (replaced if it exists).
        spawn: also stream to a rerun viewer started for the purpose.
        app_id: rerun application id.
        decimate_3d_s: simulated time between 3-D poses [s] (rounded to whole
            ticks, at least one).

    Raises:
        RecordingError: from :meth:`start` when the file cannot be created
            (missing or read-only directory, not enough free space), and from
            :meth:`chunk` / :meth:`finish` when writing fails (disk full).

    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        spawn: bool = False,
        app_id: str = "exo_ctrl",
        decimate_3d_s: float = 0.02,
    ) -> None:
        ok = isinstance(decimate_3d_s, (int, float)) and not isinstance(decimate_3d_s, bool)
        if not (ok and math.isfinite(decimate_3d_s) and decimate_3d_s > 0):
            raise InvalidParameter("decimate_3d_s", decimate_3d_s, "a finite time > 0 s")
        self.path = Path(path)
        self.spawn = bool(spawn)
        self.app_id = str(app_id)
        self.decimate_3d_s = float(decimate_3d_s)
        self._rec: rr.RecordingStream | None = None
        self._failed = False
        self._next_tick = 0
        self._dt = 0.0
        self._stride = 1
        self._exo: _Skeleton | None = None
        self._patient: _Skeleton | None = None
        self._belt: dict[str, float] = {}
        self._series: list[_Series] = []

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
        self._stride = max(1, round(self.decimate_3d_s / config.dt))
        self._series = _series_layout({name: s[0] for name, s in _signals().items()})
        exo = load_body(result.exo_source, name="exoskeleton")
        patient = load_patient(config.patient)
        hip_e, hip_p = exo.legs["left"].hip_xz, patient.legs["left"].hip_xz
        offset = (hip_e[0] - hip_p[0], hip_e[1] - hip_p[1])
        self._exo = _Skeleton(exo)
        self._patient = _Skeleton(patient, offset)
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
            self._log_static(result, exo, patient, offset)
            rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
        except (RuntimeError, OSError) as exc:
            # The loop never calls finish() when start() fails: close here.
            self._failed = True
            self.close()
            self._fail(exc)

    def chunk(self, result: SimResult, start: int, rows: dict[str, np.ndarray]) -> None:
        """Log rows ``start:start+n`` of every signal, then flush to disk.

        Rows already logged are skipped, so a chunk handed over twice is
        logged once.
        """
        rec = self._rec
        if rec is None or self._failed:
            return
        n = int(next(iter(rows.values())).shape[0])
        skip = max(0, self._next_tick - start)
        if skip >= n:
            return
        # The rows are views of buffers the loop reuses: take float64 copies.
        data = {name: np.array(arr[skip:], dtype=np.float64) for name, arr in rows.items()}
        ticks = np.arange(start + skip, start + n, dtype=np.int64)
        try:
            self._log_signals(rec, ticks, data)
            self._log_3d(rec, ticks, data, result.belt_speed_mps)
            rec.flush(timeout_sec=FLUSH_TIMEOUT_S)
        except (RuntimeError, OSError) as exc:
            self._fail(exc)
        self._next_tick = start + n

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
        closer = threading.Thread(target=shut, name="exo_ctrl-recorder-close", daemon=True)
        closer.start()
        closer.join(CLOSE_AFTER_FAILURE_S)

    # ------------------------------------------------------------------ checks

    def _spawn_viewer(self, rec: rr.RecordingStream) -> bool:
        """Start a viewer to stream to; on failure warn and record to the file only."""
        try:
            rec.spawn(connect=False)
        except (RuntimeError, OSError) as exc:
            warnings.warn(
                f"could not start the rerun viewer ({exc}); recording to {self.path} only",
                RuntimeWarning,
                stacklevel=4,
            )
            return False
        return True

    def _fail(self, exc: BaseException) -> None:
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
        if not parent.is_dir():
            raise RecordingError(
                f"cannot write recording {path}: directory {parent} does not exist"
            )
        if path.is_dir():
            raise RecordingError(f"cannot write recording {path}: it is a directory")
        target = path if path.exists() else parent
        if not os.access(target, os.W_OK):
            raise RecordingError(f"cannot write recording {path}: permission denied on {target}")
        if path.exists() and not path.is_file():
            return  # a device (/dev/null): no free-space figure applies
        with contextlib.suppress(OSError):
            free = shutil.disk_usage(parent).free
            need = n_ticks * BYTES_PER_TICK_ESTIMATE
            if free < need:
                raise RecordingError(
                    f"cannot write recording {path}: about {need / 1e6:.1f} MB needed for "
                    f"{n_ticks} ticks, {free / 1e6:.1f} MB free"
                )

    # ------------------------------------------------------------------ static

    def _log_static(
        self, result: SimResult, exo: BodyModel, patient: BodyModel, offset: tuple[float, float]
    ) -> None:
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
            "force_arrow_m_per_N": FORCE_ARROW_M_PER_N,
            "signals": {name: list(shape) for name, (shape, _, _) in _signals().items()},
        }
        _static(rec, "raw/meta", rr.TextDocument(_dumps(meta), media_type=rr.MediaType.TEXT))
        markdown = _params_markdown(result, meta)
        _static(rec, "params", rr.TextDocument(markdown, media_type=rr.MediaType.MARKDOWN))
        # Legend names and colours of the time series.
        for series in self._series:
            _static(rec, series.entity, rr.SeriesLines(names=series.names, colors=series.colors))
        # Styles of the 3-D entities (their geometry is logged per chunk).
        for body, radius in (("exo", 0.012), ("patient", 0.03)):
            for side in SIDES:
                base, color = f"world/{body}/{side}", _COLORS[body]
                _static(rec, f"{base}/leg", rr.LineStrips3D.from_fields(radii=radius, colors=color))
                joints = rr.Points3D.from_fields(radii=1.6 * radius, colors=color)
                _static(rec, f"{base}/joints", joints)
                cuffs = rr.Points3D.from_fields(radii=1.3 * radius, colors=_COLORS["cuff"])
                _static(rec, f"{base}/cuffs", cuffs)
        for cuff in CUFF_NAMES:
            arrows = rr.Arrows3D.from_fields(radii=0.006, colors=_COLORS["force"])
            _static(rec, f"world/cuff_force/{cuff}", arrows)
        self._belt = _log_scene(rec, config.gait, exo)

    # ------------------------------------------------------------------ per chunk

    def _log_signals(
        self, rec: rr.RecordingStream, ticks: np.ndarray, data: dict[str, np.ndarray]
    ) -> None:
        n = ticks.shape[0]
        index = [
            rr.TimeColumn(TIME, duration=ticks * self._dt),
            rr.TimeColumn(TICK, sequence=ticks),
        ]

        def send(entity: str, values: np.ndarray) -> None:
            _send(rec, entity, index, rr.Scalars.columns(scalars=values))

        for name, arr in data.items():
            send(f"raw/{name}", arr.reshape(n, -1))
        for series in self._series:
            values = np.column_stack([pick(data) for pick in series.picks])
            send(series.entity, values[:, 0] if values.shape[1] == 1 else values)

    def _log_3d(
        self, rec: rr.RecordingStream, ticks: np.ndarray, data: dict[str, np.ndarray], v_belt: float
    ) -> None:
        if self._exo is None or self._patient is None:
            return
        idx = np.arange((-int(ticks[0])) % self._stride, ticks.shape[0], self._stride)
        m = idx.shape[0]
        if m == 0:
            return
        t = ticks[idx] * self._dt
        index = [rr.TimeColumn(TIME, duration=t), rr.TimeColumn(TICK, sequence=ticks[idx])]
        exo_cuffs = np.zeros((m, 4, 3))
        for body, skeleton, name in (
            ("exo", self._exo, "q"),
            ("patient", self._patient, "q_patient"),
        ):
            legs, cuffs = skeleton.points(data[name][idx])
            if body == "exo":
                exo_cuffs = cuffs
            for s, side in enumerate(SIDES):
                base = f"world/{body}/{side}"
                strips = rr.LineStrips3D.columns(strips=np.ascontiguousarray(legs[:, s]))
                _send(rec, f"{base}/leg", index, _rows_of(strips, 1, m))
                joints = rr.Points3D.columns(positions=legs[:, s].reshape(-1, 3))
                _send(rec, f"{base}/joints", index, _rows_of(joints, 3, m))
                points = rr.Points3D.columns(positions=cuffs[:, 2 * s : 2 * s + 2].reshape(-1, 3))
                _send(rec, f"{base}/cuffs", index, _rows_of(points, 2, m))
        force = data["cuff_force"][idx]  # (m, 4, 2)
        for c, cuff in enumerate(CUFF_NAMES):
            vectors = np.zeros((m, 3))
            vectors[:, [0, 2]] = FORCE_ARROW_M_PER_N * force[:, c]
            arrows = rr.Arrows3D.columns(origins=exo_cuffs[:, c], vectors=vectors)
            _send(rec, f"world/cuff_force/{cuff}", index, arrows)
        # Belt markings: the top of the belt moves backwards (-x) at the belt speed.
        b = self._belt
        length = b["length"]
        ns = max(1, int(length / _STRIPE_SPACING_M))
        x0 = (np.arange(ns) + 0.5) * (length / ns)
        x = b["x_min"] + np.mod(x0[None, :] - v_belt * t[:, None], length)  # (m, ns)
        stripes = np.empty((m, ns, 2, 3))
        stripes[..., 0] = x[..., None]
        stripes[..., 0, 1] = b["y_min"]
        stripes[..., 1, 1] = b["y_max"]
        stripes[..., 2] = b["z"]
        lines = rr.LineStrips3D.columns(strips=stripes.reshape(-1, 2, 3))
        _send(rec, "world/belt/stripes", index, _rows_of(lines, ns, m))

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
            if f.name not in _NOT_IN_OUTCOME
        }
        outcome.update(events=events, ticks=ticks)
        _static(rec, "raw/outcome", rr.TextDocument(_dumps(outcome), media_type=rr.MediaType.TEXT))

    def _log_event(self, rec: rr.RecordingStream, t: float, text: str, level: str) -> None:
        rec.set_time(TIME, duration=t)
        rec.set_time(TICK, sequence=max(0, round(t / self._dt)))
        rec.log("events", rr.TextLog(text, level=level), strict=True)


def _static(rec: rr.RecordingStream, entity: str, archetype: Any) -> None:
    rec.log(entity, archetype, static=True, strict=True)


def _send(rec: rr.RecordingStream, entity: str, index: list, columns: Any) -> None:
    rec.send_columns(entity, indexes=index, columns=columns, strict=True)


def _rows_of(columns: Any, per_row: int, rows: int) -> Any:
    """Group a flat component column into ``rows`` rows of ``per_row`` instances."""
    return columns.partition(np.full(rows, per_row, dtype=np.int64))


def _log_scene(rec: rr.RecordingStream, gait: Any, exo: BodyModel) -> dict[str, float]:
    """Static belt and planned foot paths; returns the belt's geometry for the markings.

    The foot path of each leg is the plan's foot position relative to the hip
    (:meth:`GaitPlan.feet` over one period) plus the exo's hip position.  The
    belt's top is at the stance-foot height, exo hip z - hip_height.
    """
    data = exo.model.createData()
    pin.framesForwardKinematics(exo.model, data, pin.neutral(exo.model))
    hips = [data.oMi[exo.joint_ids[2 * s]].translation.copy() for s in range(2)]
    t = np.linspace(0.0, gait.period, 241)
    feet = GaitPlan(gait).feet(t).pos  # (N, leg, (x, z)) relative to the hip
    paths = np.repeat(np.stack(hips)[None], t.shape[0], axis=0)  # (N, leg, xyz)
    paths[..., [0, 2]] += feet
    for s, side in enumerate(SIDES):
        strips = rr.LineStrips3D([paths[:, s]], radii=0.004, colors=_COLORS["plan"])
        _static(rec, f"world/plan/foot_path/{side}", strips)
    top = float(hips[0][2] - gait.hip_height)
    xs = paths[..., 0]
    half_length = max(0.8, 0.5 * float(xs.max() - xs.min()) + 0.5)
    half_width = max(abs(h[1]) for h in hips) + 0.2
    x_center = float(hips[0][0])
    y_center = 0.5 * float(hips[0][1] + hips[1][1])
    belt = rr.Boxes3D(
        centers=[[x_center, y_center, top - 0.01]],
        half_sizes=[[half_length, half_width, 0.01]],
        colors=_COLORS["belt"],
        fill_mode=rr.components.FillMode.Solid,
    )
    _static(rec, "world/belt", belt)
    stripes = rr.LineStrips3D.from_fields(radii=0.003, colors=_COLORS["stripe"])
    _static(rec, "world/belt/stripes", stripes)
    return {
        "x_min": x_center - half_length,
        "length": 2.0 * half_length,
        "y_min": y_center - half_width,
        "y_max": y_center + half_width,
        "z": top + 0.002,
    }


# --------------------------------------------------------------------------- reading


def read_recording(path: str | os.PathLike[str]) -> SimResult:
    """Rebuild a run's :class:`~exo_ctrl.sim.loop.SimResult` from its recording.

    Every signal comes from ``raw/<name>`` bit for bit (float64); ``t`` is
    ``k Δt`` for the ticks k = 0 … N-1 in the file.  Status, error, events,
    wall time and the other plain fields of the result come from
    ``raw/outcome``; a file without it (the process died before the run
    finished) reads as ``"interrupted"`` with the ticks that reached the disk.
    If a crash cut a chunk between signals, only the ticks present in every
    signal are kept.  A signal of :data:`~exo_ctrl.sim.loop.SIGNALS` that the
    file lacks (written before the signal existed) is NaN.  The running
    statistics are rebuilt, so :meth:`SimResult.summary` matches the live run.

    Raises:
        RecordingError: the file is missing or unreadable, was not written by
            :class:`RerunRecorder`, or its data is inconsistent.

    """
    from ..sim.loop import SimResult

    p = Path(path)
    if not p.is_file():
        raise RecordingError(f"cannot read recording {p}: file not found")
    chunks, note = _read_chunks(p)

    texts: dict[str, str] = {}
    raw: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    for chunk in chunks:
        entity = chunk.entity_path.lstrip("/")
        if not entity.startswith("raw/"):
            continue
        batch = chunk.to_record_batch()
        if entity in ("raw/meta", "raw/outcome"):
            if "TextDocument:text" in batch.schema.names:
                values = batch.column("TextDocument:text").to_pylist()
                if values and values[-1]:
                    texts[entity] = values[-1][-1]
            continue
        if "Scalars:scalars" in batch.schema.names and TICK in batch.schema.names:
            raw.setdefault(entity[4:], []).append(_scalar_rows(p, entity, batch))

    if "raw/meta" not in texts:
        raise RecordingError(f"cannot read recording {p}: not written by exo_ctrl (no raw/meta)")
    try:
        meta = json.loads(texts["raw/meta"])
    except json.JSONDecodeError as exc:
        raise RecordingError(f"cannot read recording {p}: raw/meta is not JSON ({exc})") from None
    if not isinstance(meta, dict) or meta.get("format") != RECORDING_FORMAT:
        raise RecordingError(f"cannot read recording {p}: not an {RECORDING_FORMAT} file")
    config = _config_from_dict(p, meta.get("config", {}))
    signals = _assemble(p, meta, raw)
    n = next(iter(signals.values())).shape[0] if signals else 0

    outcome: dict[str, Any]
    if "raw/outcome" in texts:
        try:
            outcome = json.loads(texts["raw/outcome"])
        except json.JSONDecodeError as exc:
            raise RecordingError(
                f"cannot read recording {p}: raw/outcome is not JSON ({exc})"
            ) from None
    else:
        message = (
            f"the recording ends at t = {n * config.dt:.4f} s without an end record "
            f"(the process stopped before the run finished{note})"
        )
        outcome = {
            "status": "interrupted",
            "error": message,
            "events": [{"t": n * config.dt, "kind": "interrupted", "message": message}],
        }
    fields = {f.name for f in dataclasses.fields(SimResult)} - set(_NOT_IN_OUTCOME)
    plain = {
        "belt_speed_mps": float(meta.get("belt_speed_mps", config.gait.belt_speed)),
        "exo_source": str(meta.get("exo_source", "")),
        "patient_source": str(meta.get("patient_source", "")),
    }
    plain.update({key: value for key, value in outcome.items() if key in fields})
    # Signals the file lacks (a recording from before they were added) are NaN.
    for name, (shape, _, _) in _signals().items():
        signals.setdefault(name, np.full((n, *shape), np.nan))
    result = SimResult(config=config, t=np.arange(n) * config.dt, signals=signals, **plain)
    result.stats = _run_stats(config, plain["exo_source"])
    step = min(config.chunk_ticks, max(config.n_ticks, 1))  # the loop's chunks: same sums
    for start in range(0, n, step):
        result.stats.update({name: arr[start : start + step] for name, arr in signals.items()})
    return result


def _run_stats(config: SimConfig, exo_source: str) -> Any:
    """Running statistics as simulate() keeps them, so summary() matches the live run."""
    from ..sim.summary import RunStats

    try:
        from ..estimation.observer import EstimateErrorStats

        return RunStats(EstimateErrorStats(load_body(exo_source, name="exoskeleton"), config.dt))
    except (ExoCtrlError, ImportError, TypeError):  # the model moved, or an older layout
        return RunStats()


def blueprint_views(path: str | os.PathLike[str]) -> list[dict[str, str]]:
    """The views of the default blueprint stored in a recording.

    ``save(path, default_blueprint=...)`` writes the blueprint as a second
    store of kind "blueprint" in the same file (same application id, its own
    recording id), with entities ``/viewport``, ``/container/<uuid>`` and
    ``/view/<uuid>``.  This returns one dict per view with the keys
    ``class`` (``"3D"``, ``"TimeSeries"``, ``"TextLog"``, ``"TextDocument"``),
    ``name`` and ``origin``.

    Raises:
        RecordingError: the file is unreadable or holds no blueprint.

    """
    p = Path(path)
    try:
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*no footer.*")
            reader = RrdReader(p)
            stores = reader.blueprints()
            if not stores:
                raise RecordingError(f"recording {p} holds no blueprint")
            chunks = reader.stream(store=stores[0]).to_chunks()
    except (ValueError, RuntimeError, OSError) as exc:
        if isinstance(exc, ExoCtrlError):
            raise
        raise RecordingError(f"cannot read recording {p}: {exc}") from None
    views = []
    for chunk in chunks:
        batch = chunk.to_record_batch()
        if "ViewBlueprint:class_identifier" not in batch.schema.names:
            continue
        row = {
            "class": "ViewBlueprint:class_identifier",
            "name": "ViewBlueprint:display_name",
            "origin": "ViewBlueprint:space_origin",
        }
        view = {}
        for key, column in row.items():
            value = batch.column(column).to_pylist()[-1] if column in batch.schema.names else None
            view[key] = str(value[-1]) if value else ""
        views.append(view)
    return views


# --------------------------------------------------------------------------- helpers


def _load_chunks(path: Path) -> list:
    with warnings.catch_warnings():
        # A file without footer (the writer died) is still readable by stream().
        warnings.filterwarnings("ignore", message=".*no footer.*")
        return RrdReader(path).stream().to_chunks()


def _read_chunks(path: Path) -> tuple[list, str]:
    """All chunks of the file's recording, and a note if the file had to be salvaged.

    A writer stopped in the middle of a message (disk full) leaves a last
    message cut short, and rerun then refuses the whole file.  In that case
    the complete messages are copied to a temporary file and read from there.
    """
    try:
        return _load_chunks(path), ""
    except (ValueError, RuntimeError, OSError) as exc:
        error = exc
    end = _complete_prefix(path)
    if end is not None:
        with tempfile.TemporaryDirectory() as tmp:
            copy = Path(tmp) / path.name
            with path.open("rb") as src, copy.open("wb") as dst:
                _copy_bytes(src, dst, end)
            with contextlib.suppress(ValueError, RuntimeError, OSError):
                chunks = _load_chunks(copy)
                size = path.stat().st_size
                return chunks, f"; the file was cut at byte {end} of {size}"
    raise RecordingError(f"cannot read recording {path}: {error}") from None


#: RRD stream framing (rerun 0.2x-0.41): a 12-byte file header starting with
#: b"RRF2", then messages of a 16-byte header (kind, payload length; both
#: little-endian u64) and the payload.  Kind 0 ends the stream.
_RRD_MAGIC = b"RRF2"
_RRD_FILE_HEADER = 12
_RRD_MSG_HEADER = struct.Struct("<QQ")


def _complete_prefix(path: Path) -> int | None:
    """Length of the file's complete messages if the last one is cut short, else None."""
    size = path.stat().st_size
    with path.open("rb") as f:
        if f.read(len(_RRD_MAGIC)) != _RRD_MAGIC:
            return None
        offset = _RRD_FILE_HEADER
        while offset + _RRD_MSG_HEADER.size <= size:
            f.seek(offset)
            kind, length = _RRD_MSG_HEADER.unpack(f.read(_RRD_MSG_HEADER.size))
            if kind == 0:
                return None  # the stream ended properly: the problem is elsewhere
            if offset + _RRD_MSG_HEADER.size + length > size:
                return offset
            offset += _RRD_MSG_HEADER.size + length
    return offset if offset < size else None


def _copy_bytes(src: Any, dst: Any, n: int, block: int = 1 << 20) -> None:
    while n > 0:
        data = src.read(min(block, n))
        if not data:
            break
        dst.write(data)
        n -= len(data)


def _signals() -> dict[str, tuple[tuple[int, ...], str, str]]:
    from ..sim.loop import SIGNALS

    return SIGNALS


def _scalar_rows(path: Path, entity: str, batch: pa.RecordBatch) -> tuple[np.ndarray, np.ndarray]:
    """(ticks (n,), values (n, width)) of one chunk of a multi-component Scalars entity."""
    ticks = batch.column(TICK).to_numpy(zero_copy_only=False).astype(np.int64)
    column = batch.column("Scalars:scalars")
    lengths = pc.list_value_length(column).to_numpy(zero_copy_only=False)
    n = ticks.shape[0]
    if n == 0:
        return ticks, np.zeros((0, 0))
    width = int(lengths[0])
    if column.null_count or np.any(lengths != width):
        raise RecordingError(f"cannot read recording {path}: {entity} has rows of unequal width")
    values = column.flatten().to_numpy(zero_copy_only=False).astype(np.float64, copy=False)
    return ticks, values.reshape(n, width)


def _assemble(
    path: Path, meta: dict[str, Any], raw: dict[str, list[tuple[np.ndarray, np.ndarray]]]
) -> dict[str, np.ndarray]:
    """Signal arrays over the ticks 0 … N-1 present in every signal."""
    layout = meta.get("signals") or {name: list(s[0]) for name, s in _signals().items()}
    per_signal: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for name, shape in layout.items():
        shape = tuple(int(x) for x in shape)
        width = math.prod(shape)
        parts = raw.get(name, [])
        if parts:
            ticks = np.concatenate([t for t, _ in parts])
            values = np.concatenate([v.reshape(-1, width) for _, v in parts if v.size], axis=0)
        else:
            ticks, values = np.zeros(0, dtype=np.int64), np.zeros((0, width))
        if values.shape[0] != ticks.shape[0]:
            raise RecordingError(f"cannot read recording {path}: raw/{name} has a bad row width")
        ticks, first = np.unique(ticks, return_index=True)  # sorted; duplicates dropped
        values = values[first]
        n = ticks.shape[0]
        if n and (ticks[0] != 0 or ticks[-1] != n - 1):
            missing = np.setdiff1d(np.arange(ticks[-1] + 1), ticks)
            raise RecordingError(
                f"cannot read recording {path}: raw/{name} misses {missing.size} ticks "
                f"(first {int(missing[0])})"
            )
        per_signal[name] = (ticks, values.reshape(n, *shape))
    n_common = min((t.shape[0] for t, _ in per_signal.values()), default=0)
    return {name: values[:n_common].copy() for name, (_, values) in per_signal.items()}


def _from_dict(cls: type, data: dict[str, Any]) -> Any:
    """Build a (nested) dataclass from its ``asdict`` form; unknown keys are ignored."""
    kwargs = {}
    for f in dataclasses.fields(cls):
        if f.name not in data:
            continue
        value = data[f.name]
        factory = f.default_factory
        if isinstance(factory, type) and dataclasses.is_dataclass(factory):
            if isinstance(value, dict):
                value = _from_dict(factory, value)
        elif isinstance(value, list):
            value = tuple(value)
        kwargs[f.name] = value
    return cls(**kwargs)


def _config_from_dict(path: Path, data: dict[str, Any]) -> SimConfig:
    from ..sim.loop import SimConfig

    try:
        return _from_dict(SimConfig, data)
    except (ExoCtrlError, TypeError, ValueError) as exc:
        raise RecordingError(
            f"cannot read recording {path}: its config is invalid ({exc})"
        ) from None


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)


def _dumps(data: dict[str, Any]) -> str:
    return json.dumps(data, indent=1, default=_jsonable, allow_nan=True)


def _params_markdown(result: SimResult, meta: dict[str, Any]) -> str:
    config = result.config
    d = meta["config"]
    lines = [
        "# exo_ctrl run",
        "",
        "| | |",
        "|---|---|",
        f"| controller | `{config.controller}` |",
        f"| duration | {config.duration_s:g} s ({config.n_ticks} ticks) |",
        f"| control rate | {config.control_rate_hz:g} Hz (Δt = {config.dt:g} s), "
        f"{config.plant_substeps} plant substep(s) |",
        f"| belt speed | {result.belt_speed_mps:.4g} m/s |",
        f"| exoskeleton | `{result.exo_source}` |",
        f"| patient | `{result.patient_source}` |",
        f"| 3-D pose | every {meta['decimate_3d_ticks']} ticks |",
        f"| cuff-force arrows | {FORCE_ARROW_M_PER_N * 1e3:g} mm per N, force on the exo |",
        "",
    ]
    for key, value in d.items():
        if isinstance(value, dict):
            lines += [f"## {key}", "", "| parameter | value |", "|---|---|"]
            lines += [f"| {k} | {v} |" for k, v in value.items()]
            lines.append("")
    lines += [
        "## Reading back",
        "",
        "`exo_ctrl.record.recorder.read_recording(path)` rebuilds the run (every signal under "
        "`raw/`, float64, exact).",
        "",
    ]
    return "\n".join(lines)
