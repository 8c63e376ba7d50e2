"""Tests of exo_ctrl.record.format: every signal of the log schema, and only it, is recorded.

The layout is derived from :data:`exo_ctrl.sim.schema.SIGNALS` when a
recording starts: a signal added there appears under ``signals/`` and in
:func:`read_recording`'s result with no other change.  Each value is stored
once (format version 2: no second copy under ``raw/``), and the signals of
the features off in the run are left out of the file and read back as their
constant.
"""

from __future__ import annotations

import json

import numpy as np
from rerun.chunk import RrdReader

from exo_ctrl.model import load_exo, load_patient
from exo_ctrl.record import RerunRecorder, read_recording
from exo_ctrl.record.format import layout
from exo_ctrl.record.omitted import left_out_signals
from exo_ctrl.sim import SimConfig, SimResult, schema, simulate
from exo_ctrl.sim.schema import Signal, log_dtype, signal_shapes

#: The documented series of the per-joint signals: entity and component.
JOINT_SERIES = {
    "q_des": ("joint_angle", 0),
    "q": ("joint_angle", 1),
    "q_patient": ("joint_angle", 2),
    "dq_des": ("joint_speed", 0),
    "dq": ("joint_speed", 1),
    "dq_patient": ("joint_speed", 2),
    "drive_torque": ("drive_torque", 0),
    "patient_torque": ("patient_torque", 0),
    "current": ("current", 0),
    "voltage_cmd": ("voltage", 0),
    "voltage": ("voltage", 1),
}


def test_human_friendly_series_match_signals(short_run, entity_columns):
    """Every entry of SIGNALS, whatever it holds, has its series under signals/.

    Unless its feature is off in the run (no contact, fixed pelvis, ...): then
    it has none, ``raw/meta`` gives its constant, and that is what it held.
    """
    result, path = short_run
    _, meta = entity_columns(path, "raw/meta", "TextDocument:text")
    left_out = json.loads(meta[-1][0])["left_out"]
    assert left_out == left_out_signals(result.config)
    assert {"ground_force", "pelvis_z", "patient_torque", "path_phase"} <= set(left_out)
    stored = {c.entity_path for c in RrdReader(path).stream().to_chunks()}
    for name, shape in signal_shapes().items():
        values = result.signals[name]
        if name in left_out:
            assert np.all(values == left_out[name]), name
            assert not any(e.startswith(f"/signals/{name}") for e in stored), name
            continue
        if name in JOINT_SERIES:
            quantity, part = JOINT_SERIES[name]
            entity, expected = f"{quantity}/left_knee", values[:, 1]
        elif shape == (4, 2):
            entity, part, expected = f"{name}/right_shank", 1, values[:, 3, 1]
        elif shape == (2, 2):  # per foot (x, z)
            entity, part, expected = f"{name}/right", 1, values[:, 1, 1]
        else:
            flat = values.reshape(values.shape[0], -1)
            entity, part, expected = name, flat.shape[1] - 1, flat[:, -1]
        ticks, series = entity_columns(path, f"signals/{entity}", "Scalars:scalars")
        assert ticks.tolist() == list(range(300)), name
        assert np.array_equal(np.asarray(series)[:, part], expected), name
    _, force = entity_columns(path, "signals/cuff_force/left_shank", "Scalars:scalars")
    expected = np.column_stack([*result.signals["cuff_force"][:, 1].T])
    assert np.array_equal(np.asarray(force)[:, :2], expected)
    assert np.allclose(np.asarray(force)[:, 2], np.hypot(*expected.T))
    _, names = entity_columns(path, "signals/joint_angle/left_hip", "SeriesLines:names")
    assert names == [["left_hip desired", "left_hip actual", "left_hip patient"]]


def test_layout_falls_back_to_plain_series_for_signals_it_does_not_know():
    shapes = {"q": (4,), "odd": (2, 3), "pair": (4, 2), "level": ()}
    lay = layout(shapes)
    entities = {s.entity: s for s in lay.series}
    # q alone of its joint group: one entity per joint, the actual angle.
    assert entities["signals/joint_angle/left_knee"].columns == (1,)
    # Unknown (unlabelled) signals: one entity, components flattened row-major.
    assert entities["signals/odd"].names == [f"odd[{i}][{j}]" for i in range(2) for j in range(3)]
    assert entities["signals/odd"].columns == tuple(range(4, 10))
    assert entities["signals/pair"].columns == tuple(range(10, 18))
    assert entities["signals/level"].names == ["level"]
    assert entities["signals/level"].columns == (18,)
    assert lay.width == 19 and lay.magnitudes == ()


def test_a_signal_added_to_the_schema_is_recorded_and_read_back(
    tmp_path, ticks_by_entity, monkeypatch
):
    """A throwaway (3,) signal appended to SIGNALS: in the file and in read_recording.

    The recorder is driven as the loop drives it, with rows that are views of
    the fields of one structured log array (not contiguous).
    """
    probe = Signal("probe_xyz", (3,), "m", "a throwaway signal of this test")
    monkeypatch.setattr(schema, "SIGNALS", [*schema.SIGNALS, probe])
    config = SimConfig(duration_s=0.05, chunk_ticks=20)
    n = config.n_ticks
    log = np.zeros(n, dtype=log_dtype())
    rng = np.random.default_rng(7)
    for name in log.dtype.names:
        log[name] = rng.uniform(-1.0, 1.0, log[name].shape)
    result = SimResult(
        config=config,
        t=np.arange(n) * config.dt,
        signals={},
        belt_speed_mps=config.gait.belt_speed,
        exo_source=load_exo(None).source,
        patient_source=load_patient(None).source,
    )
    path = tmp_path / "probe.rrd"
    recorder = RerunRecorder(path)
    recorder.start(result)
    for start in range(0, n, config.chunk_ticks):
        view = log[start : start + config.chunk_ticks]
        rows = {name: view[name] for name in log.dtype.names}
        assert not rows["q"].flags.c_contiguous  # the loop's views of a structured array
        recorder.chunk(result, start, rows)
    recorder.finish(result)

    back = read_recording(path)
    assert back.signals["probe_xyz"].shape == (n, 3)
    for name in log.dtype.names:
        assert np.array_equal(back.signals[name], log[name]), name
    ticks = ticks_by_entity(path)
    assert sorted(ticks["/signals/probe_xyz"]) == list(range(n))
    assert not any(e.startswith("/raw/") for e in ticks)  # each value once, in its series


def test_a_signal_added_to_the_schema_reaches_the_recording_of_a_run(tmp_path, monkeypatch):
    """The same through :func:`simulate`: nothing but the schema entry is added."""
    probe = Signal("probe_xyz", (3,), "m", "a throwaway signal of this test")
    monkeypatch.setattr(schema, "SIGNALS", [*schema.SIGNALS, probe])
    path = tmp_path / "run.rrd"
    result = simulate(SimConfig(duration_s=0.05, chunk_ticks=20), observers=[RerunRecorder(path)])
    assert result.status == "completed"
    back = read_recording(path)
    assert back.signals["probe_xyz"].shape == (50, 3)
    for name in signal_shapes():
        assert np.array_equal(back.signals[name], result.signals[name]), name
    entities = {c.entity_path for c in RrdReader(path).stream().to_chunks()}
    assert "/signals/probe_xyz" in entities and "/raw/probe_xyz" not in entities


def test_a_file_without_a_schema_signal_reads_it_as_nan(short_run, monkeypatch):
    probe = Signal("probe_xyz", (3,), "m", "a throwaway signal of this test")
    monkeypatch.setattr(schema, "SIGNALS", [*schema.SIGNALS, probe])
    result, path = short_run
    back = read_recording(path)
    assert back.signals["probe_xyz"].shape == (300, 3)
    assert np.isnan(back.signals["probe_xyz"]).all()
    assert np.array_equal(back.signals["q"], result.signals["q"])
