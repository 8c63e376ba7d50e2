"""Tests of exo_ctrl.record.estimate: cuff forces estimated from a recording or a CSV log.

Also through the CLI (``exo-ctrl estimate``).  Both live estimators (the
momentum observer and the Kalman filter) are estimated offline by the one
the recording's run used, rebuilt on the run's device models.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl.cli import main as cli_main
from exo_ctrl.estimation import ESTIMATORS, MODEL_DRIVEN, write_csv_log
from exo_ctrl.estimation.errors import UNOBSERVABLE
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import CUFF_NAMES
from exo_ctrl.record import RerunRecorder, estimate_file, write_estimate_recording
from exo_ctrl.record.estimate_models import torque_rate_schedule
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.belief import Belief
from exo_ctrl.sim.session import Segment, SessionParams


def _record(folder: Path, name: str, config: SimConfig):
    path = folder / f"{name}.rrd"
    return path, simulate(config, observers=[RerunRecorder(path)])


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """A recorded CT run (1.2 s) per estimator: (path, result)."""
    folder = tmp_path_factory.mktemp("offline")
    return {
        name: _record(folder, name, SimConfig(controller="ct", duration_s=1.2, estimator=name))
        for name in ESTIMATORS
    }


@pytest.fixture(scope="module")
def recorded(runs):
    """The momentum observer's run (the CSV and gain tests are the observer's)."""
    return runs["momentum"]


def test_the_default_estimator_is_the_kalman_filter() -> None:
    assert SimConfig().estimator == "kalman"


@pytest.mark.parametrize("estimator", ESTIMATORS)
def test_offline_estimate_from_the_recording_equals_the_live_one(runs, estimator: str) -> None:
    path, result = runs[estimator]
    assert result.config.estimator == estimator
    est = estimate_file(path)  # the recording's estimator
    assert est.series.estimator == estimator
    assert est.summary()["estimator"] == estimator
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
    # What each estimator cannot see, as the live summary says it.
    unobservable = est.errors["cuff_force_estimate_unobservable"]
    assert unobservable == summary["cuff_force_estimate_unobservable"]
    if estimator == "kalman":
        assert unobservable == MODEL_DRIVEN
        assert est.summary()["observer_gain_per_s"] is None
    else:
        assert unobservable == [f"{c}: {w}" for c, x in UNOBSERVABLE.items() for w in x]
        assert est.summary()["observer_gain_per_s"] == result.config.observer_gain_per_s


@pytest.mark.parametrize("estimator", ESTIMATORS)
def test_estimator_option_runs_the_other_estimator_on_the_same_readings(
    runs, estimator: str
) -> None:
    """The other run's live estimate from this run's readings.

    CT's command does not read the estimate and the supervisor stops neither
    run, so both runs hold the same readings; the estimator named offline
    then gives the other run's live estimate.
    """
    other = next(name for name in ESTIMATORS if name != estimator)
    path, result = runs[estimator]
    _, other_result = runs[other]
    for name in ("q_meas", "dq_meas", "tau_sensor"):
        np.testing.assert_array_equal(result.signals[name], other_result.signals[name])
    est = estimate_file(path, estimator=other)
    assert est.series.estimator == other
    live = other_result.signals
    np.testing.assert_allclose(est.series.force, live["cuff_force_est"], rtol=0, atol=1e-9)
    assert not np.allclose(est.series.force, result.signals["cuff_force_est"], atol=1e-3)


def test_kalman_filter_is_rebuilt_on_the_recorded_device_patient(tmp_path: Path) -> None:
    """A device holding the true patient: the offline filter holds it too.

    PD's command does not read the patient model, so the nominal and the
    truth beliefs give the same readings; only the filter's patient differs,
    and the offline estimate must follow the recording's.
    """
    base = {"controller": "pd", "duration_s": 0.6, "estimator": "kalman"}
    path, truth = _record(tmp_path, "truth", SimConfig(**base, belief=Belief("truth")))
    _, nominal = _record(tmp_path, "nominal", SimConfig(**base))
    np.testing.assert_array_equal(truth.signals["tau_sensor"], nominal.signals["tau_sensor"])
    est = estimate_file(path)
    np.testing.assert_allclose(est.series.force, truth.signals["cuff_force_est"], rtol=0, atol=1e-9)
    gap = np.max(np.abs(est.series.force - nominal.signals["cuff_force_est"]))
    assert gap > 1.0  # N: the nominal patient's filter is another estimate


def test_kalman_is_refused_for_a_csv_log_and_a_gain_with_the_kalman_filter(
    runs, tmp_path: Path, capsys
) -> None:
    _, result = runs["kalman"]
    s = result.signals
    log = tmp_path / "log.csv"
    write_csv_log(log, result.t, s["q_meas"], s["dq_meas"], s["tau_sensor"])
    with pytest.raises(InvalidParameter) as e:
        estimate_file(log, estimator="kalman")
    assert str(e.value) == (
        "estimator must be momentum for a .csv log; got 'kalman' (the Kalman filter needs the "
        "device's patient, cuff and sensor models, which only a recording holds)"
    )
    path = runs["kalman"][0]
    with pytest.raises(InvalidParameter) as e:
        estimate_file(path, gain_per_s=50.0)
    assert str(e.value) == (
        "gain must be given with the momentum observer only; got 50.0 (the kalman estimator "
        "(the recording's estimator) has no observer gain; add --estimator momentum)"
    )
    assert estimate_file(path, gain_per_s=50.0, estimator="momentum").series.gain_per_s == 50.0
    with pytest.raises(InvalidParameter, match=r"^estimator must be one of momentum, kalman; "):
        estimate_file(path, estimator="ekf")
    code = cli_main(["estimate", str(log), "--estimator", "kalman"])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("exo-ctrl estimate: error: estimator must be momentum for a .csv log")
    assert len(err.strip().splitlines()) == 1


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


def test_cli_estimator_option_names_the_estimator(runs, tmp_path: Path, capsys) -> None:
    path, _ = runs["kalman"]
    summary_path = tmp_path / "m.json"
    code = cli_main(
        ["estimate", str(path), "--estimator", "momentum", "--summary", str(summary_path)]
    )
    out = capsys.readouterr().out
    assert code == 0
    assert "(the momentum observer, gain 100 1/s)" in out.splitlines()[0]
    data = json.loads(summary_path.read_text())
    assert data["estimator"] == "momentum"
    live = runs["momentum"][1].summary()["cuff_force_estimate_rms_error_N"]
    for cuff in CUFF_NAMES:
        assert data["cuff_force_estimate_rms_error_N"][cuff] == pytest.approx(live[cuff], rel=1e-9)
    assert cli_main(["estimate", str(path)]) == 0
    out = capsys.readouterr().out
    assert "(the Kalman filter on the device's models)" in out.splitlines()[0]
    assert "from the device's cuff and patient models" in out


def test_a_mode_that_retunes_the_filter_is_estimated_offline_as_it_ran(tmp_path: Path) -> None:
    """Transparent raises the filter's σ_d (control/modes); a session switches it back
    and forth: the offline estimate follows the recorded modes' schedule and equals
    the live one."""
    session = SessionParams(
        (Segment(0.6, "tracking"), Segment(0.6, "transparent"), Segment(0.4, "tracking"))
    )
    config = SimConfig(
        controller="ct",
        session=session,
        duration_s=session.total_s,
        patient_torque="active",
        safety=False,
    )
    path, result = _record(tmp_path, "session", config)
    rate = config.modes.estimator_torque_rate_Nm_per_sqrt_s
    assert torque_rate_schedule(config) == [(0, None), (601, rate), (1201, None)]
    est = estimate_file(path)
    live = result.signals["cuff_force_est"]
    np.testing.assert_allclose(est.series.force, live, rtol=0, atol=1e-9)
    assert torque_rate_schedule(SimConfig(mode="transparent")) == [(0, rate)]
    assert torque_rate_schedule(SimConfig()) == [(0, None)]
