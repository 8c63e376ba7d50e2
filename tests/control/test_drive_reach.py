"""The plan's torque against the drives' reach, said before the run (control/drive_reach.py).

References: the drive's peak torque i_G k_m I_max from its datasheet values
(capped at the exoskeleton URDF's effort limit), the feedforward table the
run's controller tracks, and the same gait precomputed for a synchronised run.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from exo_ctrl.control import ComputedTorqueController
from exo_ctrl.control.drive_reach import torque_reach_warning
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import JOINT_NAMES
from exo_ctrl.scenario import load_scenario
from exo_ctrl.sim import SimConfig, build


def _sentence(cap: float, over: str) -> str:
    return (
        f"the plan needs more torque than the drives' {cap:.0f} N·m at {over} (computed "
        "torque's feedforward on the device's models): the drives saturate there and the legs "
        "fall behind the plan, which makes touchdowns under body-weight support harder; a "
        "stronger drive, more support or a gentler gait lowers it (docs/performance.md, "
        "touchdowns under load)"
    )


def test_the_joints_beyond_the_peak_torque_are_named_with_their_largest_demand() -> None:
    table = np.array([[10.0, -151.0, 0.0, 20.0], [-160.5, 30.0, 149.9, -150.0]])
    assert torque_reach_warning(table, 150.0) == _sentence(
        150.0, "left_hip (up to 160 N·m), left_knee (up to 151 N·m)"
    )
    assert torque_reach_warning(table, 161.0) is None  # at most the cap: nothing said
    assert torque_reach_warning(np.zeros((0, 4)), 1.0) is None


@pytest.mark.parametrize(
    ("table", "cap", "message"),
    [
        (np.zeros((3, 2)), 150.0, "torque_ff shape must be (rows, 4): one column per joint"),
        (np.full((1, 4), np.nan), 150.0, "torque_ff must be finite torques [N·m]; got 'a non"),
        (np.zeros((1, 4)), 0.0, "peak_torque must be"),
    ],
)
def test_a_table_or_a_torque_it_cannot_read_is_refused(table, cap, message) -> None:
    with pytest.raises(InvalidParameter) as caught:
        torque_reach_warning(table, cap)
    assert str(caught.value).startswith(message)


def _reach(warnings: tuple[str, ...]) -> list[str]:
    return [w for w in warnings if w.startswith("the plan needs more torque")]


def test_the_supported_gait_is_warned_from_its_table_and_the_fixed_default_not() -> None:
    """The 1.2 s clinic gait at 30 % support passes the drives (swing hip, stance knee)."""
    faster = ["gait.period=1.2", "gait.pelvis_excursion=0.05", "run.duration_s=3.6"]
    overrides = ["pelvis.bws_fraction=0.3", "treadmill.sync=false", *faster]
    config = load_scenario(preset="clinic-bws", overrides=overrides).config
    setup = build(config)
    assert isinstance(setup.controller, ComputedTorqueController)
    motor = setup.device_motor
    urdf_cap = float(np.min(setup.device_exo.effort_limit))
    cap = min(motor.gear_ratio * motor.torque_constant_Nm_per_A * 32.0, urdf_cap)
    assert motor.peak_torque_Nm == pytest.approx(cap, rel=1e-12)
    peaks = np.abs(setup.controller.torque_ff_table).max(axis=0)
    assert (peaks > cap).all()  # every joint: the hips in swing, the knees in stance
    named = ", ".join(
        f"{name} (up to {p:.0f} N·m)" for name, p in zip(JOINT_NAMES, peaks, strict=True)
    )
    assert _reach(setup.warnings) == [_sentence(cap, named)]
    # The synchronised run (one plan row a tick) is checked on the same gait precomputed.
    synced = build(dataclasses.replace(config, sync=True))
    assert synced.plan.q.shape[0] == 1
    assert _reach(synced.warnings) == [_sentence(cap, named)]
    # The preset's own gait (1.6 s) stays within the drives, as does the default QP with the
    # pelvis fixed; PD feeds nothing forward.
    preset = build(load_scenario(preset="clinic-bws", overrides=["treadmill.sync=false"]).config)
    assert np.abs(preset.controller.torque_ff_table).max() < cap
    assert _reach(preset.warnings) == []
    fixed = build(SimConfig(controller="qp"))
    assert np.abs(fixed.controller.torque_ff_table).max() < cap
    assert _reach(fixed.warnings) == []
    assert _reach(build(dataclasses.replace(config, controller="pd")).warnings) == []
