"""Tests of exo_ctrl.record.estimate: cuff forces estimated from a recording or a CSV log.

Also through the CLI (``exo-ctrl estimate``).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl.cli import main as cli_main
from exo_ctrl.estimation import write_csv_log
from exo_ctrl.model import CUFF_NAMES
from exo_ctrl.record import RerunRecorder, estimate_file, write_estimate_recording
from exo_ctrl.sim import SimConfig, simulate


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory):
    """A recorded default CT run (1.2 s) and its result."""
    path = tmp_path_factory.mktemp("offline") / "run.rrd"
    result = simulate(SimConfig(controller="ct", duration_s=1.2), observers=[RerunRecorder(path)])
    return path, result


def test_offline_estimate_from_the_recording_equals_the_live_one(recorded) -> None:
    path, result = recorded
    est = estimate_file(path)
    live = result.signals
    np.testing.assert_allclose(est.series.normal, live["cuff_normal_est"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(est.series.force, live["cuff_force_est"], rtol=0, atol=1e-9)
    np.testing.assert_allclose(est.series.tau_ext, live["tau_ext_est"], rtol=0, atol=1e-9)
    # The error figures are the live run's (the same pairing and start-up skip).
    summary = result.summary()
    for key in ("cuff_force_estimate_rms_error_N", "cuff_force_estimate_rms_error_rel"):
        for cuff in CUFF_NAMES:
            assert est.errors[key][cuff] == pytest.approx(summary[key][cuff], rel=1e-9)
            assert est.errors[key][cuff] > 0.0


def test_csv_log_gives_the_same_estimate(recorded, tmp_path: Path) -> None:
    _, result = recorded
    s = result.signals
    log = tmp_path / "log.csv"
    write_csv_log(log, result.t, s["q_meas"], s["dq_meas"], s["tau_sensor"])
    est = estimate_file(log)
    # The CSV path takes the step from the logged times (k Δt written with
    # full precision), the recording path the run's Δt: equal to rounding.
    np.testing.assert_allclose(est.series.normal, s["cuff_normal_est"], rtol=0, atol=1e-6)
    assert est.errors == {}  # a user's log holds no true forces


def test_estimate_recording_holds_the_estimate(recorded, tmp_path: Path) -> None:
    from rerun.chunk import RrdReader

    path, _ = recorded
    est = estimate_file(path)
    out = write_estimate_recording(est, tmp_path / "est.rrd")
    found: dict[str, np.ndarray] = {}
    for chunk in RrdReader(str(out)).stream().to_chunks():
        entity = chunk.entity_path
        if not entity.startswith("/estimate/cuff_normal/"):
            continue
        batch = chunk.to_record_batch()
        column = next(c for c in batch.schema.names if c.endswith("Scalars:scalars"))
        values = np.concatenate(
            [np.asarray(v, dtype=float) for v in batch.column(column).to_pylist()]
        )
        found[entity.rsplit("/", 1)[1]] = values
    assert sorted(found) == sorted(CUFF_NAMES)
    for i, cuff in enumerate(CUFF_NAMES):
        np.testing.assert_array_equal(found[cuff], est.series.normal[:, i])


def test_cli_estimate_reports_the_errors(recorded, tmp_path: Path, capsys) -> None:
    path, result = recorded
    summary_path = tmp_path / "e.json"
    code = cli_main(["estimate", str(path), "--summary", str(summary_path)])
    out = capsys.readouterr().out
    assert code == 0
    data = json.loads(summary_path.read_text())
    live = result.summary()["cuff_force_estimate_rms_error_N"]
    for cuff in CUFF_NAMES:
        assert data["cuff_force_estimate_rms_error_N"][cuff] == pytest.approx(live[cuff], rel=1e-9)
        assert cuff in out


@pytest.mark.parametrize(
    ("name", "content", "message"),
    [
        ("x.txt", "t\n0\n", "file must be a .rrd recording or a .csv log; got"),
        ("x.rrd", "not a recording", "x.rrd"),
        ("x.csv", "t,left_hip_q\n0,0\n", "invalid log"),
    ],
)
def test_cli_estimate_bad_files(
    tmp_path: Path, capsys, name: str, content: str, message: str
) -> None:
    bad = tmp_path / name
    bad.write_text(content)
    code = cli_main(["estimate", str(bad), "--summary", str(tmp_path / "s.json")])
    err = capsys.readouterr().err
    assert code == 2
    assert message in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "s.json").exists()


def test_gain_option_changes_the_estimate(recorded) -> None:
    path, _ = recorded
    slow = estimate_file(path, gain_per_s=20.0)
    fast = estimate_file(path)
    # A slower observer lags more: a larger error against the truth.
    for cuff in CUFF_NAMES:
        assert (
            slow.errors["cuff_force_estimate_rms_error_N"][cuff]
            > fast.errors["cuff_force_estimate_rms_error_N"][cuff]
        )
