"""Tests of exo_ctrl.sweep.spec: spec checks, grid and sample order, run ids, resolved runs."""

from __future__ import annotations

import dataclasses

import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plan import GaitParams
from exo_ctrl.plant import CuffParams, MotorParams
from exo_ctrl.sim import SimConfig
from exo_ctrl.sweep import SweepPaths, SweepSpec, config_for


def test_spec_errors():
    with pytest.raises(InvalidParameter) as info:
        SweepSpec.parse(["step_length=0.3", "step_length=0.4"])
    assert str(info.value) == "sweep parameter must be given once; got 'step_length'"
    with pytest.raises(InvalidParameter) as info:
        SweepSpec.parse(["step_length=0.3"], samples=0)
    assert str(info.value) == "samples must be an integer >= 1; got 0"
    with pytest.raises(InvalidParameter) as info:
        SweepSpec.parse(["step_length=0.3"], duration_s=float("nan"))
    assert str(info.value) == "duration must be a finite number > 0 [s]; got nan"
    with pytest.raises(InvalidParameter) as info:
        SweepSpec.parse(["patient_thigh_mass=9"], base=SimConfig(patient="human"))
    assert str(info.value) == (
        "patient_thigh_mass must be swept only with the generated patient "
        "(no patient URDF given); got 'human'"
    )
    with pytest.raises(InvalidParameter) as info:
        SweepSpec(params=(("step_length", (float("nan"),)),))
    assert str(info.value) == "step_length must be a finite number [m]; got nan"
    with pytest.raises(InvalidParameter) as info:
        SweepPaths.for_output("results.csv")
    assert str(info.value) == "out must be a path ending in .parquet; got 'results.csv'"


def test_grid_order_samples_and_run_ids(make_spec):
    grid = make_spec("step_length=0.3,0.4", "controller=pd,ct")
    assert grid.points() == [
        {"step_length": 0.3, "controller": "pd"},
        {"step_length": 0.3, "controller": "ct"},
        {"step_length": 0.4, "controller": "pd"},
        {"step_length": 0.4, "controller": "ct"},
    ]
    texts = ("step_length=0.3:0.5:3", "gear_ratio=40,60", "controller=pd,ct")
    points = make_spec(*texts, samples=6, seed=7).points()
    assert points == make_spec(*texts, samples=6, seed=7).points()
    assert points != make_spec(*texts, samples=6, seed=8).points()
    assert points[:4] == make_spec(*texts, samples=4, seed=7).points()  # a larger N extends
    # Only [min, max] of a list matters for sampling.
    assert points == make_spec("step_length=0.5,0.3", *texts[1:], samples=6, seed=7).points()
    assert all(0.3 <= p["step_length"] <= 0.5 and 40 <= p["gear_ratio"] <= 60 for p in points)
    assert {p["controller"] for p in points} <= {"pd", "ct"}
    assert len({p["step_length"] for p in points}) == 6
    # A swept default value is the same run as not sweeping it: ids are of the resolved run.
    a = make_spec("step_length=0.35").tasks()[0].run_id
    b = make_spec("patient_thigh_mass=11.3").tasks()[0].run_id
    c = make_spec("gear_ratio=120", "controller=pd").tasks()[0].run_id
    assert a == b == c
    assert make_spec("step_length=0.35", duration_s=0.5).tasks()[0].run_id != a


def test_base_fields_are_kept_and_part_of_the_run_id(tmp_path, make_spec, duration):
    base = SimConfig(safety=False, cuff_force_limit_N=100.0, controller="ct", plant_substeps=2)
    spec = make_spec("gear_ratio=40", "cuff_damping=50", "period=1.0", base=base)
    (task,) = spec.tasks()
    config = config_for(base, task.values, str(tmp_path))
    assert config == dataclasses.replace(
        base,
        gait=GaitParams(period=1.0),
        motor=MotorParams(gear_ratio=40.0),
        cuffs=CuffParams(damping_N_s_per_m=50.0),
        duration_s=duration,
    )
    assert (
        task.run_id != make_spec("gear_ratio=40", "cuff_damping=50", "period=1.0").tasks()[0].run_id
    )
    # --cycles: the duration follows each point's period: a one-period ramp-in
    # (the default base's) and the cycles at full speed.
    periods = make_spec("period=1.0,1.3", duration_s=None, cycles=1.5).tasks()
    assert [t.values["duration_s"] for t in periods] == [2.5, 3.25]
