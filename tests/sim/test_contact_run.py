"""Runs on the belt: slip and touchdown measured, PD against CT, stability at the default step.

The figures are the run's own measurements (the contact's slip relative to
the moving belt, the foot's velocity at touchdown), over the gait cycles
after the ramp-in; the energy is the plant's mechanical energy with the
contact springs and the belt.
"""

from __future__ import annotations

import numpy as np
import pytest
from rerun.chunk import RrdReader

from exo_ctrl.plant import ContactParams
from exo_ctrl.record import RerunRecorder, read_recording
from exo_ctrl.sim import SimConfig, simulate
from exo_ctrl.sim.setup import build
from exo_ctrl.sim.tick import Runner

ON = ContactParams(enabled=True)
KEYS = (
    "slip_speed_rms_mps",
    "slip_speed_max_mps",
    "touchdown_speed_mps",
    "touchdown_slip_mps",
    "peak_normal_force_rate_N_per_s",
    "belt_speed_error_rms_mps",
)


@pytest.fixture(scope="module")
def runs() -> dict[str, dict]:
    out = {}
    for controller in ("ct", "pd"):
        result = simulate(SimConfig(controller=controller, contact=ON))
        assert result.status == "completed"
        out[controller] = result.summary()
    return out


def test_ct_keeps_the_feet_on_the_belt_without_slip_or_impact(runs) -> None:
    for controller, s in runs.items():
        figures = ", ".join(f"{k} {s[k]:.4g}" for k in KEYS)
        print(f"{controller}: {figures}, peak ground force {s['peak_ground_force_N']}")
    ct, pd = runs["ct"], runs["pd"]
    assert ct["touchdown_count"] >= 4  # two cycles after the ramp-in, both feet
    assert ct["slip_speed_rms_mps"] < 0.01
    assert ct["touchdown_speed_mps"] < 0.02
    assert ct["belt_speed_error_rms_mps"] < 0.002
    # PD lands harder: the touchdown speed and the force's rate several times CT's
    assert pd["touchdown_speed_mps"] > 3.0 * ct["touchdown_speed_mps"]
    assert pd["peak_normal_force_rate_N_per_s"] > 5.0 * ct["peak_normal_force_rate_N_per_s"]
    assert min(pd["peak_ground_force_N"].values()) > 5.0 * max(ct["peak_ground_force_N"].values())


def test_the_default_run_with_contact_is_stable_at_1_ms() -> None:
    config = SimConfig(controller="ct", contact=ON)
    runner = Runner(build(config))
    plant = runner.setup.plant
    energy, speed, depth = [], [], []
    for k in range(config.n_ticks):
        runner.tick(k, k % runner.chunk)
        if k % 50 == 0:
            energy.append(plant.mechanical_energy())
            speed.append(np.max(np.abs(plant.v)))
            depth.append(np.max(plant.contact.penetration(plant.q)))
    energy = np.array(energy)
    print(f"mechanical energy in [{energy.min():.2f}, {energy.max():.2f}] J")
    print(f"peak joint speed {max(speed):.2f} rad/s, deepest foot {max(depth) * 1e3:.3f} mm")
    assert np.all(np.isfinite(energy))
    assert energy.max() - energy.min() < 100.0
    assert max(speed) < 5.0
    assert max(depth) < 1e-3
    b = plant.contact.belt[0]
    assert abs(b["v"] - config.gait.belt_speed) < 0.01


def test_without_contact_the_belt_signals_are_zero_and_with_it_recorded(tmp_path) -> None:
    off = simulate(SimConfig(duration_s=0.2))
    for name in ("ground_force", "foot_slip", "contact_state", "belt_speed", "belt_speed_meas"):
        assert not np.any(off.signals[name]), name
    assert "slip_speed_rms_mps" not in off.summary()
    path = tmp_path / "run.rrd"
    config = SimConfig(duration_s=0.3, ramp_in_s=0.0, controller="pd", contact=ON)
    on = simulate(config, observers=[RerunRecorder(path)])
    assert np.any(on.signals["ground_force"][:, :, 1] > 0.0)
    np.testing.assert_allclose(
        on.signals["belt_speed_meas"][20:], config.gait.belt_speed, atol=0.01
    )
    entities = {c.entity_path for c in RrdReader(str(path)).stream().to_chunks()}
    assert {"/world/ground_force/left", "/world/ground_force/right"} <= entities
    # The summary rebuilt from the recording has the live run's contact figures.
    back = read_recording(path).summary()
    live = on.summary()
    for key in ("slip_speed_rms_mps", "touchdown_speed_mps", "peak_ground_force_N"):
        assert back[key] == pytest.approx(live[key], rel=1e-12, abs=1e-15), key
