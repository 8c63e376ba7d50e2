"""Tests of exo_ctrl.sweep.run: real (short) simulations, serial, on Dask, resumed, interrupted."""

from __future__ import annotations

import argparse
import json
import math

import pyarrow.parquet as pq
import pytest

import exo_ctrl.sweep.run as run_module
from exo_ctrl.model import CUFF_NAMES, JOINT_NAMES, BodyParams, urdf_xml, write_urdf
from exo_ctrl.plan import GaitParams
from exo_ctrl.plant import CuffParams, MotorParams
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.belief import Belief
from exo_ctrl.sweep import (
    OUTPUT_COLUMNS,
    SweepInterrupted,
    SweepPaths,
    add_sweep_arguments,
    run_sweep,
    run_sweep_command,
)


def test_bad_configuration_is_reported_and_others_complete(
    tmp_path, make_spec, serial, assert_tables_equal, duration
):
    spec = make_spec("step_length=0.3,1.2,0.4")
    table = serial(spec, tmp_path / "s.parquet")
    rows = table.to_pylist()
    assert [r["step_length"] for r in rows] == [0.3, 1.2, 0.4]
    assert [r["status"] for r in rows] == ["completed", "failed", "completed"]
    error = rows[1]["error"]
    assert error.startswith("UnreachableFootTarget: left foot path point")
    assert error.endswith("[step_length=1.2 m]")
    assert math.isnan(rows[1]["peak_drive_torque_Nm_left_hip"])
    for r in (rows[0], rows[2]):
        assert r["error"] == ""
        assert all(math.isfinite(r[f"peak_drive_torque_Nm_{j}"]) for j in JOINT_NAMES)
        assert r["sim_duration_s"] == pytest.approx(duration)
        assert r["safety_events"] == 0
    # The files on disk hold the same table.
    assert_tables_equal(pq.read_table(tmp_path / "s.parquet"), table, skip=())
    csv = (tmp_path / "s.csv").read_text().splitlines()
    assert len(csv) == 4
    assert csv[0].replace('"', "").split(",")[:3] == ["run_index", "run_id", "step_length"]


def test_divergence_is_recorded_and_not_rerun(tmp_path, count_runs, make_spec, serial):
    # 10 Hz control with 100 N/mm cuffs: the cuff mode (ω Δt ≈ 15) blows up.
    spec = make_spec("cuff_stiffness=100000", base=SimConfig(control_rate_hz=10.0), duration_s=1.0)
    (row,) = serial(spec, tmp_path / "d.parquet").to_pylist()
    assert row["status"] == "diverged"
    assert row["error"].startswith("simulation diverged at t = ")
    assert row["error"].endswith("[cuff_stiffness=100000 N/m]")
    assert 0.0 < row["sim_duration_s"] < 1.0
    serial(spec, tmp_path / "d.parquet")
    assert len(count_runs) == 1  # a divergence is a result: resuming does not redo it


def test_row_equals_independent_simulation(tmp_path, make_spec, serial, duration):
    spec = make_spec(
        "step_length=0.3",
        "patient_thigh_mass=9",
        "patient_shank_length=0.45",
        "gear_ratio=40",
        "cuff_stiffness=6000",
        "controller=ct",
    )
    row = serial(spec, tmp_path / "s.parquet").to_pylist()[0]
    assert row["status"] == "completed"
    # Independently: the patient with its shank cuff at the same fraction of the link.
    patient = BodyParams.patient_default(
        thigh_mass=9.0, shank_length=0.45, shank_cuff=0.45 * 0.45 / 0.52
    )
    path = write_urdf(patient, tmp_path / "patient.urdf")
    cached = list((tmp_path / "s.urdf_cache").glob("patient-*.urdf"))
    assert len(cached) == 1
    assert cached[0].read_text() == urdf_xml(patient)
    config = SimConfig(
        gait=GaitParams(step_length=0.3),
        patient=str(path),
        controller="ct",
        motor=MotorParams(gear_ratio=40.0),
        cuffs=CuffParams(stiffness_N_per_m=6000.0),
        duration_s=duration,
        # The device's nominal patient: the swept segments of the paper's 1.75 m, 80 kg patient.
        belief=Belief(patient_height_m=1.75, patient_mass_kg=80.0),
    )
    summary = simulate(config, keep_history=False).summary()
    keys = [
        ("peak_drive_torque_Nm", JOINT_NAMES),
        ("rms_drive_torque_Nm", JOINT_NAMES),
        ("peak_mechanical_power_W", JOINT_NAMES),
        ("peak_motor_current_A", JOINT_NAMES),
        ("peak_motor_voltage_V", JOINT_NAMES),
        ("peak_cuff_force_N", CUFF_NAMES),
        ("rms_tracking_error_rad", JOINT_NAMES),
        ("max_tracking_error_rad", JOINT_NAMES),
    ]
    checked = 0
    for key, names in keys:
        for n in names:
            assert row[f"{key}_{n}"] == summary[key][n], f"{key}_{n}"
            checked += 1
    assert checked == 32
    assert set(OUTPUT_COLUMNS) >= {f"{key}_{n}" for key, names in keys for n in names}
    assert row["belt_speed_mps"] == summary["belt_speed_mps"]
    assert row["safety_events"] == len(summary["safety_events"])
    assert row["safety_state"] == summary["safety_state"]
    assert row["qp_failures"] == summary["qp_failures"]
    assert row["sim_duration_s"] == summary["duration_s"]
    assert row["peak_drive_torque_Nm_left_knee"] > 0.0


def test_resume_runs_only_new_points(tmp_path, count_runs, make_spec, serial, assert_tables_equal):
    out = tmp_path / "s.parquet"
    first = serial(make_spec("step_length=0.3,0.35"), out)
    assert len(count_runs) == 2
    journal = SweepPaths.for_output(out).journal
    assert len(journal.read_text().splitlines()) == 2
    # A kill while writing leaves a torn last line: it is skipped and ended.
    with journal.open("a") as handle:
        handle.write('{"run_id": "abc", "outp')
    second = serial(make_spec("step_length=0.3,0.35,0.4"), out)
    assert len(count_runs) == 3  # only step_length = 0.4 ran
    assert count_runs[-1].gait.step_length == 0.4
    assert [r["step_length"] for r in second.to_pylist()] == [0.3, 0.35, 0.4]
    assert_tables_equal(second.slice(0, 2), first, skip=())
    lines = journal.read_text().splitlines()
    assert len(lines) == 4
    assert json.loads(lines[-1])["point"] == {"step_length": 0.4}
    # Nothing left to do: no run, same table.
    third = serial(make_spec("step_length=0.3,0.35,0.4"), out)
    assert len(count_runs) == 3
    assert_tables_equal(third, second, skip=())
    # Without the journal, the table itself is the record of finished runs.
    journal.unlink()
    serial(make_spec("step_length=0.3,0.35,0.4"), out)
    assert len(count_runs) == 3


def test_ctrl_c_keeps_finished_runs_and_resumes(tmp_path, monkeypatch, make_spec, serial):
    calls = []

    def interrupting(config, *args, **kwargs):
        calls.append(config.gait.step_length)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return simulate(config, *args, **kwargs)

    monkeypatch.setattr(run_module, "simulate", interrupting)
    out = tmp_path / "s.parquet"
    spec = make_spec("step_length=0.3,0.35,0.4")
    with pytest.raises(SweepInterrupted) as info:
        serial(spec, out)
    assert (info.value.done, info.value.remaining) == (1, 2)
    assert pq.read_table(out).column("step_length").to_pylist() == [0.3]
    table = serial(spec, out)
    assert calls == [0.3, 0.35, 0.35, 0.4]
    assert table.column("status").to_pylist() == ["completed"] * 3


def test_table_is_written_while_running(tmp_path, monkeypatch, make_spec, serial):
    out = tmp_path / "s.parquet"
    seen = []

    def peeking(config, *args, **kwargs):
        seen.append(len(pq.read_table(out)) if out.is_file() else None)
        return simulate(config, *args, **kwargs)

    monkeypatch.setattr(run_module, "simulate", peeking)
    monkeypatch.setattr(run_module, "_TABLE_EVERY_S", 0.0)
    serial(make_spec("step_length=0.3,0.32,0.34,0.36"), out)
    assert seen == [None, None, 2, 2]  # one worker: two runs in flight, then a write


def _listeners() -> set[tuple[int, str, int]]:
    import psutil

    me = psutil.Process()
    found = set()
    for proc in [me, *me.children(recursive=True)]:
        try:
            for conn in proc.net_connections(kind="inet"):
                if conn.status == psutil.CONN_LISTEN:
                    found.add((proc.pid, conn.laddr.ip, conn.laddr.port))
        except psutil.Error:
            continue
    return found


@pytest.mark.heavy
def test_dask_cluster_gives_the_serial_table(
    tmp_path, make_spec, serial, assert_tables_equal, duration
):
    from distributed import Client, LocalCluster

    spec = make_spec("step_length=0.3,1.2,0.4", "controller=pd,ct")
    serial = serial(spec, tmp_path / "serial.parquet")
    before = _listeners()
    with (
        LocalCluster(
            n_workers=2,
            threads_per_worker=1,
            processes=True,
            host="127.0.0.1",
            dashboard_address=None,
        ) as cluster,
        Client(cluster) as client,
    ):
        opened = _listeners() - before
        assert opened, "the cluster should listen somewhere"
        assert {ip for _, ip, _ in opened} == {"127.0.0.1"}, opened
        executor = client.get_executor(pure=False)
        dask_table = run_sweep(
            spec,
            tmp_path / "dask.parquet",
            executor=executor,
            workers=2,
            progress=False,
            plots=False,
            report=False,
        )
        ran_on = client.run(lambda: True)
        # The command line's --scheduler path (its own Client on the same cluster).
        parser = argparse.ArgumentParser()
        add_sweep_arguments(parser)
        argv = ["--param", "step_length=0.3,1.2,0.4", "--param", "controller=pd,ct"]
        argv += ["--duration", str(duration), "--out", str(tmp_path / "cli.parquet")]
        argv += ["--scheduler", cluster.scheduler_address, "--no-plots"]
        assert run_sweep_command(parser.parse_args(argv)) == 0
    assert len(ran_on) == 2
    statuses = dask_table.column("status").to_pylist()
    assert statuses == ["completed", "completed", "failed", "failed", "completed", "completed"]
    assert_tables_equal(dask_table, serial)
    assert_tables_equal(pq.read_table(tmp_path / "cli.parquet"), serial)
    # And the local process pool (2 workers) too.
    pool = run_sweep(spec, tmp_path / "pool.parquet", workers=2, progress=False, plots=False)
    assert_tables_equal(pool, serial)


def test_a_local_pool_makes_its_first_run_here_and_the_rest_in_its_workers(
    tmp_path, count_runs, make_spec, serial, assert_tables_equal
):
    """The first run compiles the kernels in this process; the workers then load them.

    Workers compiling side by side could save different signatures of one
    kernel into numba's cache index at once, which that index is not safe
    against (exo_ctrl/sweep/run.py, run_sweep).
    """
    spec = make_spec("step_length=0.3,0.35,0.4")
    pool = run_sweep(spec, tmp_path / "pool.parquet", workers=2, progress=False, plots=False)
    assert [c.gait.step_length for c in count_runs] == [0.3]  # only the first, here
    assert_tables_equal(pool, serial(spec, tmp_path / "serial.parquet"))
    assert len(count_runs) == 4  # and the serial sweep's three


def test_an_exoskeleton_sweep_generates_its_urdf_per_run(tmp_path, make_spec, serial):
    spec = make_spec("exo_thigh_length=0.50,0.54", "exo_shank_mass=4.0", "controller=ct")
    rows = serial(spec, tmp_path / "e.parquet").to_pylist()
    assert [r["status"] for r in rows] == ["completed", "completed"]
    cached = sorted((tmp_path / "e.urdf_cache").glob("exo-*.urdf"))
    assert len(cached) == 2
    # Independently: the device with its thigh cuff at the same fraction of the link.
    expected = {
        urdf_xml(BodyParams.exo_default(thigh_length=t, thigh_cuff=0.39 / 0.52 * t, shank_mass=4.0))
        for t in (0.50, 0.54)
    }
    assert {p.read_text() for p in cached} == expected
    # the ids of the runs differ by the exoskeleton alone
    assert rows[0]["run_id"] != rows[1]["run_id"]


def test_exoskeleton_parameters_need_the_generated_exoskeleton(make_spec):
    with pytest.raises(Exception, match="exo_thigh_length must be swept only with the generated"):
        make_spec("exo_thigh_length=0.5", base=SimConfig(exo="urdf/exoskeleton.urdf"))
