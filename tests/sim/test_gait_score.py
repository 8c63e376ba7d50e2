"""Gait Variable Scores and the Gait Profile Score (Baker et al. 2009) against normative gait.

The default run's figure is printed (pytest -s) and recomputed here
independently: the legs' initial contacts found from the planned foot path,
the angles resampled by linear interpolation, the normative file read with
numpy.
"""

from __future__ import annotations

import functools
import math
import sys
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.plan.gait import GaitPlan
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.gait_score import (
    GAIT_POINTS,
    NORMATIVE_FILE,
    contact_offsets,
    gait_profile_score,
    gait_variable_scores,
    load_normative,
)

ROOT = Path(__file__).resolve().parents[2]


def _raw_normative() -> dict[str, np.ndarray]:
    path = ROOT / "exo_ctrl" / "data" / NORMATIVE_FILE
    lines = [line for line in path.read_text().splitlines() if not line.startswith("#")]
    table = np.genfromtxt(lines, delimiter=",", names=True)
    return {name: table[name] for name in table.dtype.names}


def test_normative_loads_from_the_package_with_its_shape_and_units():
    data = resources.files("exo_ctrl").joinpath("data", NORMATIVE_FILE)
    assert data.is_file()
    norm = load_normative()
    assert norm.percent.shape == (GAIT_POINTS,)
    np.testing.assert_array_equal(norm.percent, np.arange(0, 101, 2))
    assert norm.mean_deg.shape == (GAIT_POINTS, 2) and norm.sd_deg.shape == (GAIT_POINTS, 2)
    assert norm.per_joint().shape == (GAIT_POINTS, 4)
    # Degrees, this project's convention: thigh from the vertical swings about
    # 40 deg (Winter 2009: about -10..+25 deg), knee flexion peaks near 60 deg
    # in early swing (about 70 % of the cycle) and is lowest near 40 %.
    thigh, knee = norm.mean_deg.T
    assert 30 < thigh.max() - thigh.min() < 50
    assert thigh.min() < -5 and 20 < thigh.max() < 30
    assert 55 < knee.max() < 70 and 64 <= norm.percent[np.argmax(knee)] <= 76
    assert 0 <= knee.min() < 10
    # The stated conversion: thigh = hip flexion (relative to the pelvis) - anterior pelvic tilt.
    raw = _raw_normative()
    np.testing.assert_allclose(thigh, raw["hip_flexion_mean_deg"] - raw["pelvic_tilt_mean_deg"])
    np.testing.assert_allclose(knee, raw["knee_flexion_mean_deg"])
    assert "Schwartz" in norm.source


@pytest.mark.skipif(sys.version_info < (3, 11), reason="tomllib")
def test_the_data_file_is_declared_as_package_data():
    import fnmatch

    import tomllib

    conf = tomllib.loads((ROOT / "pyproject.toml").read_text())
    patterns = conf["tool"]["setuptools"]["package-data"]["exo_ctrl"]
    assert any(fnmatch.fnmatch(f"data/{NORMATIVE_FILE}", p) for p in patterns)


def test_scores_of_the_normative_mean_and_of_a_shifted_mean():
    mean = load_normative().per_joint()
    np.testing.assert_allclose(gait_variable_scores(mean, mean), 0.0, atol=1e-12)
    assert gait_profile_score(gait_variable_scores(mean, mean)) == pytest.approx(0.0, abs=1e-12)
    for c in (-7.5, 3.0, 20.0):
        gvs = gait_variable_scores(mean + c, mean)
        np.testing.assert_allclose(gvs, abs(c), rtol=1e-12)
        assert gait_profile_score(gvs) == pytest.approx(abs(c), rel=1e-12)
    shifts = np.array([1.0, -2.0, 3.0, -4.0])
    gvs = gait_variable_scores(mean + shifts, mean)
    np.testing.assert_allclose(gvs, np.abs(shifts), rtol=1e-12)
    assert gait_profile_score(gvs) == pytest.approx(math.sqrt(np.mean(shifts**2)), rel=1e-12)


def test_scores_refuse_other_shapes():
    mean = load_normative().per_joint()
    with pytest.raises(InvalidParameter, match=r"angles_deg must be \(51, m\)"):
        gait_variable_scores(mean[:50], mean[:50])


@pytest.mark.parametrize("ramp_in", [1.2, 0.9, 0.0])
def test_contact_offsets_are_the_planned_touchdowns(ramp_in):
    config = SimConfig(ramp_in_s=ramp_in, duration_s=ramp_in + 2.4)
    lead = math.ceil(ramp_in / config.dt - 1e-9)
    plan, g = GaitPlan(config.gait), config.gait
    for leg, offset in enumerate(contact_offsets(config, lead)):
        assert 0.0 <= offset < g.period / config.dt
        feet = plan.feet((lead + offset) * config.dt + np.array([-1e-6, 1e-6]))
        # point B: the foot arrives at x = s/2 on the belt line, and stance begins
        np.testing.assert_allclose(feet.pos[:, leg, 0], g.step_length / 2, atol=1e-5)
        np.testing.assert_allclose(feet.pos[:, leg, 1], -g.hip_height, atol=1e-5)
        assert not feet.stance[0, leg] and feet.stance[1, leg]


@functools.cache
def _default():
    config = SimConfig()
    return config, simulate(config)


def _independent_gps(config, q: np.ndarray) -> list[float]:
    """GPS per cycle: touchdowns from the planned foot path, linear resampling."""
    raw = _raw_normative()
    norm = np.column_stack(
        [raw["hip_flexion_mean_deg"] - raw["pelvic_tilt_mean_deg"], raw["knee_flexion_mean_deg"]]
    )
    dt, period = config.dt, config.gait.period
    t = np.arange(q.shape[0]) * dt
    stance = GaitPlan(config.gait).feet(t).stance
    start = config.ramp_in
    out = []
    for c in range(round((t[-1] + dt - start) / period)):
        t0 = start + c * period
        window = (t >= t0 - 1e-9) & (t < t0 + period - 1e-9)
        sq = []
        for leg in range(2):
            # the touchdown: the tick the planned foot's stance begins
            st = stance[window, leg]
            t_td = t[window][np.flatnonzero(st & ~np.roll(st, 1))[0]]
            pts = t0 + np.mod(t_td - t0 + np.linspace(0.0, period, GAIT_POINTS), period)
            for j in range(2):
                angle = np.degrees(np.interp(pts, t[window], q[window, 2 * leg + j]))
                sq.append(np.mean((angle - norm[:, j]) ** 2))
        out.append(math.sqrt(np.mean(sq)))
    return out


def test_default_run_gps_is_recomputed_from_the_logged_angles():
    config, result = _default()
    summary = result.summary()
    gps = summary["gait_profile_score_deg"]
    cycles = summary["gait_profile_score_cycles"]
    print(
        f"\ndefault run GPS: planned {gps['planned']:.2f} deg, actual {gps['actual']:.2f} deg; "
        f"GVS actual {summary['gait_variable_scores_deg']['actual']}"
    )
    assert [c["cycle"] for c in cycles] == [0, 1]
    for kind, signal in (("planned", "q_des"), ("actual", "q_patient")):
        independent = _independent_gps(config, result.signals[signal])
        got = [c[kind] for c in cycles]
        np.testing.assert_allclose(got, independent, atol=0.05)
        pooled = math.sqrt(np.mean(np.square(got)))  # equal GVS weights per cycle
        assert gps[kind] == pytest.approx(pooled, abs=0.05)
    # the crouch: knees 54-78 deg all cycle long against a normative 4-60 deg
    knee = summary["gait_variable_scores_deg"]["actual"]["left_knee"]
    assert knee > 30.0
    assert gps["actual"] > 20.0


def test_no_score_without_a_complete_cycle():
    config = SimConfig(duration_s=1.5)
    summary = simulate(config).summary()
    assert summary["gait_profile_score_deg"] == {"planned": None, "actual": None}
    assert summary["gait_profile_score_cycles"] == []
