"""simulate's long options: spellings of scenario keys, their help read from the dataclasses."""

from __future__ import annotations

import argparse
import dataclasses

import pytest

from exo_ctrl import cli
from exo_ctrl.cli.long_options import LONG_OPTIONS
from exo_ctrl.cli.simulate import sim_config
from exo_ctrl.plant import CuffParams, MotorParams
from exo_ctrl.scenario import preset
from exo_ctrl.sim import SimConfig
from exo_ctrl.sim.scenario_file import GROUPS, field_docs, plain_text


def _parse(*argv: str) -> argparse.Namespace:
    return cli.build_parser().parse_args(["simulate", *argv])


def _config(*argv: str) -> SimConfig:
    return sim_config(_parse(*argv))


def _hidden_help() -> dict[str, str]:
    parser = cli.build_parser()
    (sub,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {
        a.option_strings[0]: " ".join(a.hidden_help.split())
        for a in sub.choices["simulate"]._actions
        if hasattr(a, "hidden_help")
    }


def _attribute(key: str) -> tuple[object, str]:
    """The object holding scenario key ``key`` in SimConfig() and the field's name."""
    parts = key.split(".")
    if parts[0] in {group for group, _, _ in GROUPS}:
        parts = parts[1:]
    owner: object = SimConfig()
    for part in parts[:-1]:
        owner = getattr(owner, part)
    return owner, parts[-1]


def test_every_long_option_is_listed_and_hidden() -> None:
    hidden = _hidden_help()
    assert list(hidden) == [opt.option for opt in LONG_OPTIONS]


@pytest.mark.parametrize("opt", [o for o in LONG_OPTIONS if o.form == "value"], ids=str)
def test_a_value_option_states_its_field_and_default(opt) -> None:
    """The help is the field's docstring entry, its key, and SimConfig()'s value of it."""
    owner, name = _attribute(opt.key)
    text = _hidden_help()[opt.option]
    doc = " ".join(plain_text(field_docs(type(owner))[name]).split()).rstrip(".")
    value = getattr(owner, name)
    shown = "none" if value is None else f"{value:g}" if isinstance(value, float) else str(value)
    assert text == f"{doc} (scenario key {opt.key}) (default {shown})"


def test_the_help_of_the_gains_follows_the_dataclass() -> None:
    text = _hidden_help()["--kd"]
    assert text.startswith("derivative gain per joint [V·s/rad]; one number for every joint")
    assert text.endswith(f"(scenario key gains.kd) (default {SimConfig().gains.kd[0]:g})")


@pytest.mark.parametrize(
    ("argv", "setting"),
    [
        (["--period", "1.1"], "gait.period=1.1"),
        (["--rate", "500"], "run.control_rate_hz=500.0"),
        (["--contact", "off"], "contact.enabled=false"),
        (["--pelvis", "supported", "--bws", "0.3"], None),
        (["--no-safety"], "safety.safety=false"),
        (["--safety-force", "truth"], "safety.safety_use_estimate=false"),
        (["--misalignment-knee", "0.01,-0.005"], "misalignment.knee_xz=[0.01, -0.005]"),
        (["--kp", "200"], "gains.kp=[200.0, 200.0, 200.0, 200.0]"),
        (["--belt-mass", "30"], "contact.belt.mass_kg=30.0"),
        (["--joint-stiffness", "10000"], None),
    ],
    ids=lambda x: " ".join(x) if isinstance(x, list) else str(x),
)
def test_beside_a_preset_an_option_is_its_key_set(argv: list[str], setting: str | None) -> None:
    """``--preset paper OPTION`` equals ``--preset paper --set KEY=VALUE``."""
    given = _config("--preset", "paper", *argv)
    if setting is None:
        return _check_implied(argv, given)
    assert given == _config("--preset", "paper", "--set", setting)
    assert given != _config("--preset", "paper")


def _check_implied(argv: list[str], config: SimConfig) -> None:
    if argv[0] == "--pelvis":  # the supported gait, the fraction given
        assert config.pelvis.supported and config.pelvis.bws_fraction == 0.3
        assert (config.gait.hip_height, config.gait.pelvis_excursion) == (1.0, 0.025)
        assert (config.gait.duty_factor, config.gait.period) == (0.6, 1.6)
    else:  # a stiffness switches the spring on
        assert config.joint_compliance.enabled
        assert config.joint_compliance.stiffness_Nm_per_rad == 10000.0


def test_an_option_given_wins_over_what_another_implies() -> None:
    config = _config("--pelvis", "supported", "--contact", "on", "--hip-height", "0.95")
    assert config.gait.hip_height == 0.95 and config.gait.duty_factor == 0.6
    printed = _config("--motor", "paper-printed", "--kp", "150")
    assert printed.motor == MotorParams.paper_printed()
    assert printed.gains.kp == (150.0,) * 4 and printed.gains.kd == (2.0,) * 4


def test_alone_the_options_run_on_free_air_for_two_cycles_after_the_ramp_in() -> None:
    config = _config("--period", "1.1", "--ramp-out", "0.5")
    base = preset("paper-free-air").config
    assert config == dataclasses.replace(
        base,
        gait=dataclasses.replace(base.gait, period=1.1),
        ramp_out_s=0.5,
        duration_s=round(1.1 + 2 * 1.1 + 0.5, 9),
    )
    assert _config("--contact", "off", "--duration", "3.6") == base


def test_the_paper_preset_is_free_air_with_the_belt_and_a_bound_for_it() -> None:
    """The belt, and the QP's per-region bound that leaves the gait's load over it."""
    paper = preset("paper").config
    assert paper.cuff_force_limit_N == (200.0, 120.0)
    assert _config("--preset", "paper", "--contact", "off") == dataclasses.replace(
        preset("paper-free-air").config, cuff_force_limit_N=(200.0, 120.0)
    )
    options = ("--contact", "on", "--duration", "3.6", "--cuff-force-limit", "200,120")
    assert _config(*options) == paper


def test_isotropic_cuffs_set_the_belief_and_split_unsets_it() -> None:
    """Split is the default (the published cuffs, issue 31); isotropic the old belief."""
    assert _config("--controller-cuffs", "isotropic").belief.cuffs == CuffParams.isotropic()
    assert _config("--preset", "paper", "--controller-cuffs", "split").belief.cuffs is None
    assert _config("--preset", "paper").belief.cuffs is None


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["--period", "1e-300"],
            "--period: gait.period: must be >= 0.1 s; got 1e-300 (ten gait cycles a second is "
            "no gait, and the plan's cubic pieces need durations whose squares do not "
            "underflow)",
        ),
        (["--kp", "1,2"], "--kp must be 1 or 4 comma-separated numbers; got '1,2'"),
        (
            ["--pelvis", "supported", "--contact", "on", "--body-mass", "0"],
            "--body-mass: pelvis.body_mass_kg: must be > 0 kg; got 0.0",
        ),
        (
            ["--patient-delay", "0.1"],
            "patient_torque must be active with --patient-delay (an active patient's); got 'none'",
        ),
        (
            ["--preset", "paper", "--set", "contact.belt.mass_kg=-1"],
            "--set: contact: belt mass must be > 0 kg; got -1.0",
        ),
    ],
    ids=["period", "kp-count", "body-mass", "active-only", "set-nested"],
)
def test_a_bad_value_names_the_option_that_set_it(capsys, argv: list[str], message: str) -> None:
    assert cli.main(["simulate", *argv, "--no-record"]) == 2
    assert capsys.readouterr().err == f"exo-ctrl simulate: error: {message}\n"


def test_alone_the_options_say_their_run_is_on_free_air(capsys) -> None:
    """The surprise of long options alone is said: their run is not the default scenario's."""
    note = (
        "exo-ctrl simulate: note: long options without --preset or a scenario file run on "
        "preset paper-free-air (the feet in free air); --preset paper for the default "
        "scenario (the belt on)\n"
    )
    assert cli.main(["simulate", "--period", "1.1", "--duration", "0.05", "--no-record"]) == 0
    assert capsys.readouterr().err.startswith(note)
    for argv in (["--preset", "paper-free-air", "--period", "1.1"], ["--set", "gait.period=1.1"]):
        assert cli.main(["simulate", *argv, "--duration", "0.05", "--no-record"]) == 0
        assert "note: long options" not in capsys.readouterr().err
