"""The examples a user copies (examples/*.py) run, shortened, and do what they say."""

from __future__ import annotations

import importlib
import runpy
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def load(name: str, monkeypatch: pytest.MonkeyPatch) -> dict:
    """The example's namespace, run as a module (not as __main__: nothing runs on import)."""
    monkeypatch.setattr(sys, "path", list(sys.path))  # compare_mine adds its directory
    return runpy.run_path(str(EXAMPLES / f"{name}.py"), run_name=f"example_{name}")


def test_every_example_is_run_here() -> None:
    assert sorted(p.stem for p in EXAMPLES.glob("*.py")) == [
        "compare_mine",
        "impedance",
        "numba_pd",
    ]


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


def test_numba_pd_is_the_built_in_pd(monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    # Imported as the module examples.numba_pd, as bench.py and a --controller path import it.
    monkeypatch.syspath_prepend(str(EXAMPLES.parent))
    example = vars(importlib.import_module("examples.numba_pd"))
    assert example["main"](duration_s=0.6) <= 1e-9  # [rad], the whole run
    assert example["pd_law"].signatures  # compiled, and called through the compiled code
    out = capsys.readouterr().out
    assert out.startswith("examples.numba_pd:NumbaPD completed largest difference ")
    # the numpy twin is the same law
    kp, kd = np.array([300.0, 280.0, 310.0, 290.0]), np.array([5.0, 4.0, 6.0, 3.0])
    plan, sensors = example["PlanRow"](), SimpleNamespace()
    plan.q[:], plan.dq[:] = [0.1, 0.2, -0.1, 0.3], [1.0, -1.0, 0.5, 0.0]
    sensors.q, sensors.dq = np.array([0.0, 0.25, -0.2, 0.3]), np.array([0.5, -1.5, 0.0, 1.0])
    numba_pd, numpy_pd = example["NumbaPD"](), example["NumpyPD"]()
    for c in (numba_pd, numpy_pd):
        c.kp, c.kd = kp, kd
    expected = kp * (plan.q - sensors.q) + kd * (plan.dq - sensors.dq)
    np.testing.assert_allclose(numba_pd.command(0.0, plan, sensors, None), expected, rtol=1e-15)
    np.testing.assert_allclose(numpy_pd.command(0.0, plan, sensors, None), expected, rtol=1e-15)
