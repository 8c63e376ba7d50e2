"""Bad plug-ins get clear errors: exact messages, the tick named, one line on the command line.

The user's controllers live in a module written to a temporary directory
and imported by its ``module:Class`` path, as a user's package would be.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from exo_ctrl import SimConfig, cli, simulate
from exo_ctrl.control import Controller
from exo_ctrl.exceptions import InvalidParameter, PluginError
from exo_ctrl.sim.setup import build

ALLOWED = (
    "controller must be pd, ct, qp, the import path 'module:Class' of an "
    "exo_ctrl.control.Controller subclass, or such a Controller object; got "
)

SOURCE = '''
import numpy as np
from exo_ctrl.control import Controller


class Hold(Controller):
    """0 V on every drive."""

    def command(self, t_s, plan, sensors, cuff_force_est_N):
        return np.zeros(4)


class Abstract(Controller):
    """Forgets command()."""


class NotOne:
    """Has a command, but is not on the interface."""

    def command(self, t_s, plan, sensors, cuff_force_est_N):
        return np.zeros(4)


class NeedsGains(Controller):
    def __init__(self, kp):
        self.kp = kp

    def command(self, t_s, plan, sensors, cuff_force_est_N):
        return np.zeros(4)


class Amps(Controller):
    command_kind = "current"

    def command(self, t_s, plan, sensors, cuff_force_est_N):
        return np.zeros(4)


class ThreeAtTick5(Controller):
    command_kind = "torque"

    def command(self, t_s, plan, sensors, cuff_force_est_N):
        return np.zeros(3 if t_s >= 0.005 - 1e-12 else 4)


class NanAtTick7(Controller):
    def command(self, t_s, plan, sensors, cuff_force_est_N):
        out = np.zeros(4)
        if t_s >= 0.007 - 1e-12:
            out[2] = np.nan
        return out


class Text(Controller):
    def command(self, t_s, plan, sensors, cuff_force_est_N):
        return "four volts"
'''


@pytest.fixture
def plugins(user_module, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> str:
    """A module of controllers importable by its name (returned), in a fresh directory."""
    monkeypatch.chdir(tmp_path)
    return user_module("user_ctl", SOURCE)


class NoCommand:
    """Neither a name nor a controller."""

    def __repr__(self) -> str:
        return "NoCommand()"


class Duck:
    """A command method, but not a Controller subclass."""

    def command(self, t_s, plan, sensors, cuff_force_est_N):
        return np.zeros(4)

    def __repr__(self) -> str:
        return "Duck()"


class Mine(Controller):
    def command(self, t_s, plan, sensors, cuff_force_est_N):
        return np.zeros(4)


def test_a_class_not_implementing_the_interface_is_refused_when_configured() -> None:
    with pytest.raises(InvalidParameter) as info:
        SimConfig(controller=Duck())
    assert str(info.value) == (
        ALLOWED + "Duck() (Duck is not a subclass of exo_ctrl.control.Controller)"
    )
    with pytest.raises(InvalidParameter) as info:
        SimConfig(controller=Mine)
    assert str(info.value).endswith("(Mine is a class: give an object, Mine())")
    with pytest.raises(InvalidParameter) as info:
        SimConfig(controller=NoCommand())
    assert str(info.value) == "controller must be one of pd, ct, qp; got NoCommand()"
    with pytest.raises(InvalidParameter) as info:
        SimConfig(controller="lqr")  # a misspelt name: the message it always had
    assert str(info.value) == "controller must be one of pd, ct, qp; got 'lqr'"
    with pytest.raises(InvalidParameter) as info:
        SimConfig(controller="my pkg:Ctl")
    assert str(info.value) == (ALLOWED + "'my pkg:Ctl' (an import path is 'package.module:Class')")


@pytest.mark.parametrize(
    ("cls", "detail"),
    [
        ("Abstract", "{m}:Abstract does not implement command()"),
        ("NotOne", "{m}:NotOne is not a subclass of exo_ctrl.control.Controller"),
        ("Missing", "module {m} has no attribute Missing"),
        (
            "NeedsGains",
            "{m}:NeedsGains cannot be built with no arguments: "
            "NeedsGains.__init__() missing 1 required positional argument: 'kp'",
        ),
    ],
)
def test_an_import_path_that_does_not_give_a_controller_is_refused(
    plugins: str, cls: str, detail: str
) -> None:
    path = f"{plugins}:{cls}"
    config = SimConfig(controller=path, duration_s=0.01)  # the form is right: checked on build
    with pytest.raises(InvalidParameter) as info:
        build(config)
    assert str(info.value) == ALLOWED + f"{path!r} ({detail.format(m=plugins)})"


def test_a_command_kind_that_is_not_voltage_or_torque_is_refused(plugins: str) -> None:
    with pytest.raises(InvalidParameter) as info:
        build(SimConfig(controller=f"{plugins}:Amps", duration_s=0.01))
    assert str(info.value) == (
        f"command_kind of {plugins}:Amps must be 'voltage' or 'torque'; got 'current'"
    )


def test_a_module_that_does_not_resolve_is_refused() -> None:
    with pytest.raises(InvalidParameter) as info:
        build(SimConfig(controller="no_such_pkg.ctl:Impedance", duration_s=0.01))
    assert str(info.value) == ALLOWED + (
        "'no_such_pkg.ctl:Impedance' (cannot import no_such_pkg.ctl: No module named 'no_such_pkg')"
    )


@pytest.mark.parametrize(
    ("cls", "message"),
    [
        (
            "ThreeAtTick5",
            "controller {m}:ThreeAtTick5 at tick 5 (t = 0.005 s): command must return "
            "4 joint torques [N·m]; got shape (3,)",
        ),
        (
            "NanAtTick7",
            "controller {m}:NanAtTick7 at tick 7 (t = 0.007 s): command must return "
            "finite numbers; got [0.0, 0.0, nan, 0.0]",
        ),
        (
            "Text",
            "controller {m}:Text at tick 0 (t = 0 s): command must return "
            "4 drive voltages [V]; got 'four volts'",
        ),
    ],
)
def test_a_bad_command_stops_the_run_naming_the_tick(plugins: str, cls: str, message: str) -> None:
    with pytest.raises(PluginError) as info:
        simulate(SimConfig(controller=f"{plugins}:{cls}", duration_s=0.05))
    assert str(info.value) == message.format(m=plugins)
    assert info.value.tick == int(message.split("tick ")[1].split()[0])
    assert isinstance(info.value, ValueError)


def test_a_user_controller_needs_the_tracking_mode() -> None:
    with pytest.raises(InvalidParameter) as info:
        SimConfig(controller=Mine(), mode="transparent")
    assert str(info.value) == (
        "mode must be tracking with a user's controller; got 'transparent' "
        "(a user's controller runs in tracking mode)"
    )


def test_the_command_line_runs_a_path_and_refuses_one_that_does_not_resolve(
    plugins: str, capsys: pytest.CaptureFixture[str]
) -> None:
    base = ["simulate", "--duration", "0.02", "--no-record"]
    assert cli.main([*base, "--controller", f"{plugins}:Hold"]) == 0
    assert f"controller {plugins}:Hold, completed" in capsys.readouterr().out
    assert cli.main([*base, "--controller", "no_such_pkg.ctl:Impedance"]) == 2
    captured = capsys.readouterr()
    assert captured.err == (
        "exo-ctrl simulate: error: " + ALLOWED + "'no_such_pkg.ctl:Impedance' "
        "(cannot import no_such_pkg.ctl: No module named 'no_such_pkg')\n"
    )
    assert "Traceback" not in captured.err
    assert cli.main([*base, "--controller", f"{plugins}:Abstract"]) == 2
    err = capsys.readouterr().err
    assert err.endswith(f"({plugins}:Abstract does not implement command())\n")
    assert err.count("\n") == 1
