"""Rerun recordings of simulated runs: written while the run goes, read back exactly.

:class:`RerunRecorder` is a :class:`~exo_ctrl.simulate.SimObserver`.  It writes
one ``.rrd`` file per run, viewable offline (``rerun run.rrd``) with a default
blueprint, and :func:`read_recording` rebuilds the run's
:class:`~exo_ctrl.simulate.SimResult` from it.

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
    signals/joint_angle/{joint}/{desired,actual,patient}   Scalars [rad]
    signals/joint_speed/{joint}/{desired,actual,patient}   Scalars [rad/s]
    signals/drive_torque/{joint}             Scalars [N·m]
    signals/patient_torque/{joint}           Scalars [N·m]
    signals/current/{joint}                  Scalars [A] (mean over the tick)
    signals/voltage/{joint}/{command,applied}              Scalars [V]
    signals/cuff_force/{cuff}/{x,z,magnitude}              Scalars [N]
    raw/{signal}                             Scalars: one row per tick holding the signal's
                                             whole row (row-major), for every entry of SIGNALS
    raw/meta                                 TextDocument, static: JSON (format marker, config,
                                             model sources, Δt, signal layout)
    raw/outcome                              TextDocument, static: JSON written at the end
                                             (status, error, events, ticks, wall time)

``{joint}`` is one of :data:`~exo_ctrl.model.JOINT_NAMES`, ``{cuff}`` one of
:data:`~exo_ctrl.model.CUFF_NAMES`.  Time-varying data sits on two timelines:
``sim_time`` (a duration, t_k = k Δt, stored in whole nanoseconds) and
``tick`` (the sequence k).  Everything under ``signals/`` and ``raw/`` is
logged at every tick; the 3-D entities every ``decimate_3d_s`` of simulated
time (ticks k with k mod round(decimate_3d_s / Δt) = 0).

Exactness.  Rerun stores scalars as float64, so ``raw/`` holds every signal
bit for bit; :func:`read_recording` rebuilds ``t`` as ``k Δt`` from the
``tick`` timeline (exactly as :func:`~exo_ctrl.simulate.simulate` computes
it), not from the nanosecond ``sim_time``.  3-D positions are float32
(rerun's Vec3D), so they are within about 1e-7 m of Pinocchio's.

The 3-D pose comes from the logged joint angles through Pinocchio forward
kinematics of the two models, loaded once in :meth:`RerunRecorder.start`.
The patient's world is shifted in x and z so that its left hip sits on the
exoskeleton's (as the plant's ``patient_offset_xz`` does); y is the model's.

Failure safety.  The file is written in place at its final path, not to a
temporary file renamed at the end: rerun streams each flushed chunk to the
file, so a crash (even SIGKILL or ``os._exit``) leaves, at the path the user
asked for, a file readable with every chunk flushed before it.  A temp file
would hide that data under another name, and a run that never reaches
:meth:`~RerunRecorder.finish` would never rename it.  The cost is that a
previous recording at the same path is replaced as soon as the run starts.
The recorder flushes after every chunk, so at most the chunk being written
is at risk; a normal end, a divergence, Ctrl-C or an exception in the loop
all reach :meth:`~RerunRecorder.finish`, which writes the outcome and the
file footer.  A file without ``raw/outcome`` reads back with status
``"interrupted"``.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import shutil
import sys
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pinocchio as pin

from .exceptions import ExoCtrlError, RecordingError
from .gait import GaitPlan
from .model import CUFF_NAMES, JOINT_NAMES, SIDES, BodyModel, load_body, load_patient

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
    from .simulate import SimConfig, SimResult

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
    "desired": (60, 180, 75, 255),
    "actual": (70, 130, 220, 255),
    "patient_series": (235, 150, 80, 255),
}
_LEVELS = {"completed": "INFO", "diverged": "ERROR", "interrupted": "WARN"}
_STRIPE_SPACING_M = 0.1


# --------------------------------------------------------------------------- blueprint


def make_blueprint() -> rrb.Blueprint:
    """The default layout: 3-D view beside time series grouped by quantity.

    Left: the 3-D scene (``world``) above tabs with the event log (``events``)
    and the parameters (``params``).  Right: time series of joint angles,
    drive torques, currents, voltages and cuff forces, with joint speeds and
    patient torques in tabs.  The time panel shows ``sim_time``.
    """
    series = [
        ("signals/joint_angle", "Joint angles [rad]"),
        ("signals/drive_torque", "Drive torques [N·m]"),
        ("signals/current", "Drive currents [A]"),
        ("signals/voltage", "Drive voltages [V]"),
        ("signals/cuff_force", "Cuff forces on the exo [N]"),
    ]
    views = [rrb.TimeSeriesView(origin=origin, name=name) for origin, name in series]
    extra = rrb.Tabs(
        rrb.TimeSeriesView(origin="signals/joint_speed", name="Joint speeds [rad/s]"),
        rrb.TimeSeriesView(origin="signals/patient_torque", name="Patient torques [N·m]"),
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
        if not (isinstance(decimate_3d_s, (int, float)) and decimate_3d_s > 0):
            from .exceptions import InvalidParameter

            raise InvalidParameter("decimate_3d_s", decimate_3d_s, "> 0 s")
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
        exo = load_body(result.exo_source, name="exoskeleton")
        patient = load_patient(config.patient)
        hip_e, hip_p = exo.legs["left"].hip_xz, patient.legs["left"].hip_xz
        offset = (hip_e[0] - hip_p[0], hip_e[1] - hip_p[1])
        self._exo = _Skeleton(exo)
        self._patient = _Skeleton(patient, offset)
        rec = rr.RecordingStream(self.app_id)
        try:
            if self.spawn:
                rec.spawn(connect=False)
                rec.set_sinks(
                    rr.FileSink(str(self.path)), rr.GrpcSink(), default_blueprint=make_blueprint()
                )
            else:
                rec.save(self.path, default_blueprint=make_blueprint())
        except (RuntimeError, OSError) as exc:
            raise RecordingError(f"cannot write recording {self.path}: {exc}") from None
        self._rec = rec
        try:
            rec.send_recording_name(self.path.stem)
            self._log_static(result, exo, patient, offset)
            rec.flush()
        except (RuntimeError, OSError) as exc:
            self._fail(exc)

    def chunk(self, result: SimResult, start: int, rows: dict[str, np.ndarray]) -> None:
        """Log rows ``start:start+n`` of every signal, then flush to disk.

        Rows already logged (the loop may hand the same chunk twice after an
        observer failed) are skipped.
        """
        rec = self._rec
        if rec is None or self._failed:
            return
        n = int(rows["q"].shape[0])
        skip = max(0, self._next_tick - start)
        if skip >= n:
            return
        # The rows are views of buffers the loop reuses: take float64 copies.
        data = {name: np.array(arr[skip:], dtype=np.float64) for name, arr in rows.items()}
        ticks = np.arange(start + skip, start + n, dtype=np.int64)
        try:
            self._log_signals(rec, ticks, data)
            self._log_3d(rec, ticks, data, result.belt_speed_mps)
            rec.flush()
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
                rec.flush()
        except (RuntimeError, OSError) as exc:
            error = exc
        finally:
            self.close()
        if error is not None:
            self._fail(error)

    def close(self) -> None:
        """Flush and close the file; safe to call more than once."""
        rec, self._rec = self._rec, None
        if rec is None:
            return
        with contextlib.suppress(RuntimeError, OSError):
            rec.flush()
        with contextlib.suppress(RuntimeError, OSError):
            rec.disconnect()

    # ------------------------------------------------------------------ checks

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
        rec.log(
            "raw/meta", rr.TextDocument(_dumps(meta), media_type=rr.MediaType.TEXT), static=True
        )
        rec.log(
            "params",
            rr.TextDocument(_params_markdown(result, meta), media_type=rr.MediaType.MARKDOWN),
            static=True,
        )
        self._log_series_styles(rec)
        self._log_scene(rec, result, exo)

    def _log_series_styles(self, rec: rr.RecordingStream) -> None:
        kinds = (("desired", "desired"), ("actual", "actual"), ("patient", "patient_series"))
        for joint in JOINT_NAMES:
            for quantity in ("joint_angle", "joint_speed"):
                for kind, color in kinds:
                    rec.log(
                        f"signals/{quantity}/{joint}/{kind}",
                        rr.SeriesLines(names=f"{joint} {kind}", colors=_COLORS[color]),
                        static=True,
                    )
            for kind in ("command", "applied"):
                rec.log(
                    f"signals/voltage/{joint}/{kind}",
                    rr.SeriesLines(names=f"{joint} {kind}"),
                    static=True,
                )
        for cuff in CUFF_NAMES:
            for axis in ("x", "z", "magnitude"):
                rec.log(
                    f"signals/cuff_force/{cuff}/{axis}",
                    rr.SeriesLines(names=f"{cuff} {axis}"),
                    static=True,
                )

    def _log_scene(self, rec: rr.RecordingStream, result: SimResult, exo: BodyModel) -> None:
        gait = result.config.gait
        data = exo.model.createData()
        pin.framesForwardKinematics(exo.model, data, pin.neutral(exo.model))
        hips = [data.oMi[exo.joint_ids[2 * s]].translation.copy() for s in range(2)]
        t = np.linspace(0.0, gait.period, 241)
        feet = GaitPlan(gait).feet(t).pos  # (N, 2 legs, (x, z)) relative to the hip
        xs = []
        for s, side in enumerate(SIDES):
            path = np.empty((t.shape[0], 3))
            path[:, 0] = hips[s][0] + feet[:, s, 0]
            path[:, 1] = hips[s][1]
            path[:, 2] = hips[s][2] + feet[:, s, 1]
            xs.append(path[:, 0])
            rec.log(
                f"world/plan/foot_path/{side}",
                rr.LineStrips3D([path], radii=0.004, colors=_COLORS["plan"]),
                static=True,
            )
        top = float(hips[0][2] - gait.hip_height)
        x_all = np.concatenate(xs)
        half_length = max(0.8, 0.5 * float(x_all.max() - x_all.min()) + 0.5)
        half_width = max(abs(h[1]) for h in hips) + 0.2
        x_center = float(hips[0][0])
        y_center = 0.5 * float(hips[0][1] + hips[1][1])
        rec.log(
            "world/belt",
            rr.Boxes3D(
                centers=[[x_center, y_center, top - 0.01]],
                half_sizes=[[half_length, half_width, 0.01]],
                colors=_COLORS["belt"],
                fill_mode=rr.components.FillMode.Solid,
            ),
            static=True,
        )
        rec.log(
            "world/belt/stripes",
            rr.LineStrips3D.from_fields(radii=0.003, colors=_COLORS["stripe"]),
            static=True,
        )
        self._belt = {
            "x_min": x_center - half_length,
            "length": 2.0 * half_length,
            "y_min": y_center - half_width,
            "y_max": y_center + half_width,
            "z": top + 0.002,
        }
        for body, radius in (("exo", 0.012), ("patient", 0.03)):
            color = _COLORS[body]
            for side in SIDES:
                base = f"world/{body}/{side}"
                rec.log(
                    f"{base}/leg",
                    rr.LineStrips3D.from_fields(radii=radius, colors=color),
                    static=True,
                )
                rec.log(
                    f"{base}/joints",
                    rr.Points3D.from_fields(radii=radius * 1.6, colors=color),
                    static=True,
                )
                rec.log(
                    f"{base}/cuffs",
                    rr.Points3D.from_fields(radii=radius * 1.3, colors=_COLORS["cuff"]),
                    static=True,
                )
        for cuff in CUFF_NAMES:
            rec.log(
                f"world/cuff_force/{cuff}",
                rr.Arrows3D.from_fields(radii=0.006, colors=_COLORS["force"]),
                static=True,
            )

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
            rec.send_columns(entity, indexes=index, columns=rr.Scalars.columns(scalars=values))

        for name, arr in data.items():
            send(f"raw/{name}", arr.reshape(n, -1))
        for j, joint in enumerate(JOINT_NAMES):
            for quantity, (des, act, pat) in (
                ("joint_angle", ("q_des", "q", "q_patient")),
                ("joint_speed", ("dq_des", "dq", "dq_patient")),
            ):
                send(f"signals/{quantity}/{joint}/desired", data[des][:, j])
                send(f"signals/{quantity}/{joint}/actual", data[act][:, j])
                send(f"signals/{quantity}/{joint}/patient", data[pat][:, j])
            send(f"signals/drive_torque/{joint}", data["drive_torque"][:, j])
            send(f"signals/patient_torque/{joint}", data["patient_torque"][:, j])
            send(f"signals/current/{joint}", data["current"][:, j])
            send(f"signals/voltage/{joint}/command", data["voltage_cmd"][:, j])
            send(f"signals/voltage/{joint}/applied", data["voltage"][:, j])
        force = data["cuff_force"]
        for c, cuff in enumerate(CUFF_NAMES):
            send(f"signals/cuff_force/{cuff}/x", force[:, c, 0])
            send(f"signals/cuff_force/{cuff}/z", force[:, c, 1])
            send(f"signals/cuff_force/{cuff}/magnitude", np.hypot(force[:, c, 0], force[:, c, 1]))

    def _log_3d(
        self,
        rec: rr.RecordingStream,
        ticks: np.ndarray,
        data: dict[str, np.ndarray],
        belt_speed: float,
    ) -> None:
        if self._exo is None or self._patient is None:
            return
        first = (-int(ticks[0])) % self._stride
        idx = np.arange(first, ticks.shape[0], self._stride)
        m = idx.shape[0]
        if m == 0:
            return
        k = ticks[idx]
        t = k * self._dt
        index = [rr.TimeColumn(TIME, duration=t), rr.TimeColumn(TICK, sequence=k)]
        exo_cuffs = np.zeros((m, 4, 3))
        for body, skeleton, q in (
            ("exo", self._exo, data["q"][idx]),
            ("patient", self._patient, data["q_patient"][idx]),
        ):
            legs, cuffs = skeleton.points(q)
            if body == "exo":
                exo_cuffs = cuffs
            for s, side in enumerate(SIDES):
                base = f"world/{body}/{side}"
                rec.send_columns(
                    f"{base}/leg",
                    indexes=index,
                    columns=rr.LineStrips3D.columns(strips=list(legs[:, s])).partition(
                        np.ones(m, dtype=np.int64)
                    ),
                )
                rec.send_columns(
                    f"{base}/joints",
                    indexes=index,
                    columns=rr.Points3D.columns(positions=legs[:, s].reshape(-1, 3)).partition(
                        np.full(m, 3, dtype=np.int64)
                    ),
                )
                rec.send_columns(
                    f"{base}/cuffs",
                    indexes=index,
                    columns=rr.Points3D.columns(
                        positions=cuffs[:, 2 * s : 2 * s + 2].reshape(-1, 3)
                    ).partition(np.full(m, 2, dtype=np.int64)),
                )
        force = data["cuff_force"][idx]  # (m, 4, 2)
        for c, cuff in enumerate(CUFF_NAMES):
            vectors = np.zeros((m, 3))
            vectors[:, 0] = FORCE_ARROW_M_PER_N * force[:, c, 0]
            vectors[:, 2] = FORCE_ARROW_M_PER_N * force[:, c, 1]
            rec.send_columns(
                f"world/cuff_force/{cuff}",
                indexes=index,
                columns=rr.Arrows3D.columns(origins=exo_cuffs[:, c], vectors=vectors),
            )
        self._log_belt(rec, index, t, belt_speed)

    def _log_belt(
        self, rec: rr.RecordingStream, index: list, t: np.ndarray, belt_speed: float
    ) -> None:
        b = self._belt
        length = b["length"]
        ns = max(1, int(length / _STRIPE_SPACING_M))
        x0 = (np.arange(ns) + 0.5) * (length / ns)
        # The belt's top moves backwards (-x) at the belt speed.
        x = b["x_min"] + np.mod(x0[None, :] - belt_speed * t[:, None], length)  # (m, ns)
        m = t.shape[0]
        strips = np.empty((m, ns, 2, 3))
        strips[..., 0] = x[..., None]
        strips[..., 0, 1] = b["y_min"]
        strips[..., 1, 1] = b["y_max"]
        strips[..., 2] = b["z"]
        rec.send_columns(
            "world/belt/stripes",
            indexes=index,
            columns=rr.LineStrips3D.columns(strips=list(strips.reshape(-1, 2, 3))).partition(
                np.full(m, ns, dtype=np.int64)
            ),
        )

    # ------------------------------------------------------------------ end

    def _log_outcome(self, rec: rr.RecordingStream, result: SimResult) -> None:
        ticks = self._next_tick
        status, error = result.status, result.error
        n_planned = result.config.n_ticks
        if status == "completed" and ticks < n_planned:
            # The loop did not catch what stopped it (an observer raised).
            exc = sys.exc_info()[1]
            why = f"{type(exc).__name__}: {exc}" if exc is not None else "unknown cause"
            status = "interrupted"
            error = f"run aborted at t = {ticks * self._dt:.4f} s ({why})"
        events = [dict(ev) for ev in result.events]
        for ev in events:
            kind = str(ev.get("kind", "event"))
            level = str(ev.get("level", _LEVELS.get(kind, "INFO")))
            self._log_event(
                rec, float(ev.get("t", ticks * self._dt)), f"{kind}: {ev.get('message', '')}", level
            )
        t_end = ticks * self._dt
        text = f"run {status}: {ticks} of {n_planned} ticks, t = {t_end:.4f} s"
        if error:
            text += f"; {error}"
        self._log_event(rec, t_end, text, _LEVELS.get(status, "WARN"))
        outcome = {
            "status": status,
            "error": error,
            "events": events,
            "ticks": ticks,
            "wall_time_s": result.wall_time_s,
        }
        rec.log(
            "raw/outcome",
            rr.TextDocument(_dumps(outcome), media_type=rr.MediaType.TEXT),
            static=True,
        )

    def _log_event(self, rec: rr.RecordingStream, t: float, text: str, level: str) -> None:
        tick = max(0, round(t / self._dt)) if self._dt > 0 else 0
        rec.set_time(TIME, duration=t)
        rec.set_time(TICK, sequence=tick)
        rec.log("events", rr.TextLog(text, level=level))


# --------------------------------------------------------------------------- reading


def read_recording(path: str | os.PathLike[str]) -> SimResult:
    """Rebuild a run's :class:`~exo_ctrl.simulate.SimResult` from its recording.

    Every signal comes from ``raw/<name>`` bit for bit (float64); ``t`` is
    ``k Δt`` for the ticks k = 0 … N-1 in the file.  Status, error, events and
    wall time come from ``raw/outcome``; a file without it (the process died
    before the run finished) reads as ``"interrupted"`` with the ticks that
    reached the disk.  If a crash cut a chunk between signals, only the ticks
    present in every signal are kept.

    Raises:
        RecordingError: the file is missing or unreadable, was not written by
            :class:`RerunRecorder`, or its data is inconsistent.

    """
    from .simulate import SimResult

    p = Path(path)
    if not p.is_file():
        raise RecordingError(f"cannot read recording {p}: file not found")
    try:
        with warnings.catch_warnings():
            # A file without footer (crashed writer) is readable by stream().
            warnings.filterwarnings("ignore", message=".*no footer.*")
            reader = RrdReader(p)
            chunks = reader.stream().to_chunks()
    except (ValueError, RuntimeError, OSError) as exc:
        raise RecordingError(f"cannot read recording {p}: {exc}") from None

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
            "(the process stopped before the run finished)"
        )
        outcome = {
            "status": "interrupted",
            "error": message,
            "events": [{"t": n * config.dt, "kind": "interrupted", "message": message}],
        }
    result = SimResult(
        config=config,
        t=np.arange(n) * config.dt,
        signals=signals,
        status=str(outcome.get("status", "interrupted")),
        error=str(outcome.get("error", "")),
        wall_time_s=float(outcome.get("wall_time_s", 0.0)),
        belt_speed_mps=float(meta.get("belt_speed_mps", config.gait.belt_speed)),
        exo_source=str(meta.get("exo_source", "")),
        patient_source=str(meta.get("patient_source", "")),
        events=list(outcome.get("events", [])),
    )
    if n:
        result.stats.update(signals)
    return result


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


def _signals() -> dict[str, tuple[tuple[int, ...], str, str]]:
    from .simulate import SIGNALS

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
    from .simulate import SimConfig

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
        "`exo_ctrl.record.read_recording(path)` rebuilds the run (every signal under "
        "`raw/`, float64, exact).",
        "",
    ]
    return "\n".join(lines)
