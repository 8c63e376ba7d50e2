"""A user's controller named in a scenario file, and compared from the command line."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from exo_ctrl import cli, load_scenario, simulate

SOURCE = """
from exo_ctrl.control import Controller


class PlainPD(Controller):
    def command(self, t_s, plan, sensors, cuff_force_est_N):
        return 300.0 * (plan.q - sensors.q) + 5.0 * (plan.dq - sensors.dq)
"""


@pytest.fixture
def module(user_module, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    monkeypatch.chdir(tmp_path)
    return user_module("scenario_ctl", SOURCE)


def test_a_scenario_file_names_the_class(tmp_path: Path, module: str) -> None:
    path = tmp_path / "mine.toml"
    path.write_text(f'[run]\ncontroller = "{module}:PlainPD"\nduration_s = 0.3\n')
    config = load_scenario(path).config
    assert config.controller == f"{module}:PlainPD"
    mine = simulate(config).summary()
    assert mine["controller"] == f"{module}:PlainPD" and mine["status"] == "completed"
    builtin = simulate(load_scenario(path, overrides=["run.controller=pd"]).config).summary()
    assert mine["rms_tracking_error_rad"] == pytest.approx(builtin["rms_tracking_error_rad"])


def test_compare_on_the_command_line(tmp_path: Path, module: str, capsys) -> None:
    mine = f"{module}:PlainPD"
    argv = ["compare", "--controllers", f"pd,{mine}", "--duration", "0.3", "--out", "cmp"]
    assert cli.main(argv) == 0
    with open(tmp_path / "cmp" / "compare.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [(r["label"], r["controller"], r["status"]) for r in rows] == [
        ("pd", "pd", "completed"),
        (mine, mine, "completed"),
    ]
    assert "Traceback" not in capsys.readouterr().err
