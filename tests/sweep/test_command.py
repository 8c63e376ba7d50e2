"""Tests of exo_ctrl.sweep.command: the ``exo-ctrl sweep`` options and exit codes."""

from __future__ import annotations

import argparse
import sys

import pytest

import exo_ctrl.sweep.run as run_module
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.sweep import MissingDependency, SweepPaths, add_sweep_arguments, run_sweep_command


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
    assert str(info.value) == '--scheduler needs Dask: pip install "exo-ctrl[dask]"'
