"""Every output of the command line: checked before the run, special files, the umask."""

from __future__ import annotations

import json
import os
import stat
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from exo_ctrl import cli
from exo_ctrl.cli import simulate as simulate_cli
from exo_ctrl.record import writer
from exo_ctrl.sim.loop import STARTING
from exo_ctrl.sweep import SweepPaths
from exo_ctrl.sweep import command as sweep_command

EXO_CTRL = Path(sys.executable).parent / "exo-ctrl"
ALLOWED = "a writable file in an existing directory"


def must_not_run(*args: object, **kwargs: object) -> None:
    raise AssertionError("the outputs are checked before the run starts")


@pytest.fixture
def no_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make the simulation and the sweep fail the test if they are reached."""
    monkeypatch.setattr(simulate_cli, "simulate", must_not_run)
    monkeypatch.setattr(sweep_command, "run_sweep", must_not_run)


@pytest.fixture
def umask():
    """Set the umask for one test (restored after it)."""
    old = os.umask(0o022)
    yield os.umask
    os.umask(old)


def missing_dir_message(command: str, option: str, path: Path) -> str:
    return (
        f"exo-ctrl {command}: error: {option} must be {ALLOWED}; got '{path}' "
        f"(directory {path.parent} does not exist)\n"
    )


@pytest.mark.parametrize(
    ("command", "option", "name", "extra"),
    [
        ("simulate", "--summary", "s.json", ["--no-record"]),
        ("simulate", "--out", "run.rrd", ["--summary", "IN_TMP"]),
        ("estimate", "--out", "est.rrd", ["no_such_input.rrd"]),
        ("estimate", "--summary", "s.json", ["no_such_input.rrd"]),
        ("sweep", "--out", "x.parquet", ["--param", "step_length=0.3,0.35"]),
        ("gait", "--csv", "g.csv", []),
        ("urdf", "--out", "p.urdf", ["--kind", "patient"]),
    ],
)
def test_a_missing_directory_is_refused_before_the_run_and_not_created(
    tmp_path: Path, capsys, no_run, command: str, option: str, name: str, extra: list[str]
) -> None:
    path = tmp_path / "missing" / name
    extra = [str(tmp_path / "s.json") if a == "IN_TMP" else a for a in extra]
    assert cli.main([command, *extra, option, str(path)]) == 2
    captured = capsys.readouterr()
    assert captured.err == missing_dir_message(command, option, path)
    assert captured.out == ""
    assert list(tmp_path.iterdir()) == []


def test_a_directory_as_summary_is_refused_before_the_run(tmp_path: Path, capsys, no_run) -> None:
    out = tmp_path / "run.rrd"
    code = cli.main(["simulate", "--summary", str(tmp_path), "--out", str(out)])
    assert code == 2
    assert capsys.readouterr().err == (
        f"exo-ctrl simulate: error: --summary must be {ALLOWED}; got '{tmp_path}' "
        f"({tmp_path} is a directory)\n"
    )
    assert list(tmp_path.iterdir()) == []


def test_a_sweep_file_beside_the_table_is_checked_too(tmp_path: Path, capsys, no_run) -> None:
    out = tmp_path / "x.parquet"
    (tmp_path / "x.report.txt").mkdir()
    assert cli.main(["sweep", "--param", "step_length=0.3", "--out", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"exo-ctrl sweep: error: --out must be {ALLOWED}; got '{out}' "
        f"({tmp_path / 'x.report.txt'} is a directory)\n"
    )
    assert [p.name for p in tmp_path.iterdir()] == ["x.report.txt"]
    assert cli.main(["sweep", "--param", "step_length=0.3", "--out", str(tmp_path / "x")]) == 2
    assert capsys.readouterr().err == (
        f"exo-ctrl sweep: error: --out must be a path ending in .parquet; got '{tmp_path / 'x'}'\n"
    )


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full")
def test_gait_to_dev_full_fails_cleanly_and_keeps_the_device() -> None:
    proc = subprocess.run(
        [str(EXO_CTRL), "gait", "--csv", "/dev/full"], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 1
    assert proc.stderr == "exo-ctrl gait: error: cannot write /dev/full: No space left on device\n"
    assert proc.stdout == ""
    assert stat.S_ISCHR(os.lstat("/dev/full").st_mode)


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="no /dev/full")
def test_simulate_summary_to_dev_full_is_exit_1(tmp_path: Path, capsys) -> None:
    argv = ["simulate", "--duration", "0.02", "--no-record", "--summary", "/dev/full"]
    assert cli.main(argv) == 1
    # A start-up over a second (the first run after an install, or a loaded machine) also
    # says that it compiles or loads the kernels.
    starting = tuple(f"simulate: {text}" for text in STARTING.values())
    lines = [line for line in capsys.readouterr().err.splitlines() if not line.startswith(starting)]
    assert lines == ["exo-ctrl simulate: error: cannot write /dev/full: No space left on device"]
    assert stat.S_ISCHR(os.lstat("/dev/full").st_mode)


def test_gait_to_a_fifo_streams_to_its_reader(tmp_path: Path, capsys) -> None:
    fifo = tmp_path / "gait.fifo"
    os.mkfifo(fifo)
    got: list[bytes] = []

    def reader() -> None:
        with open(fifo, "rb") as handle:
            got.append(handle.read())

    thread = threading.Thread(target=reader, daemon=True)
    thread.start()
    assert cli.main(["gait", "--rate", "10", "--csv", str(fifo)]) == 0
    thread.join(10)
    lines = got[0].decode().splitlines()
    assert lines[0].startswith("t,left_foot_x,") and len(lines) == 1 + 13  # 1.2 s at 10 Hz
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    assert [p.name for p in tmp_path.iterdir()] == ["gait.fifo"]
    assert f"to {fifo}" in capsys.readouterr().out


@pytest.mark.parametrize(("mask", "mode"), [(0o022, 0o644), (0o077, 0o600)])
def test_gait_and_simulate_outputs_honour_the_umask(
    tmp_path: Path, capsys, umask, mask: int, mode: int
) -> None:
    umask(mask)
    csv, summary, rrd = tmp_path / "g.csv", tmp_path / "s.json", tmp_path / "r.rrd"
    assert cli.main(["gait", "--csv", str(csv)]) == 0
    argv = ["simulate", "--duration", "0.02", "--summary", str(summary), "--out", str(rrd)]
    assert cli.main(argv) == 0
    assert json.loads(summary.read_text())["status"] == "completed"
    for path in (csv, summary, rrd):
        assert stat.S_IMODE(path.stat().st_mode) == mode, path.name
    assert sorted(p.name for p in tmp_path.iterdir()) == ["g.csv", "r.rrd", "s.json"]


@pytest.mark.parametrize(("mask", "mode"), [(0o022, 0o644), (0o077, 0o600)])
def test_sweep_outputs_honour_the_umask(
    tmp_path: Path, capsys, umask, mask: int, mode: int
) -> None:
    umask(mask)
    out = tmp_path / "s.parquet"
    argv = ["sweep", "--param", "step_length=0.3,0.35", "--duration", "0.05"]
    assert cli.main([*argv, "--workers", "1", "--out", str(out)]) == 0
    paths = SweepPaths.for_output(out)
    files = [paths.table, paths.csv, paths.report, paths.journal, paths.plot("step_length")]
    for path in files:
        assert stat.S_IMODE(path.stat().st_mode) == mode, path.name
    assert not [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_the_free_space_estimate_matches_a_default_recording(tmp_path: Path, capsys) -> None:
    """The recorder's size estimate per tick is the measured one (within 10 %), not 40 % low.

    The estimate is SimConfig()'s: the preset paper-free-air.
    """
    out = tmp_path / "default.rrd"
    assert cli.main(["simulate", "--preset", "paper-free-air", "--out", str(out)]) == 0
    per_tick = out.stat().st_size / 3600  # 3.6 s at 1 kHz (the ramp-in and two cycles)
    assert 0.9 < per_tick / writer.BYTES_PER_TICK_ESTIMATE < 1.1, per_tick
