"""CSV sensor logs: round trips, a user's own file, and errors that name line and column."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from exo_ctrl.estimation import (
    CSV_REQUIRED_COLUMNS,
    InvalidLog,
    estimate_series,
    read_csv_log,
    write_csv_log,
)
from exo_ctrl.exceptions import ExoCtrlError

DT = 1e-3
SKIP_S = 0.05
SKIP = round(SKIP_S / DT)


def test_csv_log_round_trip_gives_the_same_estimate(noisy_run, tmp_path: Path) -> None:
    run = noisy_run
    path = write_csv_log(tmp_path / "log.csv", run.t, run.q, run.dq, run.tau)
    assert path.read_text().splitlines()[0] == ",".join(
        [*CSV_REQUIRED_COLUMNS, "left_hip_dq", "left_knee_dq", "right_hip_dq", "right_knee_dq"]
    )
    t, q, dq, tau = read_csv_log(path)
    assert np.array_equal(t, run.t) and np.array_equal(q, run.q)
    assert np.array_equal(dq, run.dq) and np.array_equal(tau, run.tau)
    series = estimate_series(t, q, dq, tau, run.exo, run.gain, dt=DT)
    assert np.max(np.abs(series.normal - run.normal)) < 1e-12
    # Steps taken from t itself differ from dt by rounding only.
    series_t = estimate_series(t, q, dq, tau, run.exo, run.gain)
    assert np.max(np.abs(series_t.normal - run.normal)) < 1e-6


def test_csv_log_written_by_hand_with_extra_columns(noisy_run, tmp_path: Path, show) -> None:
    """A user's file: documented header in another order, an extra column, no dq."""
    run = noisy_run
    n = 400
    header = (
        "right_knee_tau,t,left_hip_q,left_knee_q,right_hip_q,right_knee_q,"
        "left_hip_tau,left_knee_tau,right_hip_tau,comment"
    )
    lines = [header]
    for k in range(n):
        vals = [run.tau[k, 3], run.t[k], *run.q[k], *run.tau[k, :3]]
        lines.append(",".join(repr(float(x)) for x in vals) + ",ok")
    (tmp_path / "user.csv").write_text("\n".join(lines) + "\n")
    t, q, dq, tau = read_csv_log(tmp_path / "user.csv")
    assert dq is None
    assert np.array_equal(q, run.q[:n]) and np.array_equal(tau, run.tau[:n])
    # Without speeds, q is differentiated: close to the live estimate, not equal.
    series = estimate_series(t, q, None, tau, run.exo, run.gain)
    err = np.sqrt(np.mean((series.normal - run.normal[:n])[SKIP:] ** 2, axis=0))
    show("\nCSV without dq (speed by differentiation) vs live: RMS difference", err, "N")
    assert np.all(err < 5.0)


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


HEADER = ",".join(CSV_REQUIRED_COLUMNS)


ROW = "0.0,0.1,0.2,0.3,0.4,1,2,3,4"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "the file is empty; expected a header line"),
        (
            "t,left_hip_q,left_knee_q,right_hip_q,right_knee_q,left_hip_tau\n",
            "line 1: missing column(s) left_knee_tau, right_hip_tau, right_knee_tau",
        ),
        (
            HEADER + ",left_hip_dq\n" + ROW + ",0\n",
            "line 1: has left_hip_dq but not left_knee_dq: give all four *_dq or none",
        ),
        (HEADER + "\n" + ROW + "\n", "needs at least 2 data rows; got 1"),
        (
            HEADER
            + "\n"
            + ROW
            + "\n"
            + ROW.replace("0.0,", "0.001,", 1).replace("0.3", "nan")
            + "\n",
            "line 3, column 'right_hip_q': not a finite number: 'nan'",
        ),
        (
            HEADER + "\n" + ROW + "\n" + ROW.replace("0.2", "abc") + "\n",
            "line 3, column 'left_knee_q': not a number: 'abc'",
        ),
        (
            HEADER + "\n" + ROW + "\n" + ROW.replace("0.0,", "0.002,", 1) + "\n" + ROW + "\n",
            "line 4, column 't': t must be strictly increasing; t = 0.0 s follows t = 0.002 s",
        ),
        (HEADER + "\n" + ROW + "\n0.001,1,2\n", "line 3: 3 fields, the header has 9"),
    ],
)
def test_csv_errors_name_the_line_and_column(tmp_path: Path, text: str, message: str) -> None:
    path = _write(tmp_path / "bad.csv", text)
    with pytest.raises(InvalidLog) as info:
        read_csv_log(path)
    assert str(info.value).startswith(f"invalid log {path}")
    assert message in str(info.value)
    assert isinstance(info.value, ExoCtrlError) and isinstance(info.value, ValueError)


def test_missing_csv_file(tmp_path: Path) -> None:
    with pytest.raises(InvalidLog, match="file not found"):
        read_csv_log(tmp_path / "nope.csv")
