"""Absurd numbers and colliding paths: exit 2 with the parameter named, nothing written.

Each case was found by feeding the commands random and extreme options: before,
these ended in a traceback (an int too large for a float, a period whose square
underflows, a run shorter than one tick, a link whose inertia overflows), in
NaN with exit 0, in a run that never ends, or in one output file written over
another (or over the input).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl import cli
from exo_ctrl.cli.common import check_outputs
from exo_ctrl.estimation import estimate_series
from exo_ctrl.exceptions import InvalidLog, InvalidParameter


def _refused(capsys: pytest.CaptureFixture, argv: list[str]) -> str:
    """Run the command: exit 2, one line on stderr, nothing on stdout; that line."""
    code = cli.main(argv)
    captured = capsys.readouterr()
    assert code == 2
    assert captured.out == ""
    assert captured.err.count("\n") == 1
    return captured.err


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (
            ["simulate", "--duration", "1e300"],
            "--duration: run.duration_s: must be in [0.001, 1e+07] s; got 1e+300 (at least one "
            "control tick at "
            "1000 Hz)",
        ),
        (
            ["simulate", "--duration", "1e-4", "--contact", "on"],
            "--duration: run.duration_s: must be in [0.001, 1e+07] s; got 0.0001 (at least one "
            "control tick at "
            "1000 Hz)",
        ),
        (
            ["simulate", "--cycles", "1e300"],
            "cycles must be at most 8.33333e+06 at the 1.2 s period; got 1e+300 (the run would "
            "last 1.2e+300 s, beyond 1e+07 s)",
        ),
        (
            ["simulate", "--substeps", "100000"],
            "--substeps: run.plant_substeps: must be an integer in [1, 1000]; got 100000",
        ),
        (
            ["simulate", "--period", "1e-300"],
            "--period: gait.period: must be >= 0.1 s; got 1e-300 (ten gait cycles a second is no "
            "gait, and the "
            "plan's cubic pieces need durations whose squares do not underflow)",
        ),
        (
            [*("simulate", "--contact", "on", "--pelvis", "supported"), "--body-mass", "1e6"],
            "--body-mass: pelvis.body_mass_kg: must be in (0, 300] kg; got 1000000.0",
        ),
        (
            ["simulate", "--contact", "on", "--speed-profile", "0:1e-300"],
            "--speed-profile: treadmill.speed_profile: must be speeds >= 0.01 m/s; got '0:1e-300' "
            "(point 1, 0:1e-300)",
        ),
        (
            ["simulate", "--step-length", "2"],
            "left foot path point (x = 1.088 m, z = -0.8923 m) at t = 0.249 s is 1.407 m from "
            "the hip; the leg reaches from 0 m to 1.039 m (set by step_length = 2 m, hip_height "
            "= 0.9 m, lift_height = 0.1 m, pelvis_excursion = 0 m, shape_coeff = 0.5)",
        ),
    ],
    ids=[
        "duration-huge",
        "duration-under-a-tick",
        "cycles-huge",
        "substeps",
        "period-tiny",
        "body-mass",
        "belt-crawl",
        "step-out-of-reach",
    ],
)
def test_simulate_refuses_absurd_numbers(
    capsys: pytest.CaptureFixture, argv: list[str], expected: str
) -> None:
    err = _refused(capsys, [*argv, "--no-record"])
    assert err == f"exo-ctrl simulate: error: {expected}\n"


def test_a_session_duration_beyond_floats_or_the_longest_run(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    session = tmp_path / "s.json"
    session.write_text('[{"duration": 1' + "0" * 400 + ', "mode": "tracking"}]')
    err = _refused(capsys, ["simulate", "--no-record", "--session", str(session)])
    assert err == (
        "exo-ctrl simulate: error: session segment 1 duration must be a finite number; got "
        f"{'1' + '0' * 39}…{'0' * 12} (401 digits)\n"
    )
    session.write_text('[{"duration": 1e300, "mode": "tracking"}]')
    err = _refused(capsys, ["simulate", "--no-record", "--session", str(session)])
    assert err == (
        "exo-ctrl simulate: error: session segment 1 duration must be in (0, 1e+07] s; got 1e+300\n"
    )


def test_gait_and_urdf_refuse_what_would_overflow(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    err = _refused(capsys, ["gait", "--period", "1e-300", "--csv", str(tmp_path / "g.csv")])
    assert err.startswith("exo-ctrl gait: error: period must be >= 0.1 s; got 1e-300")
    argv = ["urdf", "--kind", "exo", "--thigh-length", "1e300", "--out", str(tmp_path / "e.urdf")]
    err = _refused(capsys, argv)
    assert err == "exo-ctrl urdf: error: thigh_length must be in (0, 10] m; got 1e+300\n"
    assert not any(tmp_path.iterdir())


def test_an_empty_urdf_path_is_not_the_working_directory(
    tmp_path: Path, capsys: pytest.CaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    err = _refused(capsys, ["urdf", "--kind", "exo", "--out", ""])
    assert err == (
        "exo-ctrl urdf: error: --out must be a writable file in an existing directory; "
        "got '' (the path is empty)\n"
    )
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (
            ["simulate", "--out", "{d}/x.rrd", "--summary", "{d}/x.rrd"],
            "simulate: error: --out must be a file other than --summary's; got '{d}/x.rrd' (one "
            "would replace the other)",
        ),
        (
            ["simulate", "--out", "{d}/x.rrd", "--summary", "{d}/../{n}/x.rrd"],
            "simulate: error: --out must be a file other than --summary's; got '{d}/x.rrd' (one "
            "would replace the other)",
        ),
        (
            ["estimate", "{d}/in.rrd", "--out", "{d}/in.rrd"],
            "estimate: error: --out must be a file other than the input file; got '{d}/in.rrd' "
            "(one would replace the other)",
        ),
        (
            ["identify", "{d}/in.rrd", "--out", "{d}/p.urdf", "--summary", "{d}/p.urdf"],
            "identify: error: --summary must be a file other than --out's; got '{d}/p.urdf' "
            "(one would replace the other)",
        ),
    ],
    ids=["simulate", "simulate-dotdot", "estimate-input", "identify"],
)
def test_one_file_for_two_outputs_or_an_output_over_the_input_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture, argv: list[str], expected: str
) -> None:
    d, n = str(tmp_path), tmp_path.name
    recording = tmp_path / "in.rrd"
    recording.write_bytes(b"kept as it is")  # refused before it is read
    err = _refused(capsys, [a.format(d=d, n=n) for a in argv])
    assert err == f"exo-ctrl {expected.format(d=d, n=n)}\n"
    assert recording.read_bytes() == b"kept as it is"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.rrd"]


def test_a_link_and_its_target_are_one_file_a_device_may_take_both(tmp_path: Path) -> None:
    target = tmp_path / "a.json"
    target.write_text("{}")
    (tmp_path / "link.json").symlink_to(target)
    args = argparse.Namespace(out=str(tmp_path / "link.json"), summary=str(target))
    with pytest.raises(InvalidParameter, match=r"^summary|^--summary"):
        check_outputs(args, out="--out", summary="--summary")
    check_outputs(
        argparse.Namespace(out="/dev/null", summary="/dev/null"), out="--out", summary="--summary"
    )


def test_finite_readings_too_large_for_the_model_are_refused_not_nan(
    tmp_path: Path, capsys: pytest.CaptureFixture, exo
) -> None:
    n = 40
    t = np.arange(n) * 1e-3
    q = np.tile([0.1, 0.2, 0.1, 0.2], (n, 1))
    tau = np.tile([5.0, 3.0, 5.0, 3.0], (n, 1))
    q[:, 0] = 1e300  # finite, but the model's dynamics overflow
    with pytest.raises(InvalidLog, match=r"the estimate is not finite from sample \d+ "):
        estimate_series(t, q, None, tau, exo)
    log = tmp_path / "huge.csv"
    header = "t,left_hip_q,left_knee_q,right_hip_q,right_knee_q,"
    header += "left_hip_tau,left_knee_tau,right_hip_tau,right_knee_tau"
    rows = [",".join(repr(float(x)) for x in (t[k], *q[k], *tau[k])) for k in range(n)]
    log.write_text("\n".join([header, *rows]) + "\n")
    summary = tmp_path / "s.json"
    err = _refused(capsys, ["estimate", str(log), "--summary", str(summary)])
    assert err.startswith(f"exo-ctrl estimate: error: invalid log {log}, line 2, column ")
    assert err.endswith("--accept-implausible reads it anyway\n")
    # read anyway: the estimate itself is refused, not written as NaN
    accept = ["estimate", str(log), "--accept-implausible", "--summary", str(summary)]
    err = _refused(capsys, accept)
    assert err.startswith(
        f"exo-ctrl estimate: error: invalid log {log}: the estimate is not finite from sample "
    )
    assert not summary.exists()
    # the same log with a leg's angle the model takes: finite figures
    q[:, 0] = 0.1
    rows = [",".join(repr(float(x)) for x in (t[k], *q[k], *tau[k])) for k in range(n)]
    log.write_text("\n".join([header, *rows]) + "\n")
    assert cli.main(["estimate", str(log), "--summary", str(summary)]) == 0
    capsys.readouterr()
    peaks = json.loads(summary.read_text())["peak_cuff_normal_est_N"]
    assert all(np.isfinite(x) for x in peaks.values())


@pytest.mark.parametrize(
    ("path", "why"), [("/dev/null", "not a regular file"), ("{d}", "a directory")]
)
def test_a_session_that_is_not_a_file_says_what_it_is(
    tmp_path: Path, capsys: pytest.CaptureFixture, path: str, why: str
) -> None:
    path = path.format(d=tmp_path)
    err = _refused(capsys, ["simulate", "--no-record", "--session", path])
    assert err == (
        f"exo-ctrl simulate: error: session must be an existing JSON file; got {path!r} ({why})\n"
    )


def _log(path: Path, t: np.ndarray) -> Path:
    """A CSV log of still joints at times ``t``."""
    header = "t,left_hip_q,left_knee_q,right_hip_q,right_knee_q,"
    header += "left_hip_tau,left_knee_tau,right_hip_tau,right_knee_tau"
    rows = [",".join(repr(float(x)) for x in (tk, 0.1, 0.2, 0.1, 0.2, 5, 3, 5, 3)) for tk in t]
    path.write_text("\n".join([header, *rows]) + "\n")
    return path


def test_identify_refuses_a_cutoff_or_a_step_whose_sample_count_overflows(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    log = _log(tmp_path / "ok.csv", np.arange(500) * 1e-3)
    out = str(tmp_path / "p.urdf")
    err = _refused(capsys, ["identify", str(log), "--out", out, "--cutoff", "1e-308"])
    assert err == (
        f"exo-ctrl identify: error: invalid log {log}: it lasts 0.499 s; identification needs "
        "at least four periods at a 1e-308 Hz cut-off\n"
    )
    tiny = _log(tmp_path / "tiny.csv", np.arange(500) * 5e-324)  # denormal steps
    err = _refused(capsys, ["identify", str(tiny), "--out", out])
    assert err.startswith(f"exo-ctrl identify: error: invalid log {tiny}, column 't': ")
    assert "median time step is 4.941e-324 s, outside [1e-05, 1] s" in err
    accept = ["identify", str(tiny), "--out", out, "--accept-implausible"]
    assert cli.main(accept) == 2
    warning, err = capsys.readouterr().err.splitlines(keepends=True)  # read with a warning
    assert warning.startswith(f"exo-ctrl identify: warning: {tiny}, column 't': ")
    assert err.startswith(f"exo-ctrl identify: error: invalid log {tiny}: it lasts ")
    assert err.endswith("identification needs at least 2 s at a 2 Hz cut-off\n")


def test_a_csv_log_must_be_utf8_and_may_start_with_a_byte_order_mark(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    log = _log(tmp_path / "ok.csv", np.arange(200) * 1e-3)
    latin = tmp_path / "latin1.csv"
    latin.write_bytes(log.read_bytes() + "café\n".encode("latin-1"))
    err = _refused(capsys, ["estimate", str(latin)])
    assert (
        err == f"exo-ctrl estimate: error: invalid log {latin}: not UTF-8 text: a CSV log is text\n"
    )
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + log.read_bytes())
    assert cli.main(["estimate", str(bom)]) == 0
    with_bom = capsys.readouterr().out
    assert cli.main(["estimate", str(log)]) == 0
    assert with_bom.replace(str(bom), str(log)) == capsys.readouterr().out  # the same figures


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (
            ["--param", "step_length=0.3:0.4:99999999999999999999999"],
            "step_length must be at most 100,000 values (N); got '0.3:0.4:99999999999999999999999'",
        ),
        (
            ["--param", "step_length=0.3,0.4", "--samples", "99999999999999999999"],
            "samples must be at most 100,000; got 99999999999999999999",
        ),
        (
            ["--param", "step_length=0.3:0.4:1000", "--param", "period=1:2:1000"],
            "sweep parameters must be a grid of at most 100,000 runs; got '1000 step_length × "
            "1000 period' (this one has 1,000,000; --samples N draws N points instead)",
        ),
    ],
    ids=["range", "samples", "grid"],
)
def test_a_sweep_of_more_runs_than_the_cap_is_refused_at_once(
    tmp_path: Path, capsys: pytest.CaptureFixture, args: list[str], expected: str
) -> None:
    out = tmp_path / "s.parquet"
    err = _refused(capsys, ["sweep", *args, "--out", str(out), "--duration", "0.3"])
    assert err == f"exo-ctrl sweep: error: {expected}\n"
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (
            ["--shape-coeff", "1e-20"],
            "shape_coeff must be >= 0.001; got 1e-20 (below it the swing foot's path runs metres "
            "behind the hip, and tends to NaN as k_v goes to 0)",
        ),
        (["--step-length", "1e308"], "step_length must be in (0, 10] m; got 1e+308"),
    ],
    ids=["shape-coeff", "step-length"],
)
def test_gait_numbers_that_made_nan_or_overflow_are_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture, args: list[str], expected: str
) -> None:
    err = _refused(capsys, ["gait", *args, "--csv", str(tmp_path / "g.csv")])
    assert err == f"exo-ctrl gait: error: {expected}\n"
