"""Tests of exo_ctrl.record.blueprint and the file as a whole: verified, with its blueprint."""

from __future__ import annotations

import json

from rerun.chunk import RrdReader

from exo_ctrl.record import blueprint_views


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
    views = {(v["class"], v["origin"]) for v in blueprint_views(path)}
    expected = {
        ("3D", "world"),
        ("TextLog", "events"),
        ("TextDocument", "params"),
        ("TimeSeries", "signals/joint_angle"),
        ("TimeSeries", "signals/drive_torque"),
        ("TimeSeries", "signals/current"),
        ("TimeSeries", "signals/voltage"),
        ("TimeSeries", "signals/cuff_force"),
    }
    assert expected <= views
    # Every view shows something that is in the recording.
    entities = {c.entity_path for c in reader.stream().to_chunks()}
    for _, origin in views:
        assert any(e == "/" + origin or e.startswith(f"/{origin}/") for e in entities), origin


def test_params_document_holds_the_config(short_run, short_config, entity_columns):
    _, path = short_run
    _, texts = entity_columns(path, "params", "TextDocument:text")
    text = texts[-1][0]
    assert "# exo_ctrl run" in text and "step_length" in text and "stiffness_N_per_m" in text
    _, meta = entity_columns(path, "raw/meta", "TextDocument:text")
    assert json.loads(meta[-1][0])["config"] == json.loads(json.dumps(short_config.to_dict()))
