"""Tests of exo_ctrl.record.reader: real simulations written to real .rrd files and read back."""

from __future__ import annotations

import dataclasses
import struct

import numpy as np
import pytest
import rerun as rr
from rerun.chunk import RrdReader

from exo_ctrl.exceptions import RecordingError
from exo_ctrl.plan import GaitParams
from exo_ctrl.plant.cuffs import CuffParams
from exo_ctrl.record import RerunRecorder, read_recording
from exo_ctrl.record.reader import read_recording_integrity
from exo_ctrl.scenario import preset
from exo_ctrl.sim import SimConfig, simulate


def test_readback_equals_simulation_exactly(short_run, short_config, assert_same_run):
    result, path = short_run
    back = read_recording(path)
    assert back.n_ticks == result.n_ticks == short_config.n_ticks == 300
    assert_same_run(back, result)
    assert back.status == "completed" and back.error == "" and back.events == []
    assert back.config == short_config
    assert back.exo_source == result.exo_source
    assert back.patient_source == result.patient_source
    assert back.belt_speed_mps == result.belt_speed_mps
    assert back.summary() == result.summary()


def test_readback_of_a_non_default_config(tmp_path, assert_same_run, entity_columns):
    config = SimConfig(
        duration_s=0.05,
        chunk_ticks=16,
        controller="ct",
        gait=GaitParams(step_length=0.3, period=1.4),
        cuffs=CuffParams(stiffness_N_per_m=6000.0, damping_N_s_per_m=80.0),
        control_rate_hz=800.0,
        patient_torque="spastic",
        estop_at_s=0.02,
    )
    path = tmp_path / "ct.rrd"
    result = simulate(config, observers=[RerunRecorder(path)])
    assert [e["kind"] for e in result.events] == ["estop", "state"]  # precondition
    back = read_recording(path)
    assert back.config == config
    assert_same_run(back, result)
    assert back.events == result.events
    assert back.safety_state == result.safety_state == "stopping"
    _, logs = entity_columns(path, "events", "TextLog:text")
    assert any("emergency stop" in text[0] for text in logs)
    ticks, _ = entity_columns(path, "signals/q_meas", "Scalars:scalars")
    times, _ = entity_columns(path, "signals/joint_angle/left_hip", "Scalars:scalars")
    assert ticks.tolist() == list(range(40)) and times.tolist() == list(range(40))


def test_sim_time_timeline_is_tick_times_dt(short_run):
    _, path = short_run
    chunks = [
        c
        for c in RrdReader(path).stream().to_chunks()
        if c.entity_path == "/signals/drive_torque/left_hip" and "sim_time" in c.timeline_names
    ]
    ns = np.concatenate(
        [c.to_record_batch().column("sim_time").cast("int64").to_numpy() for c in chunks]
    )
    assert np.array_equal(np.sort(ns), np.round(np.arange(300) * 1e-3 * 1e9).astype(np.int64))


def test_read_refuses_missing_foreign_and_junk_files(tmp_path):
    with pytest.raises(RecordingError, match="file not found"):
        read_recording(tmp_path / "nope.rrd")
    junk = tmp_path / "junk.rrd"
    junk.write_text("not a recording")
    with pytest.raises(RecordingError, match=r"junk\.rrd"):
        read_recording(junk)
    foreign = tmp_path / "foreign.rrd"
    rec = rr.RecordingStream("someone_else")
    rec.save(foreign)
    rec.send_columns(
        "raw/q",
        indexes=[rr.TimeColumn("tick", sequence=np.arange(3))],
        columns=rr.Scalars.columns(scalars=np.zeros((3, 4))),
    )
    rec.disconnect()
    with pytest.raises(RecordingError, match="not written by exo_ctrl"):
        read_recording(foreign)


def test_a_file_gone_while_it_is_read_is_a_recording_error(tmp_path, monkeypatch):
    """A run that fails at its start removes its empty partial file, perhaps mid-read."""
    gone = tmp_path / "run.partial.rrd"
    gone.write_bytes(b"")

    def vanish(path):
        path.unlink()
        raise ValueError("empty file")  # what rerun says of the empty file

    monkeypatch.setattr("exo_ctrl.record.reader._load_chunks", vanish)
    with pytest.raises(RecordingError) as info:
        read_recording_integrity(gone)
    assert str(info.value) == (
        f"cannot read recording {gone}: [Errno 2] No such file or directory: '{gone}'"
    )


@pytest.mark.parametrize("keep", [-1, -32, -40, -5000])
def test_a_file_cut_in_its_footer_keeps_every_message(short_run, assert_same_run, tmp_path, keep):
    """A file that ends inside the end marker or the stream footer (a write cut short).

    Cut 1, 32, 40 and 5000 bytes before its end: in the stream footer, at its
    start, in and well inside the footer.  Every message before the footer is
    whole: all 300 ticks and the end record come back; the cut is reported
    at the end marker's offset.
    """
    result, path = short_run
    data = path.read_bytes()
    marker, _, _ = struct.unpack_from("<QQI", data, len(data) - 32)  # the footer's payload
    cut = tmp_path / "cut.rrd"
    cut.write_bytes(data[:keep])
    back, integrity = read_recording_integrity(cut)
    assert integrity.cut_at_byte == marker - 16  # the end marker's header
    assert integrity.has_end_record and back.status == result.status == "completed"
    assert_same_run(back, result)


def test_a_runs_notes_are_read_back(tmp_path):
    """The QP over the belt tells how it keeps its bound (a note, not a warning); read back."""
    config = dataclasses.replace(preset("paper").config, controller="qp", duration_s=0.02)
    path = tmp_path / "qp.rrd"
    result = simulate(config, observers=[RerunRecorder(path)])
    (note,) = result.notes
    assert note.startswith("with the feet over the belt the walk stops (yield)")
    assert not any("over the belt" in w for w in result.warnings)
    back = read_recording(path)
    assert back.notes == result.notes and back.warnings == result.warnings
    assert back.summary()["notes"] == [note]
