"""tools/robustness.py on a tiny cohort: its table holds the figures of the same runs made here.

Two patients, 1.5 s gait runs, on the sweeps' process pool (2 workers).  The
same runs are made directly in this process from their definition (the
fitted exoskeleton, the true patient, the knee misalignment, the default
gait scaled to the legs; the nominal belief; for the identified model a 6 s
calibration on the true patient and the identification), and every figure
of the tool's runs, and the table's medians and worsts, must equal theirs.
"""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl.estimation.identification import body_model, calibration_samples, identify_patient
from exo_ctrl.model import BodyParams, benchmark_cohort, load_exo, nominal_patient, write_urdf
from exo_ctrl.plan import GaitParams
from exo_ctrl.plant.misalignment import Misalignment
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.belief import Belief

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "tools"))  # the pool's workers import the tool by this name

import robustness  # noqa: E402

DURATION_S = 1.5


@pytest.fixture(scope="module")
def bench() -> robustness.Benchmark:
    return robustness.run_benchmark(n=2, seed=0, duration_s=DURATION_S, workers=2, progress=False)


def _direct(patient, controller: str, folder: Path) -> dict:
    """The run made here from its definition (module docstring), its summary's figures."""
    p = patient.params
    exo = BodyParams.exo_default().replace(
        thigh_length=p.thigh_length,
        shank_length=p.shank_length,
        thigh_cuff=p.thigh_cuff,
        shank_cuff=p.shank_cuff,
    )
    exo_path = str(write_urdf(exo, folder / "exo.urdf"))
    truth_path = str(write_urdf(p, folder / "truth.urdf"))
    k = (p.thigh_length + p.shank_length) / (0.52 + 0.52)
    gait = GaitParams(hip_height=0.90 * k, step_length=0.35 * k, lift_height=0.10 * k)
    nominal = Belief("nominal", None, patient.height_m, patient.mass_kg, patient.sex)
    config = SimConfig(
        gait=gait,
        exo=exo_path,
        patient=truth_path,
        misalignment=Misalignment(knee_xz=patient.knee_misalignment_xz),
        duration_s=DURATION_S,
        belief=nominal,
        controller={"ct_nominal": "ct", "ct_identified": "ct"}.get(controller, controller),
    )
    if controller == "ct_identified":
        calibration = simulate(
            SimConfig(
                gait=gait,
                exo=exo_path,
                patient=truth_path,
                misalignment=config.misalignment,
                duration_s=6.0,
                belief=nominal,
                controller="ct",
                exercise="calibration",
            )
        )
        s = calibration.signals
        prior = nominal_patient(
            p.thigh_length, p.shank_length, patient.height_m, patient.mass_kg, patient.sex
        )
        found = identify_patient(
            calibration_samples(calibration.t, s["q_meas"], s["tau_sensor"]),
            load_exo(exo_path),
            body_model(prior),
            prior,
        )
        identified = str(write_urdf(found.patient, folder / "identified.urdf"))
        config = dataclasses.replace(config, belief=Belief(patient=identified))
    summary = simulate(config).summary()
    rms = np.array(list(summary["rms_tracking_error_rad"].values()))
    rel = [x for x in summary["cuff_force_estimate_rms_error_rel"].values() if x is not None]
    return {
        "rms_error_mrad": 1e3 * math.sqrt(float(np.mean(rms**2))),
        "peak_cuff_force_N": max(summary["peak_cuff_force_N"].values()),
        "estimate_error_pct": 100.0 * max(rel),
        "safety_stop": summary["safety_state"] != "normal",
        "status": summary["status"],
    }


def test_the_tools_figures_are_those_of_the_runs_made_directly(
    bench: robustness.Benchmark, tmp_path: Path
) -> None:
    assert bench.cohort == benchmark_cohort(2, 0)
    assert len(bench.runs) == 2 * len(robustness.CONTROLLERS)
    direct: dict[str, list[dict]] = {c: [] for c in robustness.CONTROLLERS}
    for run in bench.runs:
        patient = bench.cohort[run["patient"]]
        folder = tmp_path / f"{patient.index}_{run['controller']}"
        folder.mkdir()
        mine = _direct(patient, run["controller"], folder)
        direct[run["controller"]].append(mine)
        assert run["status"] == mine["status"] == "completed", run["error"]
        assert run["safety_stop"] == mine["safety_stop"]
        for key in ("rms_error_mrad", "peak_cuff_force_N", "estimate_error_pct"):
            assert run[key] == pytest.approx(mine[key], rel=1e-12), (run["controller"], key)
    table = bench.table()
    print(table)
    for c, runs in direct.items():
        for key, _, _ in robustness.METRICS:
            values = np.array([r[key] for r in runs])
            median, worst = bench.aggregate(c, key)
            assert median == pytest.approx(float(np.median(values)), rel=1e-12)
            assert worst == pytest.approx(float(values.max()), rel=1e-12)
        line = next(row for row in table.splitlines() if row.startswith(f"| {c} |"))
        median, worst = bench.aggregate(c, "rms_error_mrad")
        assert line.startswith(f"| {c} | {median:.2f} | {worst:.2f} |")
        stops = sum(r["safety_stop"] for r in runs)
        assert f"| {stops}/2 | 0 |" in line


def test_the_png_has_a_panel_per_metric(bench: robustness.Benchmark, tmp_path: Path) -> None:
    path = tmp_path / "robustness.png"
    robustness.write_png(bench, path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--n", "0"], "n must be an integer in [1, 10000]; got 0"),
        (["--seed", "-1"], "seed must be an integer >= 0; got -1"),
        (["--duration", "0"], "duration must be a number > 0 [s]; got 0.0"),
        (["--workers", "0"], "workers must be an integer >= 1; got 0"),
        (["--png", "/nonexistent/r.png"],
         "--png must be a writable file in an existing directory; got '/nonexistent/r.png' "
         "(directory /nonexistent does not exist)"),
    ],
)  # fmt: skip
def test_bad_input_is_one_line_and_exit_2(capsys, argv: list, message: str) -> None:
    with pytest.raises(SystemExit) as info:
        robustness.main(argv)
    assert info.value.code == 2
    assert capsys.readouterr().err == f"robustness: error: {message}\n"
