"""The layout of a recording: entities, timelines, and the series derived from the log schema.

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
    world/ground_force/{left,right}          Arrows3D: the belt's force on each exoskeleton
                                             foot (with the contact on), and
    world/patient_ground_force/{left,right}  on each patient foot (with the patient's feet on)
    signals/joint_angle/{joint}              Scalars (desired, actual, patient) [rad]
    signals/joint_speed/{joint}              Scalars (desired, actual, patient) [rad/s]
    signals/drive_torque/{joint}             Scalars [N·m]
    signals/patient_torque/{joint}           Scalars [N·m]
    signals/current/{joint}                  Scalars [A] (mean over the tick)
    signals/voltage/{joint}                  Scalars (command, applied) [V]
    signals/{name}/{cuff}                    Scalars (x, z, magnitude) [N]: a (4, 2) signal
                                             labelled by cuff, e.g. cuff_force, cuff_force_est
    signals/{name}                           Scalars: any other signal, its components
                                             flattened row-major (named by joint or cuff
                                             for a (4,) signal labelled so)
    raw/{signal}                             Scalars: one row per tick holding the signal's
                                             whole row (row-major), for a signal some value
                                             of which no series shows (none in the schema
                                             today; version 1 files: every signal)
    raw/meta                                 TextDocument, static: JSON (format marker, config,
                                             model sources, Δt, signal layout, where each
                                             value is stored, the signals left out)
    raw/outcome                              TextDocument, static: JSON written at the end
                                             (status, error, events, ticks, and the other
                                             plain fields of SimResult)

``{joint}`` is one of :data:`~exo_ctrl.model.JOINT_NAMES`, ``{cuff}`` one of
:data:`~exo_ctrl.model.CUFF_NAMES`; "every signal" is every entry of the log
schema :data:`exo_ctrl.sim.schema.SIGNALS`, read when a recording starts, so
a signal added there is recorded and read back with no change here.
Time-varying data sits on two timelines: ``sim_time`` (a duration,
t_k = k Δt, stored in whole nanoseconds) and ``tick`` (the sequence k).
Everything under ``signals/`` and ``raw/`` is logged at every tick; the 3-D
entities at the scene rate (ticks k with k mod round(f_ctrl / f_scene) = 0).

Every value once (version 2).  Each logged value is stored once, in the
series that shows it: ``raw/meta``'s ``"columns"`` says, per stored entity,
which signal and which component of its row each of the entity's components
holds (``null`` for a magnitude), and :func:`~.reader.read_recording`
rebuilds every signal from it.  The signals of the features that are off in
the run (:mod:`.omitted`: no contact, fixed pelvis, ...) are constant and
not stored: ``raw/meta``'s ``"left_out"`` gives each one's constant, and the
reader fills it in.  Version 1 files also held every signal whole under
``raw/{signal}`` (a second copy: 43 more entities, about 40 % of the file)
and every signal of every feature; the reader still reads them.

Exactness.  Rerun stores scalars as float64, so the series hold every
signal bit for bit (the magnitudes are ``hypot(x, z)``, computed).  3-D
positions are float32 (rerun's Vec3D), so they are within about 1e-7 m of
Pinocchio's.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..control import controller_name
from ..model import CUFF_NAMES, JOINT_NAMES, SIDES
from ..sim import SimResult, schema
from ..sim.scenario_file import scenario_toml

__all__ = [
    "FORCE_ARROW_M_PER_N",
    "FORMAT_VERSION",
    "RECORDING_FORMAT",
    "SERIES_COLORS",
    "TICK",
    "TIME",
    "Layout",
    "Series",
    "dumps",
    "layout",
    "params_markdown",
    "schema_shapes",
]

#: Marker stored in ``raw/meta``; :func:`~.reader.read_recording` refuses files without it.
RECORDING_FORMAT = "exo_ctrl.recording"
#: Version of the layout described in the module docstring (1: every signal
#: also under ``raw/``, nothing left out; read all the same).
FORMAT_VERSION = 2
#: Length of a cuff-force arrow per newton of force [m/N] (1 mm per N).
FORCE_ARROW_M_PER_N = 1e-3
#: The timelines: simulated time (a duration) and the tick number.
TIME = "sim_time"
TICK = "tick"

#: Colours (RGBA) of the scene and of the joint series' components.
COLORS = {
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
    "series_command": (60, 180, 75, 255),
    "series_applied": (70, 130, 220, 255),
}
#: Series colours (RGBA) by what a component is, and the word a panel's name uses
#: for each (the panels hide their legends: the name says which line is which).
#: Left dark, right light; hip and thigh blue, knee and shank red.
SERIES_COLORS = {
    "left_hip": ((0, 90, 180, 255), "blue"),
    "left_knee": ((200, 50, 30, 255), "red"),
    "right_hip": ((110, 180, 240, 255), "pale blue"),
    "right_knee": ((240, 160, 40, 255), "orange"),
    "left_thigh": ((0, 90, 180, 255), "blue"),
    "left_shank": ((200, 50, 30, 255), "red"),
    "right_thigh": ((110, 180, 240, 255), "pale blue"),
    "right_shank": ((240, 160, 40, 255), "orange"),
    "x": ((200, 50, 30, 255), "red"),
    "z": ((0, 90, 180, 255), "blue"),
    "magnitude": ((30, 30, 30, 255), "black"),
    "desired": (COLORS["series_desired"], "green"),
    "actual": (COLORS["series_actual"], "blue"),
    "patient": (COLORS["series_patient"], "orange"),
    "command": (COLORS["series_command"], "green"),
    "applied": (COLORS["series_applied"], "blue"),
    "left": ((0, 90, 180, 255), "blue"),
    "right": ((240, 160, 40, 255), "orange"),
}
#: Human-friendly series of the per-joint signals: one entity per quantity and
#: joint, signals/{quantity}/{joint}, whose components are these signals.
JOINT_GROUPS = {
    "joint_angle": (("q_des", "desired"), ("q", "actual"), ("q_patient", "patient")),
    "joint_speed": (("dq_des", "desired"), ("dq", "actual"), ("dq_patient", "patient")),
    "drive_torque": (("drive_torque", ""),),
    "patient_torque": (("patient_torque", ""),),
    "current": (("current", ""),),
    "voltage": (("voltage_cmd", "command"), ("voltage", "applied")),
}
#: The estimated cuff forces, shown beside the simulated ones.
EST_ENTITY = "signals/cuff_force_est"
#: SimResult fields not stored in raw/outcome (they have their own entities).
NOT_IN_OUTCOME = ("config", "t", "signals", "stats")


def schema_shapes() -> dict[str, tuple[int, ...]]:
    """Name → row shape of every signal of the log schema as it is now, in log order."""
    return {s.name: tuple(s.shape) for s in schema.SIGNALS}


@dataclass(frozen=True)
class Series:
    """One human-friendly time-series entity.

    Attributes:
        entity: entity path.
        names: legend of each component.
        colors: RGBA per component, or None for rerun's defaults.
        columns: per component, the column of the chunk's extended row
            (:class:`Layout`) it shows.
        unit: SI unit of the values (the log schema's; "" for a count or code).
        title: what the values are, in words (the log schema's description).
        key: per component, the colour's word and what it is, e.g.
            ``("blue", "left hip")`` (empty with rerun's default colours).

    """

    entity: str
    names: list[str]
    colors: list[tuple[int, int, int, int]] | None
    columns: tuple[int, ...]
    unit: str = ""
    title: str = ""
    key: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True)
class Layout:
    """Where each signal sits in a chunk's flat rows, and the series built from them.

    A tick's row holds every signal flattened, side by side: signal s, w_s
    values per row, is columns ``offsets[s] … offsets[s] + w_s - 1``.  The
    series read an *extended row* of ``width + len(magnitudes)`` columns,
    whose column ``width + m`` is the magnitude hypot(x, z) of the column
    pair ``magnitudes[m]``.

    Attributes:
        shapes: name → row shape, in log order.
        offsets: name → first column of the signal.
        width: columns of all signals, Σ w_s.
        magnitudes: (x column, z column) of each magnitude.
        series: the entities under ``signals/``.

    """

    shapes: dict[str, tuple[int, ...]]
    offsets: dict[str, int]
    width: int
    magnitudes: tuple[tuple[int, int], ...]
    series: tuple[Series, ...]

    def column_of(self, column: int) -> tuple[str, int] | None:
        """(signal, flat index in its row) of a column of the extended row; None for a magnitude."""
        for name, shape in self.shapes.items():
            off = self.offsets[name]
            if off <= column < off + math.prod(shape):
                return name, column - off
        return None

    def raw_signals(self) -> tuple[str, ...]:
        """The signals some column of which no series shows: stored whole under ``raw/``."""
        shown = {c for s in self.series for c in s.columns}
        return tuple(
            name
            for name, shape in self.shapes.items()
            if not all(self.offsets[name] + i in shown for i in range(math.prod(shape)))
        )

    def stored(self) -> dict[str, list[tuple[str, int] | None]]:
        """Entity → what each of its components holds: (signal, flat index), None for a magnitude.

        Every series, and ``raw/{signal}`` of :meth:`raw_signals`: where
        :func:`~.reader.read_recording` finds each value (``raw/meta``'s
        ``"columns"``).
        """
        out: dict[str, list[tuple[str, int] | None]] = {
            s.entity: [self.column_of(c) for c in s.columns] for s in self.series
        }
        for name in self.raw_signals():
            out[f"raw/{name}"] = [(name, i) for i in range(math.prod(self.shapes[name]))]
        return out

    def without(self, left_out: Iterable[str]) -> Layout:
        """The layout without the series that show only signals of ``left_out``."""
        gone = set(left_out)

        def kept(s: Series) -> bool:
            return any((c := self.column_of(i)) is not None and c[0] not in gone for i in s.columns)

        return dataclasses.replace(self, series=tuple(s for s in self.series if kept(s)))


def layout(shapes: dict[str, tuple[int, ...]] | None = None) -> Layout:
    """The layout of the signals ``shapes`` (default: the log schema as it is now).

    The per-joint quantities of :data:`JOINT_GROUPS` give one entity per
    joint.  Any other signal: a (4, 2) signal labelled by cuff gives one
    entity per cuff with (x, z, magnitude), a (4,) signal labelled by joint
    or cuff one entity named so; any other signal (one this layout does not
    know) one plain entity of its components flattened row-major, named
    ``name[i]…``.
    """
    if shapes is None:
        shapes = schema_shapes()
    labels = {s.name: s.labels for s in schema.SIGNALS}
    units = {s.name: s.unit for s in schema.SIGNALS}
    titles = {s.name: s.description for s in schema.SIGNALS}
    offsets, width = {}, 0
    for name, shape in shapes.items():
        offsets[name] = width
        width += math.prod(shape)
    magnitudes: list[tuple[int, int]] = []
    out: list[Series] = []
    used: set[str] = set()
    for quantity, parts in JOINT_GROUPS.items():
        present = [(sig, label) for sig, label in parts if shapes.get(sig) == (4,)]
        used.update(sig for sig, _ in present)
        unit = units.get(present[0][0], "") if present else ""
        title = quantity.replace("_", " ")
        for j, joint in enumerate(JOINT_NAMES if present else ()):
            names = [f"{joint} {label}".rstrip() for _, label in present]
            columns = tuple(offsets[sig] + j for sig, _ in present)
            parts = [label or joint for _, label in present]
            colors, key = _colors(parts)
            out.append(
                Series(f"signals/{quantity}/{joint}", names, colors, columns, unit, title, key)
            )
    for name, shape in shapes.items():
        if name in used:
            continue
        off, label = offsets[name], labels.get(name, "")
        unit, title = units.get(name, ""), titles.get(name, name)
        if shape == (4, 2) and label == "cuff":
            colors, key = _colors(["x", "z", "magnitude"])
            for c, cuff in enumerate(CUFF_NAMES):
                tag = "" if name == "cuff_force" else f" ({name})"
                names = [f"{cuff} {part}{tag}" for part in ("x", "z", "magnitude")]
                x, z = off + 2 * c, off + 2 * c + 1
                columns = (x, z, width + len(magnitudes))
                magnitudes.append((x, z))
                entity = f"signals/{name}/{cuff}"
                out.append(Series(entity, names, colors, columns, unit, title, key))
        elif label == "foot" and shape in ((2,), (2, 2)):  # the feet (left, right)
            if shape == (2,):
                colors, key = _colors(list(SIDES))
                names = [f"{name} {side}" for side in SIDES]
                out.append(
                    Series(f"signals/{name}", names, colors, (off, off + 1), unit, title, key)
                )
            else:
                colors, key = _colors(["x", "z"])
                for f, side in enumerate(SIDES):
                    names = [f"{side} foot {part} ({name})" for part in ("x", "z")]
                    columns = (off + 2 * f, off + 2 * f + 1)
                    entity = f"signals/{name}/{side}"
                    out.append(Series(entity, names, colors, columns, unit, title, key))
        elif shape == (4,) and label in ("joint", "cuff"):
            items = CUFF_NAMES if label == "cuff" else JOINT_NAMES
            names = [f"{name} {item}" for item in items]
            colors, key = _colors(list(items))
            columns = tuple(range(off, off + 4))
            out.append(Series(f"signals/{name}", names, colors, columns, unit, title, key))
        else:  # a plain per-component series (rerun's colours, its legend names them)
            idx = list(np.ndindex(*shape))
            names = [name + "".join(f"[{i}]" for i in ix) for ix in idx]
            columns = tuple(range(off, off + len(idx)))
            out.append(Series(f"signals/{name}", names, None, columns, unit, title))
    return Layout(dict(shapes), offsets, width, tuple(magnitudes), tuple(out))


def _colors(parts: list[str]) -> tuple[list[tuple[int, int, int, int]] | None, tuple]:
    """Colours of components named ``parts``, and the key naming them (("blue", "actual"), …)."""
    if not all(p in SERIES_COLORS for p in parts):
        return None, ()
    colors = [SERIES_COLORS[p][0] for p in parts]
    key = tuple((SERIES_COLORS[p][1], p.replace("_", " ")) for p in parts)
    return colors, key


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    return str(value)


def dumps(data: dict[str, Any]) -> str:
    """JSON of ``data`` (numpy values as plain numbers, NaN allowed)."""
    return json.dumps(data, indent=1, default=_jsonable, allow_nan=True)


def params_markdown(result: SimResult, meta: dict[str, Any]) -> str:
    """The ``params`` document: the run's settings (``meta`` of ``raw/meta``) as markdown."""
    config = result.config
    lines = [
        "# exo_ctrl run",
        "",
        "| | |",
        "|---|---|",
        f"| controller | `{controller_name(config.controller)}` |",
        f"| duration | {config.duration_s:g} s ({config.n_ticks} ticks) |",
        f"| control rate | {config.control_rate_hz:g} Hz (Δt = {config.dt:g} s), "
        f"{config.plant_substeps} plant substep(s) |",
        f"| belt speed | {result.belt_speed_mps:.4g} m/s |",
        f"| exoskeleton | `{result.exo_source}` |",
        f"| patient | `{result.patient_source}` |",
        f"| 3-D scene | every {meta['decimate_3d_ticks']} ticks "
        f"({config.control_rate_hz / meta['decimate_3d_ticks']:.4g} Hz) |",
        f"| cuff-force arrows | {FORCE_ARROW_M_PER_N * 1e3:g} mm per N, force on the exo |",
        "",
    ]
    for key, value in meta["config"].items():
        if isinstance(value, dict):
            lines += [f"## {key}", "", "| parameter | value |", "|---|---|"]
            lines += [f"| {k} | {v} |" for k, v in value.items()]
            lines.append("")
    lines += [
        "## Reading back",
        "",
        "`exo_ctrl.read_recording(path)` rebuilds the run (every signal from the series "
        "that show it, float64, exact; those of the features off in the run, constant, "
        "from `raw/meta`).",
        "",
        f"## Scenario (exo_ctrl {meta['package_version']})",
        "",
        "`exo-ctrl scenario --from THIS.rrd --out run.toml` writes it; "
        "`exo-ctrl simulate run.toml` runs it again.",
        "",
        "```toml",
        scenario_toml(config, comments=False).rstrip(),
        "```",
        "",
    ]
    return "\n".join(lines)
