"""A plan the device cannot follow is bad input, refused when the run is built.

The planned joint speeds are checked against the URDFs' speed limits and the
drive's no-load speed at the supply, U_max / (i_G / k_E) (exo_ctrl.sim.setup).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from exo_ctrl import cli
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import BodyParams, load_exo, write_urdf
from exo_ctrl.plan import GaitParams, GaitPlan, plan_joints
from exo_ctrl.plant import MotorParams
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.setup import build, drive_for

TAIL = "a longer period or a shorter step slows it)"

#: The messages below name the first peak of a run started on the gait at speed
#: (a ramp-in moves it one period later: tests/sim/test_start.py checks the ramp's).
AT_SPEED = {"ramp_in_s": 0.0}

#: A 48 V supply: no-load speed 10.4 rad/s, so the URDF's 6 rad/s is the limit that binds.
HIGH_SUPPLY = MotorParams(supply_voltage_V=48.0)


def message(joint: str, speed: str, limit: str, t: str, period: str = "1.2") -> str:
    return (
        f"planned {joint} speed must be at most {limit}; got {speed} (rad/s, at t = {t} s of a "
        f"gait with period {period} s and step_length 0.35 m: {TAIL}"
    )


def test_default_scenario_is_well_within_every_limit() -> None:
    exo = load_exo(None)
    motor = drive_for(MotorParams(), exo)
    gait = GaitParams()
    t = np.linspace(0.0, gait.period, 1201)
    peak = np.abs(plan_joints(GaitPlan(gait), exo, t).dq).max(axis=0)
    # 2.15 rad/s at the knees: 36 % of the URDF's 6 rad/s, and the back-EMF
    # at that speed (4.63 V·s/rad × 2.15 rad/s = 10.0 V) is 42 % of the supply.
    assert np.all(peak < 0.4 * exo.velocity_limit)
    assert np.all(motor.back_emf_V_per_rad_s * peak < 0.45 * motor.supply_voltage_V)
    build(SimConfig())  # and nothing is refused


def test_a_tenth_of_a_second_period_is_refused_not_diverged(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """Before the check, ``--period 0.01`` ran and "diverged" (exit 1).

    0.1 s is the shortest period a gait may have (GaitParams); the joint speeds
    it asks for are refused by name.
    """
    expected = message("left_knee", "25.8", "6 rad/s, the exoskeleton URDF's speed limit",
                       "0.0869", "0.1")  # fmt: skip
    back_emf = "5.18 rad/s, where the drive's back-EMF i_G ω / k_E (4.633 V·s/rad × ω) takes "
    drive = message("left_knee", "25.8", back_emf + "the whole 24 V supply", "0.0869", "0.1")
    with pytest.raises(InvalidParameter) as info:
        simulate(SimConfig(gait=GaitParams(period=0.1), motor=HIGH_SUPPLY, **AT_SPEED))
    assert str(info.value) == expected
    out, summary = tmp_path / "run.rrd", tmp_path / "s.json"
    argv = ["simulate", "--period", "0.1", "--ramp-in", "0", "--out", str(out)]
    argv += ["--summary", str(summary)]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err == f"exo-ctrl simulate: error: {drive}\n"  # the default drive's 24 V binds first
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_the_check_does_not_depend_on_the_control_rate() -> None:
    """The plan is sampled 1000 times a period at least: 0.4 s peaks at 6.449 rad/s at any rate."""
    expected = message("left_knee", "6.449", "6 rad/s, the exoskeleton URDF's speed limit",
                       "0.3476", "0.4")  # fmt: skip
    for rate in (10.0, 100.0, 1000.0):
        with pytest.raises(InvalidParameter) as info:
            build(
                SimConfig(
                    gait=GaitParams(period=0.4), control_rate_hz=rate, motor=HIGH_SUPPLY, **AT_SPEED
                )
            )
        assert str(info.value) == expected, rate


def test_a_limit_just_above_the_peak_is_accepted(tmp_path: Path) -> None:
    path = write_urdf(BodyParams.exo_default(velocity_limit=6.5), tmp_path / "exo.urdf")
    build(SimConfig(gait=GaitParams(period=0.4), exo=str(path), motor=HIGH_SUPPLY))


def test_the_patient_urdf_limit_counts(tmp_path: Path) -> None:
    path = write_urdf(BodyParams.patient_default(velocity_limit=1.5), tmp_path / "patient.urdf")
    with pytest.raises(InvalidParameter) as info:
        build(SimConfig(patient=str(path), **AT_SPEED))
    assert str(info.value) == message(
        "right_knee", "2.15", "1.5 rad/s, the patient URDF's speed limit", "0.757"
    )


def test_a_supply_the_back_emf_alone_exceeds_is_refused(capsys: pytest.CaptureFixture) -> None:
    """3 V supply: the no-load speed is 3 V / 4.633 V·s/rad = 0.6475 rad/s < 2.15 rad/s."""
    motor = MotorParams(supply_voltage_V=3.0)
    limit = 3.0 / motor.back_emf_V_per_rad_s
    assert f"{limit:.4g}" == "0.6475"
    with pytest.raises(InvalidParameter) as info:
        build(SimConfig(motor=motor, **AT_SPEED))
    assert str(info.value) == message(
        "right_knee",
        "2.15",
        "0.6475 rad/s, where the drive's back-EMF i_G ω / k_E (4.633 V·s/rad × ω) "
        "takes the whole 3 V supply",
        "0.757",
    )
    # 12 V: 2.59 rad/s of no-load speed, above the plan's 2.15 rad/s: accepted.
    build(SimConfig(motor=MotorParams(supply_voltage_V=12.0)))
