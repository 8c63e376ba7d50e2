"""exo_ctrl.compare_recordings: recordings read back give the live runs' figures and cycle."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import exo_ctrl
from exo_ctrl import InvalidParameter, SimConfig, SimResult, simulate
from exo_ctrl.comparison.recordings import compare_recordings, recording_labels
from exo_ctrl.record import RerunRecorder

#: The runs of tests/comparison/test_compare.py: a 0.3 s ramp-in and one 1.2 s cycle.
BASE = SimConfig(ramp_in_s=0.3, duration_s=1.5, chunk_ticks=700)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, SimResult]]:
    """PD and CT recorded, and a PD run of another step length and duration."""
    folder = tmp_path_factory.mktemp("recordings")
    configs = {
        "pd": dataclasses.replace(BASE, controller="pd"),
        "ct": dataclasses.replace(BASE, controller="ct"),
        "other": dataclasses.replace(
            BASE, duration_s=0.5, gait=dataclasses.replace(BASE.gait, step_length=0.3)
        ),
    }
    out = {}
    for name, config in configs.items():
        path = folder / f"{name}.rrd"
        out[name] = (path, simulate(config, observers=[RerunRecorder(path)]))
    return out


def test_recordings_give_the_live_runs_figures(recorded) -> None:
    table = compare_recordings([recorded["pd"][0], recorded["ct"][0]])
    assert table.labels == ["pd", "ct"]
    assert table.differences == {"controller": ["pd", "ct"]}
    live = exo_ctrl.compare(BASE, controllers=("pd", "ct"))
    for name in ("pd", "ct"):
        path, result = recorded[name]
        row = table[name]
        assert row.source == str(path) and row.status == "completed"
        # the recording's figures are its own live run's, the clock's included
        assert row.summary == result.summary()
        clockless = {k: v for k, v in row.figures.items() if k != "real_time_factor"}
        # and those of the same configuration compared live (runs are deterministic)
        assert clockless == {k: v for k, v in live[name].figures.items() if k != "real_time_factor"}
        a, b = row.cycle, live[name].cycle
        assert a.complete and b.complete and a.t0_s == b.t0_s == 0.3
        for field in ("t", "q", "q_des", "drive_torque", "cuff_force", "cuff_force_est"):
            assert np.array_equal(getattr(a, field), getattr(b, field)), field


def test_recordings_that_differ_are_refused_naming_the_keys(recorded) -> None:
    paths = [recorded["pd"][0], recorded["other"][0]]
    with pytest.raises(InvalidParameter) as caught:
        compare_recordings(paths)
    assert str(caught.value) == (
        "runs must be of one configuration but the controller and its gains (--allow-different, or "
        "allow_different=True, compares them anyway); got ['pd', 'other'] (they differ in 2 "
        "keys: duration_s (pd: 1.5, other: 0.5); gait.step_length (pd: 0.35, other: 0.3))"
    )
    table = compare_recordings(paths, allow_different=True)
    assert table.differences == {"duration_s": [1.5, 0.5], "gait.step_length": [0.35, 0.3]}
    short = table["other"]
    assert short.figures["duration_s"] == 0.5 and short.cycle.t.shape == (500,)
    assert not short.cycle.complete  # no whole cycle after the ramp-in: the run's 500 ticks


def test_recording_labels_and_bad_lists(recorded, tmp_path: Path) -> None:
    assert recording_labels(["a/run.rrd", "b/run.rrd", "c/x.rrd"]) == [
        "a/run.rrd",
        "b/run.rrd",
        "x",
    ]
    pd = recorded["pd"][0]
    with pytest.raises(InvalidParameter, match=r"^recordings must be each file once"):
        compare_recordings([pd, pd])
    with pytest.raises(InvalidParameter, match=r"^recordings must be one or more \.rrd files"):
        compare_recordings([])
    with pytest.raises(exo_ctrl.RecordingError, match="file not found"):
        compare_recordings([pd, tmp_path / "none.rrd"])


def test_the_public_face_gives_compare_recordings() -> None:
    assert exo_ctrl.compare_recordings is compare_recordings
    assert "compare" in exo_ctrl.__all__ and "compare_recordings" in exo_ctrl.__all__
