"""The patient's feet on the belt in runs: the law's depth, no pull, the weight shared, off.

References: the contact law at a foot's deepest point (δ̇ = 0 there, so
F_n = k δⁿ: δ_max = (F_n / k)^(1/n) for the force the foot carries then, at
most the peak (F_peak / k)^(1/n)); Coulomb's cone |F_t| ≤ μ F_n; the cycle
average of the vertical momentum's rate (the belt's mean vertical force on
all four feet is the weight the support leaves, M g − F_s, within 2 %).

The runs leave the safety supervisor off: its belt monitor explains the belt's
speed by the drive and the foot plates' load cells, which read the
exoskeleton's feet only, so the patient's feet's friction on the belt is an
unexplained load to it, and it stops the gait (reported, not tested here).
"""

from __future__ import annotations

import numpy as np
import pytest
from rerun.chunk import RrdReader

from exo_ctrl.plan import GaitParams
from exo_ctrl.plant import ContactParams, PelvisParams
from exo_ctrl.record import RerunRecorder, read_recording
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.setup import build

FEET = ContactParams(enabled=True, patient_feet=True)
SIGNALS = (
    "patient_ground_force",
    "patient_foot_slip",
    "patient_foot_penetration",
    "patient_contact_state",
)


def _ramp_in(config: SimConfig) -> int:
    return int(np.ceil(config.ramp_in / config.dt - 1e-9))


@pytest.fixture(scope="module")
def runs() -> dict[str, tuple]:
    out = {}
    for name, contact in (("off", ContactParams(enabled=True)), ("on", FEET)):
        config = SimConfig(controller="ct", contact=contact, safety=False)
        result = simulate(config)
        assert result.status == "completed"
        out[name] = (config, result)
    return out


def _patient_depth(config: SimConfig, result) -> np.ndarray:
    """The patient's foot points' depth below the belt at the end of each tick [m], (n, 2)."""
    feet = build(config).plant.patient_feet
    s = result.signals
    q = np.concatenate((s["q"], s["q_patient"]), axis=1)
    return np.array([feet.penetration(row, z) for row, z in zip(q, s["pelvis_z"], strict=True)])


def test_the_patient_foot_sinks_only_as_deep_as_the_law_gives_for_its_load(runs) -> None:
    config, on = runs["on"]
    _, off = runs["off"]
    start = _ramp_in(config)
    s = on.signals
    k, n = FEET.stiffness_N_per_m_n, FEET.exponent
    state = s["patient_contact_state"][start:]
    depth = s["patient_foot_penetration"][start:]
    fn = s["patient_ground_force"][start:, :, 1]
    sunk = _patient_depth(runs["off"][0], off)[start:]
    for leg, side in enumerate(("left", "right")):
        stance = state[:, leg] > 0.0
        deepest = int(np.argmax(np.where(stance, depth[:, leg], -np.inf)))
        law = (fn[deepest, leg] / k) ** (1.0 / n)
        bound = (fn[stance, leg].max() / k) ** (1.0 / n)
        free = sunk[:, leg].max()
        print(
            f"{side}: deepest {depth[deepest, leg] * 1e3:.3f} mm under {fn[deepest, leg]:.1f} N "
            f"(law {law * 1e3:.3f} mm, at the peak force {bound * 1e3:.3f} mm); "
            f"off: {free * 1e3:.3f} mm"
        )
        assert depth[deepest, leg] == pytest.approx(law, rel=0.02)  # δ̇ ≈ 0 at the deepest
        assert depth[deepest, leg] <= bound * 1.001
        assert depth[deepest, leg] < 0.5 * free  # off, nothing held it up
    summary = on.summary()["patient_feet"]
    np.testing.assert_allclose(
        list(summary["max_penetration_m"].values()),
        np.where(state > 0.0, depth, 0.0).max(axis=0),
        rtol=1e-15,
    )


def test_the_belt_pushes_the_patients_feet_never_pulls_and_friction_stays_in_its_cone(
    runs,
) -> None:
    _, on = runs["on"]
    s = on.signals
    fx, fz = s["patient_ground_force"][..., 0], s["patient_ground_force"][..., 1]
    free = s["patient_contact_state"] == 0.0
    assert np.all(fz >= 0.0)
    assert np.all(fz[s["patient_foot_penetration"] <= 0.0] == 0.0)
    for name in ("patient_ground_force", "patient_foot_slip"):  # nothing off the belt
        assert not np.any(s[name][free]), name
    assert np.all(np.abs(fx) <= FEET.friction_coeff * fz * (1.0 + 1e-12))
    assert np.any(s["patient_contact_state"] == 1.0)  # they stand on the belt (stick) ...
    assert np.all(fz.max(axis=0) > 20.0)  # ... carrying part of the leg's weight


def test_off_the_patients_signals_are_zero_and_the_summary_has_no_block(runs) -> None:
    _, off = runs["off"]
    for name in SIGNALS:
        assert not np.any(off.signals[name]), name
    assert "patient_feet" not in off.summary()


def test_with_body_weight_support_all_four_feet_carry_what_the_harness_leaves() -> None:
    """Supported pelvis at 50 %: the cycle-averaged vertical force of the four feet is M g − F_s."""
    gait = GaitParams(hip_height=1.0, pelvis_excursion=0.05)
    config = SimConfig(
        controller="ct",
        contact=FEET,
        sync=False,
        gait=gait,
        duration_s=4 * gait.period,
        pelvis=PelvisParams(supported=True, bws_fraction=0.5),
        safety=False,
    )
    result = simulate(config)
    assert result.status == "completed"
    p = result.summary()["pelvis"]
    s = result.signals
    start = _ramp_in(config)
    end = start + p["averaged_ticks"]
    exo = s["ground_force"][start:end, :, 1].sum(axis=1).mean()
    pat = s["patient_ground_force"][start:end, :, 1].sum(axis=1).mean()
    print(
        f"\nmean vertical force: exoskeleton's feet {exo:.1f} N, patient's {pat:.1f} N, "
        f"together {p['mean_vertical_ground_force_N']:.1f} N; M g − F_s "
        f"{p['unsupported_weight_N']:.1f} N"
    )
    assert p["mean_vertical_ground_force_N"] == pytest.approx(exo + pat, rel=1e-12)
    assert p["mean_harness_stop_force_N"] == 0.0
    assert p["mean_vertical_ground_force_N"] == pytest.approx(p["unsupported_weight_N"], rel=0.02)
    assert pat > 0.05 * p["unsupported_weight_N"]  # the patient's feet took a real share


def test_the_patients_feet_are_recorded_and_read_back(tmp_path) -> None:
    path = tmp_path / "run.rrd"
    config = SimConfig(duration_s=0.3, ramp_in_s=0.0, controller="ct", contact=FEET, safety=False)
    live = simulate(config, observers=[RerunRecorder(path)])
    back = read_recording(path)
    for name in SIGNALS:
        np.testing.assert_array_equal(back.signals[name], live.signals[name])
    assert back.summary()["patient_feet"] == live.summary()["patient_feet"]
    entities = {c.entity_path for c in RrdReader(str(path)).stream().to_chunks()}
    assert {"/world/patient_ground_force/left", "/world/patient_ground_force/right"} <= entities
