"""A sweep runs a user's controller: by its ``module:Class`` path beside the built-in ones,
and as its base's object."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from exo_ctrl.control import Controller, PDGains
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.sim import SimConfig
from exo_ctrl.sweep import SweepSpec, run_sweep

SOURCE = """
from exo_ctrl.control import Controller


class PlainPD(Controller):
    def command(self, t_s, plan, sensors, cuff_force_est_N):
        return 300.0 * (plan.q - sensors.q) + 5.0 * (plan.dq - sensors.dq)
"""


class ObjectPD(Controller):
    """The default PD gains as an object's parameters [V/rad], [V·s/rad]."""

    def __init__(self, gains: PDGains) -> None:
        self.kp, self.kd = np.array(gains.kp), np.array(gains.kd)
        self.setups = 0

    def setup(self, device) -> None:
        self.setups += 1

    def command(self, t_s, plan, sensors, cuff_force_est_N):
        return self.kp * (plan.q - sensors.q) + self.kd * (plan.dq - sensors.dq)


@pytest.fixture
def module(user_module) -> str:
    return user_module("sweep_ctl", SOURCE)


def test_a_path_is_swept_beside_the_built_in_pd(tmp_path: Path, module: str) -> None:
    mine = f"{module}:PlainPD"
    spec = SweepSpec.parse(["step_length=0.3,0.35", f"controller=pd,{mine}"], duration_s=0.4)
    rows = run_sweep(spec, tmp_path / "s.parquet", workers=1, progress=False).to_pylist()
    assert [(r["step_length"], r["controller"]) for r in rows] == [
        (0.3, "pd"),
        (0.3, mine),
        (0.35, "pd"),
        (0.35, mine),
    ]
    assert all(r["status"] == "completed" for r in rows)
    for pd, user in ((rows[0], rows[1]), (rows[2], rows[3])):  # the same law, the same loads
        assert user["peak_drive_torque_Nm_left_hip"] == pytest.approx(
            pd["peak_drive_torque_Nm_left_hip"], abs=1e-9
        )
    assert list(tmp_path.glob("*step_length*.png"))  # the load diagram, a marker per controller


def test_a_base_with_a_user_object_is_swept(tmp_path: Path) -> None:
    mine = ObjectPD(PDGains())
    spec = SweepSpec.parse(["step_length=0.3"], duration_s=0.4, base=SimConfig(controller=mine))
    assert spec.describe()["base"]["controller"] == f"{__name__}:ObjectPD"  # plain data
    rows = run_sweep(spec, tmp_path / "o.parquet", workers=1, progress=False).to_pylist()
    assert rows[0]["status"] == "completed"
    assert mine.setups == 1  # the object itself ran (one worker: in this process)


def test_a_bad_controller_is_refused_by_the_sweep() -> None:
    with pytest.raises(InvalidParameter) as info:
        SweepSpec.parse(["controller=pd,lqr"])
    assert str(info.value) == "controller must be one of pd, ct, qp; got 'lqr'"
