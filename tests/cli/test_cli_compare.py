"""``exo-ctrl compare``: the command as a user runs it, its files, and what it refuses."""

from __future__ import annotations

import csv
import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from exo_ctrl import cli, simulate
from exo_ctrl.plan import GaitParams
from exo_ctrl.scenario import load_scenario


def run_cli(*args: str, env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "exo_ctrl", *args],
        capture_output=True,
        text=True,
        env={**os.environ, **(env or {})},
        timeout=600,
    )


@pytest.mark.heavy
def test_compare_controllers_prints_the_table_and_writes_three_files(tmp_path: Path) -> None:
    done = run_cli("compare", "--controllers", "pd,ct", "--cycles", "1", "--out", str(tmp_path))
    assert done.returncode == 0, done.stderr
    lines = done.stderr.splitlines()
    progress = [line for line in lines if line.startswith("exo-ctrl compare: run ")]
    assert [line.split(":")[1] for line in progress] == [" run 1/2 (pd)", " run 2/2 (ct)"]
    assert all("): completed, 2.400 s simulated, real-time factor" in line for line in progress)
    assert "Traceback" not in done.stderr
    lines = done.stdout.splitlines()
    assert lines[0] == "| figure | unit | pd | ct |"
    assert f"written: {tmp_path}/compare.csv, {tmp_path}/compare.json, {tmp_path}/compare.png" in (
        lines
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "compare.csv",
        "compare.json",
        "compare.png",
    ]
    # the figures are the runs' own: a PD run of the default scenario, made here
    paper = load_scenario().config
    alone = simulate(dataclasses.replace(paper, controller="pd", duration_s=2.4)).summary()
    with open(tmp_path / "compare.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [r["label"] for r in rows] == ["pd", "ct"]
    for joint, value in alone["peak_drive_torque_Nm"].items():
        assert float(rows[0][f"peak_drive_torque_Nm.{joint}"]) == value
    knee = alone["rms_tracking_error_rad"]["left_knee"]
    assert f"| RMS tracking error, left knee | rad | {knee:.4g} |" in done.stdout
    data = json.loads((tmp_path / "compare.json").read_text())
    assert data["runs"][0]["peak_cuff_force_est_N"] == alone["peak_cuff_force_est_N"]
    assert (tmp_path / "compare.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_compare_without_matplotlib_stops_before_any_run(tmp_path: Path) -> None:
    blocker = tmp_path / "blocker" / "matplotlib"
    blocker.mkdir(parents=True)
    (blocker / "__init__.py").write_text("raise ImportError('no matplotlib here')\n")
    out = tmp_path / "out"
    out.mkdir()
    env = {"PYTHONPATH": str(blocker.parent)}
    done = run_cli("compare", "--controllers", "pd,ct", "--out", str(out), env=env)
    assert done.returncode == 2
    assert done.stderr == (
        'exo-ctrl compare: error: compare.png needs matplotlib: pip install "exo-ctrl[plots]"\n'
    )
    assert list(out.iterdir()) == []


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--controllers", "pd"], "--out must be a directory, existing or new in an existing "
         "directory; got '{missing}'"),
        ([], "--controllers must be given (pd,ct,qp), or recordings RUN.rrd as arguments; "
         "got None"),
        (["a.rrd", "--cycles", "1"], "--cycles must be given only with --controllers; got 1.0"),
        (
            ["--controllers", "pd", "a.toml", "b.toml"],
            "SCENARIO must be at most one scenario with --controllers (no recordings); "
            "got ['a.toml', 'b.toml']",
        ),
        (["--controllers", "pd,lqr"], "controllers must be one or more of pd, ct, qp, each once; "
         "got 'pd,lqr' ('lqr' is not one)"),
        (["--controllers", "pd", "paper.toml"], "scenario paper.toml: no such file"),
        (["--controllers", "pd", "--preset", "paper", "--set", "gait.stride=1"],
         "--set: gait.stride: must be a key of GaitParams ({gait_keys}); got 1"),
        (["a.rrd", "--preset", "paper"], "--preset must be given only with --controllers; "
         "got 'paper'"),
    ],
)  # fmt: skip
def test_compare_refuses_bad_input_in_one_line(
    tmp_path: Path, capsys, args: list[str], message: str
) -> None:
    missing = tmp_path / "missing" / "new"
    out = missing if args == ["--controllers", "pd"] else tmp_path
    assert cli.main(["compare", *args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    gait_keys = ", ".join(f.name for f in dataclasses.fields(GaitParams))
    expected = message.format(missing=missing, gait_keys=gait_keys)
    assert err == f"exo-ctrl compare: error: {expected}\n"
    assert list(tmp_path.iterdir()) == []


def test_compare_recordings_refuses_differing_runs_unless_allowed(tmp_path: Path, capsys) -> None:
    a, b = tmp_path / "a.rrd", tmp_path / "b.rrd"
    assert cli.main(["simulate", "--duration", "0.2", "--out", str(a)]) == 0
    step = ["--set", "gait.step_length=0.3", "--set", "gait.lift_height=0.08"]
    assert cli.main(["simulate", "--duration", "0.2", *step, "--out", str(b)]) == 0
    out = tmp_path / "out"
    out.mkdir()
    capsys.readouterr()
    assert cli.main(["compare", str(a), str(b), "--out", str(out)]) == 2
    err = capsys.readouterr().err.splitlines()[-1] + "\n"
    assert err.startswith("exo-ctrl compare: error: runs must be of one configuration but the ")
    assert err.endswith(
        "got ['a', 'b'] (they differ in 2 keys: gait.lift_height (a: 0.1, b: 0.08); "
        "gait.step_length (a: 0.35, b: 0.3))\n"
    )
    assert list(out.iterdir()) == []
    assert cli.main(["compare", str(a), str(b), "--out", str(out), "--allow-different"]) == 0
    captured = capsys.readouterr()
    assert "the runs differ in: gait.lift_height, gait.step_length" in captured.out
    assert "exo-ctrl compare: read 2/2 (b): completed, 0.200 s simulated" in captured.err
    data = json.loads((out / "compare.json").read_text())
    assert [r["label"] for r in data["runs"]] == ["a", "b"]
    assert [r["source"] for r in data["runs"]] == [str(a), str(b)]


def test_a_new_out_directory_is_made_and_removed_again_on_failure(tmp_path: Path, capsys) -> None:
    new = tmp_path / "new"
    assert cli.main(["compare", "--controllers", "pd,lqr", "--out", str(new)]) == 2
    assert capsys.readouterr().err.startswith("exo-ctrl compare: error: controllers must be ")
    assert not new.exists()
    runs = [str(tmp_path / "a.rrd"), str(tmp_path / "b.rrd")]
    for run in runs:
        assert cli.main(["simulate", "--duration", "0.1", "--out", run]) == 0
    assert cli.main(["compare", *runs, "--out", str(new)]) == 0
    assert sorted(p.name for p in new.iterdir()) == ["compare.csv", "compare.json", "compare.png"]
