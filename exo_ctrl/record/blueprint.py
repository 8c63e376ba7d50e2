"""The default rerun blueprint of a recording, and reading it back from a file.

:func:`make_blueprint` is the layout the viewer opens a recording with;
``save(path, default_blueprint=...)`` stores it in the ``.rrd`` file as a
second store of kind "blueprint", which :func:`blueprint_views` reads back.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import rerun.blueprint as rrb
from rerun.chunk import RrdReader

from ..exceptions import ExoCtrlError, RecordingError
from .format import EST_ENTITY, TIME

__all__ = ["blueprint_views", "make_blueprint"]


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
            origin=series[-1][0], name=series[-1][1], contents=["$origin/**", f"/{EST_ENTITY}/**"]
        )
    )
    tabs = [
        ("signals/joint_speed", "Joint speeds [rad/s]"),
        ("signals/patient_torque", "Patient torques [N·m]"),
        ("signals/safety_state", "Safety state"),
    ]
    shown = [origin for origin, _ in series + tabs] + [EST_ENTITY]
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
