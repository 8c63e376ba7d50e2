"""Scenario files: the TOML form of SimConfig, the presets, overrides and their errors."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import tomllib

from exo_ctrl import SimConfig
from exo_ctrl.exceptions import InvalidParameter, InvalidScenario
from exo_ctrl.model import load_exo, write_urdf
from exo_ctrl.model.body_params import BodyParams
from exo_ctrl.plan import GaitParams
from exo_ctrl.plan.exercise import CALIBRATION_DURATION_S
from exo_ctrl.plant import ContactParams, CuffParams
from exo_ctrl.scenario import (
    PRESETS,
    RecordingParams,
    Scenario,
    load_scenario,
    preset,
    preset_description,
    scenario_template,
)
from exo_ctrl.sim.belief import Belief
from exo_ctrl.sim.faults import Fault
from exo_ctrl.sim.scenario_file import GROUPS, ORDER, scenario_toml
from exo_ctrl.sim.scenario_read import config_from_document, parse_scenario
from exo_ctrl.sim.session import Segment, SessionParams


def _sections_of_config() -> set[str]:
    groups = {name for _, _, names in GROUPS for name in names}
    return {f.name for f in dataclasses.fields(SimConfig)} - groups


def test_every_simconfig_field_is_in_exactly_one_section() -> None:
    grouped = [name for _, _, names in GROUPS for name in names]
    assert len(grouped) == len(set(grouped))
    fields = {f.name for f in dataclasses.fields(SimConfig)}
    assert set(grouped) <= fields
    sections = {group for group, _, _ in GROUPS} | _sections_of_config()
    assert sections == set(ORDER)


#: A configuration away from the defaults in every kind of value: nested
#: tables, an optional table set, a tuple of tables, a session, a text profile.
ODD = SimConfig(
    gait=GaitParams(step_length=0.3, period=1.1),
    controller="ct",
    cuffs=CuffParams(stiffness_N_per_m=7000.0),
    contact=ContactParams(enabled=True, friction_coeff=0.6),
    belief=Belief(patient_height_m=1.8, patient_mass_kg=75.5, cuffs=CuffParams()),
    faults=(Fault("torque_drift", 1.0, "left_knee", 2.0),),
    duration_s=1.0 / 3.0 + 2.0,
    ramp_in_s=0.7,
    speed_profile="0:0.5,1:0.6",
)


@pytest.mark.parametrize("comments", [True, False])
@pytest.mark.parametrize("config", [SimConfig(), ODD], ids=["defaults", "odd"])
def test_a_written_scenario_reads_back_to_the_same_config(config, comments) -> None:
    text = scenario_toml(config, comments=comments)
    back, extra = config_from_document(parse_scenario(text, "x.toml"), "x.toml")
    assert back == config and extra == {}
    assert back.duration_s == config.duration_s  # a float written by repr: exact


def test_a_session_round_trips() -> None:
    session = SessionParams(
        (Segment(1.0, "tracking", 0.5), Segment(1.5, "guidance", 0.6, (("guidance", 0.5),)))
    )
    config = SimConfig(
        session=session, duration_s=2.5, contact=ContactParams(enabled=True), controller="ct"
    )
    text = scenario_toml(config)
    back, _ = config_from_document(parse_scenario(text, "s.toml"), "s.toml")
    assert back == config


def test_the_template_shows_every_key_with_its_doc() -> None:
    text = scenario_template("paper")
    doc = tomllib.loads(text)
    assert doc["contact"]["enabled"] is True
    assert doc["gait"]["hip_height"] == "auto" and doc["gait"]["step_length"] == "auto"
    assert doc["recording"] == dataclasses.asdict(RecordingParams())
    # every field of every part is a key, or an unset key's comment line
    for section in _sections_of_config() - {"faults", "session", "speed_profile"}:
        cls = type(getattr(SimConfig(), section))
        for f in dataclasses.fields(cls):
            assert (
                f.name in doc[section]
                or f"# {f.name} =   (unset)" in text
                or (f"[{section}.{f.name}]" in text)
            ), (section, f.name)
    # comments come from the docstrings, without their markup
    assert "# s, distance the foot travels on the belt per stance [m]." in text
    assert ":mod:" not in text and "``" not in text


def test_presets_are_listed_described_and_load() -> None:
    assert PRESETS[0] == "paper"
    for name in PRESETS:
        assert preset_description(name)
        assert isinstance(preset(name), Scenario)
    assert preset("paper-free-air").config == SimConfig()
    assert preset("paper").config == SimConfig(
        contact=ContactParams(enabled=True), cuff_force_limit_N=(200.0, 120.0)
    )
    bws = preset("clinic-bws").config
    assert (bws.pelvis.supported, bws.pelvis.bws_fraction, bws.gait.pelvis_excursion) == (
        True,
        0.4,
        0.025,
    )
    assert (bws.gait.period, bws.duration_s) == (1.6, 4.8)  # the ramp-in and two cycles
    assert bws.cuff_force_limit_N == (200.0, 120.0)  # the QP's, leaving the plan's load
    spastic = preset("clinic-spastic").config
    assert (spastic.gait.period, spastic.duration_s) == (2.0, 6.0)  # the ramp-in and two cycles
    assert (spastic.patient_torque, spastic.controller) == ("spastic", "ct")
    assert spastic.pelvis.supported and spastic.cuff_force_limit_N == (200.0, 120.0)
    assert preset("spastic-qp").config.controller == "qp"
    assert preset("spastic-qp").config.patient_torque == "spastic"
    active = preset("active-transparent").config
    assert (active.mode, active.patient_torque) == ("transparent", "active")
    calibration = preset("calibration").config
    assert calibration.exercise == "calibration"
    assert calibration.duration_s == CALIBRATION_DURATION_S


def test_overrides_apply_in_order_and_default_restores() -> None:
    s = load_scenario(
        preset="paper",
        overrides=[
            "gait.period=1.1",
            "run.controller=ct",
            "contact.belt.mass_kg=25",
            "run.controller=qp",
            "contact.enabled=default",
        ],
    )
    assert s.config.gait.period == 1.1 and s.config.controller == "qp"
    assert s.config.contact.belt.mass_kg == 25.0
    assert s.config.contact.enabled is False


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "s.toml"
    path.write_text(text)
    return path


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "[gait]\nstep_lenght = 0.3\n",
            "gait.step_lenght: must be a key of GaitParams (step_length, "
            "lift_height, hip_height, shape_coeff, period, duty_factor, pelvis_excursion, "
            "landing_speed_mps, landing_depth_m); "
            "got 0.3",
        ),
        ("[gait]\nperiod = 'slow'\n", "gait.period: must be a number; got 'slow'"),
        ("[gait]\nperiod = -1.0\n", "gait.period: must be > 0 s; got -1.0"),
        ("[contact]\nenabled = 1\n", "contact.enabled: must be true or false; got 1"),
        ("[run]\ncontroller = 'lqr'\n", "run.controller: must be one of pd, ct, qp; got 'lqr'"),
        (
            "[run]\ncontroler = 'ct'\n",
            "run.controler: is not a key here; allowed: controller, exercise, duration_s, "
            "ramp_in_s, ramp_out_s, cuff_fit, control_rate_hz, plant_substeps, chunk_ticks",
        ),
        ("[treadmil]\nsync = true\n", "treadmil: is not a section; the sections: run, urdf"),
        ("[gait\n", "not a valid TOML file (Expected ']' at the end of a table declaration"),
        ("[recording]\nscene_rate_hz = 0\n", "recording.scene_rate_hz: must be > 0 Hz; got 0.0"),
        (
            "[[faults]]\nkind = 'bogus'\nat_s = 0.1\n",
            "faults[0]: fault kind must be one of encoder_freeze, encoder_dropout,",
        ),
    ],
)
def test_bad_scenarios_name_the_file_and_the_key(tmp_path: Path, text: str, message: str) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(InvalidScenario) as info:
        load_scenario(path)
    assert str(info.value).startswith(f"scenario {path}: ")
    assert message in str(info.value)


def test_a_missing_file_a_directory_and_an_unknown_preset(tmp_path: Path) -> None:
    with pytest.raises(InvalidScenario, match="no such file"):
        load_scenario(tmp_path / "none.toml")
    with pytest.raises(InvalidScenario, match="not a regular file"):
        load_scenario(tmp_path)
    with pytest.raises(InvalidParameter, match="preset must be one of paper, paper-free-air"):
        load_scenario(preset="fast")


def test_the_gait_follows_the_device_when_not_given(tmp_path: Path) -> None:
    exo = write_urdf(
        BodyParams.exo_default(thigh_length=0.45, shank_length=0.48), tmp_path / "exo.urdf"
    )
    leg = load_exo(exo).legs["left"]
    default = load_exo(None).legs["left"]
    scale = (leg.thigh_length + leg.shank_length) / (default.thigh_length + default.shank_length)
    assert scale == pytest.approx(0.93 / 1.04)
    s = load_scenario(preset="paper", overrides=[f"urdf.exo={str(exo)!r}"])
    assert s.config.gait.hip_height == pytest.approx(0.9 * scale, rel=1e-12)
    assert s.config.gait.step_length == pytest.approx(0.35 * scale, rel=1e-12)
    given = load_scenario(
        preset="paper", overrides=[f"urdf.exo={str(exo)!r}", "gait.hip_height=0.85"]
    )
    assert given.config.gait.hip_height == 0.85
    assert given.config.gait.step_length == pytest.approx(0.35 * scale, rel=1e-12)
    # the paper's device: the defaults exactly
    assert load_scenario(preset="paper").config.gait == GaitParams()
