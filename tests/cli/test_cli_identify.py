"""``exo-ctrl identify`` end to end on a real recording and a CSV log, and on bad input.

The truth is a generated patient 20 % heavier than the nominal one (masses
×1.2, de Leva's ratios kept); the calibration run is ``exo-ctrl simulate
--exercise calibration`` with CT on the nominal model and the default
sensors and cuffs.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl.cli import main as cli_main
from exo_ctrl.estimation import write_csv_log
from exo_ctrl.model import load_patient, nominal_patient, write_urdf
from exo_ctrl.record import read_recording


@pytest.fixture(scope="module")
def calibration(tmp_path_factory: pytest.TempPathFactory) -> dict:
    folder = tmp_path_factory.mktemp("identify")
    prior = nominal_patient(0.52, 0.52, 1.75, 80.0, "male")
    truth = prior.replace(thigh_mass=1.2 * prior.thigh_mass, shank_mass=1.2 * prior.shank_mass)
    truth_path = write_urdf(truth, folder / "truth.urdf")
    run = folder / "calibration.rrd"
    code = cli_main(
        [
            "simulate",
            "--exercise",
            "calibration",
            "--controller",
            "ct",
            "--patient",
            str(truth_path),
            "--controller-patient",
            "nominal",
            "--patient-height",
            "1.75",
            "--patient-mass",
            "80",
            "--out",
            str(run),
        ]
    )
    assert code == 0
    return {"folder": folder, "run": run, "truth": truth}


def test_identify_recording_writes_a_loadable_patient(
    calibration: dict, capsys: pytest.CaptureFixture[str]
) -> None:
    capsys.readouterr()
    out = calibration["folder"] / "patient.urdf"
    summary = calibration["folder"] / "identify.json"
    code = cli_main(
        ["identify", str(calibration["run"]), "--out", str(out), "--summary", str(summary)]
    )
    printed = capsys.readouterr().out
    print(printed)
    assert code == 0
    assert "condition number" in printed and "thigh mass [kg]" in printed
    patient = load_patient(str(out))
    truth = calibration["truth"]
    masses = [patient.model.inertias[j].mass for j in patient.joint_ids]
    assert masses[0] == pytest.approx(truth.thigh_mass, rel=0.05)
    assert masses[1] == pytest.approx(truth.shank_mass, rel=0.05)
    # what the motion cannot excite is said, in the table and in the summary
    assert "not excited by the calibration" in printed
    assert "folded: shank.m only as part of thigh.mcz, thigh.Iyy" in printed
    assert "same torques for any motion: thigh mass +10 %" in printed
    data = json.loads(summary.read_text())
    assert data["not_excited"]["folded"] == {"shank.m": ["thigh.mcz", "thigh.Iyy"]}
    assert set(data["not_excited"]["null_directions"]) == {"thigh mass", "shank mass"}
    assert len(data["base_parameters"]) == 7
    assert data["condition_number"] < 20.0
    # the identified model is what the device then holds
    code = cli_main(
        [
            "simulate",
            "--controller",
            "ct",
            "--controller-patient",
            str(out),
            "--duration",
            "0.3",
            "--no-record",
        ]
    )
    assert code == 0


def test_identify_csv_log_matches_the_recording(calibration: dict, tmp_path: Path) -> None:
    result = read_recording(calibration["run"])
    s = result.signals
    csv = write_csv_log(tmp_path / "log.csv", result.t, s["q_meas"], None, s["tau_sensor"])
    from_rrd, from_csv = tmp_path / "a.json", tmp_path / "b.json"
    for source, summary in ((calibration["run"], from_rrd), (csv, from_csv)):
        code = cli_main(
            ["identify", str(source), "--out", str(tmp_path / "p.urdf"), "--summary", str(summary)]
        )
        assert code == 0
    a = [p["estimate"] for p in json.loads(from_rrd.read_text())["base_parameters"]]
    b = [p["estimate"] for p in json.loads(from_csv.read_text())["base_parameters"]]
    np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--cutoff", "0"], "cutoff must be > 0"),
        (["--cutoff", "40"], "cutoff must be < 25 Hz (the differentiation's low-pass)"),
        (["--height", "0.5"], "height"),
    ],
)
def test_bad_options_exit_2_with_one_line(
    calibration: dict,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    extra: list[str],
    message: str,
) -> None:
    out = tmp_path / "p.urdf"
    code = cli_main(["identify", str(calibration["run"]), "--out", str(out), *extra])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert err.startswith("exo-ctrl identify: error:") and message in err
    assert "\n" not in err
    assert not out.exists()


def test_bad_files_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    text = tmp_path / "run.txt"
    text.write_text("t\n")
    cases = [
        ([str(text), "--out", str(tmp_path / "p.urdf")], "a .rrd recording or a .csv log"),
        ([str(tmp_path / "none.rrd"), "--out", str(tmp_path / "p.urdf")], "file not found"),
        # the output is checked before the input is read (this input does not exist)
        ([str(tmp_path / "none.rrd"), "--out", str(tmp_path / "no" / "p.urdf")], "--out"),
    ]
    for argv, message in cases:
        code = cli_main(["identify", *argv])
        err = capsys.readouterr().err.strip()
        assert code == 2, argv
        assert message in err and "\n" not in err
    assert not (tmp_path / "p.urdf").exists()


def test_identified_by_name_is_refused_with_a_hint(capsys: pytest.CaptureFixture[str]) -> None:
    code = cli_main(["simulate", "--controller-patient", "identified", "--no-record"])
    err = capsys.readouterr().err
    assert code == 2
    assert "give the file exo-ctrl identify --out wrote" in err


def test_short_calibration_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    code = cli_main(["simulate", "--exercise", "calibration", "--duration", "2", "--no-record"])
    err = capsys.readouterr().err
    assert code == 2
    assert "duration must be >= 3 s for the calibration exercise" in err
