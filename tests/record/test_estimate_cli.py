"""``exo-ctrl estimate`` on bad input: what the user sees (exit code, stdout, stderr, files).

The library's answers are tested in test_estimate_checks.py; here the same
cases through the command line, in-process (:func:`exo_ctrl.cli.main`) and
as a subprocess of the installed entry point.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from exo_ctrl.cli import main as cli_main
from exo_ctrl.model import CUFF_NAMES
from exo_ctrl.record import RerunRecorder
from exo_ctrl.sim import SimConfig, simulate

EXO_CTRL = Path(sys.executable).with_name("exo-ctrl")


def _record(path: Path, **config) -> Path:
    simulate(SimConfig(**config), observers=[RerunRecorder(path)])
    return path


@pytest.fixture(scope="module")
def chunked(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 0.6 s default run recorded in 100-tick chunks."""
    return _record(tmp_path_factory.mktemp("cli") / "run.rrd", duration_s=0.6, chunk_ticks=100)


def test_truncated_recording_exits_0_with_one_warning_line(chunked: Path, tmp_path: Path) -> None:
    data = chunked.read_bytes()
    cut = tmp_path / "half.rrd"
    cut.write_bytes(data[: len(data) // 2])
    summary = tmp_path / "s.json"
    done = subprocess.run(
        [str(EXO_CTRL), "estimate", str(cut), "--summary", str(summary)],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr
    figures = json.loads(summary.read_text())
    n = figures["ticks_recovered"]
    assert figures["complete"] is False and 0 < n < 600
    lines = done.stderr.splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr
    assert lines[0].startswith(f"exo-ctrl estimate: warning: {cut}: incomplete recording: ")
    assert lines[0].endswith(f"; {n} ticks of the 600 planned recovered; the estimate covers those")
    assert figures["warnings"] == [lines[0].removeprefix("exo-ctrl estimate: warning: ")]
    assert done.stdout.startswith(f"estimated {n} samples of {cut}")


def test_vanishing_denominator_shows_a_dash_and_null(tmp_path: Path, capsys) -> None:
    # The cuffs start relaxed (fitted slack, on the gait at speed): a true force of ~0 N.
    path = _record(
        tmp_path / "coarse.rrd",
        duration_s=0.1,
        control_rate_hz=20.0,
        ramp_in_s=0.0,
        cuff_fit="slack",
    )
    summary = tmp_path / "s.json"
    assert cli_main(["estimate", str(path), "--summary", str(summary)]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    rows = captured.out.splitlines()[1:]
    assert (
        rows[0]
        == f"{'cuff':<13}{'peak normal est [N]':>20}{'rms err [N]':>13}{'rel':>9}"
        + f"{'normal/peak':>13}{'normal/rms':>12}{'along/rms':>11}"
    )
    for row, cuff in zip(rows[1:5], CUFF_NAMES, strict=True):
        assert row.startswith(cuff) and row.endswith(" —") and len(row) == len(rows[0])
    rel = json.loads(summary.read_text())["cuff_force_estimate_rms_error_rel"]
    assert rel == dict.fromkeys(CUFF_NAMES)


def test_other_exo_allowed_on_request(chunked: Path, tmp_path: Path, capsys) -> None:
    heavy = tmp_path / "heavy.urdf"
    assert cli_main(["urdf", "--kind", "exo", "--thigh-mass", "20", "--out", str(heavy)]) == 0
    capsys.readouterr()
    assert cli_main(["estimate", str(chunked), "--exo", str(heavy), "--allow-other-exo"]) == 0
    err = capsys.readouterr().err
    assert err.splitlines()[0] == (
        f"exo-ctrl estimate: warning: {chunked}: estimating with exo {str(heavy)!r}, "
        "not the recorded one: left_hip link mass 20 kg against 3.5 kg recorded"
    )


def test_run_too_short_for_error_figures(tmp_path: Path, capsys) -> None:
    path = _record(tmp_path / "short.rrd", duration_s=0.03, estimator="momentum")
    assert cli_main(["estimate", str(path)]) == 0
    captured = capsys.readouterr()
    assert captured.err == (
        f"exo-ctrl estimate: warning: {path}: 30 ticks, not more than the observer's "
        "start-up of 50 ticks (5 / K_O = 0.05 s): no error figures\n"
    )
    assert "rms err" not in captured.out
