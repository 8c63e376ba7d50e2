"""exo_ctrl.compare: PD, CT and QP on one scenario, the table against each run's own summary.

The compared runs keep no history; the same configurations run separately
with their whole history give the independent figures (every run is
deterministic), the cycle drawn and the estimate's peak.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import struct
from pathlib import Path

import numpy as np
import pytest

import exo_ctrl
from exo_ctrl import InvalidParameter, InvalidScenario, SimConfig, SimResult, simulate
from exo_ctrl.comparison import (
    CompareTable,
    cycle_figure,
    cycle_ticks,
    trace_from_history,
    write_compare_png,
)
from exo_ctrl.control import PD
from exo_ctrl.model import CUFF_NAMES, JOINT_NAMES
from exo_ctrl.scenario import preset_text

#: A short scenario: a 0.3 s ramp-in, then one 1.2 s cycle; 700-tick chunks, so that
#: the kept cycle (ticks 300-1500) wraps around its ring buffer across three chunks.
BASE = SimConfig(ramp_in_s=0.3, duration_s=5.0, chunk_ticks=700)
CONTROLLERS = ("pd", "ct", "qp")
#: The figures that depend on the wall clock: equal to the row's own summary only.
CLOCK = ("wall_time_s", "real_time_factor")


@pytest.fixture(scope="module")
def table() -> CompareTable:
    return exo_ctrl.compare(BASE, controllers=CONTROLLERS, cycles=1)


@pytest.fixture(scope="module")
def separate() -> dict[str, SimResult]:
    """The same runs, one by one, keeping their whole history."""
    config = dataclasses.replace(BASE, duration_s=1.5)
    return {c: simulate(dataclasses.replace(config, controller=c)) for c in CONTROLLERS}


def expected_figures(s: dict) -> dict:
    """The table's figures read straight from a summary, written out by hand."""
    return {
        "duration_s": s["duration_s"],
        "rms_tracking_error_rad": s["rms_tracking_error_rad"],
        "max_tracking_error_rad": s["max_tracking_error_rad"],
        "peak_drive_torque_Nm": s["peak_drive_torque_Nm"],
        "rms_drive_torque_Nm": s["rms_drive_torque_Nm"],
        "peak_motor_current_A": s["peak_motor_current_A"],
        "rms_motor_current_A": s["rms_motor_current_A"],
        "electrical_energy_J": {j: s["energy_J"][j]["electrical"] for j in JOINT_NAMES},
        "peak_cuff_force_N": s["peak_cuff_force_N"],
        "peak_cuff_force_est_N": s["peak_cuff_force_est_N"],
        "cuff_force_estimate_rms_error_N": s["cuff_force_estimate_rms_error_N"],
        "slip_speed_rms_mps": s.get("slip_speed_rms_mps"),
        "slip_speed_max_mps": s.get("slip_speed_max_mps"),
        "touchdown_speed_mps": s.get("touchdown_speed_mps"),
        "touchdown_slip_mps": s.get("touchdown_slip_mps"),
        "safety_event_count": len(s["safety_events"]),
        "safety_state": s["safety_state"],
        "real_time_factor": s["real_time_factor"],
    }


def without_clock(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if k not in CLOCK}


def test_the_table_equals_each_runs_own_summary(table, separate) -> None:
    assert table.labels == list(CONTROLLERS)
    assert table.differences == {"controller": list(CONTROLLERS)}
    for c in CONTROLLERS:
        row, alone = table[c], separate[c].summary()
        assert row.status == "completed" and row.controller == c
        assert row.figures == expected_figures(row.summary)  # its own, every figure
        # The run made separately: every figure and the whole summary but the clock's.
        assert {k: v for k, v in row.figures.items() if k not in CLOCK} == {
            k: v for k, v in expected_figures(alone).items() if k not in CLOCK
        }
        assert json.dumps(without_clock(row.summary)) == json.dumps(without_clock(alone))
        assert row.slip_speed_rms_mps is None  # no belt in this scenario
        assert row.rms_tracking_error_rad.worst == max(alone["rms_tracking_error_rad"].values())
    # the one-line check a user's suite makes
    assert table["ct"].rms_tracking_error_rad.worst < table["pd"].rms_tracking_error_rad.worst


def test_the_estimates_peak_is_the_largest_estimated_force(separate) -> None:
    for result in separate.values():
        est = result.signals["cuff_force_est"]
        peak = np.sqrt(est[..., 0] ** 2 + est[..., 1] ** 2).max(axis=0)
        summary = result.summary()["peak_cuff_force_est_N"]
        assert list(summary) == list(CUFF_NAMES)
        np.testing.assert_allclose(list(summary.values()), peak, rtol=1e-15, atol=0)
        assert min(summary.values()) > 10.0  # the cuffs carry the legs


def test_peak_force_magnitudes() -> None:
    from exo_ctrl.sim.summary import peak_force_magnitudes

    force = np.array([[[3.0, -4.0], [0.0, 1.0]], [[-1.0, 1.0], [6.0, -8.0]]])
    assert peak_force_magnitudes(force).tolist() == [5.0, 10.0]
    assert peak_force_magnitudes(np.zeros((0, 4, 2))).tolist() == [0.0] * 4


def test_the_kept_cycle_is_the_histories_last_full_cycle(table, separate) -> None:
    assert cycle_ticks(dataclasses.replace(BASE, duration_s=1.5)) == (300, 1500)
    for c in CONTROLLERS:
        kept, s = table[c].cycle, separate[c].signals
        assert kept.complete and kept.t0_s == 0.3 and kept.t.shape == (1200,)
        assert np.array_equal(kept.q, s["q"][300:1500])
        assert np.array_equal(kept.q_des, s["q_des"][300:1500])
        assert np.array_equal(kept.drive_torque, s["drive_torque"][300:1500])
        f = s["cuff_force"][300:1500]
        assert np.array_equal(kept.cuff_force, np.hypot(f[..., 0], f[..., 1]))
        other = trace_from_history(separate[c].config, s)
        assert np.array_equal(other.cuff_force_est, kept.cuff_force_est)


@pytest.mark.parametrize(
    ("changes", "expected"),
    [
        ({"duration_s": 3.6}, (2400, 3600)),  # the default: ramp-in 1.2 s and 2 cycles
        ({"duration_s": 3.6, "ramp_out_s": 0.6}, (1200, 2400)),  # 1 whole cycle before it
        ({"duration_s": 1.0}, (0, 1000)),  # shorter than the ramp-in: what there is
        ({"duration_s": 4.0, "ramp_in_s": 0.0}, (2400, 3600)),
    ],
)
def test_cycle_ticks(changes: dict, expected: tuple[int, int]) -> None:
    assert cycle_ticks(SimConfig(**changes)) == expected


def test_a_run_that_stops_early_keeps_its_last_period() -> None:
    from exo_ctrl.comparison import CycleKeeper

    class Run:
        config = SimConfig(duration_s=3.6)  # cycle drawn: ticks 2400-3600

    keeper = CycleKeeper()
    keeper.start(Run())
    for start in range(0, 3100, 700):  # stops at tick 3100, ticks numbered in every signal
        n = min(700, 3100 - start)
        k = np.arange(start, start + n, dtype=float)
        rows = {
            "q": np.repeat(k[:, None], 4, axis=1),
            "q_des": np.repeat(-k[:, None], 4, axis=1),
            "drive_torque": np.zeros((n, 4)),
            "cuff_force": np.zeros((n, 4, 2)),
            "cuff_force_est": np.zeros((n, 4, 2)),
        }
        keeper.chunk(Run(), start, rows)
    trace = keeper.trace()
    assert not trace.complete and trace.t0_s == pytest.approx(1.9)
    assert trace.q[:, 0].tolist() == list(range(1900, 3100))
    assert trace.q_des[:, 3].tolist() == [-x for x in range(1900, 3100)]


def test_the_files_hold_the_figures_exactly(table, tmp_path: Path) -> None:
    table.to_csv(tmp_path / "c.csv")
    table.to_json(tmp_path / "c.json")
    with open(tmp_path / "c.csv", newline="") as f:
        lines = list(csv.DictReader(f))
    assert [line["label"] for line in lines] == list(CONTROLLERS)
    data = json.loads((tmp_path / "c.json").read_text())
    for line, run in zip(lines, data["runs"], strict=True):
        row = table[line["label"]]
        for j in JOINT_NAMES:
            value = row.summary["rms_tracking_error_rad"][j]
            assert float(line[f"rms_tracking_error_rad.{j}"]) == value
            assert run["rms_tracking_error_rad"][j] == value
            energy = row.summary["energy_J"][j]["electrical"]
            assert float(line[f"electrical_energy_J.{j}"]) == energy
        assert line["slip_speed_rms_mps"] == "" and run["slip_speed_rms_mps"] is None
        assert int(line["safety_event_count"]) == len(row.summary["safety_events"])
        assert float(line["real_time_factor"]) == row.summary["real_time_factor"]
    assert data["figures"]["peak_drive_torque_Nm"] == {"title": "peak drive torque", "unit": "N·m"}
    assert data["config_differences"] == {"controller": list(CONTROLLERS)}


def test_the_markdown_table(table) -> None:
    lines = table.markdown().splitlines()
    assert lines[0] == "| figure | unit | pd | ct | qp |"
    knee = next(line for line in lines if line.startswith("| RMS tracking error, left knee |"))
    cells = [c.strip() for c in knee.strip("|").split("|")]
    rms = [table[c].summary["rms_tracking_error_rad"]["left_knee"] for c in CONTROLLERS]
    assert cells == ["RMS tracking error, left knee", "rad", *(f"{x:.4g}" for x in rms)]
    assert not any("slip" in line for line in lines)  # no run had the belt


def test_the_figure_overlays_the_runs(table, tmp_path: Path) -> None:
    fig = cycle_figure(table)
    axes = fig.axes
    assert len(axes) == 12
    for i, ax in enumerate(axes):
        gids = [line.get_gid() for line in ax.get_lines()]
        assert [g for g in gids if g.startswith("run:")] == [f"run:{c}" for c in CONTROLLERS]
        assert gids.count("plan") == (1 if i < 4 else 0)  # the runs share the plan
        assert "[" in ax.get_ylabel() and ax.get_title()
        run = next(line for line in ax.get_lines() if line.get_gid() == "run:ct")
        assert np.array_equal(run.get_xdata(), table["ct"].cycle.t)
    assert all("[s]" in ax.get_xlabel() for ax in axes[8:])
    torque = next(line for line in axes[5].get_lines() if line.get_gid() == "run:qp")
    assert np.array_equal(torque.get_ydata(), table["qp"].cycle.drive_torque[:, 1])
    assert [t.get_text() for t in fig.legends[0].get_texts()][:4] == ["plan", "pd", "ct", "qp"]
    path = write_compare_png(table, tmp_path / "compare.png")
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    assert struct.unpack(">II", data[16:24]) == (1600, 1000)


def test_a_scenario_file_is_compared_as_its_config(tmp_path) -> None:
    """A scenario file's path, its Scenario and its SimConfig give the same runs."""
    path = tmp_path / "s.toml"
    path.write_text(preset_text("paper-free-air"))
    scenario = exo_ctrl.load_scenario(path)
    assert scenario.config == SimConfig()
    tables = [
        exo_ctrl.compare(s, ("pd",), duration_s=0.1) for s in (str(path), scenario, SimConfig())
    ]
    figures = [{k: v for k, v in t.rows[0].summary.items() if k not in CLOCK} for t in tables]
    assert figures[0] == figures[1] == figures[2]


def test_bad_input_is_refused_by_name() -> None:
    with pytest.raises(InvalidParameter, match=r"^controllers must be one or more of pd, ct, qp"):
        exo_ctrl.compare(BASE, controllers=("pd", "pd"))
    with pytest.raises(InvalidParameter, match=r"'lqr' is not one"):
        exo_ctrl.compare(BASE, controllers="pd,lqr")
    with pytest.raises(InvalidScenario, match=r"^scenario paper.toml: no such file$"):
        exo_ctrl.compare("paper.toml", controllers=("pd",))
    with pytest.raises(InvalidParameter, match=r"^scenario must be a SimConfig, a Scenario or a "):
        exo_ctrl.compare(1.0, controllers=("pd",))
    with pytest.raises(InvalidParameter, match=r"^cycles must be not given with duration"):
        exo_ctrl.compare(BASE, controllers=("pd",), cycles=1, duration_s=1.0)
    with pytest.raises(InvalidParameter, match=r"^cycles must be > 0"):
        exo_ctrl.compare(BASE, controllers=("pd",), cycles=0)


def test_the_row_label_must_exist(table) -> None:
    with pytest.raises(InvalidParameter, match=r"^label must be one of \['pd', 'ct', 'qp'\]"):
        table["lqr"]


def test_two_tunings_of_one_controller_are_compared_by_their_labels() -> None:
    """A mapping labels its rows; each row is the run of its own gains, the stiffer the closer."""
    config = dataclasses.replace(BASE, duration_s=0.8)
    tunings = {"soft": PD(kp=150.0), "stiff": PD(kp=600.0)}
    table = exo_ctrl.compare(config, controllers=tunings)
    assert table.labels == ["soft", "stiff"]
    for label, controller in tunings.items():
        alone = simulate(dataclasses.replace(config, controller=controller)).summary()
        assert without_clock(table[label].summary) == without_clock(alone)
        assert table[label].controller == "pd"
    assert set(table.differences) == {"gains.kp.0", "gains.kp.1", "gains.kp.2", "gains.kp.3"}
    soft, stiff = (table[k].figures["rms_tracking_error_rad"] for k in tunings)
    # PD's steady error under one load goes as 1/k_p: four times the gain, a smaller error.
    assert all(stiff[j] < soft[j] for j in JOINT_NAMES)


def test_one_controller_twice_or_a_bad_label_is_refused() -> None:
    with pytest.raises(InvalidParameter, match=r"^controllers must be one or more of pd, ct, qp"):
        exo_ctrl.compare(BASE, controllers=(PD(kp=200.0), "pd"))
    with pytest.raises(
        InvalidParameter,
        match=r"mapping of labels \(non-empty text\) to controllers; got \{3: 'pd'\} \(label 3\)$",
    ):
        exo_ctrl.compare(BASE, controllers={3: "pd"})
    with pytest.raises(InvalidParameter, match=r"to controllers; got \{' ': 'pd'\} \(label ' '\)$"):
        exo_ctrl.compare(BASE, controllers={" ": "pd"})
    with pytest.raises(InvalidParameter, match=r"'lqr' is not one"):
        exo_ctrl.compare(BASE, controllers={"mine": "lqr"})
    other = {"a": "pd", "b": PD(kp=200.0)}
    with pytest.raises(InvalidParameter, match=r"they differ in 1 key: gait.period"):
        exo_ctrl.comparison.check_same(
            {"gains.kp.0": [300.0, 200.0], "gait.period": [1.2, 1.0]}, list(other), False
        )
