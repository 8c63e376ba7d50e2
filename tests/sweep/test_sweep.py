"""Parameter sweeps: real (short) simulations, serial, on Dask, resumed, reported."""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

import exo_ctrl.sweep.sweep as sweep
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model.body import CUFF_NAMES, JOINT_NAMES
from exo_ctrl.model.urdfgen import BodyParams, urdf_xml, write_urdf
from exo_ctrl.plan.gait import GaitParams
from exo_ctrl.plant.cuffs import CuffParams
from exo_ctrl.plant.motor import MotorParams
from exo_ctrl.sim.loop import CONTROLLERS, SimConfig, simulate
from exo_ctrl.sweep.sweep import (
    OUTPUT_COLUMNS,
    MissingDependency,
    SweepInterrupted,
    SweepPaths,
    SweepSpec,
    add_sweep_arguments,
    config_for,
    parse_param,
    run_sweep,
    run_sweep_command,
)

DURATION = 0.4  # simulated time per run [s]: short, but past the start-up transient


def _spec(*params: str, **kw) -> SweepSpec:
    kw.setdefault("duration_s", DURATION)
    return SweepSpec.parse(list(params), **kw)


def _serial(spec: SweepSpec, out: Path, **kw):
    kw.setdefault("plots", False)
    kw.setdefault("report", False)
    return run_sweep(spec, out, workers=1, progress=False, **kw)


def _same(a, b) -> bool:
    """Equal values, NaN equal to NaN."""
    if isinstance(a, float) and isinstance(b, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    return a == b


def _assert_tables_equal(a, b, skip=("wall_time_s",)) -> None:
    assert a.column_names == b.column_names
    assert len(a) == len(b)
    for name in a.column_names:
        if name in skip:
            continue
        va, vb = a.column(name).to_pylist(), b.column(name).to_pylist()
        bad = [i for i, (x, y) in enumerate(zip(va, vb, strict=True)) if not _same(x, y)]
        assert not bad, f"column {name} differs in rows {bad}: {va} vs {vb}"


@pytest.fixture
def count_runs(monkeypatch):
    """Count the simulations run in this process (serial sweeps)."""
    calls = []

    def counting(config, *args, **kwargs):
        calls.append(config)
        return simulate(config, *args, **kwargs)

    monkeypatch.setattr(sweep, "simulate", counting)
    return calls


# --------------------------------------------------------------------------- parsing


def test_parse_lists_and_ranges():
    assert parse_param("step_length=0.3,0.35,0.3") == ("step_length", (0.3, 0.35))
    assert parse_param(" period = 1.0:1.4:5 ") == ("period", (1.0, 1.1, 1.2, 1.3, 1.4))
    assert parse_param("step_length=0.3:0.5:3") == ("step_length", (0.3, 0.4, 0.5))
    assert parse_param("controller=ct,pd") == ("controller", ("ct", "pd"))
    assert parse_param("gear_ratio=50") == ("gear_ratio", (50.0,))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "stride=0.3",
            "sweep parameter must be one of step_length, lift_height, hip_height, shape_coeff, "
            "period, duty_factor, patient_thigh_mass, patient_shank_mass, patient_thigh_length, "
            "patient_shank_length, cuff_stiffness, cuff_damping, gear_ratio, controller; "
            "got 'stride'",
        ),
        ("step_length", "--param must be NAME=V1,V2,... or NAME=LO:HI:N; got 'step_length'"),
        ("step_length=", "--param must be NAME=V1,V2,... or NAME=LO:HI:N; got 'step_length='"),
        (
            "step_length=0.3:0.5",
            "step_length must be V1,V2,... or LO:HI:N with LO < HI and an integer N >= 2; "
            "got '0.3:0.5'",
        ),
        (
            "step_length=0.5:0.3:3",
            "step_length must be V1,V2,... or LO:HI:N with LO < HI and an integer N >= 2; "
            "got '0.5:0.3:3'",
        ),
        (
            "step_length=0.3:0.5:2.5",
            "step_length must be V1,V2,... or LO:HI:N with LO < HI and an integer N >= 2; "
            "got '0.3:0.5:2.5'",
        ),
        (
            "step_length=0.3:0.5:1",
            "step_length must be V1,V2,... or LO:HI:N with LO < HI and an integer N >= 2; "
            "got '0.3:0.5:1'",
        ),
        ("step_length=0.3,nan", "step_length must be a finite number [m]; got 'nan'"),
        ("step_length=nan:0.5:3", "step_length must be a finite number [m]; got 'nan'"),
        ("shape_coeff=inf", "shape_coeff must be a finite number; got 'inf'"),
        ("lift_height=0.1,,0.2", "lift_height must be a finite number [m]; got ''"),
        ("step_length=-0.3", "step_length must be in (0, 2] m; got -0.3"),
        ("duty_factor=1", "duty_factor must be in [0.5, 1); got 1.0"),
        ("patient_thigh_mass=20", "patient_thigh_mass must be in [7, 14] kg; got 20.0"),
        ("patient_shank_length=0.3", "patient_shank_length must be in [0.39, 0.65] m; got 0.3"),
        (
            "controller=lqr",
            f"controller must be one of {', '.join(CONTROLLERS)}; got 'lqr'",
        ),
    ],
)
def test_parse_errors(text, message):
    with pytest.raises(InvalidParameter) as info:
        parse_param(text)
    assert str(info.value) == message


def test_spec_errors():
    with pytest.raises(InvalidParameter) as info:
        SweepSpec.parse(["step_length=0.3", "step_length=0.4"])
    assert str(info.value) == "sweep parameter must be given once; got 'step_length'"
    with pytest.raises(InvalidParameter) as info:
        SweepSpec.parse(["step_length=0.3"], samples=0)
    assert str(info.value) == "samples must be an integer >= 1; got 0"
    with pytest.raises(InvalidParameter) as info:
        SweepSpec.parse(["step_length=0.3"], duration_s=float("nan"))
    assert str(info.value) == "duration must be a finite number > 0 [s]; got nan"
    with pytest.raises(InvalidParameter) as info:
        SweepSpec.parse(["patient_thigh_mass=9"], base=SimConfig(patient="human"))
    assert str(info.value) == (
        "patient_thigh_mass must be swept only with the generated patient "
        "(no patient URDF given); got 'human'"
    )
    with pytest.raises(InvalidParameter) as info:
        SweepSpec(params=(("step_length", (float("nan"),)),))
    assert str(info.value) == "step_length must be a finite number [m]; got nan"
    with pytest.raises(InvalidParameter) as info:
        SweepPaths.for_output("results.csv")
    assert str(info.value) == "out must be a path ending in .parquet; got 'results.csv'"


def test_grid_order_samples_and_run_ids():
    grid = _spec("step_length=0.3,0.4", "controller=pd,ct")
    assert grid.points() == [
        {"step_length": 0.3, "controller": "pd"},
        {"step_length": 0.3, "controller": "ct"},
        {"step_length": 0.4, "controller": "pd"},
        {"step_length": 0.4, "controller": "ct"},
    ]
    texts = ("step_length=0.3:0.5:3", "gear_ratio=40,60", "controller=pd,ct")
    points = _spec(*texts, samples=6, seed=7).points()
    assert points == _spec(*texts, samples=6, seed=7).points()
    assert points != _spec(*texts, samples=6, seed=8).points()
    assert points[:4] == _spec(*texts, samples=4, seed=7).points()  # a larger N extends
    # Only [min, max] of a list matters for sampling.
    assert points == _spec("step_length=0.5,0.3", *texts[1:], samples=6, seed=7).points()
    assert all(0.3 <= p["step_length"] <= 0.5 and 40 <= p["gear_ratio"] <= 60 for p in points)
    assert {p["controller"] for p in points} <= {"pd", "ct"}
    assert len({p["step_length"] for p in points}) == 6
    # A swept default value is the same run as not sweeping it: ids are of the resolved run.
    a = _spec("step_length=0.35").tasks()[0].run_id
    b = _spec("patient_thigh_mass=11.3").tasks()[0].run_id
    c = _spec("gear_ratio=50", "controller=pd").tasks()[0].run_id
    assert a == b == c
    assert _spec("step_length=0.35", duration_s=0.5).tasks()[0].run_id != a


def test_base_fields_are_kept_and_part_of_the_run_id(tmp_path):
    base = SimConfig(safety=False, cuff_force_limit_N=100.0, controller="ct", plant_substeps=2)
    spec = _spec("gear_ratio=40", "cuff_damping=50", "period=1.0", base=base)
    (task,) = spec.tasks()
    config = config_for(base, task.values, str(tmp_path))
    assert config == dataclasses.replace(
        base,
        gait=GaitParams(period=1.0),
        motor=MotorParams(gear_ratio=40.0),
        cuffs=CuffParams(damping_N_s_per_m=50.0),
        duration_s=DURATION,
    )
    assert task.run_id != _spec("gear_ratio=40", "cuff_damping=50", "period=1.0").tasks()[0].run_id
    # --cycles: the duration follows each point's period.
    periods = _spec("period=1.0,1.3", duration_s=None, cycles=1.5).tasks()
    assert [t.values["duration_s"] for t in periods] == [1.5, 1.95]


# --------------------------------------------------------------------------- runs


def test_bad_configuration_is_reported_and_others_complete(tmp_path):
    spec = _spec("step_length=0.3,1.2,0.4")
    table = _serial(spec, tmp_path / "s.parquet")
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
        assert r["sim_duration_s"] == pytest.approx(DURATION)
        assert r["safety_events"] == 0
    # The files on disk hold the same table.
    _assert_tables_equal(pq.read_table(tmp_path / "s.parquet"), table, skip=())
    csv = (tmp_path / "s.csv").read_text().splitlines()
    assert len(csv) == 4
    assert csv[0].replace('"', "").split(",")[:3] == ["run_index", "run_id", "step_length"]


def test_divergence_is_recorded_and_not_rerun(tmp_path, count_runs):
    # 10 Hz control with 100 N/mm cuffs: the cuff mode (ω Δt ≈ 15) blows up.
    spec = _spec("cuff_stiffness=100000", base=SimConfig(control_rate_hz=10.0), duration_s=1.0)
    (row,) = _serial(spec, tmp_path / "d.parquet").to_pylist()
    assert row["status"] == "diverged"
    assert row["error"].startswith("simulation diverged at t = ")
    assert row["error"].endswith("[cuff_stiffness=100000 N/m]")
    assert 0.0 < row["sim_duration_s"] < 1.0
    _serial(spec, tmp_path / "d.parquet")
    assert len(count_runs) == 1  # a divergence is a result: resuming does not redo it


def test_row_equals_independent_simulation(tmp_path):
    spec = _spec(
        "step_length=0.3",
        "patient_thigh_mass=9",
        "patient_shank_length=0.45",
        "gear_ratio=40",
        "cuff_stiffness=6000",
        "controller=ct",
    )
    row = _serial(spec, tmp_path / "s.parquet").to_pylist()[0]
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
        duration_s=DURATION,
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


def test_resume_runs_only_new_points(tmp_path, count_runs):
    out = tmp_path / "s.parquet"
    first = _serial(_spec("step_length=0.3,0.35"), out)
    assert len(count_runs) == 2
    journal = SweepPaths.for_output(out).journal
    assert len(journal.read_text().splitlines()) == 2
    # A kill while writing leaves a torn last line: it is skipped and ended.
    with journal.open("a") as handle:
        handle.write('{"run_id": "abc", "outp')
    second = _serial(_spec("step_length=0.3,0.35,0.4"), out)
    assert len(count_runs) == 3  # only step_length = 0.4 ran
    assert count_runs[-1].gait.step_length == 0.4
    assert [r["step_length"] for r in second.to_pylist()] == [0.3, 0.35, 0.4]
    _assert_tables_equal(second.slice(0, 2), first, skip=())
    lines = journal.read_text().splitlines()
    assert len(lines) == 4
    assert json.loads(lines[-1])["point"] == {"step_length": 0.4}
    # Nothing left to do: no run, same table.
    third = _serial(_spec("step_length=0.3,0.35,0.4"), out)
    assert len(count_runs) == 3
    _assert_tables_equal(third, second, skip=())
    # Without the journal, the table itself is the record of finished runs.
    journal.unlink()
    _serial(_spec("step_length=0.3,0.35,0.4"), out)
    assert len(count_runs) == 3


def test_ctrl_c_keeps_finished_runs_and_resumes(tmp_path, monkeypatch):
    calls = []

    def interrupting(config, *args, **kwargs):
        calls.append(config.gait.step_length)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return simulate(config, *args, **kwargs)

    monkeypatch.setattr(sweep, "simulate", interrupting)
    out = tmp_path / "s.parquet"
    spec = _spec("step_length=0.3,0.35,0.4")
    with pytest.raises(SweepInterrupted) as info:
        _serial(spec, out)
    assert (info.value.done, info.value.remaining) == (1, 2)
    assert pq.read_table(out).column("step_length").to_pylist() == [0.3]
    table = _serial(spec, out)
    assert calls == [0.3, 0.35, 0.35, 0.4]
    assert table.column("status").to_pylist() == ["completed"] * 3


def test_table_is_written_while_running(tmp_path, monkeypatch):
    out = tmp_path / "s.parquet"
    seen = []

    def peeking(config, *args, **kwargs):
        seen.append(len(pq.read_table(out)) if out.is_file() else None)
        return simulate(config, *args, **kwargs)

    monkeypatch.setattr(sweep, "simulate", peeking)
    monkeypatch.setattr(sweep, "_TABLE_EVERY_S", 0.0)
    _serial(_spec("step_length=0.3,0.32,0.34,0.36"), out)
    assert seen == [None, None, 2, 2]  # one worker: two runs in flight, then a write


def test_cli_exit_codes(tmp_path, monkeypatch, capsys):
    parser = argparse.ArgumentParser()
    add_sweep_arguments(parser)
    out = tmp_path / "c.parquet"
    argv = ["--param", "step_length=0.3,0.35", "--duration", "0.3", "--out", str(out)]
    args = parser.parse_args([*argv, "--workers", "1"])
    assert run_sweep_command(args) == 0
    assert "wrote 2 runs (2 completed)" in capsys.readouterr().out
    assert SweepPaths.for_output(out).plot("step_length").is_file()

    def interrupting(config, *a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep, "simulate", interrupting)
    args = parser.parse_args(
        ["--param", "step_length=0.3,0.4", "--duration", "0.3", "--out", str(out), "--workers", "1"]
    )
    assert run_sweep_command(args) == 130
    err = capsys.readouterr().err
    assert "interrupted: 0 runs finished, 1 to do; 1 rows written" in err
    with pytest.raises(InvalidParameter) as info:
        run_sweep_command(
            parser.parse_args([*argv, "--controller", "pd", "--param", "controller=ct"])
        )
    assert str(info.value) == (
        "controller must be given once: --controller or --param controller=...; got 'pd'"
    )
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(MissingDependency) as info:
        run_sweep_command(parser.parse_args([*argv, "--scheduler", "tcp://127.0.0.1:1"]))
    assert str(info.value) == '--scheduler needs Dask: pip install "exo-ctrl[dask]"'


def test_plots_and_report_name_the_worst_case(tmp_path):
    spec = _spec("step_length=0.3,0.45", "patient_shank_mass=3,6", "lift_height=0.1,0.5")
    out = tmp_path / "r.parquet"
    table = run_sweep(spec, out, workers=1, progress=False)
    paths = SweepPaths.for_output(out)
    for name in spec.names:
        png = paths.plot(name).read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
    cols = {n: np.array(table.column(n).to_pylist()) for n in table.column_names}
    ok = cols["status"] == "completed"
    assert 0 < ok.sum() < len(table)  # some fail (a 0.5 m lift overflexes the knee)
    report = paths.report.read_text().splitlines()
    for title, key, names, unit in (
        ("peak drive torque", "peak_drive_torque_Nm", JOINT_NAMES, "N·m"),
        ("peak cuff force", "peak_cuff_force_N", CUFF_NAMES, "N"),
    ):
        values = np.column_stack([cols[f"{key}_{n}"] for n in names])
        per_run = np.where(ok, np.nan_to_num(values, nan=-1).max(axis=1), -1)
        row = int(np.argmax(per_run))
        name = names[int(np.argmax(values[row]))]
        (line,) = [s for s in report if s.startswith(f"worst {title}:")]
        point = ", ".join(f"{n}={cols[n][row]:.10g} {sweep.PARAMETERS[n].unit}" for n in spec.names)
        assert line == (
            f"worst {title}: {per_run[row]:.6g} {unit} at {name}, run {row} "
            f"({cols['run_id'][row]}): {point}"
        )
    failures = [s for s in report if s.startswith("  run ")]
    assert len(failures) == int((~ok).sum())
    assert all("lift_height=0.5 m" in s for s in failures)


# --------------------------------------------------------------------------- Dask


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


def test_dask_cluster_gives_the_serial_table(tmp_path):
    from distributed import Client, LocalCluster

    spec = _spec("step_length=0.3,1.2,0.4", "controller=pd,ct")
    serial = _serial(spec, tmp_path / "serial.parquet")
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
        argv += ["--duration", str(DURATION), "--out", str(tmp_path / "cli.parquet")]
        argv += ["--scheduler", cluster.scheduler_address, "--no-plots"]
        assert run_sweep_command(parser.parse_args(argv)) == 0
    assert len(ran_on) == 2
    statuses = dask_table.column("status").to_pylist()
    assert statuses == ["completed", "completed", "failed", "failed", "completed", "completed"]
    _assert_tables_equal(dask_table, serial)
    _assert_tables_equal(pq.read_table(tmp_path / "cli.parquet"), serial)
    # And the local process pool (2 workers) too.
    pool = run_sweep(spec, tmp_path / "pool.parquet", workers=2, progress=False, plots=False)
    _assert_tables_equal(pool, serial)
