"""Plausibility: logs in the wrong unit and non-physical URDFs are refused by name.

A CSV log's first sample far outside the exoskeleton's URDF limits (range
of motion, speed limit) or its time steps far from uniform: exit 2 naming
the line, the column, the value and the limit, or, with
``--accept-implausible``, a warning and the estimate.  A URDF whose joint
limits or dynamics are not physical, or whose centre of mass is far from
its joint: exit 2 naming the element, before any run.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from hostile_corpus import SHORT_RUN, csv_log, edited_urdf

from exo_ctrl.cli.app import main
from exo_ctrl.model import default_urdf_path

EXO = str(default_urdf_path("exo"))
EXO_TEXT = default_urdf_path("exo").read_text()
ACCEPT = "--accept-implausible reads it anyway"


def run(argv: list[str], capsys) -> tuple[int, str, str]:
    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.mark.parametrize(
    ("options", "where", "reason"),
    [
        # listed in issue 32: angles in degrees
        (
            {"scale_q": 180 / math.pi},
            "line 2, column 'left_knee_q'",
            f"5.73 rad is far outside the range of motion [-0.05, 2.09] rad of {EXO} (more "
            "than 0.5 rad beyond; angles in degrees?)",
        ),
        # listed: times in hours
        (
            {"dt": 0.001 / 3600},
            "column 't'",
            "the median time step is 2.778e-07 s, outside [1e-05, 1] s (times in another unit?)",
        ),
        # listed: a 1e6 s gap in t
        (
            {"gap": (500, 1e6)},
            "line 502, column 't'",
            "t = 1e+06 s comes 1e+06 s after the sample before, over 10 times the median "
            "step 0.001 s (a gap in the log?)",
        ),
        # sibling: a speed column in degrees per second
        (
            {"edit": {(300, "right_hip_dq"): 40.0}},
            "line 302, column 'right_hip_dq'",
            f"a speed of 40 rad/s is over 3 times the speed limit 6 rad/s of {EXO}",
        ),
    ],
)
@pytest.mark.parametrize("command", ["estimate", "identify"])
def test_an_implausible_log_is_refused_naming_the_first_sample(
    tmp_path: Path, capsys, options: dict, where: str, reason: str, command: str
) -> None:
    log = csv_log(tmp_path, "log.csv", **options)
    argv = [command, str(log)] + (
        ["--out", str(tmp_path / "p.urdf")] if command == "identify" else []
    )
    code, _, err = run(argv, capsys)
    assert (code, err) == (
        2,
        f"exo-ctrl {command}: error: invalid log {log}, {where}: {reason}; {ACCEPT}\n",
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == ["log.csv"]


def test_accept_implausible_warns_and_estimates(tmp_path: Path, capsys) -> None:
    log = csv_log(tmp_path, "log.csv", scale_q=180 / math.pi)
    code, out, err = run(["estimate", str(log), "--accept-implausible"], capsys)
    assert code == 0
    assert err.splitlines()[0] == (
        f"exo-ctrl estimate: warning: {log}, line 2, column 'left_knee_q': 5.73 rad is far "
        f"outside the range of motion [-0.05, 2.09] rad of {EXO} (more than 0.5 rad beyond; "
        "angles in degrees?); read as it is (--accept-implausible)"
    )
    assert out.startswith(f"estimated 2000 samples of {log}")
    plain = csv_log(tmp_path, "plain.csv")  # the same log in radians: no warning
    code, _, err = run(["estimate", str(plain)], capsys)
    assert (code, err) == (0, "")


KNEE = '<limit effort="150.0" velocity="6.0" lower="-0.05" upper="2.09"/>'
SHANK_COM = '<origin xyz="0.0 0.0 -0.26" rpy="0.0 -0.0 0.0"/>\n      <mass value="4.5"/>'


@pytest.mark.parametrize(
    ("old", "new", "element", "reason"),
    [
        # listed in issue 32
        ('damping="0.5"', 'damping="-50"', "left_hip", "damping must be >= 0 N·m·s/rad; got -50"),
        (
            SHANK_COM,
            SHANK_COM.replace("-0.26", "-1e6"),
            "left_shank",
            "centre of mass 1e+06 m from its joint; at most 10 times the link's length "
            "(0.52 m) + 1 m = 6.2 m",
        ),
        ('velocity="6.0"', 'velocity="0"', "left_hip", "velocity limit must be > 0 rad/s; got 0"),
        ('effort="150.0"', 'effort="0"', "left_hip", "effort limit must be > 0 N·m; got 0"),
        (
            '<joint name="left_knee" type="revolute">',
            '<joint name="left_knee" type="prismatic">',
            "left_knee",
            "must be a revolute joint (the drive turns it); got a prismatic joint (JointModelPY)",
        ),
        (
            SHANK_COM,
            SHANK_COM.replace("0.0 0.0 -0.26", "nan 0.0 -0.26"),
            "left_shank",
            "centre of mass xyz='nan 0.0 -0.26' must be three finite numbers [m]",
        ),
        (
            KNEE,
            KNEE.replace('lower="-0.05" upper="2.09"', 'lower="2.09" upper="-0.05"'),
            "left_knee",
            "lower limit 2.09 rad is above the upper limit -0.05 rad",
        ),
        (KNEE, "", "left_knee", "a revolute joint needs a <limit> (effort, velocity, range)"),
        (
            '<link name="left_shank">',
            '<link name="left_thigh">',
            "left_thigh",
            "link defined twice",
        ),
        # siblings: negative friction, a far centre of mass on a link without children
        ('friction="0.3"', 'friction="-1"', "left_hip", "friction must be >= 0 N·m; got -1"),
    ],
)
def test_non_physical_urdfs_are_refused_by_name(
    tmp_path: Path, capsys, old: str, new: str, element: str, reason: str
) -> None:
    urdf = edited_urdf(tmp_path, "bad.urdf", old, new)
    code, out, err = run(["simulate", "--exo", str(urdf), *SHORT_RUN], capsys)
    assert (code, out, err) == (
        2,
        "",
        f"exo-ctrl simulate: error: invalid model: {element!r} in {urdf}: {reason}\n",
    )


@pytest.mark.parametrize(
    ("old", "new", "said"),
    [
        (
            '<origin xyz="0.0 0.0 -0.52" rpy="0.0 -0.0 0.0"/>',
            '<origin xyz="0.0 0.0 -0.52" rpy="nan -0.0 0.0"/>',
            "Unable to parse component [nan] to a double (while parsing a vector value)",
        ),
        (
            '<axis xyz="0.0 1.0 0.0"/>',
            '<axis xyz="0.0 1.0"/>',
            "Malformed axis element for joint [left_knee]: Parser found 2 elements but 3 "
            "expected while parsing vector [0.0 1.0]",
        ),
    ],
)
def test_the_parsers_own_complaint_is_one_line(
    tmp_path: Path, capfd, old: str, new: str, said: str
) -> None:
    """urdfdom writes its reason to file descriptor 2 over several lines: now one line."""
    urdf = edited_urdf(tmp_path, "bad.urdf", old, new, count=1)
    code = main(["simulate", "--patient", str(urdf), *SHORT_RUN])
    out, err = capfd.readouterr()
    assert (code, out, err) == (
        2,
        "",
        f"exo-ctrl simulate: error: invalid model: {urdf}: Pinocchio could not build a model "
        f"from it (The XML stream does not contain a valid URDF model.; the parser said: "
        f"{said})\n",
    )


LEFT_KNEE_JOINT = EXO_TEXT[
    EXO_TEXT.index('<joint name="left_knee"') : EXO_TEXT.index(
        "</joint>", EXO_TEXT.index('<joint name="left_knee"')
    )
    + len("</joint>")
]


@pytest.mark.parametrize(
    ("old", "new", "where", "reason"),
    [
        # listed in issue 32: a missing joint (urdfdom said it on several lines)
        (
            LEFT_KNEE_JOINT,
            "",
            "",
            "2 root links ('left_shank', 'pelvis'); a URDF has one, every other link the child "
            "of a joint (a joint missing?)",
        ),
        # sibling: a loop beside a root (Pinocchio built a model from the root and the
        # message was "joint not found")
        (
            '<child link="left_shank"/>',
            '<child link="pelvis"/>',
            "'left_thigh' in ",
            "is not reached from the root link 'left_shank': the joints form a loop "
            "('left_hip' makes it a child of a link below it)",
        ),
    ],
)
def test_a_urdf_that_is_not_one_tree_is_refused_by_link(
    tmp_path: Path, capfd, old: str, new: str, where: str, reason: str
) -> None:
    urdf = edited_urdf(tmp_path, "bad.urdf", old, new)
    code = main(["simulate", "--exo", str(urdf), *SHORT_RUN])
    out, err = capfd.readouterr()
    assert (code, out, err) == (
        2,
        "",
        f"exo-ctrl simulate: error: invalid model: {where}{urdf}: {reason}\n",
    )
