"""Tests of exo_ctrl.record.blueprint and the file as a whole: verified, with its blueprint."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

from exo_ctrl.model import CUFF_NAMES, JOINT_NAMES
from exo_ctrl.record import blueprint_views
from exo_ctrl.record.biofeedback import BIOFEEDBACK, BIOFEEDBACK_SERIES
from exo_ctrl.record.blueprint import MAX_LINES_PER_PANEL
from exo_ctrl.record.format import JOINT_GROUPS
from exo_ctrl.sim.schema import SIGNALS


def test_rrd_verify_passes(short_run, verify):
    proc = verify(short_run[1])
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_blueprint_is_stored_in_the_file(short_run):
    _, path = short_run
    reader = RrdReader(path)
    (recording,) = reader.recordings()
    (blueprint,) = reader.blueprints()  # a second store in the same file
    assert blueprint.application_id == recording.application_id == "exo_ctrl"
    assert blueprint.recording_id != recording.recording_id
    views = blueprint_views(path)
    kinds = {(v["class"], v["origin"]) for v in views}
    assert {("3D", "world"), ("TextLog", "events"), ("TextDocument", "params")} <= kinds
    shown = {
        rule.lstrip("/") for v in views if v["class"] == "TimeSeries" for rule in v["contents"]
    }
    for quantity in ("joint_angle", "drive_torque", "current", "voltage", "joint_speed"):
        assert {f"signals/{quantity}/{j}" for j in JOINT_NAMES} <= shown, quantity
    for cuff in CUFF_NAMES:
        assert {f"signals/cuff_force/{cuff}", f"signals/cuff_force_est/{cuff}"} <= shown
    # Every view shows something that is in the recording.
    entities = {c.entity_path for c in reader.stream().to_chunks()}
    for _, origin in kinds:
        assert any(e == "/" + origin or e.startswith(f"/{origin}/") for e in entities), origin


def _unit_of(entity: str) -> str:
    """The log schema's unit of the values a series entity shows."""
    units = {s.name: s.unit for s in SIGNALS}
    root, quantity, *_ = entity.split("/")
    if root == BIOFEEDBACK:  # the per-cycle figures (exo_ctrl/record/biofeedback.py)
        return BIOFEEDBACK_SERIES[entity.partition("/")[2]][0]
    if quantity in JOINT_GROUPS:
        (unit,) = {units[sig] for sig, _ in JOINT_GROUPS[quantity]}
        return unit
    return units[quantity]


def test_every_panel_has_few_lines_no_legend_and_its_unit(short_run, entity_columns):
    """Each time-series panel: at most 4 lines (3 in the tabs of the main quantities).

    The lines are counted from the file: each shown entity's static
    ``SeriesLines`` names (one per component), so a panel that showed a
    parent path or a whole quantity would fail.  Legends are off (rerun 0.41
    draws them over the curves); the panel's name carries the unit of every
    signal it shows (one unit per panel) and one colour word per line.
    """
    _, path = short_run
    panels = [v for v in blueprint_views(path) if v["class"] == "TimeSeries"]
    assert len(panels) >= 30
    shown: list[str] = []
    for view in panels:
        assert view["legend_visible"] is False, view["name"]
        entities = [rule.lstrip("/") for rule in view["contents"]]
        assert all("*" not in e and "$" not in e for e in entities), view  # exact paths only
        lines = 0
        for entity in entities:
            _, names = entity_columns(path, entity, "SeriesLines:names")
            assert names, entity
            lines += len(names[-1])
        assert 1 <= lines <= MAX_LINES_PER_PANEL == 4, view
        main = entities[0].split("/")[1] in (*JOINT_GROUPS, "cuff_force", "cuff_force_est")
        assert lines <= (3 if main else 4), view
        (unit,) = {_unit_of(e) for e in entities}
        if unit:
            assert f"[{unit}]" in view["name"], view
        else:
            assert "[" not in view["name"] and "(" in view["name"], view  # says what it is
        key = view["name"].partition(": ")[2]
        assert lines == 1 or len(key.split(", ")) == lines, view  # a colour word per line
        shown += entities
    # Every series of the recording is shown, each in one panel.
    series = {
        c.entity_path.lstrip("/")
        for c in RrdReader(path).stream().to_chunks()
        if "SeriesLines:names" in c.to_record_batch().schema.names
    }
    assert sorted(shown) == sorted(series)


def test_params_document_holds_the_config(short_run, short_config, entity_columns):
    _, path = short_run
    _, texts = entity_columns(path, "params", "TextDocument:text")
    text = texts[-1][0]
    assert "# exo_ctrl run" in text and "step_length" in text and "stiffness_N_per_m" in text
    _, meta = entity_columns(path, "raw/meta", "TextDocument:text")
    assert json.loads(meta[-1][0])["config"] == json.loads(json.dumps(short_config.to_dict()))


def test_every_series_chunk_carries_the_seconds_timeline(short_run):
    """Every chunk under signals/ is on sim_time, t_k = k Δt in whole ns, beside the tick."""
    _, path = short_run
    seen = set()
    for chunk in RrdReader(path).stream().to_chunks():
        if not chunk.entity_path.startswith("/signals/"):
            continue
        batch = chunk.to_record_batch()
        if "Scalars:scalars" not in batch.schema.names:
            continue
        assert "sim_time" in chunk.timeline_names, chunk.entity_path
        ticks = batch.column("tick").to_numpy()
        ns = batch.column("sim_time").cast("int64").to_numpy()
        assert np.array_equal(ns, np.round(ticks * 1e-3 * 1e9).astype(np.int64))
        seen.update(ticks.tolist())
    assert seen == set(range(300))


def test_the_time_panel_shows_seconds_and_the_blueprint_is_active(short_run):
    _, path = short_run
    reader = RrdReader(path)
    (store,) = reader.blueprints()
    timelines = [
        c.to_record_batch().column("TimePanelBlueprint:timeline").to_pylist()[-1]
        for c in reader.stream(store=store).to_chunks()
        if c.entity_path == "/time_panel"
        and "TimePanelBlueprint:timeline" in c.to_record_batch().schema.names
    ]
    assert timelines == [["sim_time"]]
    # Sent active, not only as a default (the viewer kept its own layout over a default).
    printed = subprocess.run(
        [str(Path(sys.executable).with_name("rerun")), "rrd", "print", str(path)],
        capture_output=True,
        text=True,
        timeout=120,
    ).stdout
    (command,) = [line for line in printed.splitlines() if "BlueprintActivationCommand" in line]
    assert "make_active: true" in command and "make_default: true" in command


def test_panel_names_say_the_quantity_and_the_joint_or_cuff_in_full(short_run):
    _, path = short_run
    names = {v["name"].partition(" [")[0] for v in blueprint_views(path)}
    for joint in JOINT_NAMES:
        words = joint.replace("_", " ")
        for what in ("Joint angle", "Joint speed", "Drive voltage"):
            assert f"{what}, {words}" in names
    for leg in ("left", "right"):  # (no patient torque: left out of a passive run)
        for what in ("Drive torque", "Drive current"):
            assert f"{what}, {leg} leg" in names
    for cuff in CUFF_NAMES:
        words = cuff.replace("_", " ")
        assert f"Cuff force on the exo, {words} cuff" in names
        assert f"Estimated cuff force on the exo, {words} cuff" in names
    assert "Joint torque sensor reading (tau_sensor)" in names
    assert not any("/" in name for name in names)  # no entity path


def test_the_3d_view_takes_at_least_half_the_width(short_run):
    _, path = short_run
    views = blueprint_views(path)
    (scene,) = [v for v in views if v["class"] == "3D"]
    assert scene["width_share"] == pytest.approx(0.6) and scene["width_share"] >= 0.5
    plots = [v["width_share"] for v in views if v["class"] == "TimeSeries"]
    assert max(plots) == pytest.approx(0.4)
