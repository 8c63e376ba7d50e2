"""Messages and exit codes: one line naming the real cause, the codes the README defines.

Standard output that cannot be written (a closed pipe, a full device) is
exit 1 like any output; a terminal that cannot show τ gets an escape, not a
traceback; a sweep ended by SIGTERM is 143 and counts the runs left right;
a ramp too short to compute is refused by name; what a command's outputs
need (matplotlib, a plot path) is checked before any run.
"""

from __future__ import annotations

import concurrent.futures as cf
import subprocess
import sys
from pathlib import Path

import pytest
from hostile_corpus import EXO_CTRL, SHORT_RUN, exo_ctrl

import exo_ctrl.sweep.run as run_module
from exo_ctrl.cli.app import main
from exo_ctrl.exceptions import Terminated


def test_stdout_to_a_full_device_is_exit_1(tmp_path: Path) -> None:
    with open("/dev/full", "w") as full:
        proc = subprocess.run(
            [str(EXO_CTRL), "gait", "--csv", "g.csv"],
            cwd=tmp_path,
            stdout=full,
            stderr=subprocess.PIPE,
            text=True,
        )
    assert (proc.returncode, proc.stderr) == (
        1,
        "exo-ctrl gait: error: cannot write standard output: No space left on device\n",
    )
    assert (tmp_path / "g.csv").is_file()  # the file itself was written whole


@pytest.mark.parametrize(
    ("argv", "prog"),
    [(["simulate", "--help"], "exo-ctrl simulate"), (["--help"], "exo-ctrl")],
)
def test_help_to_a_full_device_is_exit_1_not_lost(
    tmp_path: Path, argv: list[str], prog: str
) -> None:
    """Sibling: argparse dropped a failed help silently (exit 0, nothing printed)."""
    with open("/dev/full", "w") as full:
        proc = subprocess.run(
            [str(EXO_CTRL), *argv], cwd=tmp_path, stdout=full, stderr=subprocess.PIPE, text=True
        )
    assert (proc.returncode, proc.stderr) == (
        1,
        f"{prog}: error: cannot write standard output: No space left on device\n",
    )


def test_stdout_to_a_closed_pipe_is_exit_1(tmp_path: Path) -> None:
    proc = subprocess.Popen(
        [str(EXO_CTRL), "gait", "--csv", "g.csv"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    proc.stdout.close()  # long before the command writes (its imports take a second)
    err = proc.stderr.read().decode()
    assert (proc.wait(timeout=120), err) == (
        1,
        "exo-ctrl gait: error: cannot write standard output: Broken pipe\n",
    )


def test_an_ascii_terminal_gets_escapes_not_a_traceback(tmp_path: Path) -> None:
    proc = exo_ctrl(["simulate", *SHORT_RUN], tmp_path, env={"PYTHONIOENCODING": "ascii"})
    assert proc.returncode == 0, proc.stderr
    assert "peak \\u03c4 [N\\xb7m]" in proc.stdout
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize("option", ["--ramp-in", "--ramp-out"])
def test_a_vanishing_ramp_is_refused_by_name(tmp_path: Path, capsys, option: str) -> None:
    code = main(["simulate", option, "1e-300", *SHORT_RUN])
    name = f"{option}: run.{option[2:].replace('-', '_')}_s:"
    assert (code, capsys.readouterr().err) == (
        2,
        f"exo-ctrl simulate: error: {name} must be 0 (no ramp) or at least 1e-06 s; "
        "got 1e-300 (a shorter ramp overflows)\n",
    )


def test_plots_without_matplotlib_are_refused_before_the_run(
    tmp_path: Path, capsys, monkeypatch
) -> None:
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # as if not installed
    monkeypatch.setattr("exo_ctrl.cli.simulate.simulate", _must_not_run)
    code = main(["simulate", *SHORT_RUN, "--plots", str(tmp_path)])
    assert (code, capsys.readouterr().err) == (
        2,
        "exo-ctrl simulate: error: the torque-speed plot needs matplotlib: "
        'pip install "exo-ctrl[plots]"\n',
    )
    assert list(tmp_path.iterdir()) == []


def _must_not_run(*args: object, **kwargs: object) -> None:
    raise AssertionError("the run started")


def test_a_sweep_plot_path_that_is_a_directory_is_refused_before_any_run(
    tmp_path: Path, capsys, monkeypatch
) -> None:
    (tmp_path / "c.load_step_length.png").mkdir()
    monkeypatch.setattr(run_module, "simulate", _must_not_run)
    out = tmp_path / "c.parquet"
    code = main(
        ["sweep", "--param", "step_length=0.3,0.35", "--duration", "0.05", "--out", str(out)]
    )
    assert (code, capsys.readouterr().err) == (
        2,
        f"exo-ctrl sweep: error: --out must be a writable file in an existing directory; got "
        f"'{out}' ({tmp_path / 'c.load_step_length.png'} is a directory)\n",
    )


@pytest.mark.parametrize(
    ("stop", "code", "how"),
    [
        (Terminated("SIGTERM"), 143, "terminated by SIGTERM"),
        (KeyboardInterrupt(), 130, "interrupted"),
    ],
)
def test_a_stopped_pooled_sweep_counts_the_runs_left(
    tmp_path: Path, capsys, monkeypatch, stop: BaseException, code: int, how: str
) -> None:
    """Three runs on two workers: the first in this process, then the signal: 2 to do, not 1."""
    real_wait = cf.wait

    def stopped(*args: object, **kwargs: object) -> object:
        raise stop

    monkeypatch.setattr(run_module.cf, "wait", stopped)
    out = tmp_path / "s.parquet"
    argv = ["sweep", "--param", "step_length=0.3,0.35,0.4", "--duration", "0.05"]
    try:
        got = main([*argv, "--workers", "2", "--out", str(out), "--no-plots"])
    finally:
        monkeypatch.setattr(run_module.cf, "wait", real_wait)
    err = capsys.readouterr().err.splitlines()
    assert got == code
    assert err[-1] == (
        f"exo-ctrl sweep: {how}: 1 runs finished, 2 to do; 1 rows written to {out} "
        "(run the same command to resume)"
    )
