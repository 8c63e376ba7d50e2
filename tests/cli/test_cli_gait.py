"""End-to-end tests of ``exo-ctrl gait`` and ``exo-ctrl urdf``: files checked by physics."""

from __future__ import annotations

import csv
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl import cli
from exo_ctrl.model import load_body

HEADER = [
    "t",
    "left_foot_x",
    "left_foot_z",
    "right_foot_x",
    "right_foot_z",
    "left_foot_vx",
    "left_foot_vz",
    "right_foot_vx",
    "right_foot_vz",
    "left_phi1",
    "left_phi2",
    "right_phi1",
    "right_phi2",
    "left_hip",
    "left_knee",
    "right_hip",
    "right_knee",
]


def read_csv(path: Path) -> tuple[list[str], dict[str, np.ndarray]]:
    with path.open(newline="") as handle:
        rows = list(csv.reader(handle))
    data = np.array(rows[1:], dtype=float)
    return rows[0], {name: data[:, i] for i, name in enumerate(rows[0])}


def run_gait(tmp_path: Path, *args: str, name: str = "gait.csv") -> dict[str, np.ndarray]:
    out = tmp_path / name
    assert cli.main(["gait", *args, "--csv", str(out)]) == 0
    header, cols = read_csv(out)
    assert header == HEADER
    return cols


def fk(phi1: np.ndarray, phi2: np.ndarray, l1: float, l2: float) -> np.ndarray:
    return np.column_stack(
        (l1 * np.cos(phi1) + l2 * np.cos(phi2), l1 * np.sin(phi1) + l2 * np.sin(phi2))
    )


def stance_rows(cols: dict[str, np.ndarray], side: str, hip_height: float) -> np.ndarray:
    return np.abs(cols[f"{side}_foot_z"] + hip_height) < 1e-9


# --------------------------------------------------------------------------- gait CSV


def test_header_constant_is_the_documented_one() -> None:
    assert list(cli.GAIT_CSV_HEADER) == HEADER


def test_gait_rows_at_the_requested_rate_and_duration(tmp_path: Path) -> None:
    cols = run_gait(tmp_path, "--duration", "2.0", "--rate", "50")
    t = cols["t"]
    assert t.size == 101  # t = 0, 0.02, …, 2.0
    np.testing.assert_allclose(t, np.arange(101) / 50, atol=1e-12)
    default = run_gait(tmp_path, name="default.csv")  # one period (1.2 s) at 100 Hz
    assert default["t"].size == 121
    assert default["t"][-1] == pytest.approx(1.2)


def test_gait_csv_obeys_the_physics(tmp_path: Path) -> None:
    s, h, H, T, beta = 0.35, 0.10, 0.90, 1.2, 0.5
    cols = run_gait(tmp_path, "--duration", "2.4", "--rate", "200")
    l1 = l2 = 0.52
    for side in ("left", "right"):
        phi1, phi2 = cols[f"{side}_phi1"], cols[f"{side}_phi2"]
        foot = np.column_stack((cols[f"{side}_foot_x"], cols[f"{side}_foot_z"]))
        np.testing.assert_allclose(fk(phi1, phi2, l1, l2), foot, atol=1e-8)
        # generated URDF: φ1 = -π/2 + q_hip, φ2 = φ1 - q_knee (compare as angles)
        qh, qk = cols[f"{side}_hip"], cols[f"{side}_knee"]
        np.testing.assert_allclose(np.cos(-math.pi / 2 + qh - phi1), 1.0, atol=1e-12)
        np.testing.assert_allclose(np.cos(phi1 - qk - phi2), 1.0, atol=1e-12)
        assert np.all(qk > 0)  # knee flexed, never hyperextended
        # no slip: on the belt the foot moves back at belt speed s / (β T)
        st = stance_rows(cols, side, H)
        assert 0.4 < st.mean() < 0.6
        np.testing.assert_allclose(cols[f"{side}_foot_vx"][st], -s / (beta * T), rtol=1e-9)
        np.testing.assert_allclose(cols[f"{side}_foot_vz"][st], 0.0, atol=1e-12)
        # in swing the foot is above the belt and reaches the lift height
        assert np.max(cols[f"{side}_foot_z"]) == pytest.approx(-(H - h), abs=1e-9)
    # t = 0: left foot at A (top of swing, moving forward at v_b), right at mid-stance
    assert cols["left_foot_x"][0] == pytest.approx(0.0, abs=1e-12)
    assert cols["left_foot_vx"][0] == pytest.approx(s / (beta * T) / 0.5)
    assert cols["right_foot_x"][0] == pytest.approx(0.0, abs=1e-12)
    # the right leg is the left leg half a period later (T/2 = 120 rows at 200 Hz)
    np.testing.assert_allclose(cols["right_foot_x"][:-120], cols["left_foot_x"][120:], atol=1e-9)
    np.testing.assert_allclose(cols["right_hip"][:-120], cols["left_hip"][120:], atol=1e-9)


def test_step_length_option_changes_the_stance_span(tmp_path: Path) -> None:
    spans = {}
    for s in ("0.35", "0.3"):
        cols = run_gait(tmp_path, "--step-length", s, "--rate", "1000", name=f"s{s}.csv")
        st = stance_rows(cols, "left", 0.90)
        x = cols["left_foot_x"][st]
        spans[s] = x.max() - x.min()
        dt_span = 0.001 * float(s) / (0.5 * 1.2)  # one sample of belt travel
        assert spans[s] == pytest.approx(float(s), abs=dt_span + 1e-9)
    assert spans["0.3"] < spans["0.35"] - 0.04


def test_exo_option_changes_the_joint_angles(tmp_path: Path, write_short_urdf) -> None:
    short = write_short_urdf(tmp_path / "short.urdf")
    # a 0.85 m leg cannot reach a belt 0.90 m below the hip: lower the hip for both runs
    default = run_gait(tmp_path, "--hip-height", "0.75", name="default.csv")
    other = run_gait(tmp_path, "--hip-height", "0.75", "--exo", str(short), name="short.csv")
    for key in ("left_foot_x", "left_foot_z", "right_foot_vx"):
        np.testing.assert_allclose(other[key], default[key])  # the gait is the same
    assert np.max(np.abs(other["left_knee"] - default["left_knee"])) > 0.1
    for side in ("left", "right"):
        foot = np.column_stack((other[f"{side}_foot_x"], other[f"{side}_foot_z"]))
        np.testing.assert_allclose(
            fk(other[f"{side}_phi1"], other[f"{side}_phi2"], 0.45, 0.40), foot, atol=1e-8
        )


def test_gait_via_subprocess(tmp_path: Path) -> None:
    out = tmp_path / "sub.csv"
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "exo_ctrl",
            "gait",
            "--period",
            "1.0",
            "--rate",
            "20",
            "--csv",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 0, proc.stderr
    assert "belt speed 0.7 m/s" in proc.stdout  # 2 s / T = 2 × 0.35 / 1.0
    header, cols = read_csv(out)
    assert header == HEADER
    assert cols["t"].size == 21
    st = stance_rows(cols, "left", 0.90)
    np.testing.assert_allclose(cols["left_foot_vx"][st], -0.7, rtol=1e-9)


# --------------------------------------------------------------------------- bad input


BAD = [
    (["--step-length", "nan"], "step_length must be a finite number [m]; got nan"),
    (["--period=-1"], "period must be > 0 s; got -1.0"),
    (["--lift-height", "0.9"], "lift_height must be < hip_height = 0.9 m; got 0.9"),
    (["--duty-factor", "0.3"], "duty_factor must be in [0.5, 1); got 0.3"),
    (["--step-length", "1.5"], "the leg reaches from 0 m to 1.039 m"),
    (["--rate", "0"], "rate must be > 0 Hz; got 0.0"),
]
BAD_IDS = ["nan-step", "negative-period", "lift-at-hip", "duty", "unreachable", "rate"]


def assert_clean_failure(code: int, err: str, expected: str, directory: Path, before: set) -> None:
    assert code == 2
    assert "Traceback" not in err
    assert err.endswith("\n") and err.count("\n") == 1, err
    assert err.startswith("exo-ctrl gait: error: ")
    assert expected in err
    assert {p.name for p in directory.iterdir()} == before  # no output, no temp file


@pytest.mark.parametrize(("args", "expected"), BAD, ids=BAD_IDS)
def test_bad_gait_input_in_process(
    tmp_path: Path, capsys: pytest.CaptureFixture, args: list[str], expected: str
) -> None:
    out = tmp_path / "out.csv"
    code = cli.main(["gait", *args, "--csv", str(out)])
    err = capsys.readouterr().err
    assert_clean_failure(code, err, expected, tmp_path, set())


def test_bad_urdf_files(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    bad = tmp_path / "bad.urdf"
    bad.write_text('<robot name="x">\n<link name="a">\n</robot>\n')
    missing = tmp_path / "missing.urdf"
    out = tmp_path / "out.csv"
    cases = [
        (bad, f"invalid model: {bad}: malformed XML at line 3, column 2"),
        (missing, f"invalid model: {missing}: file not found"),
    ]
    for urdf, expected in cases:
        code = cli.main(["gait", "--exo", str(urdf), "--csv", str(out)])
        err = capsys.readouterr().err
        assert_clean_failure(code, err, expected, tmp_path, {"bad.urdf"})


#: The left shank's inertia in the committed exoskeleton URDF.
SHANK_INERTIA = 'ixx="0.1024125" ixy="0.0" ixz="0.0" iyy="0.1024125" iyz="0.0" izz="0.002025"'

BAD_BODIES = [
    (
        'ixx="-1" ixy="0.0" ixz="0.0" iyy="0.1024125" iyz="0.0" izz="0.002025"',
        "inertia is not physically valid: ixx = -1 kg·m² must be > 0",
    ),
    (
        'ixx="1" ixy="2" ixz="0" iyy="1" iyz="0" izz="1"',
        "inertia is not physically valid: the principal moments -1, 1, 3 kg·m² must be > 0 "
        "and each smaller than the sum of the other two",
    ),
    ("MASS", "mass must be a finite number > 0 kg; got -4.5"),
]
BAD_BODY_IDS = ["negative-ixx", "not-positive-definite", "negative-mass"]


def bad_body_urdf(tmp_path: Path, exo_path: Path, inertia: str) -> Path:
    """The committed exoskeleton with the left shank's inertia (or mass) made non-physical."""
    text = exo_path.read_text(encoding="utf-8")
    if inertia == "MASS":
        bad = text.replace('<mass value="4.5"/>', '<mass value="-4.5"/>', 1)
    else:
        bad = text.replace(SHANK_INERTIA, inertia, 1)
    assert bad != text
    path = tmp_path / "bad.urdf"
    path.write_text(bad, encoding="utf-8")
    return path


@pytest.mark.parametrize(("inertia", "reason"), BAD_BODIES, ids=BAD_BODY_IDS)
@pytest.mark.parametrize("command", ["gait", "simulate", "estimate"])
def test_non_physical_urdf_is_bad_input_for_every_command(
    tmp_path: Path,
    exo_path: Path,
    capsys: pytest.CaptureFixture,
    command: str,
    inertia: str,
    reason: str,
) -> None:
    urdf = bad_body_urdf(tmp_path, exo_path, inertia)
    log = tmp_path / "log.csv"  # a valid estimate input: 1 s at rest, 1 kHz
    columns = "t," + ",".join(f"{j}_{x}" for x in ("q", "tau") for j in HEADER[-4:])
    log.write_text(columns + "\n" + "".join(f"{k / 1000},{'0,' * 7}0\n" for k in range(1000)))
    out = tmp_path / "out.file"
    argv = {
        "gait": ["gait", "--exo", str(urdf), "--csv", str(out)],
        "simulate": ["simulate", "--exo", str(urdf), "--duration", "0.05", "--out", str(out)],
        "estimate": ["estimate", str(log), "--exo", str(urdf), "--out", str(tmp_path / "est.rrd")],
    }[command]
    code = cli.main(argv)
    err = capsys.readouterr().err
    assert code == 2
    assert err == f"exo-ctrl {command}: error: invalid model: 'left_shank' in {urdf}: {reason}\n"
    assert {p.name for p in tmp_path.iterdir()} == {"bad.urdf", "log.csv"}


def test_negative_inertia_via_the_installed_command(tmp_path: Path, exo_path: Path) -> None:
    urdf = bad_body_urdf(tmp_path, exo_path, BAD_BODIES[0][0])
    exe = Path(sys.executable).with_name("exo-ctrl")
    proc = subprocess.run(
        [str(exe), "gait", "--exo", str(urdf), "--csv", str(tmp_path / "o.csv")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2
    assert proc.stderr == (
        f"exo-ctrl gait: error: invalid model: 'left_shank' in {urdf}: {BAD_BODIES[0][1]}\n"
    )
    assert proc.stdout == ""
    assert [p.name for p in tmp_path.iterdir()] == ["bad.urdf"]


def test_failure_leaves_an_existing_file_untouched(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "out.csv"
    out.write_text("previous run\n")
    code = cli.main(["gait", "--step-length", "1.5", "--csv", str(out)])
    assert code == 2
    capsys.readouterr()
    assert out.read_text() == "previous run\n"
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--step-length", "nan"], "step_length must be a finite number [m]; got nan"),
        (["--exo", "{dir}/missing.urdf"], "missing.urdf: file not found"),
    ],
    ids=["nan", "missing-urdf"],
)
def test_bad_gait_input_via_subprocess(tmp_path: Path, args: list[str], expected: str) -> None:
    args = [a.replace("{dir}", str(tmp_path)) for a in args]
    proc = subprocess.run(
        [sys.executable, "-m", "exo_ctrl", "gait", *args, "--csv", str(tmp_path / "o.csv")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert_clean_failure(proc.returncode, proc.stderr, expected, tmp_path, set())
    assert proc.stdout == ""


# --------------------------------------------------------------------------- urdf


def test_urdf_command_writes_other_lengths(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "x.urdf"
    args = [
        "urdf",
        "--kind",
        "exo",
        "--thigh-length",
        "0.45",
        "--shank-length",
        "0.40",
        "--shank-cuff",
        "0.35",
        "--out",
        str(out),
    ]
    assert cli.main(args) == 0
    capsys.readouterr()
    body = load_body(out)
    for side in ("left", "right"):
        assert body.legs[side].thigh_length == pytest.approx(0.45, abs=1e-12)
        assert body.legs[side].shank_length == pytest.approx(0.40, abs=1e-12)
    assert body.mass == pytest.approx(16.0)


def test_urdf_command_with_only_the_lengths(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    out = tmp_path / "x.urdf"
    args = [
        "urdf",
        "--kind",
        "exo",
        "--thigh-length",
        "0.45",
        "--shank-length",
        "0.40",
        "--out",
        str(out),
    ]
    code = cli.main(args)
    capsys.readouterr()
    assert code == 0
    body = load_body(out)
    assert body.legs["left"].thigh_length == pytest.approx(0.45, abs=1e-12)
    assert body.legs["left"].shank_length == pytest.approx(0.40, abs=1e-12)
    # The cuffs keep their fraction of the link: 0.39/0.52 and 0.45/0.52.
    cuff_z = body.frame_position(np.zeros(4), "left_shank_cuff")[2]
    knee_z = -0.45
    assert cuff_z - knee_z == pytest.approx(-0.45 / 0.52 * 0.40, abs=1e-12)


def test_urdf_command_refuses_a_cuff_beyond_the_thigh(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "x.urdf"
    code = cli.main(["urdf", "--kind", "exo", "--thigh-cuff", "0.6", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert "Traceback" not in err
    assert err == (
        "exo-ctrl urdf: error: thigh_cuff must be in (0, 0.52] m (the thigh length); got 0.6\n"
    )
    assert list(tmp_path.iterdir()) == []
