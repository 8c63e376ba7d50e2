"""The built-in PD and CT as public Controller classes (exo_ctrl/control/builtin.py).

Real runs, no mocks: ``SimConfig(controller=PD())`` runs the compiled tick
``"pd"`` runs and logs the same bits (likewise CT and ``"ct"``, and a PD's
own gains against the configuration's); a subclass that overrides
``command`` and calls ``super().command(...)`` runs through the Python
adapter and matches the built-in within 1e-9 rad (on the synchronised
plan too); bad gains are refused
when the object is built, with the message naming the gain, the value and
what is allowed.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from exo_ctrl import SimConfig, simulate
from exo_ctrl.control import (
    CT,
    PD,
    ComputedTorqueController,
    Controller,
    PDController,
    PDGains,
    PluginController,
)
from exo_ctrl.exceptions import ExoCtrlError, InvalidParameter
from exo_ctrl.scenario import load_scenario
from exo_ctrl.sim.setup import build
from exo_ctrl.sweep import SweepSpec, config_for

#: A short run on the belt [s]: ramp-in and the first steps.
DURATION_S = 0.5

#: The logged arrays compared bit for bit.
SIGNALS = ("q", "dq", "voltage_cmd", "voltage", "current")


class CountingPD(PD):
    """A user's PD: the built-in law through ``super()``, counting its ticks."""

    def __init__(self) -> None:
        super().__init__()
        self.ticks = 0

    def command(self, t_s, plan, sensors, cuff_force_est_N):
        self.ticks += 1
        return super().command(t_s, plan, sensors, cuff_force_est_N)


class CountingCT(CT):
    """A user's CT: the built-in law and feedforward through ``super()``, counting its ticks."""

    def __init__(self) -> None:
        super().__init__()
        self.ticks = 0

    def command(self, t_s, plan, sensors, cuff_force_est_N):
        self.ticks += 1
        return super().command(t_s, plan, sensors, cuff_force_est_N)


def _run(controller, **kw):
    result = simulate(SimConfig(controller=controller, duration_s=DURATION_S, **kw))
    assert result.status == "completed"
    return result


@pytest.fixture(scope="module")
def pd_runs():
    return _run("pd"), _run(PD())


@pytest.fixture(scope="module")
def ct_runs():
    return _run("ct"), _run(CT())


def _max_difference(a, b, name: str) -> float:
    return float(np.max(np.abs(a.signals[name] - b.signals[name])))


@pytest.mark.parametrize(
    ("controller", "expected"),
    [
        (PD(), PDController),
        (CT(), ComputedTorqueController),
        ("pd", PDController),
        ("ct", ComputedTorqueController),
        (CountingPD(), PluginController),
        (CountingCT(), PluginController),
    ],
)
def test_an_exact_pd_or_ct_takes_the_compiled_tick_and_a_subclass_the_adapter(
    controller, expected
) -> None:
    setup = build(SimConfig(controller=controller, duration_s=DURATION_S))
    assert type(setup.controller) is expected


def test_the_gains_of_a_pd_object_reach_its_compiled_tick() -> None:
    gains = build(SimConfig(controller=PD(kp=250.0, kd=(4.0, 3.0, 4.0, 3.0)))).controller.gains
    assert gains == PDGains(kp=250.0, kd=(4.0, 3.0, 4.0, 3.0))
    assert build(SimConfig(controller="pd")).controller.gains == PDGains()


def test_pd_object_equals_pd_bit_for_bit(pd_runs) -> None:
    named, obj = pd_runs
    for name in SIGNALS:
        assert np.array_equal(named.signals[name], obj.signals[name]), name
    assert obj.summary()["controller"] == named.summary()["controller"] == "pd"
    # the run is not trivial: the legs move and the drives are driven
    assert np.ptp(named.signals["q"], axis=0).max() > 0.05  # [rad]
    assert np.abs(named.signals["voltage_cmd"]).max() > 1.0


def test_ct_object_equals_ct_bit_for_bit(ct_runs, pd_runs) -> None:
    named, obj = ct_runs
    for name in SIGNALS:
        assert np.array_equal(named.signals[name], obj.signals[name]), name
    assert obj.summary()["controller"] == "ct"
    # CT is not PD: its feedforward changes the voltages by tenths of volts and more
    assert _max_difference(named, pd_runs[0], "voltage_cmd") > 0.3  # [V]


def test_a_pd_objects_gains_equal_the_configurations_gains_bit_for_bit(pd_runs) -> None:
    gains = PDGains(kp=200.0, kd=3.0)
    named = _run("pd", gains=gains)
    obj = _run(PD(kp=200.0, kd=3.0))
    for name in SIGNALS:
        assert np.array_equal(named.signals[name], obj.signals[name]), name
    assert _max_difference(obj, pd_runs[0], "q") > 1e-4  # other gains track otherwise [rad]


def test_a_pd_subclass_calling_super_matches_the_built_in(pd_runs) -> None:
    user = CountingPD()
    mine = _run(user)
    assert user.ticks == SimConfig(duration_s=DURATION_S).n_ticks  # through the adapter
    assert mine.summary()["controller"] == f"{__name__}:CountingPD"
    assert _max_difference(mine, pd_runs[0], "q") <= 1e-9  # [rad]
    assert _max_difference(mine, pd_runs[0], "voltage_cmd") <= 1e-9  # [V]


def test_a_ct_subclass_calling_super_matches_the_built_in(ct_runs) -> None:
    user = CountingCT()
    mine = _run(user)
    assert user.ticks == SimConfig(duration_s=DURATION_S).n_ticks
    assert _max_difference(mine, ct_runs[0], "q") <= 1e-9  # [rad]
    assert _max_difference(mine, ct_runs[0], "voltage_cmd") <= 1e-9  # [V]


@pytest.mark.parametrize(
    ("cls", "kwargs", "message"),
    [
        (PD, {"kp": -1.0}, "kp must be >= 0 V/rad; got -1.0"),
        (PD, {"kp": 0.0}, "kp must be > 0 V/rad for every joint; got 0.0"),
        (PD, {"kd": -2.0}, "kd must be >= 0 V·s/rad; got -2.0"),
        (CT, {"kd": float("nan")}, "kd must be a finite number [V·s/rad]; got nan"),
        (
            CT,
            {"kp": (1.0, 2.0)},
            "kp must be a number or 4 numbers (one per joint: left_hip, left_knee, "
            "right_hip, right_knee); got (1.0, 2.0)",
        ),
    ],
)
def test_bad_gains_are_refused_when_built(cls, kwargs, message) -> None:
    with pytest.raises(InvalidParameter) as err:
        cls(**kwargs)
    assert str(err.value) == message
    assert isinstance(err.value, ExoCtrlError)


def test_gains_beside_a_pd_object_are_refused() -> None:
    with pytest.raises(InvalidParameter) as err:
        SimConfig(controller=PD(kp=250.0), gains=PDGains(kp=100.0))
    assert str(err.value).startswith("gains must be the default PDGains() with a PD or CT object")
    assert "the object carries its gains: PD(kp=(250.0, 250.0, 250.0, 250.0)" in str(err.value)


def test_the_plain_data_names_the_built_in_and_its_objects_gains() -> None:
    plain = SimConfig(controller=CT(kp=250.0)).to_dict()
    assert plain["controller"] == "ct"
    assert tuple(plain["gains"]["kp"]) == (250.0,) * 4
    user = SimConfig(controller=CountingPD()).to_dict()
    assert user["controller"] == f"{__name__}:CountingPD"


def test_pd_and_ct_are_controllers_with_voltage_commands() -> None:
    for cls in (PD, CT):
        assert issubclass(cls, Controller)
        assert cls.command_kind == "voltage"
    # a PD object is a built-in: the interaction modes take it, as they take "pd"
    assert SimConfig(controller=PD(), mode="guidance").mode == "guidance"


def test_a_ct_subclass_on_the_synchronised_plan_matches_the_built_in() -> None:
    # the paper preset: the belt and the plan generated each tick (one row rewritten)
    base = dataclasses.replace(load_scenario(preset="paper").config, duration_s=0.6)
    assert base.synced
    named = simulate(dataclasses.replace(base, controller="ct"))
    mine = simulate(dataclasses.replace(base, controller=CountingCT()))
    assert named.status == mine.status == "completed"
    assert _max_difference(mine, named, "q") <= 1e-9  # [rad]
    assert _max_difference(mine, named, "voltage_cmd") <= 1e-9  # [V]


def test_a_pd_object_in_guidance_mode_equals_pd_bit_for_bit() -> None:
    named = _run("pd", mode="guidance")
    obj = _run(PD(), mode="guidance")
    for name in SIGNALS:
        assert np.array_equal(named.signals[name], obj.signals[name]), name


@pytest.mark.parametrize(
    ("param", "controller", "gains"),
    [
        ("kd=3", "pd", PDGains(kp=250.0, kd=3.0)),
        ("controller=ct", "ct", PDGains(kp=250.0, kd=4.0)),
    ],
)
def test_a_sweep_from_a_pd_object_starts_from_its_gains(tmp_path, param, controller, gains):
    base = SimConfig(controller=PD(kp=250.0, kd=4.0))
    (task,) = SweepSpec.parse([param], duration_s=0.4, base=base).tasks()
    config = config_for(base, task.values, str(tmp_path))
    assert (config.controller, config.gains) == (controller, gains)
    assert task.run["controller"] == controller
    assert task.run["gains"] == {"kp": gains.kp, "kd": gains.kd}
