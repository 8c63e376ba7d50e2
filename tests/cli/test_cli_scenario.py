"""``exo-ctrl scenario`` and ``exo-ctrl simulate SCENARIO.toml``: presets, files, reproduction."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from exo_ctrl import cli
from exo_ctrl.model import load_exo, load_patient
from exo_ctrl.model.fit import LENGTH_TOLERANCE_M, fit_warnings
from exo_ctrl.scenario import PRESETS

#: Summary keys that time the run (they differ between two runs of one scenario).
TIMING = ("wall_time_s", "real_time_factor")


def _figures(path: Path) -> dict:
    summary = json.loads(path.read_text())
    return {k: v for k, v in summary.items() if k not in TIMING}


def _run(capsys, *argv: str) -> tuple[int, str, str]:
    code = cli.main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.heavy
@pytest.mark.parametrize("name", PRESETS)
def test_a_preset_written_and_run_equals_the_preset_run(tmp_path: Path, capsys, name: str) -> None:
    toml = tmp_path / f"{name}.toml"
    code, out, _ = _run(capsys, "scenario", "--preset", name, "--out", str(toml))
    assert code == 0 and f"scenario: {toml}" in out
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    # the calibration's swing takes at least 3 s (exo_ctrl/plan/exercise.py)
    short = ["--duration", "3" if name == "calibration" else "0.25", "--no-record"]
    assert _run(capsys, "simulate", str(toml), *short, "--summary", str(a))[0] == 0
    assert _run(capsys, "simulate", "--preset", name, *short, "--summary", str(b))[0] == 0
    # bit for bit, the QP's too (its solver is reused from run to run: control/qp/solver_pool.py)
    assert _figures(a) == _figures(b)
    assert _figures(a)["status"] == "completed"


def test_a_recording_gives_back_its_scenario_and_its_summary(tmp_path: Path, capsys) -> None:
    rrd, first, again = tmp_path / "r.rrd", tmp_path / "1.json", tmp_path / "2.json"
    argv = ["simulate", "--controller", "ct", "--duration", "0.3", "--set", "gait.period=1.1"]
    assert _run(capsys, *argv, "--out", str(rrd), "--summary", str(first))[0] == 0
    toml = tmp_path / "back.toml"
    assert _run(capsys, "scenario", "--from", str(rrd), "--out", str(toml))[0] == 0
    text = toml.read_text()
    assert 'controller = "ct"' in text and "period = 1.1" in text
    assert _run(capsys, "simulate", str(toml), "--no-record", "--summary", str(again))[0] == 0
    assert _figures(first) == _figures(again)
    summary = json.loads(first.read_text())
    assert summary["scenario"].startswith('[run]\ncontroller = "ct"\n')
    assert summary["version"] and summary["warnings"] == []


def test_simulate_help_fits_on_a_screen(capsys) -> None:
    with pytest.raises(SystemExit):
        cli.main(["simulate", "--help"])
    text = capsys.readouterr().out
    assert len(text.splitlines()) <= 60
    assert "--set SECTION.KEY=VALUE" in text and "  --contact" not in text


def test_scenario_list_names_every_preset(capsys) -> None:
    code, out, _ = _run(capsys, "scenario", "--list")
    assert code == 0
    assert [line.split()[0] for line in out.splitlines()] == list(PRESETS)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["--preset", "fast"],
            "preset must be one of paper, paper-free-air, clinic-bws, clinic-spastic, spastic-qp, "
            "active-transparent, calibration; got 'fast'",
        ),
        (
            ["--set", "gait.period"],
            "--set: gait.period: expected section.key=value, e.g. gait.period=1.1",
        ),
        (["--set", "gait.perod=1.1"], "--set: gait.perod: must be a key of"),
        (
            ["--preset", "paper", "--bws", "2"],
            "--bws: pelvis.bws_fraction: must be in [0, 1] (a fraction of body weight); got 2.0",
        ),
    ],
)
def test_bad_scenario_input_is_one_line_and_exit_2(capsys, argv, message) -> None:
    code, _, err = _run(capsys, "simulate", *argv, "--no-record")
    assert code == 2
    assert err.startswith(f"exo-ctrl simulate: error: {message}")
    assert err.count("\n") == 1 and "Traceback" not in err


def test_a_bad_scenario_file_names_the_file_and_the_key(tmp_path: Path, capsys) -> None:
    toml = tmp_path / "s.toml"
    toml.write_text("[pelvis]\nbws_fraction = 'lots'\n")
    code, _, err = _run(capsys, "simulate", str(toml), "--no-record")
    assert code == 2
    assert err == (
        f"exo-ctrl simulate: error: scenario {toml}: pelvis.bws_fraction: must be a number; "
        "got 'lots'\n"
    )


def test_long_options_alone_run_on_the_free_air_defaults(capsys) -> None:
    from exo_ctrl.cli.app import build_parser
    from exo_ctrl.cli.simulate import sim_config
    from exo_ctrl.sim import SimConfig
    from exo_ctrl.sim.belief import Belief

    parse = build_parser().parse_args
    assert sim_config(parse(["simulate"])).contact.enabled  # the paper preset: on the belt
    flags = sim_config(parse(["simulate", "--estimator", "momentum"]))
    assert flags == SimConfig(estimator="momentum", belief=Belief())
    on = sim_config(parse(["simulate", "--contact", "on", "--controller", "ct", "--cycles", "1"]))
    assert on.contact.enabled and on.controller == "ct"
    assert on.duration_s == pytest.approx(2 * on.gait.period)


def _device(tmp_path: Path, capsys, *argv: str) -> Path:
    out = tmp_path / f"exo{len(list(tmp_path.iterdir()))}.urdf"
    assert _run(capsys, "urdf", "--kind", "exo", *argv, "--out", str(out))[0] == 0
    return out


def test_a_device_that_does_not_fit_warns_and_a_fitted_one_does_not(tmp_path: Path, capsys) -> None:
    short = _device(tmp_path, capsys, "--thigh-length", "0.45", "--shank-length", "0.48")
    warnings = fit_warnings(load_exo(short), load_patient(None))
    assert len(warnings) == 4  # thigh and shank of both legs
    assert warnings[0].startswith(
        "the exoskeleton's left thigh is 0.450 m and the patient's 0.520 m (70 mm apart, over "
        f"the {1e3 * LENGTH_TOLERANCE_M:.0f} mm of a fitted device)"
    )
    assert "exo-ctrl urdf --kind patient --height M --mass KG --out P.urdf" in warnings[0]
    summary = tmp_path / "s.json"
    code, _, err = _run(
        capsys, "simulate", "--set", f"urdf.exo={str(short)!r}", "--duration", "0.2",
        "--no-record", "--summary", str(summary),
    )  # fmt: skip
    assert code == 0
    assert json.loads(summary.read_text())["warnings"] == warnings
    assert err.count("exo-ctrl simulate: warning: the exoskeleton's") == 4
    # a device fitted to a patient: its own lengths
    patient = tmp_path / "p.urdf"
    args = ("--height", "1.62", "--mass", "58")
    code, out, _ = _run(capsys, "urdf", "--kind", "patient", *args, "--out", str(patient))
    fit = out.split("exo-ctrl urdf --kind exo ")[1].split(" --out")[0].split()
    fitted = _device(tmp_path, capsys, *fit)
    assert fit_warnings(load_exo(fitted), load_patient(str(patient))) == []
    assert fit_warnings(load_exo(None), load_patient(None)) == []


def test_the_default_patient_named_behaves_as_not_named(tmp_path: Path, capsys) -> None:
    from exo_ctrl.model import default_urdf_path

    a, b = tmp_path / "a.json", tmp_path / "b.json"
    short = ["--duration", "0.2", "--no-record", "--controller", "ct"]
    path = str(default_urdf_path("patient"))
    assert _run(capsys, "simulate", *short, "--summary", str(a))[0] == 0
    code, _, err = _run(capsys, "simulate", *short, "--set", f"urdf.patient={path!r}",
                        "--summary", str(b))  # fmt: skip
    assert code == 0 and "warning" not in err
    fa, fb = _figures(a), _figures(b)
    for key in ("scenario",):
        fa.pop(key), fb.pop(key)
    assert fa == fb
