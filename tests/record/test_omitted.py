"""Tests of exo_ctrl.record.omitted and of the signals a recording leaves out.

The table of features (:data:`~exo_ctrl.record.omitted.FEATURES`) is checked
against the simulation itself: off, every signal it names holds its constant
over a whole run; on, each of those signals moves in a run that exercises
it, so the table names nothing that matters.  The recorder's safety net (a
left-out signal that moves is stored from that chunk on) and the reading of
format-1 files (every signal whole under ``raw/``) are checked on files.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import rerun as rr

from exo_ctrl.model import load_exo, load_patient
from exo_ctrl.plant import CompliantJoint, ContactParams, PelvisParams
from exo_ctrl.record import RECORDING_FORMAT, RerunRecorder, read_recording
from exo_ctrl.record.format import dumps
from exo_ctrl.record.omitted import FEATURES, left_out_signals
from exo_ctrl.sensing import CuffSensorParams, FootLoadParams
from exo_ctrl.sim import SimConfig, SimResult, simulate
from exo_ctrl.sim.schema import log_dtype, signal_shapes

CONTACT = ContactParams(enabled=True)
#: Runs with every feature of the table off (the default) and runs with each on.
OFF = SimConfig(duration_s=0.3)
ON = {
    # The plates' torque with any upward reading: with the pelvis fixed the feet skim the belt,
    # under the default contact threshold (sensing/foot_load.py), and it would stay 0.
    "foot-belt contact": SimConfig(
        duration_s=0.6,
        controller="ct",
        contact=CONTACT,
        sync=False,
        foot_load=FootLoadParams(contact_threshold_sd=0.0),
    ),
    "the patient's feet": SimConfig(
        duration_s=0.6,
        controller="ct",
        contact=ContactParams(enabled=True, patient_feet=True),
        safety=False,
    ),
    "the pelvis on its guide": SimConfig(
        duration_s=0.6,
        controller="ct",
        contact=CONTACT,
        sync=False,
        pelvis=PelvisParams(supported=True, bws_fraction=0.5),
    ),
    "the patient's own torques": SimConfig(duration_s=0.6, patient_torque="spastic"),
    "compliant joints": SimConfig(duration_s=0.3, joint_compliance=CompliantJoint(enabled=True)),
    "the QP controller": SimConfig(
        duration_s=0.6, controller="qp", patient_torque="spastic", cuff_force_limit_N=150.0
    ),
    "the path mode": SimConfig(duration_s=2.5, mode="path", patient_torque="active"),
    "the cuffs' force sensors": SimConfig(
        duration_s=0.3, cuff_sensors=CuffSensorParams(mode="normal")
    ),
    "the cuff sensors' along axis": SimConfig(
        duration_s=0.3, cuff_sensors=CuffSensorParams(mode="full")
    ),
}


def _feature(prefix: str):
    (feature,) = [f for f in FEATURES if f.name.startswith(prefix)]
    return feature


def test_every_feature_of_the_table_is_off_in_the_default_run():
    assert set(left_out_signals(OFF)) == {s for f in FEATURES for s in f.signals}
    assert set(left_out_signals(OFF)) < set(signal_shapes())  # only schema signals
    assert not set(left_out_signals(ON["foot-belt contact"])) & set(_feature("foot-belt").signals)


def test_a_feature_that_is_off_holds_its_signals_constant():
    result = simulate(OFF)
    for name, value in left_out_signals(OFF).items():
        assert np.all(result.signals[name] == value), name


@pytest.mark.parametrize("prefix", sorted(ON))
def test_a_feature_that_is_on_moves_its_signals(prefix):
    """On, each signal the table names for the feature leaves its constant at some tick.

    (The foot-belt contact's touchdown velocity moves once a foot lands.  Two
    stay at 0 in a run that goes well: the QP's count of fallbacks, and the
    pelvis's stop force, which acts only at the end of its travel.)
    """
    feature = _feature(prefix)
    config = ON[prefix]
    assert not set(feature.signals) & set(left_out_signals(config))
    result = simulate(config)
    for name, value in left_out_signals(config).items():  # the features still off: constant
        assert np.all(result.signals[name] == value), name
    moved = {name for name in feature.signals if np.any(result.signals[name] != feature.value)}
    quiet = {"qp_failures", "pelvis_stop_force"}
    assert moved >= set(feature.signals) - quiet, sorted(set(feature.signals) - moved)


def _result(config: SimConfig) -> SimResult:
    return SimResult(
        config=config,
        t=np.arange(config.n_ticks) * config.dt,
        signals={},
        belt_speed_mps=config.gait.belt_speed,
        exo_source=load_exo(None).source,
        patient_source=load_patient(None).source,
    )


def test_a_left_out_signal_that_moves_is_stored_from_that_chunk_on(tmp_path, ticks_by_entity):
    """The contact is off, yet ground_force moves in the third chunk: nothing is lost.

    The file stores it from tick 40 on (the chunk it moved in); the reader
    fills the ticks before with the constant ``raw/meta`` gives: the rows as
    they were handed over, bit for bit.
    """
    config = SimConfig(duration_s=0.1, chunk_ticks=20)
    n = config.n_ticks
    log = np.zeros(n, dtype=log_dtype())
    rng = np.random.default_rng(3)
    left_out = left_out_signals(config)
    for name in log.dtype.names:
        if name not in left_out:
            log[name] = rng.uniform(-1.0, 1.0, log[name].shape)
        else:
            log[name] = left_out[name]
    log["ground_force"][45:] = rng.uniform(0.0, 100.0, log["ground_force"][45:].shape)
    path = tmp_path / "moved.rrd"
    recorder = RerunRecorder(path)
    result = _result(config)
    recorder.start(result)
    for start in range(0, n, config.chunk_ticks):
        view = log[start : start + config.chunk_ticks]
        recorder.chunk(result, start, {name: view[name] for name in log.dtype.names})
    recorder.finish(result)

    back = read_recording(path)
    for name in log.dtype.names:
        assert np.array_equal(back.signals[name], log[name]), name
    ticks = ticks_by_entity(path)
    assert sorted(ticks["/signals/ground_force/left"]) == list(range(40, n))
    assert "/signals/foot_slip" not in ticks  # still constant: still left out


def test_a_version_1_file_reads_back(tmp_path, short_run, assert_same_run):
    """A file of format 1 (every signal whole under raw/, nothing left out) reads as before."""
    result, _ = short_run
    config = result.config
    path = tmp_path / "v1.rrd"
    rec = rr.RecordingStream("exo_ctrl")
    rec.save(path)
    meta = {
        "format": RECORDING_FORMAT,
        "version": 1,
        "config": config.to_dict(),
        "dt": config.dt,
        "n_ticks_planned": config.n_ticks,
        "belt_speed_mps": result.belt_speed_mps,
        "exo_source": result.exo_source,
        "patient_source": result.patient_source,
        "signals": {name: list(shape) for name, shape in signal_shapes().items()},
    }
    rec.log("raw/meta", rr.TextDocument(dumps(meta)), static=True)
    ticks = np.arange(result.n_ticks)
    for name, values in result.signals.items():
        rec.send_columns(
            f"raw/{name}",
            indexes=[rr.TimeColumn("tick", sequence=ticks)],
            columns=rr.Scalars.columns(scalars=values.reshape(ticks.shape[0], -1)),
        )
    outcome = {"status": result.status, "events": result.events, "ticks": result.n_ticks}
    rec.log("raw/outcome", rr.TextDocument(json.dumps(outcome)), static=True)
    rec.disconnect()
    back = read_recording(path)
    assert back.status == "completed"
    assert_same_run(back, result)
