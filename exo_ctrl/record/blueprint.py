"""The default rerun blueprint of a recording, and reading it back from a file.

:func:`make_blueprint` is the layout the viewer opens a recording with;
``save(path, default_blueprint=...)`` stores it in the ``.rrd`` file as a
second store of kind "blueprint", which :func:`blueprint_views` reads back.
"""

from __future__ import annotations

import math
import os
import re
import uuid
import warnings
from pathlib import Path

import rerun.blueprint as rrb
from rerun.chunk import RrdReader

from ..exceptions import ExoCtrlError, RecordingError
from ..model import CUFF_NAMES, JOINT_NAMES
from .biofeedback import BIOFEEDBACK, BIOFEEDBACK_SERIES
from .format import TIME, Layout, Series, layout

__all__ = [
    "BIOFEEDBACK_PANELS",
    "MAX_LINES_PER_PANEL",
    "SCENE_COLUMN_SHARES",
    "biofeedback_tab",
    "blueprint_views",
    "make_blueprint",
]

#: Most lines any time-series panel of :func:`make_blueprint` shows (the
#: per-joint and per-cuff panels show 1-3; a 4-joint signal of the "Other
#: signals" tab shows 4, one entity cannot be split between panels).
MAX_LINES_PER_PANEL = 4
#: The time-series panels hide their legends (rerun 0.41 draws a legend
#: inside the plot, in a corner, over the curves); each panel's name says
#: which colour is which line instead.
_NO_LEGEND = rrb.PlotLegend(visible=False)
_LEGS = ("left", "right")
#: Column shares of the default layout: the 3-D scene (with the events and
#: parameters below it), then the tabs of time series.
SCENE_COLUMN_SHARES = (3.0, 2.0)
#: A panel's quantity, singular, by the tab's series (the tab's title is plural).
_QUANTITY = {
    "joint_angle": "Joint angle",
    "joint_speed": "Joint speed",
    "voltage": "Drive voltage",
    "drive_torque": "Drive torque",
    "current": "Drive current",
    "patient_torque": "Patient torque",
}


def make_blueprint(lay: Layout | None = None) -> rrb.Blueprint:
    """The default layout: the 3-D scene beside tabs of time series, one quantity per tab.

    Left: the 3-D scene (``world``) above tabs with the event log
    (``events``) and the parameters (``params``).  Right: one tab per
    quantity, its unit in the tab's name: joint angles and voltages (a panel
    per joint: desired, actual and patient angle; command and applied
    voltage), drive torques and currents (a panel per leg: hip and knee),
    cuff forces (a row per cuff: simulated and estimated x, z and magnitude
    side by side), joint speeds, patient torques, the biofeedback panel
    (:func:`biofeedback_tab`: per-cycle figures), and every other signal of
    the log schema (a panel each).  No panel holds more than
    :data:`MAX_LINES_PER_PANEL` lines; legends are hidden and each panel's
    name says what it shows in full (the quantity and the joint, leg or
    cuff: "Joint angle, left hip"), its unit and which colour is which line.
    The 3-D column takes :data:`SCENE_COLUMN_SHARES` of the width (3/5), the
    viewer's blueprint and selection side panels start collapsed so that the
    layout has the window's width, and the time panel (and so every plot's
    time axis) shows ``sim_time``, the time in seconds.

    Args:
        lay: the series to lay out (default: those of the log schema now).

    """
    series = {s.entity: s for s in (lay or layout()).series}
    shown: set[str] = set()

    def take(entities: list[str]) -> list[Series]:
        found = [series[e] for e in entities if e in series]
        shown.update(s.entity for s in found)
        return found

    tabs = [
        _per_joint(take, "joint_angle", "Joint angles"),
        _per_leg(take, "drive_torque", "Drive torques"),
        _per_leg(take, "current", "Drive currents"),
        _per_joint(take, "voltage", "Drive voltages"),
        _cuffs(take),
        _per_joint(take, "joint_speed", "Joint speeds"),
        _per_leg(take, "patient_torque", "Patient torques"),
        biofeedback_tab(),
    ]
    rest = take([e for e in series if e not in shown])
    if rest:  # one panel per signal, named by what it is and its log-schema name
        others = (_panel(s.entity, [s], _signal_name(s)) for s in rest)
        tabs.append(rrb.Grid(*others, grid_columns=2, name="Other signals"))
    left = rrb.Vertical(
        rrb.Spatial3DView(origin="world", name="Exoskeleton, patient and belt"),
        rrb.Tabs(
            rrb.TextLogView(origin="events", name="Events"),
            rrb.TextDocumentView(origin="params", name="Parameters"),
        ),
        row_shares=[3, 1],
    )
    right = rrb.Tabs(*(tab for tab in tabs if tab is not None))
    return rrb.Blueprint(
        rrb.Horizontal(left, right, column_shares=list(SCENE_COLUMN_SHARES)),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="expanded", timeline=TIME),
    )


#: The biofeedback tab's panels: (title, entities below ``biofeedback/``).
BIOFEEDBACK_PANELS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("RMS interaction force", ("interaction_force/true", "interaction_force/estimated")),
    ("Patient effort: RMS joint torque", ("patient_torque",)),
    ("Positive work per cycle", ("work/patient", "work/device")),
    (
        "Gait Profile Score (sagittal hip, knee)",
        ("gait_profile_score/planned", "gait_profile_score/actual"),
    ),
    ("aan support level", ("aan_support",)),
)


def biofeedback_tab() -> rrb.Vertical:
    """The therapist's tab: one panel per figure, a point per gait cycle after the ramp-in.

    The figures of :mod:`exo_ctrl.record.biofeedback`; each panel's name
    gives its unit and which colour is which line (at most two lines a panel).
    """
    panels = []
    for title, names in BIOFEEDBACK_PANELS:
        unit = BIOFEEDBACK_SERIES[names[0]][0]
        key = ", ".join(f"{BIOFEEDBACK_SERIES[n][2]} {BIOFEEDBACK_SERIES[n][3]}" for n in names)
        name = f"{title} [{unit}]" + (f": {key}" if len(names) > 1 else "")
        contents = [f"/{BIOFEEDBACK}/{n}" for n in names]
        panels.append(
            rrb.TimeSeriesView(
                origin=BIOFEEDBACK, contents=contents, name=name, plot_legend=_NO_LEGEND
            )
        )
    return rrb.Vertical(*panels, name="Biofeedback (per gait cycle)")


def _panel(origin: str, shown: list[Series], what: str, item: str = "") -> rrb.TimeSeriesView:
    """A time-series panel of ``shown``, named ``what``, its unit and its colour key.

    ``item``: the joint, leg or cuff the panel is of (its key leaves that out).
    """
    unit = shown[0].unit
    key = ", ".join(f"{color} {_short(part, item)}" for s in shown for color, part in s.key)
    name = what + (f" [{unit}]" if unit else "") + (f": {key}" if key else "")
    contents = [f"/{s.entity}" for s in shown]
    return rrb.TimeSeriesView(origin=origin, contents=contents, name=name, plot_legend=_NO_LEGEND)


def _per_joint(take, quantity: str, title: str) -> rrb.Vertical | None:
    """A tab of one panel per joint (its series' components: desired, actual, ...)."""
    panels, units = [], set()
    for joint in JOINT_NAMES:
        found = take([f"signals/{quantity}/{joint}"])
        if found:
            what = f"{_QUANTITY[quantity]}, {joint.replace('_', ' ')}"
            panels.append(_panel(found[0].entity, found, what, joint.replace("_", " ")))
            units.add(found[0].unit)
    return rrb.Vertical(*panels, name=_titled(title, units)) if panels else None


def _per_leg(take, quantity: str, title: str) -> rrb.Vertical | None:
    """A tab of one panel per leg, its hip and knee together."""
    panels, units = [], set()
    for leg in _LEGS:
        found = take([f"signals/{quantity}/{j}" for j in JOINT_NAMES if j.startswith(leg)])
        if found:
            what = f"{_QUANTITY[quantity]}, {leg} leg"
            panels.append(_panel(f"signals/{quantity}", found, what, f"{leg} leg"))
            units.update(s.unit for s in found)
    return rrb.Vertical(*panels, name=_titled(title, units)) if panels else None


def _cuffs(take) -> rrb.Grid | None:
    """A row per cuff: the simulated force on the exo, then its estimate."""
    panels, units = [], set()
    for cuff in CUFF_NAMES:
        name = cuff.replace("_", " ")
        for entity, what in (
            ("cuff_force", f"Cuff force on the exo, {name} cuff"),
            ("cuff_force_est", f"Estimated cuff force on the exo, {name} cuff"),
        ):
            found = take([f"signals/{entity}/{cuff}"])
            if found:
                panels.append(_panel(found[0].entity, found, what, name))
                units.add(found[0].unit)
    if not panels:
        return None
    return rrb.Grid(*panels, grid_columns=2, name=_titled("Cuff forces on the exo", units))


def _signal_name(series: Series) -> str:
    """What a signal is, from its log-schema description, and its log-schema name.

    A signal with a unit: the description's first clause (up to its first
    comma or parenthesis); a count or a code: the whole description (it
    says what the values mean).
    """
    name = series.entity.split("/", 1)[1]
    if not series.title:
        return name
    title = series.title
    if series.unit:
        title = re.split(r",\s|\s\(", title, maxsplit=1)[0]
    name, _, side = name.partition("/")  # a per-foot series: signals/{name}/{side}
    at = f": {side} foot" if side else ""
    return f"{title[0].upper()}{title[1:]}{at} ({name})"


def _short(part: str, item: str) -> str:
    """A component's name in a panel's key: without the leg the panel is of, L/R otherwise."""
    if part == "magnitude":
        return "|F|"
    for leg in _LEGS:
        if part.startswith(f"{leg} "):
            rest = part[len(leg) + 1 :]
            return rest if item.startswith(leg) else f"{leg[0].upper()} {rest}"
    return part


def _titled(title: str, units: set[str]) -> str:
    """``title [unit]`` (units joined if a tab mixes them, none if unitless)."""
    named = sorted(u for u in units if u)
    return f"{title} [{', '.join(named)}]" if named else title


def blueprint_views(path: str | os.PathLike[str]) -> list[dict]:
    """The views of the default blueprint stored in a recording.

    ``save(path, default_blueprint=...)`` (or a sink's default blueprint)
    writes the blueprint as a second store of kind "blueprint" in the same
    file (same application id, its own recording id), with entities
    ``/viewport``, ``/container/<uuid>``, ``/view/<uuid>`` and the view's
    properties below it (``/view/<uuid>/ViewContents``,
    ``/view/<uuid>/PlotLegend``).  This returns one dict per view with the
    keys ``class`` (``"3D"``, ``"TimeSeries"``, ``"TextLog"``,
    ``"TextDocument"``), ``name``, ``origin``, ``contents`` (the view's
    entity query, one rule per item, ``$origin`` as written),
    ``legend_visible`` (None when the view does not set it) and
    ``width_share``: the fraction of the layout's width the view takes
    (from ``/viewport``'s root container down: a horizontal container gives
    each child its column share over their sum, equal shares if none are
    set, a grid 1 / its columns (⌈√n⌉ of n items if not set), tabs and vertical containers the whole
    width; None for a view the root does not reach).

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
    columns = {
        "class": "ViewBlueprint:class_identifier",
        "name": "ViewBlueprint:display_name",
        "origin": "ViewBlueprint:space_origin",
        "contents": "ViewContents:query",
        "legend_visible": "PlotLegend:visible",
    }
    found: dict[str, dict] = {}
    containers: dict[str, dict] = {}
    root = ""
    for chunk in chunks:
        entity = chunk.entity_path.lstrip("/")
        batch = chunk.to_record_batch()
        if entity == "viewport" and "ViewportBlueprint:root_container" in batch.schema.names:
            value = batch.column("ViewportBlueprint:root_container").to_pylist()[-1]
            root = f"container/{uuid.UUID(bytes=bytes(value[-1]))}" if value else ""
        elif entity.startswith("container/"):
            part = containers.setdefault(entity, {})
            for key, column in _CONTAINER_COLUMNS.items():
                if column in batch.schema.names:
                    value = batch.column(column).to_pylist()[-1]
                    part[key] = value if key in ("contents", "col_shares") else value[-1]
        if not entity.startswith("view/"):
            continue
        view = found.setdefault(entity.split("/")[1], {})
        for key, column in columns.items():
            if column in batch.schema.names:
                values = batch.column(column).to_pylist()[-1]
                view[key] = values if key == "contents" else (values[-1] if values else None)
    shares = _width_shares(root, containers)
    views = []
    for view_id, view in found.items():
        if "class" not in view:
            continue
        views.append(
            {
                "class": str(view["class"]),
                "name": str(view.get("name") or ""),
                "origin": str(view.get("origin") or ""),
                "contents": [str(rule) for rule in view.get("contents") or []],
                "legend_visible": view.get("legend_visible"),
                "width_share": shares.get(f"view/{view_id}"),
            }
        )
    return views


#: The container components :func:`blueprint_views` reads, and rerun's container kinds.
_CONTAINER_COLUMNS = {
    "kind": "ContainerBlueprint:container_kind",
    "contents": "ContainerBlueprint:contents",
    "col_shares": "ContainerBlueprint:col_shares",
    "grid_columns": "ContainerBlueprint:grid_columns",
}
_HORIZONTAL, _GRID = 2, 4


def _width_shares(root: str, containers: dict[str, dict]) -> dict[str, float]:
    """Each item (``view/<id>``, ``container/<id>``) below ``root`` → its share of the width."""
    shares: dict[str, float] = {}
    todo = [(root, 1.0)] if root in containers else []
    while todo:
        entity, share = todo.pop()
        shares[entity] = share
        part = containers.get(entity)
        if part is None:  # a view
            continue
        items = list(part.get("contents") or [])
        if not items:
            continue
        kind = part.get("kind")
        if kind == _HORIZONTAL:
            given = list(part.get("col_shares") or [])
            weights = given if len(given) == len(items) else [1.0] * len(items)
            parts = [share * w / sum(weights) for w in weights]
        elif kind == _GRID:
            auto = math.ceil(math.sqrt(len(items)))  # rerun's own choice when none is set
            columns = max(1, min(int(part.get("grid_columns") or auto), len(items)))
            parts = [share / columns] * len(items)
        else:
            parts = [share] * len(items)
        todo += [(item, p) for item, p in zip(items, parts, strict=True) if item not in shares]
    return shares
