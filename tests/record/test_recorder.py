"""Tests of exo_ctrl.record.recorder: real simulations written to real .rrd files and read back.

Exactness: rerun stores scalars as float64, so every signal must come back
bit for bit (``np.array_equal``), and ``t`` too (rebuilt as k Δt).  3-D
points are float32 in rerun, so they are compared to Pinocchio within 1e-6 m.
The raw rerun reader (``rerun.chunk.RrdReader``) is used here to look at
entities directly, independently of :func:`read_recording`.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import rerun as rr
from rerun.chunk import RrdReader

from exo_ctrl.exceptions import RecordingError
from exo_ctrl.model.body import CUFF_NAMES, SIDES, load_body, load_patient
from exo_ctrl.plan.gait import GaitParams
from exo_ctrl.plant.cuffs import CuffParams
from exo_ctrl.record import recorder as record
from exo_ctrl.record.recorder import (
    FORCE_ARROW_M_PER_N,
    RerunRecorder,
    blueprint_views,
    read_recording,
)
from exo_ctrl.sim.loop import SIGNALS, SimConfig, SimResult, simulate

#: A short run; 70-tick chunks so the last chunk (300 = 4 x 70 + 20) is partial.
SHORT = SimConfig(duration_s=0.3, chunk_ticks=70)
#: Absurdly stiff cuffs (1250 x the paper's 8 N/mm): the 1 ms step is unstable.
#: (Absurd PD gains do not diverge: the 24 V supply saturates the drives.)
DIVERGING = SimConfig(duration_s=0.3, chunk_ticks=4, cuffs=CuffParams(stiffness_N_per_m=1e7))


def rerun_cli() -> list[str]:
    exe = Path(sys.executable).with_name("rerun")
    if exe.is_file():
        return [str(exe)]
    found = shutil.which("rerun")
    return [found] if found else [sys.executable, "-m", "rerun"]


def verify(path: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [*rerun_cli(), "rrd", "verify", str(path)], capture_output=True, text=True, timeout=60
    )


def entity_columns(path: Path, entity: str, column: str) -> tuple[np.ndarray, list]:
    """(ticks, values) of one component of one entity, straight from the file, by tick.

    Static entities have no ticks: an empty tick array and the values as stored.
    """
    ticks, values = [], []
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*no footer.*")  # crashed writers
        chunks = RrdReader(path).stream().to_chunks()
    for chunk in chunks:
        if chunk.entity_path != "/" + entity:
            continue
        batch = chunk.to_record_batch()
        if column not in batch.schema.names:
            continue
        if "tick" in batch.schema.names:
            ticks += batch.column("tick").to_pylist()
        values += batch.column(column).to_pylist()
    if not ticks:
        return np.zeros(0, dtype=np.int64), values
    order = np.argsort(ticks, kind="stable")
    return np.asarray(ticks)[order], [values[i] for i in order]


def assert_same_run(back: SimResult, ref: SimResult, n: int | None = None) -> None:
    """Every signal and t exactly equal (the first n ticks of ref when n is given)."""
    n = ref.t.shape[0] if n is None else n
    assert back.t.shape == (n,)
    assert np.array_equal(back.t, ref.t[:n])
    assert set(back.signals) == set(SIGNALS)
    for name, (shape, _, _) in SIGNALS.items():
        assert back.signals[name].shape == (n, *shape), name
        assert back.signals[name].dtype == np.float64, name
        assert np.array_equal(back.signals[name], ref.signals[name][:n]), name


class Raise:
    """An observer that raises ``exc`` (once, or every time) from chunk() at tick >= at."""

    def __init__(self, exc: BaseException, at: int, once: bool = True) -> None:
        self.exc, self.at, self.once, self.raised = exc, at, once, 0

    def start(self, result: SimResult) -> None:
        pass

    def chunk(self, result: SimResult, start: int, rows: dict) -> None:
        if start >= self.at and not (self.once and self.raised):
            self.raised += 1
            raise self.exc

    def finish(self, result: SimResult) -> None:
        pass


@pytest.fixture(scope="module")
def short_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[SimResult, Path]:
    path = tmp_path_factory.mktemp("rec") / "short.rrd"
    result = simulate(SHORT, observers=[RerunRecorder(path)])
    assert result.status == "completed"
    return result, path


@pytest.fixture(scope="module")
def reference() -> SimResult:
    """SHORT run without observers (the loop is deterministic)."""
    return simulate(SHORT)


# --------------------------------------------------------------------------- readback


def test_readback_equals_simulation_exactly(short_run):
    result, path = short_run
    back = read_recording(path)
    assert back.n_ticks == result.n_ticks == SHORT.n_ticks == 300
    assert_same_run(back, result)
    assert back.status == "completed" and back.error == "" and back.events == []
    assert back.config == SHORT
    assert back.exo_source == result.exo_source
    assert back.patient_source == result.patient_source
    assert back.belt_speed_mps == result.belt_speed_mps
    assert back.summary() == result.summary()


def test_readback_of_a_non_default_config(tmp_path):
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
    ticks, _ = entity_columns(path, "raw/q", "Scalars:scalars")
    times, _ = entity_columns(path, "signals/joint_angle/left_hip", "Scalars:scalars")
    assert ticks.tolist() == list(range(40)) and times.tolist() == list(range(40))


def test_sim_time_timeline_is_tick_times_dt(short_run):
    _, path = short_run
    chunks = [
        c for c in RrdReader(path).stream().to_chunks() if c.entity_path == "/raw/drive_torque"
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


# --------------------------------------------------------------------------- file and blueprint


def test_rrd_verify_passes(short_run):
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


def test_params_document_holds_the_config(short_run):
    _, path = short_run
    _, texts = entity_columns(path, "params", "TextDocument:text")
    text = texts[-1][0]
    assert "# exo_ctrl run" in text and "step_length" in text and "stiffness_N_per_m" in text
    _, meta = entity_columns(path, "raw/meta", "TextDocument:text")
    assert json.loads(meta[-1][0])["config"] == json.loads(json.dumps(SHORT.to_dict()))


# --------------------------------------------------------------------------- failures


def test_diverged_run_keeps_ticks_and_error(tmp_path):
    path = tmp_path / "diverged.rrd"
    result = simulate(DIVERGING, observers=[RerunRecorder(path)])
    assert result.status == "diverged", "precondition: the stiff-cuff run must diverge"
    assert 0 < result.n_ticks < DIVERGING.n_ticks and result.n_ticks % 4 != 0
    back = read_recording(path)
    assert back.status == "diverged"
    assert back.error == result.error and "diverged" in back.error
    assert back.events == result.events
    assert_same_run(back, result)
    _, logs = entity_columns(path, "events", "TextLog:text")
    _, levels = entity_columns(path, "events", "TextLog:level")
    assert any(result.error in text[0] for text in logs)
    assert ["ERROR"] in levels
    assert verify(path).returncode == 0


@pytest.mark.parametrize("recorder_first", [True, False])
def test_keyboard_interrupt_from_an_observer(tmp_path, recorder_first):
    """Ctrl-C inside an observer: the run ends "interrupted" and the file is complete.

    The loop hands each chunk to the observers in order, so an observer that
    raises before the recorder keeps that chunk from it (140 ticks instead
    of 210).
    """
    path = tmp_path / "interrupted.rrd"
    recorder = RerunRecorder(path)
    stop = Raise(KeyboardInterrupt(), at=140)
    observers = [recorder, stop] if recorder_first else [stop, recorder]
    result = simulate(SHORT, observers=observers)
    assert result.status == "interrupted" and stop.raised == 1
    assert result.t.shape[0] == 210
    n = 210 if recorder_first else 140
    back = read_recording(path)
    assert back.n_ticks == n
    ticks, _ = entity_columns(path, "raw/q", "Scalars:scalars")
    assert ticks.tolist() == list(range(n))  # each tick stored once
    assert_same_run(back, result, n=n)
    assert back.status == "interrupted" and back.error == result.error
    assert back.events == result.events
    _, levels = entity_columns(path, "events", "TextLog:level")
    assert ["WARN"] in levels
    assert verify(path).returncode == 0


def test_observer_that_raises_leaves_a_complete_file(tmp_path, reference):
    """Another observer's exception: recorded as status "error", then raised."""
    path = tmp_path / "boom.rrd"
    recorder = RerunRecorder(path)
    with pytest.raises(RuntimeError, match="boom"):
        simulate(SHORT, observers=[recorder, Raise(RuntimeError("boom"), at=140, once=False)])
    back = read_recording(path)
    assert back.n_ticks == 210  # chunks 0-69, 70-139 and 140-209 were flushed
    assert_same_run(back, reference, n=210)
    assert back.status == "error" and back.error == "RuntimeError: boom"
    _, levels = entity_columns(path, "events", "TextLog:level")
    assert ["ERROR"] in levels
    assert verify(path).returncode == 0
    recorder.close()  # a no-op after finish()
    assert read_recording(path).n_ticks == 210


def test_each_chunk_is_on_disk_when_chunk_returns(tmp_path):
    """Each chunk is in the file when chunk() returns: nothing is held back for later."""
    path = tmp_path / "flushed.rrd"

    class OnDisk:
        def __init__(self) -> None:
            self.seen: list[int] = []

        def start(self, result):
            pass

        def chunk(self, result, start, rows):
            self.seen.append(read_recording(path).n_ticks)

        def finish(self, result):
            pass

    probe = OnDisk()
    simulate(SHORT, observers=[RerunRecorder(path), probe])
    assert probe.seen == [70, 140, 210, 280, 300]


def test_hard_crash_keeps_every_flushed_chunk(tmp_path, reference):
    path = tmp_path / "crash.rrd"
    script = textwrap.dedent(
        f"""
        import os
        from exo_ctrl.record.recorder import RerunRecorder
        from exo_ctrl.sim.loop import SimConfig, simulate

        class Crash:
            def start(self, result): pass
            def chunk(self, result, start, rows):
                if start >= 140:
                    os._exit(3)
            def finish(self, result): pass

        simulate(SimConfig(duration_s=0.3, chunk_ticks=70),
                 observers=[RerunRecorder({str(path)!r}), Crash()])
        """
    )
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, timeout=120)
    assert proc.returncode == 3, proc.stderr.decode()
    back = read_recording(path)
    assert back.n_ticks == 210
    assert_same_run(back, reference, n=210)
    assert back.status == "interrupted" and "without an end record" in back.error
    # The last entity the recorder sends per chunk made it too (the flush).
    ticks, _ = entity_columns(path, "world/belt/stripes", "LineStrips3D:strips")
    assert ticks.tolist() == list(range(0, 210, 20))


def test_unwritable_paths_raise_at_start(tmp_path):
    ran = Raise(AssertionError("the loop must not start"), at=0)
    with pytest.raises(RecordingError, match=r"missing.* does not exist"):
        simulate(SHORT, observers=[RerunRecorder(tmp_path / "missing" / "x.rrd"), ran])
    with pytest.raises(RecordingError, match="is a directory"):
        simulate(SHORT, observers=[RerunRecorder(tmp_path), ran])
    if Path("/dev/full").exists():
        with pytest.raises(RecordingError, match="No space left"):
            simulate(SHORT, observers=[RerunRecorder("/dev/full"), ran])
    if os.geteuid() != 0:  # root ignores permissions
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        with pytest.raises(RecordingError, match="permission denied"):
            simulate(SHORT, observers=[RerunRecorder(locked / "x.rrd"), ran])


def test_not_enough_free_space_raises_at_start(tmp_path, monkeypatch):
    monkeypatch.setattr(record, "BYTES_PER_TICK_ESTIMATE", 10**12)
    path = tmp_path / "big.rrd"
    with pytest.raises(RecordingError, match=r"MB needed for 300 ticks, .* MB free"):
        simulate(SHORT, observers=[RerunRecorder(path)])
    assert not path.exists()


def test_write_failure_mid_run_raises_recording_error(tmp_path, reference):
    """A 1 MB file-size limit makes the disk 'full' in the third chunk.

    The file holds about 127 kB of parameters, geometry and blueprint, then
    about 320 kB per 70-100-tick chunk.
    """
    path = tmp_path / "full.rrd"
    script = textwrap.dedent(
        f"""
        import resource, signal
        from exo_ctrl.record import recorder as record
        from exo_ctrl.exceptions import RecordingError
        from exo_ctrl.record.recorder import RerunRecorder
        from exo_ctrl.sim.loop import SimConfig, simulate

        # After the write error rerun's flush sometimes blocks until the timeout.
        record.FLUSH_TIMEOUT_S = 3.0
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (1_000_000, 1_000_000))
        try:
            simulate(SimConfig(duration_s=0.3, chunk_ticks=70),
                     observers=[RerunRecorder({str(path)!r})])
        except RecordingError as exc:
            print("RecordingError:", exc)
        """
    )
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, timeout=120)
    out = proc.stdout.decode()
    assert proc.returncode == 0, proc.stderr.decode()
    assert out.startswith(f"RecordingError: writing recording {path} failed after tick"), out
    flushed = int(re.search(r"after tick (\d+)", out).group(1))
    assert flushed in (140, 210)
    # What reached the disk is still readable (the message cut short is dropped).
    back = read_recording(path)
    assert flushed <= back.n_ticks < 300
    assert back.status == "interrupted" and "cut at byte" in back.error
    assert_same_run(back, reference, n=back.n_ticks)


# --------------------------------------------------------------------------- 3-D


def test_3d_points_match_pinocchio(short_run):
    result, path = short_run
    exo = load_body(result.exo_source)
    patient = load_patient(None)
    q, qp = result.signals["q"], result.signals["q_patient"]
    hip_e, hip_p = exo.legs["left"].hip_xz, patient.legs["left"].hip_xz
    shift = np.array([hip_e[0] - hip_p[0], 0.0, hip_e[1] - hip_p[1]])
    for side in SIDES:
        ticks, joints = entity_columns(path, f"world/exo/{side}/joints", "Points3D:positions")
        assert ticks.tolist() == list(range(0, 300, 20))  # every 0.02 s
        for k, pts in zip(ticks, joints, strict=True):
            data = exo.model.createData()
            pin.framesForwardKinematics(exo.model, data, exo.to_model_q(q[k]))
            hip = data.oMi[exo.model.getJointId(f"{side}_hip")].translation
            knee = data.oMi[exo.model.getJointId(f"{side}_knee")].translation
            foot = exo.frame_position(q[k], f"{side}_foot")
            assert np.allclose(pts, [hip, knee, foot], atol=1e-6)
        _, legs = entity_columns(path, f"world/exo/{side}/leg", "LineStrips3D:strips")
        assert np.array_equal(np.asarray(legs[5][0]), np.asarray(joints[5]))
        _, cuffs = entity_columns(path, f"world/exo/{side}/cuffs", "Points3D:positions")
        k = int(ticks[7])
        thigh = exo.frame_position(q[k], f"{side}_thigh_cuff")
        shank = exo.frame_position(q[k], f"{side}_shank_cuff")
        assert np.allclose(cuffs[7], [thigh, shank], atol=1e-6)
        ticks_p, joints_p = entity_columns(
            path, f"world/patient/{side}/joints", "Points3D:positions"
        )
        assert np.array_equal(ticks_p, ticks)
        for k, pts in zip(ticks_p, joints_p, strict=True):
            foot = patient.frame_position(qp[k], f"{side}_foot") + shift
            assert np.allclose(pts[2], foot, atol=1e-6)
    # The patient's left hip sits on the exo's left hip in x and z.
    _, pe = entity_columns(path, "world/exo/left/joints", "Points3D:positions")
    _, pp = entity_columns(path, "world/patient/left/joints", "Points3D:positions")
    assert np.allclose(np.asarray(pe[0][0])[[0, 2]], np.asarray(pp[0][0])[[0, 2]], atol=1e-6)


def test_cuff_arrows_are_scaled_forces_at_the_exo_cuffs(short_run):
    result, path = short_run
    exo = load_body(result.exo_source)
    force, q = result.signals["cuff_force"], result.signals["q"]
    assert np.max(np.abs(force)) > 1.0  # the check below is not vacuous
    for c, cuff in enumerate(CUFF_NAMES):
        ticks, vectors = entity_columns(path, f"world/cuff_force/{cuff}", "Arrows3D:vectors")
        _, origins = entity_columns(path, f"world/cuff_force/{cuff}", "Arrows3D:origins")
        assert ticks.tolist() == list(range(0, 300, 20))
        for k, vec, org in zip(ticks, vectors, origins, strict=True):
            expected = FORCE_ARROW_M_PER_N * np.array([force[k, c, 0], 0.0, force[k, c, 1]])
            assert np.allclose(vec[0], expected, rtol=1e-6, atol=1e-7)
            assert np.allclose(org[0], exo.frame_position(q[k], f"{cuff}_cuff"), atol=1e-6)


def test_belt_and_planned_foot_paths(short_run):
    result, path = short_run
    gait = SHORT.gait
    exo = load_body(result.exo_source)
    hip_z = exo.legs["left"].hip_xz[1]
    for side in SIDES:
        _, strips = entity_columns(path, f"world/plan/foot_path/{side}", "LineStrips3D:strips")
        pts = np.asarray(strips[-1][0])
        bottom = hip_z - gait.hip_height
        assert np.isclose(pts[:, 2].min(), bottom, atol=1e-6)
        stance = pts[np.abs(pts[:, 2] - bottom) < 1e-6]  # the foot on the belt spans s
        assert np.isclose(np.ptp(stance[:, 0]), gait.step_length, atol=1e-2)
        assert np.isclose(pts[:, 2].max(), bottom + gait.lift_height, atol=1e-6)
    _, half = entity_columns(path, "world/belt", "Boxes3D:half_sizes")
    _, centers = entity_columns(path, "world/belt", "Boxes3D:centers")
    top = centers[-1][0][2] + half[-1][0][2]
    assert np.isclose(top, hip_z - gait.hip_height, atol=1e-6)
    # Stripes move backwards at belt speed: 0.02 s moves them by v 0.02 m.
    ticks, stripes = entity_columns(path, "world/belt/stripes", "LineStrips3D:strips")
    x0 = np.array([s[0][0] for s in stripes[0]])
    x1 = np.array([s[0][0] for s in stripes[1]])
    step = result.belt_speed_mps * (ticks[1] - ticks[0]) * SHORT.dt
    moved = x0 - x1
    assert np.allclose(moved[np.abs(moved) < 0.5], step, atol=1e-5)


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


def test_human_friendly_series_match_signals(short_run):
    """Every entry of SIGNALS, whatever it holds, has its series under signals/."""
    result, path = short_run
    for name, (shape, _, _) in SIGNALS.items():
        values = result.signals[name]
        if name in JOINT_SERIES:
            quantity, part = JOINT_SERIES[name]
            entity, expected = f"{quantity}/left_knee", values[:, 1]
        elif shape == (4, 2):
            entity, part, expected = f"{name}/right_shank", 1, values[:, 3, 1]
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


# --------------------------------------------------------------------------- memory

MEMORY_CHILD = textwrap.dedent(
    """
    import json, sys
    from exo_ctrl.record.recorder import RerunRecorder
    from exo_ctrl.sim.loop import SimConfig, simulate

    def status_kb(key):
        with open("/proc/self/status") as f:
            return next(int(line.split()[1]) for line in f if line.startswith(key + ":"))

    class Probe:
        def start(self, result):
            self.pre_loop_peak_kb = status_kb("VmHWM")
            try:  # reset the peak RSS to the current RSS (Linux >= 4.0)
                with open("/proc/self/clear_refs", "w") as f:
                    f.write("5")
                self.reset = True
            except OSError:
                self.reset = False
            self.start_kb = self.sampled_kb = status_kb("VmRSS")
        def chunk(self, result, start, rows):
            self.sampled_kb = max(self.sampled_kb, status_kb("VmRSS"))
        def finish(self, result):
            pass

    probe = Probe()
    result = simulate(SimConfig(duration_s=float(sys.argv[1])),
                      observers=[RerunRecorder(sys.argv[2]), probe], keep_history=False)
    end_peak_kb = status_kb("VmHWM")  # after finish(): the footer is written too
    loop_peak_kb = end_peak_kb if probe.reset else probe.sampled_kb
    print(json.dumps({"status": result.status, "ticks": result.n_ticks,
                      "loop_growth_kb": loop_peak_kb - probe.start_kb,
                      "pre_loop_peak_kb": probe.pre_loop_peak_kb,
                      "process_peak_kb": max(probe.pre_loop_peak_kb, end_peak_kb)}))
    """
)


def test_recording_memory_does_not_grow_with_run_length(tmp_path):
    """Peak RSS of a recorded 60 s run vs a 10 s one (keep_history=False), in children.

    Measured: the peak RSS from the recorder's start() to the end of the run,
    footer included (the peak is reset at start() through
    /proc/self/clear_refs), because simulate builds the joint plan for the
    whole run before the loop (about 18 MB more at 60 s than at 10 s:
    simulate's memory, not the recorder's).
    Holding the rows would cost 50 s x 1000 ticks/s x 97 floats (SIGNALS now)
    x 8 B = 39 MB more at 60 s (21 MB for the original 52 floats), holding
    what was logged (the file grows by about 125 MB) far more.  What does
    grow is rerun's footer index, about 0.15 MB per 2000-tick chunk, and the
    transient of writing the footer: measured differences 7.5-10.5 MB.  So
    the bound is 16 MB.  With keep_history=True the difference measured
    40 MB: the test then fails, as it should.
    (ru_maxrss is not used: it survives exec, so a child spawned from a large
    pytest process reports the parent's size.)
    """
    procs = {
        d: subprocess.Popen(
            [sys.executable, "-c", MEMORY_CHILD, str(d), str(tmp_path / f"m{d}.rrd")],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        for d in (10, 60)
    }
    out = {}
    for d, proc in procs.items():
        stdout, stderr = proc.communicate(timeout=300)
        assert proc.returncode == 0, stderr.decode()
        out[d] = json.loads(stdout)
        assert out[d]["status"] == "completed" and out[d]["ticks"] == d * 1000
    growth_mb = (out[60]["loop_growth_kb"] - out[10]["loop_growth_kb"]) / 1024
    peaks = ", ".join(f"{d} s: {out[d]['process_peak_kb'] / 1024:.0f} MB" for d in out)
    print(f"loop peak growth 60 s - 10 s: {growth_mb:.1f} MB; process peak RSS {peaks}")
    assert growth_mb < 16.0
