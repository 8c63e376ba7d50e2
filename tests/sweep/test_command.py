"""Tests of exo_ctrl.sweep.command: the ``exo-ctrl sweep`` options and exit codes."""

from __future__ import annotations

import argparse
import sys

import pytest

import exo_ctrl.sweep.run as run_module
from exo_ctrl import cli
from exo_ctrl._io import OUTPUT_ALLOWED
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.sweep import MissingDependency, SweepPaths, add_sweep_arguments, run_sweep_command


def test_cli_exit_codes(tmp_path, monkeypatch, capsys):
    parser = argparse.ArgumentParser()
    add_sweep_arguments(parser)
    out = tmp_path / "c.parquet"
    argv = ["--param", "step_length=0.3,0.35", "--duration", "0.3", "--out", str(out)]
    args = parser.parse_args([*argv, "--workers", "1"])
    assert run_sweep_command(args) == 0
    assert "wrote 2 runs (2 completed, 0 failed)" in capsys.readouterr().out
    assert SweepPaths.for_output(out).plot("step_length").is_file()

    def interrupting(config, *a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(run_module, "simulate", interrupting)
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
    assert str(info.value) == '--scheduler needs Dask: .venv/bin/pip install -e ".[dask]"'


UNREACHABLE = (
    "UnreachableFootTarget: left foot path point (x = 0.6514 m, z = -0.894 m) at t = 0.2555 s "
    "is 1.106 m from the hip; the leg reaches from 0 m to 1.039 m (set by step_length = 1.2 m, "
    "hip_height = 0.9 m, lift_height = 0.1 m, pelvis_excursion = 0 m, shape_coeff = 0.5) "
    "[step_length=1.2 m]"
)


def test_no_run_completed_exits_1_and_says_why(tmp_path, capsys):
    """Before: ``wrote 2 runs (0 completed)`` and exit 0."""
    out = tmp_path / "f.parquet"
    argv = ["sweep", "--param", "step_length=1.2,1.3", "--duration", "0.3", "--workers", "1"]
    assert cli.main([*argv, "--out", str(out), "--no-plots"]) == 1
    captured = capsys.readouterr()
    assert captured.out.splitlines()[0] == (
        f"wrote 2 runs (0 completed, 2 failed) to {out} and {out.with_suffix('.csv')}"
    )
    assert captured.err.splitlines()[-1] == (
        f"exo-ctrl sweep: none of the 2 runs completed; the first error: {UNREACHABLE}"
    )
    assert out.is_file()  # the table of the failures is written all the same


def test_some_runs_failed_exits_0_and_counts_them(tmp_path, capsys):
    out = tmp_path / "p.parquet"
    argv = ["sweep", "--param", "period=0.3,1.2", "--duration", "0.3", "--workers", "1"]
    assert cli.main([*argv, "--out", str(out), "--no-plots"]) == 0
    captured = capsys.readouterr()
    assert captured.out.splitlines()[0] == (
        f"wrote 2 runs (1 completed, 1 failed) to {out} and {out.with_suffix('.csv')}"
    )
    assert "none of" not in captured.err


def test_out_is_checked_before_any_run(tmp_path, count_runs):
    parser = argparse.ArgumentParser()
    add_sweep_arguments(parser)
    out = tmp_path / "missing" / "s.parquet"
    args = parser.parse_args(
        ["--param", "step_length=0.3", "--duration", "0.3", "--workers", "1", "--out", str(out)]
    )
    with pytest.raises(InvalidParameter) as info:
        run_sweep_command(args)
    assert str(info.value) == (
        f"--out must be {OUTPUT_ALLOWED}; got {str(out)!r} (directory {out.parent} does not exist)"
    )
    assert count_runs == []
    assert list(tmp_path.iterdir()) == []  # no directory created
