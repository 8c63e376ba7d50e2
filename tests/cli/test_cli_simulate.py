"""End-to-end tests of ``exo-ctrl simulate``: the recording, its scene rate, the summary."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

from exo_ctrl import cli, read_recording


def scene_ticks(path: Path, entity: str) -> list[int]:
    ticks: list[int] = []
    for chunk in RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        if chunk.entity_path == entity and "tick" in batch.schema.names:  # not the static style
            ticks += batch.column("tick").to_pylist()
    return sorted(ticks)


def test_simulate_records_the_scene_at_the_given_rate(tmp_path: Path, capsys) -> None:
    out, summary = tmp_path / "run.rrd", tmp_path / "s.json"
    args = ["simulate", "--duration", "0.1", "--out", str(out), "--summary", str(summary)]
    assert cli.main([*args, "--scene-rate", "100"]) == 0
    printed = capsys.readouterr().out
    assert f"recording: {out}" in printed and "real-time factor" in printed
    back = read_recording(out)
    assert back.n_ticks == 100 and back.status == "completed"
    assert np.array_equal(back.t, np.arange(100) * 1e-3)
    assert scene_ticks(out, "/world/exo/left/joints") == list(range(0, 100, 10))
    assert scene_ticks(out, "/signals/joint_angle/left_hip") == list(range(100))
    data = json.loads(summary.read_text())
    assert data == json.loads(json.dumps(back.summary()))  # the live run's, read back


def test_simulate_scene_rate_default_is_50_hz(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run.rrd"
    assert cli.main(["simulate", "--duration", "0.1", "--out", str(out)]) == 0
    capsys.readouterr()
    assert scene_ticks(out, "/world/belt/stripes") == list(range(0, 100, 20))


@pytest.mark.parametrize("rate", ["0", "-5", "nan"])
def test_simulate_refuses_a_bad_scene_rate(tmp_path: Path, capsys, rate: str) -> None:
    out = tmp_path / "run.rrd"
    code = cli.main(["simulate", "--duration", "0.1", "--out", str(out), "--scene-rate", rate])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("exo-ctrl simulate: error: scene_rate must be a finite rate > 0 Hz")
    assert "Traceback" not in err and err.count("\n") == 1
    assert not out.exists()


def test_simulate_without_recording(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run.rrd"
    args = ["simulate", "--duration", "0.05", "--out", str(out), "--no-record"]
    assert cli.main(args) == 0
    assert "recording:" not in capsys.readouterr().out
    assert not out.exists()
