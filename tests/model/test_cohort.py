"""The virtual cohort: seeded, spread as stated, physical, and written by the CLI.

The spreads are checked against the module's statement: each parameter over
its nominal value is 1 + s z with z a standard normal truncated at ±2.5, so
its sample standard deviation estimates s σ_t, σ_t = 0.9546 (computed here
independently from the normal's density and distribution).  The sample
standard deviation of N draws has a relative standard error below
1 / √(2 (N - 1)) (the normal's; the truncated normal has the lighter tails,
kurtosis below 3); the tolerance is four of those.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy import stats

from exo_ctrl import cli
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import (
    BodyParams,
    CohortSpread,
    benchmark_cohort,
    draw_cohort,
    fitted_exo,
    load_body,
    patient_from_anthropometry,
    write_urdf,
)
from exo_ctrl.model.cohort import TRUNCATION_Z, truncated_sd

FIELDS = ("length", "mass", "com_ratio", "gyration_ratio", "radius")


def _ratios(cohort: list[BodyParams], nominal: BodyParams, field: str) -> np.ndarray:
    return np.array([getattr(p, field) / getattr(nominal, field) for p in cohort])


def test_the_truncated_normals_spread_agrees_with_scipy() -> None:
    z = TRUNCATION_Z
    assert truncated_sd(z) == pytest.approx(stats.truncnorm(-z, z).std(), rel=1e-12)
    assert truncated_sd(z) == pytest.approx(0.9546, abs=5e-5)


def test_a_cohort_is_deterministic_per_seed_and_differs_across_seeds() -> None:
    a, b = draw_cohort(5, 7, 1.7, 70.0, "female"), draw_cohort(5, 7, 1.7, 70.0, "female")
    assert a == b
    assert draw_cohort(3, 7, 1.7, 70.0, "female") == a[:3]  # patient i whatever n > i
    c = draw_cohort(5, 8, 1.7, 70.0, "female")
    assert all(p.thigh_mass != q.thigh_mass for p, q in zip(a, c, strict=True))
    assert benchmark_cohort(4, 3) == benchmark_cohort(4, 3)
    assert benchmark_cohort(4, 3)[0].height_m != benchmark_cohort(4, 4)[0].height_m


def test_the_drawn_spreads_are_the_stated_ones() -> None:
    n = 4000
    spread = CohortSpread()
    nominal = patient_from_anthropometry(1.75, 80.0, "male")
    cohort = draw_cohort(n, 0, 1.75, 80.0, "male", spread)
    tolerance = 4.0 / math.sqrt(2.0 * (n - 1))  # relative, four standard errors
    for seg in ("thigh", "shank"):
        for name in FIELDS:
            r = _ratios(cohort, nominal, f"{seg}_{name}")
            expected = getattr(spread, name) * truncated_sd()
            cv = r.std(ddof=1)
            print(f"{seg} {name}: sample CV {cv:.4f}, stated {expected:.4f}")
            assert cv == pytest.approx(expected, rel=tolerance)
            # the mean factor is 1 (a symmetric truncation): within 4 standard errors
            assert abs(r.mean() - 1.0) < 4.0 * expected / math.sqrt(n)
            # every factor within the stated bounds 1 ± z_max s
            assert np.all(np.abs(r - 1.0) <= TRUNCATION_Z * getattr(spread, name) + 1e-12)
    # the cuffs keep the nominal's fractions of the drawn links
    for p in cohort[:50]:
        assert p.thigh_cuff / p.thigh_length == pytest.approx(
            nominal.thigh_cuff / nominal.thigh_length, rel=1e-12
        )


def test_a_zero_spread_gives_the_nominal_patient() -> None:
    zero = CohortSpread(length=0, mass=0, com_ratio=0, gyration_ratio=0, radius=0)
    nominal = patient_from_anthropometry(1.75, 80.0, "male")
    for p in draw_cohort(3, 1, 1.75, 80.0, "male", zero):
        for field in ("thigh_mass", "shank_mass", "thigh_length", "shank_gyration_ratio"):
            assert getattr(p, field) == pytest.approx(getattr(nominal, field), rel=1e-15)
    # de Leva's male thigh and leg + foot, 14.16 % and 5.70 % of 80 kg (Table 4)
    assert nominal.thigh_mass == pytest.approx(0.1416 * 80.0, rel=0.01)
    assert nominal.shank_mass == pytest.approx((0.0433 + 0.0137) * 80.0, rel=0.01)


def test_every_patient_of_the_benchmark_loads_with_the_projects_checks(tmp_path: Path) -> None:
    """Masses > 0 and pseudo-inertias positive definite, in the written URDF, exo fitted."""
    cohort = benchmark_cohort(20, 0)
    for p in cohort:
        assert 1.55 <= p.height_m <= 1.95
        assert 50.0 <= p.mass_kg <= 110.0
        assert 18.5 - 1e-9 <= p.mass_kg / p.height_m**2 <= 35.0 + 1e-9
        assert math.hypot(*p.knee_misalignment_xz) <= 0.03
        body = load_body(write_urdf(p.params, tmp_path / f"p{p.index}.urdf"), name="patient")
        model = body.model
        for j in range(1, model.njoints):
            inertia = model.inertias[j]
            assert inertia.mass > 0.0
            assert np.all(np.linalg.eigvalsh(inertia.toPseudoInertia().toMatrix()) > 0.0)
        exo = load_body(write_urdf(fitted_exo(p.params), tmp_path / "exo.urdf"), name="exo")
        assert exo.legs["left"].thigh_length == pytest.approx(p.params.thigh_length, rel=1e-9)
        assert exo.legs["left"].shank_length == pytest.approx(p.params.shank_length, rel=1e-9)
        # the cuff frames coincide with the patient's at q = 0 (coaxial joints, same places)
        for name in ("left_thigh_cuff", "left_shank_cuff"):
            np.testing.assert_allclose(
                exo.frame_position(np.zeros(4), name),
                body.frame_position(np.zeros(4), name),
                atol=1e-9,
            )


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"n": 0}, "n must be an integer in [1, 10000]; got 0"),
        ({"n": 2.0}, "n must be an integer in [1, 10000]; got 2.0"),
        ({"seed": -1}, "seed must be an integer >= 0; got -1"),
        ({"seed": True}, "seed must be an integer >= 0; got True"),
    ],
)
def test_bad_counts_are_refused(kwargs: dict, message: str) -> None:
    args = {"n": 2, "seed": 0, "height_m": 1.7, "mass_kg": 70.0, **kwargs}
    with pytest.raises(InvalidParameter) as info:
        draw_cohort(**args)
    assert str(info.value) == message


def test_a_spread_beyond_the_bound_is_refused() -> None:
    with pytest.raises(InvalidParameter) as info:
        CohortSpread(mass=0.3)
    assert str(info.value) == "spread.mass must be in [0, 0.2]; got 0.3"


def test_the_cli_writes_the_cohort(tmp_path: Path, capsys) -> None:
    argv = ["urdf", "--kind", "patient", "--height", "1.68", "--mass", "62", "--sex", "female"]
    assert cli.main([*argv, "--cohort", "3", "--seed", "5", "--out", str(tmp_path)]) == 0
    expected = draw_cohort(3, 5, 1.68, 62.0, "female")
    for i, params in enumerate(expected):
        body = load_body(tmp_path / f"patient_s5_{i:03d}.urdf", name="patient")
        knee = body.model.getJointId("left_knee")
        assert body.model.inertias[knee].mass == pytest.approx(params.shank_mass, rel=1e-9)
        assert body.legs["left"].thigh_length == pytest.approx(params.thigh_length, rel=1e-9)
    assert "patient_s5_002.urdf" in capsys.readouterr().out
    pattern = str(tmp_path / "p{i:02d}.urdf")
    assert cli.main([*argv, "--cohort", "2", "--out", pattern]) == 0  # seed 0 by default
    assert (tmp_path / "p01.urdf").read_text() == (
        write_urdf(draw_cohort(2, 0, 1.68, 62.0, "female")[1], tmp_path / "ref.urdf").read_text()
    )


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--cohort", "0"], "--cohort must be an integer in [1, 10000]; got 0"),
        (["--cohort", "2", "--seed", "-3"], "--seed must be an integer >= 0; got -3"),
        (["--seed", "4"], "--seed must be given with --cohort only; got 4"),
        (["--cohort", "2", "--thigh-mass", "9"],
         "--thigh-mass must be unset with --cohort; got 9.0 (the cohort draws the segments)"),
        (["--cohort", "2", "--out", "OUT/one.urdf"],
         "--out must be an existing directory or a file pattern with {i} "
         "(e.g. cohort/p{i:02d}.urdf); got 'OUT/one.urdf' (--cohort writes one file per patient)"),
        (["--cohort", "2", "--out", "OUT/missing/p{i}.urdf"],
         "--out must be a writable file in an existing directory; got 'OUT/missing/p0.urdf' "
         "(directory OUT/missing does not exist)"),
    ],
)  # fmt: skip
def test_cli_bad_cohorts_exit_2_with_one_line(
    tmp_path: Path, capsys, argv: list, message: str
) -> None:
    argv = [a.replace("OUT", str(tmp_path)) for a in argv]
    if "--out" not in argv:
        argv += ["--out", str(tmp_path)]
    base = ["urdf", "--kind", "patient", "--height", "1.7", "--mass", "70"]
    assert cli.main([*base, *argv]) == 2
    assert (
        capsys.readouterr().err
        == f"exo-ctrl urdf: error: {message.replace('OUT', str(tmp_path))}\n"
    )
    assert not list(tmp_path.iterdir())  # nothing written


def test_cli_cohort_needs_a_patient_of_height_and_mass(tmp_path: Path, capsys) -> None:
    assert cli.main(["urdf", "--kind", "exo", "--cohort", "2", "--out", str(tmp_path)]) == 2
    assert capsys.readouterr().err == (
        "exo-ctrl urdf: error: --cohort must be given with --kind patient only; got 2\n"
    )
    assert cli.main(["urdf", "--kind", "patient", "--cohort", "2", "--out", str(tmp_path)]) == 2
    assert capsys.readouterr().err == (
        "exo-ctrl urdf: error: --height must be a stature [m] given with --cohort; got None\n"
    )
