"""``exo-ctrl export`` and exo_ctrl.record.export: a recording's time series as CSV and Parquet.

The tables are read back independently (Python's csv module and ``float``;
pyarrow's Parquet reader) and compared, column by column, bit for bit, with
the run read back by :func:`read_recording` and with the series entity
straight from the file.
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
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import CUFF_NAMES, JOINT_NAMES, SIDES
from exo_ctrl.record import read_recording
from exo_ctrl.record.export import column_names, export_recording, parse_signals, unit_tag
from exo_ctrl.sim.schema import SIGNALS, signal

EXO_CTRL = Path(sys.executable).with_name("exo-ctrl")
ALLOWED = ", ".join(s.name for s in SIGNALS)


def _expected(path: Path) -> dict[str, np.ndarray]:
    """Column → values, from the run read back, by an independent naming of the columns."""
    result = read_recording(path)
    items = {"joint": JOINT_NAMES, "cuff": CUFF_NAMES, "foot": SIDES}
    units = {"rad": "rad", "rad/s": "rad_per_s", "N·m": "Nm", "N": "N", "A": "A", "V": "V"}
    units |= {"m": "m", "m/s": "m_per_s", "N/s": "N_per_s", "": ""}
    out = {"t": result.t}
    for s in SIGNALS:
        rows = result.signals[s.name]
        tail = f"_{units[s.unit]}" if units[s.unit] else ""
        if s.shape == ():
            out[f"{s.name}{tail}"] = rows
        elif len(s.shape) == 1:
            for i, item in enumerate(items[s.labels]):
                out[f"{item}_{s.name}{tail}"] = rows[:, i]
        else:
            for i, item in enumerate(items[s.labels]):
                for k, axis in enumerate("xz"):
                    out[f"{item}_{s.name}_{axis}{tail}"] = rows[:, i, k]
    return out


def _read_csv(path: Path) -> dict[str, np.ndarray]:
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    return {name: np.array([float(r[i]) for r in body]) for i, name in enumerate(header)}


def test_column_names_come_from_the_schema() -> None:
    assert column_names(signal("q")) == [f"{j}_q_rad" for j in JOINT_NAMES]
    assert column_names(signal("cuff_force"))[:2] == [
        "left_thigh_cuff_force_x_N",
        "left_thigh_cuff_force_z_N",
    ]
    assert column_names(signal("drive_torque"))[1] == "left_knee_drive_torque_Nm"
    assert column_names(signal("foot_slip")) == [
        "left_foot_slip_m_per_s",
        "right_foot_slip_m_per_s",
    ]
    assert column_names(signal("safety_state")) == ["safety_state"]
    assert unit_tag("N·m") == "Nm" and unit_tag("rad/s") == "rad_per_s" and unit_tag("") == ""
    every = [c for s in SIGNALS for c in column_names(s)]
    assert len(every) == len(set(every)) == sum(int(np.prod(s.shape)) for s in SIGNALS)


def test_csv_export_equals_the_recording(short_run, entity_columns, tmp_path: Path) -> None:
    _, path = short_run
    out = tmp_path / "run.csv"
    done = subprocess.run(
        [str(EXO_CTRL), "export", str(path), "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    columns = 1 + sum(int(np.prod(s.shape)) for s in SIGNALS)
    assert done.stdout == f"{out}: 300 rows, {columns} columns (t [s] first)\n"
    got, want = _read_csv(out), _expected(path)
    assert list(got) == list(want)
    for name, values in want.items():
        assert np.array_equal(got[name], values, equal_nan=True), name
    # t is tick × Δt [s]; the values are the series stored in the file.
    assert np.array_equal(got["t"], np.arange(300) * 1e-3)
    ticks, stored = entity_columns(path, "signals/joint_angle/left_knee", "Scalars:scalars")
    assert ticks.tolist() == list(range(300))
    assert np.array_equal(got["left_knee_q_rad"], [row[1] for row in stored])


def test_parquet_export_of_chosen_signals(short_run, tmp_path: Path, capsys) -> None:
    _, path = short_run
    out = tmp_path / "run.parquet"
    assert cli_main(["export", str(path), "--out", str(out), "--signals", "cuff_force,q"]) == 0
    table = pq.read_table(out)
    names = ["t", *column_names(signal("cuff_force")), *column_names(signal("q"))]
    assert table.column_names == names
    want = _expected(path)
    for name in names:
        column = table.column(name)
        assert str(column.type) == "double", name
        assert np.array_equal(column.to_numpy(), want[name]), name
    assert capsys.readouterr().out == f"{out}: 300 rows, {len(names)} columns (t [s] first)\n"


def test_library_export_returns_the_table(short_run, tmp_path: Path) -> None:
    _, path = short_run
    table = export_recording(path, tmp_path / "x.csv", ["safety_state", "q_des", "q_des"])
    assert table.column_names == ["t", "safety_state", *column_names(signal("q_des"))]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["--out", "{tmp}/x.csv", "--signals", "q,knee_angle"],
            "--signals must be one of the signal names of the log schema, comma-separated: "
            f"{ALLOWED}; got 'knee_angle'",
        ),
        (
            ["--out", "{tmp}/x.xlsx"],
            "--out must be a file name ending in .csv or .parquet; got '{tmp}/x.xlsx'",
        ),
    ],
)
def test_bad_options_exit_2_with_one_line(short_run, tmp_path: Path, argv, message) -> None:
    _, path = short_run
    argv = [a.format(tmp=tmp_path) for a in argv]
    done = subprocess.run(
        [str(EXO_CTRL), "export", str(path), *argv], capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 2
    assert done.stderr == f"exo-ctrl export: error: {message.format(tmp=tmp_path)}\n"
    assert done.stdout == "" and list(tmp_path.iterdir()) == []


def test_bad_signals_are_refused_before_the_recording_is_read(tmp_path: Path) -> None:
    with pytest.raises(InvalidParameter, match=r"^--signals must be signal names"):
        parse_signals(" , ")
    with pytest.raises(InvalidParameter, match="got 'nope'"):
        export_recording(tmp_path / "missing.rrd", tmp_path / "x.csv", "nope")
    assert parse_signals("q, dq") == ["q", "dq"]
