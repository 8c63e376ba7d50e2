"""``--pelvis-excursion M``: the hip's rise and fall through the gait options; bad values."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl import cli

H_S, E = 1.0, 0.05  # [m]


def run_gait(tmp_path: Path, *args: str, name: str = "gait.csv") -> dict[str, np.ndarray]:
    """``exo-ctrl gait ARGS --csv``, its columns by name."""
    out = tmp_path / name
    assert cli.main(["gait", *args, "--csv", str(out)]) == 0
    header = out.read_text().splitlines()[0].split(",")
    data = np.loadtxt(out, delimiter=",", skiprows=1)
    return {n: data[:, i] for i, n in enumerate(header)}


def test_the_feet_relative_to_the_belt_are_the_fixed_hip_feet(tmp_path: Path) -> None:
    fixed = run_gait(tmp_path, "--hip-height", "1.0", "--rate", "1000", name="fixed.csv")
    moving = run_gait(
        tmp_path, "--hip-height", "1.0", "--pelvis-excursion", "0.05", "--rate", "1000"
    )
    t = moving["t"]
    omega = 4 * math.pi / 1.2  # the default period
    rise = 0.5 * E * np.cos(omega * t)  # ΔH(t) [m]
    rate = -0.5 * E * omega * np.sin(omega * t)  # [m/s]
    for side in ("left", "right"):
        np.testing.assert_array_equal(moving[f"{side}_foot_x"], fixed[f"{side}_foot_x"])
        np.testing.assert_allclose(
            moving[f"{side}_foot_z"] + rise, fixed[f"{side}_foot_z"], rtol=0, atol=1e-9
        )
        np.testing.assert_allclose(
            moving[f"{side}_foot_vz"] + rate, fixed[f"{side}_foot_vz"], rtol=0, atol=1e-9
        )
    # the left foot at mid-stance (t = 0.6 s) is H_s + e/2 below the hip: the knee extends
    i = int(np.flatnonzero(np.isclose(t, 0.6))[0])
    assert moving["left_foot_z"][i] == pytest.approx(-(H_S + E / 2), abs=1e-9)
    flexion = moving["left_phi1"][i] - moving["left_phi2"][i]
    assert flexion == pytest.approx(
        math.pi - math.acos((2 * 0.52**2 - (H_S + E / 2) ** 2) / (2 * 0.52**2)), abs=1e-8
    )


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--pelvis-excursion", "nan"], "pelvis_excursion must be a finite number [m]; got nan"),
        (["--pelvis-excursion=-0.01"], "pelvis_excursion must be >= 0 m; got -0.01"),
        (
            ["--pelvis-excursion", "1.6"],
            "pelvis_excursion must be < 2 (hip_height - lift_height) = 1.6 m; got 1.6 (the lifted "
            "swing foot would rise to the hip when the hip is at its lowest, H_s - e/2)",
        ),
        (
            ["--hip-height", "1.0", "--pelvis-excursion", "0.1"],
            "pelvis_excursion must be at most 0.0774 m for this gait and a 0.52 m + 0.52 m leg; "
            "got 0.1 (left foot path point (x = -2.776e-17 m, z = -1.05 m) at t = 0.6 s is "
            "1.05 m from the hip; the leg reaches from 0 m to 1.039 m (set by step_length = "
            "0.35 m, hip_height = 1 m, lift_height = 0.1 m, pelvis_excursion = 0.1 m, "
            "shape_coeff = 0.5))",
        ),
    ],
    ids=["nan", "negative", "above-the-lift", "beyond-reach"],
)
def test_bad_excursions_exit_2_naming_the_value(
    tmp_path: Path, capsys: pytest.CaptureFixture, args: list[str], expected: str
) -> None:
    code = cli.main(["gait", *args, "--csv", str(tmp_path / "out.csv")])
    err = capsys.readouterr().err
    assert code == 2
    assert err == f"exo-ctrl gait: error: {expected}\n"
    assert not any(tmp_path.iterdir())  # no output, no temporary file


def test_simulate_and_sweep_refuse_it_too(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    code = cli.main(["simulate", "--pelvis-excursion=-1", "--no-record"])
    assert code == 2
    assert capsys.readouterr().err == (
        "exo-ctrl simulate: error: --pelvis-excursion: gait.pelvis_excursion: must be >= 0 m; "
        "got -1.0\n"
    )
    out = tmp_path / "sweep.parquet"
    code = cli.main(["sweep", "--param", "pelvis_excursion=0.6", "--out", str(out)])
    assert code == 2
    assert capsys.readouterr().err == (
        "exo-ctrl sweep: error: pelvis_excursion must be in [0, 0.5] m; got 0.6\n"
    )
    assert not any(tmp_path.iterdir())
