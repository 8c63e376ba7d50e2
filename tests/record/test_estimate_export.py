"""``exo-ctrl estimate --out EST.csv|EST.parquet``, and what it says on a log without the truth.

The tables are read back independently (csv module, pyarrow's Parquet
reader) and compared bit for bit with :func:`estimate_file`'s series.
"""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from exo_ctrl.cli import main as cli_main
from exo_ctrl.estimation import write_csv_log
from exo_ctrl.model import CUFF_NAMES, JOINT_NAMES
from exo_ctrl.record import estimate_file
from exo_ctrl.record.estimate import NO_TRUTH_CSV

EXO_CTRL = Path(sys.executable).with_name("exo-ctrl")


def _expected(series) -> dict[str, np.ndarray]:
    out = {"t": series.t}
    out |= {f"{j}_tau_ext_est_Nm": series.tau_ext[:, i] for i, j in enumerate(JOINT_NAMES)}
    out |= {f"{c}_cuff_normal_est_N": series.normal[:, i] for i, c in enumerate(CUFF_NAMES)}
    for i, cuff in enumerate(CUFF_NAMES):
        for k, axis in enumerate("xz"):
            out[f"{cuff}_cuff_force_est_{axis}_N"] = series.force[:, i, k]
    return out


@pytest.fixture(scope="module")
def csv_log(short_run, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The short run's sensor readings as a user's CSV log (no true forces in it)."""
    result, _ = short_run
    s = result.signals
    path = tmp_path_factory.mktemp("log") / "log.csv"
    write_csv_log(path, result.t, s["q_meas"], s["dq_meas"], s["tau_sensor"])
    return path


def test_csv_log_says_why_there_is_no_accuracy_and_writes_a_csv(csv_log, tmp_path: Path) -> None:
    out = tmp_path / "est.csv"
    done = subprocess.run(
        [str(EXO_CTRL), "estimate", str(csv_log), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[1] == f"no accuracy figures: {NO_TRUTH_CSV}"
    assert "true cuff forces" in lines[1] and lines[-1] == f"estimate written: {out}"
    with out.open(newline="") as f:
        rows = list(csv.reader(f))
    want = _expected(estimate_file(csv_log).series)
    assert rows[0] == list(want)
    for i, (name, values) in enumerate(want.items()):
        assert np.array_equal([float(r[i]) for r in rows[1:]], values), name


def test_recording_estimate_as_parquet_has_errors_and_no_excuse(
    short_run, tmp_path: Path, capsys
) -> None:
    _, path = short_run
    out = tmp_path / "est.parquet"
    assert cli_main(["estimate", str(path), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "no accuracy figures" not in printed and "rms err [N]" in printed
    table = pq.read_table(out)
    want = _expected(estimate_file(path).series)
    assert table.column_names == list(want)
    for name, values in want.items():
        assert np.array_equal(table.column(name).to_numpy(), values), name


def test_bad_out_suffix_exits_2_before_reading(tmp_path: Path, capsys) -> None:
    out = tmp_path / "est.json"
    assert cli_main(["estimate", str(tmp_path / "missing.rrd"), "--out", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"exo-ctrl estimate: error: --out must be a file name ending in .rrd, .csv or "
        f".parquet; got '{out}'\n"
    )
    assert list(tmp_path.iterdir()) == []
