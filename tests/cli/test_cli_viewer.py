"""``--spawn``: the viewer beside the interpreter is used; a missing one is said in one line.

No viewer is started: ``rerun.spawn`` is replaced by a stand-in.
"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
import rerun as rr

from exo_ctrl import cli
from exo_ctrl.record import viewer


@pytest.fixture
def no_viewer(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An interpreter path with no rerun beside it, and a PATH without rerun."""
    python = tmp_path / "bin" / "python"
    monkeypatch.setattr(sys, "executable", str(python))
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    return python.parent / "rerun"


def test_the_viewer_beside_the_interpreter_is_found_and_spawned_by_path(monkeypatch) -> None:
    beside = Path(sys.executable).parent / "rerun"
    if not beside.is_file():
        pytest.skip("rerun-sdk's viewer is not installed beside this interpreter")
    monkeypatch.setenv("PATH", "/nonexistent")  # as when the environment is not activated
    assert viewer.find_viewer() == beside
    calls: list[dict] = []
    monkeypatch.setattr(rr, "spawn", lambda **kw: calls.append(kw))
    rec = rr.RecordingStream("exo_ctrl_test")
    assert viewer.spawn_viewer(rec) is None
    assert calls == [{"connect": False, "executable_path": str(beside), "recording": rec}]


def test_a_missing_viewer_is_said_in_one_line(no_viewer: Path, monkeypatch) -> None:
    monkeypatch.setattr(rr, "spawn", lambda **kw: pytest.fail("nothing to spawn"))
    assert viewer.find_viewer() is None
    assert viewer.spawn_viewer(rr.RecordingStream("exo_ctrl_test")) == (
        f"no rerun viewer found (neither {no_viewer} nor 'rerun' on PATH; it comes with rerun-sdk)"
    )


def test_a_viewer_that_fails_to_start_is_said_in_one_line(monkeypatch) -> None:
    def fail(**kw: object) -> None:
        raise RuntimeError("Failed to spawn:\n  port in use")

    monkeypatch.setattr(viewer, "find_viewer", lambda: Path("/opt/rerun"))
    monkeypatch.setattr(rr, "spawn", fail)
    assert viewer.spawn_viewer(rr.RecordingStream("exo_ctrl_test")) == (
        "could not start the rerun viewer /opt/rerun: Failed to spawn: port in use"
    )


def test_simulate_spawn_without_a_viewer_records_and_warns_in_one_line(
    tmp_path: Path, no_viewer: Path, capsys
) -> None:
    out = tmp_path / "run.rrd"
    assert cli.main(["simulate", "--duration", "0.02", "--spawn", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    line = (
        f"exo-ctrl simulate: warning: no rerun viewer found (neither {no_viewer} nor 'rerun' "
        f"on PATH; it comes with rerun-sdk); recording to {out} only\n"
    )
    assert line in err
    assert "RuntimeWarning" not in err and "warnings.warn" not in err and "cargo" not in err
    assert out.is_file()
