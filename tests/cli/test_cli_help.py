"""Every option of every subcommand says its unit (or that it has none) and its default.

The rules, checked by walking the parser:

- every option and argument has a help text;
- an option taking a number names its unit in brackets (``[m]``, ``[Hz]``,
  ``[V/rad]``) or says ``no unit``;
- an optional option taking a value gives its default; a numeric default is
  a number (``default 0.35``, ``default: 2 gait cycles, 2.4 s``), or
  ``none`` when there is none.
"""

from __future__ import annotations

import argparse
import re

import pytest

from exo_ctrl import cli

#: The subcommands, in the order ``exo-ctrl --help`` lists them.
COMMANDS = [
    "simulate",
    "compare",
    "scenario",
    "gait",
    "urdf",
    "estimate",
    "export",
    "identify",
    "sweep",
]

UNIT = re.compile(r"\[[^\]]+\]|\bno unit\b")
NUMERIC_DEFAULT = re.compile(r"\(default:?\s[^)]*(\d|\bnone\b)")


def subparsers() -> dict[str, argparse.ArgumentParser]:
    parser = cli.build_parser()
    (sub,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def problems(parser: argparse.ArgumentParser) -> list[str]:
    """What each option's help lacks, one line per option at fault."""
    found = []
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        name = "/".join(action.option_strings) or action.dest
        text = " ".join((getattr(action, "hidden_help", action.help) or "").split())
        if not text or text == argparse.SUPPRESS:
            found.append(f"{name}: no help")
            continue
        numeric = action.type in (int, float)
        if numeric and not UNIT.search(text):
            found.append(f"{name}: no unit in {text!r}")
        takes_value = action.nargs != 0
        if action.option_strings and takes_value and not action.required:
            if "default" not in text:
                found.append(f"{name}: no default in {text!r}")
            elif numeric and not NUMERIC_DEFAULT.search(text):
                found.append(f"{name}: the default is not a number in {text!r}")
    return found


@pytest.mark.parametrize("command", COMMANDS)
def test_every_option_has_its_unit_and_default(command: str) -> None:
    assert problems(subparsers()[command]) == []


def test_the_subcommands_are_the_documented_ones() -> None:
    assert list(subparsers()) == COMMANDS


def test_the_checker_catches_what_it_should() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--a", type=float, default=1.0, help="a length (default 1)")
    parser.add_argument("--b", type=float, default=None, help="a time [s]")
    parser.add_argument("--c", type=float, default=None, help="a time [s] (default: paper)")
    parser.add_argument("--d", choices=("x", "y"))
    parser.add_argument("--e", type=int, default=2, help="a count, no unit (default 2)")
    assert problems(parser) == [
        "--a: no unit in 'a length (default 1)'",
        "--b: no default in 'a time [s]'",
        "--c: the default is not a number in 'a time [s] (default: paper)'",
        "--d: no help",
    ]


def test_simulate_help_shows_the_numbers(capsys) -> None:
    with pytest.raises(SystemExit) as info:
        cli.main(["simulate", "--help"])
    assert info.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert (
        "--duration SEC simulated time, ramps included [s] (default: the scenario's "
        "run.duration_s, 3.6 s in most presets)" in text.replace("- ", "-")
    )
    assert "--out PATH.rrd the rerun recording (default: recording.out, exo_run.rrd)" in text
    # the long options, hidden from --help, keep their help for docs/cli.md
    hidden = {
        a.dest: " ".join(a.hidden_help.split())
        for a in subparsers()["simulate"]._actions
        if hasattr(a, "hidden_help")
    }
    assert hidden["kd"].startswith("derivative gain per joint [V·s/rad]; one number for every")
    assert hidden["kd"].endswith("(scenario key gains.kd) (default 5)")
    assert hidden["step_length"] == (
        "s, distance the foot travels on the belt per stance [m] (scenario key "
        "gait.step_length) (default 0.35)"
    )


def test_top_level_help_says_what_the_command_does(capsys) -> None:
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    out = capsys.readouterr().out
    assert "``" not in out
    assert "Plan, simulate and estimate a lower-limb exoskeleton" in out
