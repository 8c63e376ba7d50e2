"""`simulate --pelvis supported`: its gait defaults, the options reaching SimConfig."""

from __future__ import annotations

import pytest

from exo_ctrl import cli
from exo_ctrl.cli.long_options import SUPPORTED_GAIT
from exo_ctrl.cli.simulate import sim_config
from exo_ctrl.plan import GaitParams
from exo_ctrl.plan.kinematics import inverse_kinematics
from exo_ctrl.scenario import load_scenario


def _config(*args: str):
    return sim_config(cli.build_parser().parse_args(["simulate", *args]))


def test_the_supported_pelvis_walks_the_extended_gait_by_default() -> None:
    config = _config("--contact", "on", "--pelvis", "supported", "--bws", "0.5")
    assert config.pelvis.supported and config.pelvis.bws_fraction == 0.5
    assert config.gait.hip_height == SUPPORTED_GAIT["hip_height"] == 1.0
    assert config.gait.pelvis_excursion == SUPPORTED_GAIT["pelvis_excursion"] == 0.025
    assert config.gait.duty_factor == SUPPORTED_GAIT["duty_factor"] == 0.6  # a double support
    assert config.gait.period == SUPPORTED_GAIT["period"] == 1.6  # within the drives' torque
    # The preset's gait: the command line's supported pelvis walks the clinic-bws gait.
    clinic = load_scenario(preset="clinic-bws").config.gait
    assert all(getattr(clinic, name) == value for name, value in SUPPORTED_GAIT.items())
    # The knee at mid-stance: the leg H_s + e/2 long, straight below the hip.
    l1 = l2 = 0.52
    phi1, phi2 = inverse_kinematics(0.0, -(1.0 + 0.0125), l1, l2)
    assert 0.0 < float(phi1 - phi2) < 0.5  # about 26° of flexion, not the 60° crouch


def test_given_values_and_the_fixed_pelvis_keep_their_own() -> None:
    given = _config(
        "--contact", "on", "--pelvis", "supported", "--hip-height", "0.95",
        "--pelvis-excursion", "0.02", "--duty-factor", "0.5",
    )  # fmt: skip
    assert (given.gait.hip_height, given.gait.pelvis_excursion) == (0.95, 0.02)
    assert given.gait.duty_factor == 0.5
    fixed = _config()
    assert fixed.gait == GaitParams()


def test_bws_without_the_supported_pelvis_exits_2(capsys: pytest.CaptureFixture) -> None:
    code = cli.main(["simulate", "--contact", "on", "--bws", "0.3", "--no-record"])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert code == 2
    assert err == (
        "exo-ctrl simulate: error: scenario preset paper-free-air: bws must be 0 with the pelvis "
        "fixed (--pelvis supported); "
        "got 0.3"
    )
