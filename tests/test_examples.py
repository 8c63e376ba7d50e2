"""The examples a user copies (examples/*.py) run, shortened, and do what they say."""

from __future__ import annotations

import runpy
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def load(name: str, monkeypatch: pytest.MonkeyPatch) -> dict:
    """The example's namespace, run as a module (not as __main__: nothing runs on import)."""
    monkeypatch.setattr(sys, "path", list(sys.path))  # compare_mine adds its directory
    return runpy.run_path(str(EXAMPLES / f"{name}.py"), run_name=f"example_{name}")


def test_every_example_is_run_here() -> None:
    assert sorted(p.stem for p in EXAMPLES.glob("*.py")) == ["compare_mine", "impedance"]


def test_impedance_walks_on_torque_commands(monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    example = load("impedance", monkeypatch)
    assert example["Impedance"].command_kind == "torque"
    summary = example["main"](duration_s=1.5)
    assert summary["status"] == "completed"
    assert summary["controller"] == "example_impedance:Impedance"
    assert max(summary["rms_tracking_error_rad"].values()) < 0.05  # [rad]
    assert capsys.readouterr().out.startswith("example_impedance:Impedance completed ")


def test_compare_mine_tabulates_pd_ct_and_impedance(monkeypatch: pytest.MonkeyPatch) -> None:
    table = load("compare_mine", monkeypatch)["main"](duration_s=1.5)
    assert [row.label for row in table.rows] == ["pd", "ct", "impedance:Impedance"]
    assert all(row.status == "completed" for row in table.rows)
    # computed torque's feedforward tracks best of the three
    worst = {row.label: max(row.figures["rms_tracking_error_rad"].values()) for row in table.rows}
    assert worst["ct"] < worst["pd"] and worst["ct"] < worst["impedance:Impedance"]
