"""Tests of exo_ctrl.sweep.parameters: the ``--param`` syntax, ranges and exact messages."""

from __future__ import annotations

import contextlib
import io

import pytest

from exo_ctrl import cli
from exo_ctrl.control import PDGains
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.sim import CONTROLLERS, SimConfig
from exo_ctrl.sweep import PARAMETERS, SweepSpec, config_for, parse_param, resolved_run
from exo_ctrl.sweep.parameters import parameter_listing


def test_parse_lists_and_ranges():
    assert parse_param("step_length=0.3,0.35,0.3") == ("step_length", (0.3, 0.35))
    assert parse_param(" period = 1.0:1.4:5 ") == ("period", (1.0, 1.1, 1.2, 1.3, 1.4))
    assert parse_param("step_length=0.3:0.5:3") == ("step_length", (0.3, 0.4, 0.5))
    assert parse_param("controller=ct,pd") == ("controller", ("ct", "pd"))
    assert parse_param("gear_ratio=50") == ("gear_ratio", (50.0,))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "stride=0.3",
            "sweep parameter must be one of step_length, lift_height, hip_height, "
            "pelvis_excursion, shape_coeff, period, duty_factor, landing_speed, landing_depth, "
            "patient_thigh_mass, "
            "patient_shank_mass, patient_thigh_length, "
            "patient_shank_length, exo_thigh_length, exo_shank_length, exo_thigh_mass, "
            "exo_shank_mass, exo_thigh_cuff, exo_shank_cuff, cuff_stiffness, cuff_damping, "
            "gear_ratio, kp, kd, controller; "
            "got 'stride'",
        ),
        ("step_length", "--param must be NAME=V1,V2,... or NAME=LO:HI:N; got 'step_length'"),
        ("step_length=", "--param must be NAME=V1,V2,... or NAME=LO:HI:N; got 'step_length='"),
        (
            "step_length=0.3:0.5",
            "step_length must be V1,V2,... or LO:HI:N with LO < HI and an integer N >= 2; "
            "got '0.3:0.5'",
        ),
        (
            "step_length=0.5:0.3:3",
            "step_length must be V1,V2,... or LO:HI:N with LO < HI and an integer N >= 2; "
            "got '0.5:0.3:3'",
        ),
        (
            "step_length=0.3:0.5:2.5",
            "step_length must be V1,V2,... or LO:HI:N with LO < HI and an integer N >= 2; "
            "got '0.3:0.5:2.5'",
        ),
        (
            "step_length=0.3:0.5:1",
            "step_length must be V1,V2,... or LO:HI:N with LO < HI and an integer N >= 2; "
            "got '0.3:0.5:1'",
        ),
        ("step_length=0.3,nan", "step_length must be a finite number [m]; got 'nan'"),
        ("step_length=nan:0.5:3", "step_length must be a finite number [m]; got 'nan'"),
        ("shape_coeff=inf", "shape_coeff must be a finite number; got 'inf'"),
        ("lift_height=0.1,,0.2", "lift_height must be a finite number [m]; got ''"),
        ("step_length=-0.3", "step_length must be in (0, 2] m; got -0.3"),
        ("duty_factor=1", "duty_factor must be in [0.5, 1); got 1.0"),
        ("patient_thigh_mass=20", "patient_thigh_mass must be in [7, 14] kg; got 20.0"),
        ("patient_shank_length=0.3", "patient_shank_length must be in [0.39, 0.65] m; got 0.3"),
        ("cuff_stiffness=8", "cuff_stiffness must be in [1000, 100000] N/m; got 8.0"),
        ("kp=0", "kp must be in (0, 1000] V/rad; got 0.0"),
        ("kp=100,1e4", "kp must be in (0, 1000] V/rad; got 10000.0"),
        ("kd=-1", "kd must be in [0, 20] V·s/rad; got -1.0"),
        ("landing_speed=0.6", "landing_speed must be in [0, 0.5] m/s; got 0.6"),
        ("landing_depth=0", "landing_depth must be in (0, 0.01] m; got 0.0"),
        ("kd=2,x", "kd must be a finite number [V·s/rad]; got 'x'"),
        (
            "controller=lqr",
            f"controller must be one of {', '.join(CONTROLLERS)}; got 'lqr'",
        ),
    ],
)
def test_parse_errors(text, message):
    with pytest.raises(InvalidParameter) as info:
        parse_param(text)
    assert str(info.value) == message


def test_gains_are_sweepable_with_the_same_gain_on_every_joint(tmp_path):
    assert parse_param("kp=50:150:3") == ("kp", (50.0, 100.0, 150.0))
    assert parse_param("kd=0,2") == ("kd", (0.0, 2.0))
    spec = SweepSpec.parse(["kp=50,300", "kd=1"], duration_s=0.4)
    low, default = spec.tasks()
    assert low.run["gains"] == {"kp": (50.0,) * 4, "kd": (1.0,) * 4}
    assert default.run["gains"] == {"kp": (300.0,) * 4, "kd": (1.0,) * 4}
    # Sweeping the base's gain is the same run as not sweeping it (same run id).
    (unswept,) = SweepSpec.parse(["step_length=0.35"], duration_s=0.4).tasks()
    (swept,) = SweepSpec.parse(["kp=300", "kd=5"], duration_s=0.4).tasks()
    assert swept.run_id == unswept.run_id
    # A base with per-joint gains keeps them while they are not swept.
    base = SimConfig(gains=PDGains(kp=(100, 90, 80, 70)))
    (task,) = SweepSpec.parse(["kd=3"], duration_s=0.4, base=base).tasks()
    assert task.run["gains"] == {"kp": (100.0, 90.0, 80.0, 70.0), "kd": (3.0,) * 4}
    assert "kp" not in task.values and task.values["kd"] == 3.0
    assert resolved_run(base, {}) == {**base.to_dict(), "patient_body": None}


def test_swept_gains_reach_the_run(tmp_path):
    (task,) = SweepSpec.parse(["kp=50", "kd=1"], duration_s=0.4).tasks()
    config = config_for(SimConfig(), task.values, str(tmp_path))
    assert config.gains == PDGains(kp=50.0, kd=1.0)


def test_a_swept_landing_approach_reaches_the_run(tmp_path):
    spec = SweepSpec.parse(["landing_speed=0,0.025", "landing_depth=0.002"], duration_s=0.4)
    paper, approach = (config_for(SimConfig(), t.values, str(tmp_path)).gait for t in spec.tasks())
    assert (paper.landing_speed_mps, approach.landing_speed_mps) == (0.0, 0.025)
    assert paper.landing_depth_m == approach.landing_depth_m == 0.002
    # a depth the swing cannot hold is the run's failure, named by the gait's own field
    (deep,) = SweepSpec.parse(
        ["landing_speed=0.025", "landing_depth=0.01", "lift_height=0.015"], duration_s=0.4
    ).tasks()
    with pytest.raises(InvalidParameter) as info:
        config_for(SimConfig(), deep.values, str(tmp_path))
    assert str(info.value) == (
        "landing_depth_m must be in (0, 0.01] m and below lift_height / 2 = 0.0075 m; got 0.01 "
        "(the approach is the last millimetres of the swing, into the sole's compliance)"
    )


def test_listing_gives_every_parameter_its_unit_range_and_default():
    lines = parameter_listing().splitlines()
    assert lines[0] == "sweep parameters (name, unit, accepted values, default):"
    rows = {line.split()[0]: line for line in lines[1:]}
    assert list(rows) == [*PARAMETERS, "controller"]
    for name, info in PARAMETERS.items():
        cells = rows[name].split()
        assert cells[1] == f"[{info.unit or '-'}]", name
        unit = f" {info.unit}" if info.unit else ""
        assert f"in {cells[2]} {cells[3]}{unit}" == info.interval(), name
    assert rows["cuff_stiffness"].split()[:5] == [
        "cuff_stiffness",
        "[N/m]",
        "[1000,",
        "100000]",
        "8000",
    ]
    assert "8000 N/m = the paper's 8 N/mm" in rows["cuff_stiffness"]
    assert rows["kp"].split()[:5] == ["kp", "[V/rad]", "(0,", "1000]", "300"]
    assert rows["kd"].split()[:5] == ["kd", "[V·s/rad]", "[0,", "20]", "5"]
    assert rows["controller"].split() == [
        "controller",
        *[f"{c}," for c in CONTROLLERS],
        "MODULE:CLASS",
        "pd",
        "names",
    ]
    assert rows["patient_thigh_mass"].split()[4] == "11.3"
    human = parameter_listing(SimConfig(patient="human", gains=PDGains(kp=(1, 2, 3, 4))))
    rows = {line.split()[0]: line for line in human.splitlines()[1:]}
    assert rows["patient_thigh_mass"].split()[4] == "URDF"
    assert rows["kp"].split()[4:6] == ["per", "joint"]


def test_sweep_help_shows_the_listing():
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit) as info:
        cli.main(["sweep", "--help"])
    assert info.value.code == 0
    assert parameter_listing() in out.getvalue()
