"""The patient's feet on the belt, with the safety supervisor on.

Before the shoes' load cells (sensing/foot_load.py) the belt monitor took the patient's
feet's friction on the belt (up to 99 N, PD) for a fault and stopped the healthy default
run at its first touchdown (0.87 s, 0.039 m/s against 0.0148 m/s); the patient-load monitor
read the shank cuffs as unloaded (α = −1.08 and 0.05).  Now the belt monitor adds the shoes'
friction to the forces it knows, and a real fault, a belt stop, is still caught within its
bound.  The patient's foot sinks into the belt only as far as the sole's law gives under the
force it carries.
"""

from __future__ import annotations

import dataclasses
import math

import pytest

from exo_ctrl.safety.belt_monitor import BELT_DEVIATION_MPS, threshold_mps
from exo_ctrl.scenario import load_scenario
from exo_ctrl.sim import simulate
from exo_ctrl.sim.faults import Fault

QUANTITY = "belt speed deviation"


def with_feet(controller: str = "pd", **kw):
    """The default scenario (preset paper: belt on, pelvis fixed, safety on) with the
    patient's feet on the belt."""
    overrides = ["contact.patient_feet=true", f"run.controller={controller}"]
    config = load_scenario(preset="paper", overrides=overrides).config
    assert config.safety and config.contact.patient_feet
    return dataclasses.replace(config, **kw)


def test_the_healthy_default_run_with_the_patients_feet_runs_with_the_supervisor_on() -> None:
    """2 cycles after the ramp-in: no stop and no event at all; the patient's feet carry
    load (> 50 N), and their deepest point in contact is at most the sole's sink under the
    largest force they carried, (F_max / k)^(1/n) (at the deepest point δ̇ = 0, where the
    Hunt–Crossley force is k δⁿ)."""
    config = with_feet()
    result = simulate(config)
    assert result.status == "completed"
    assert result.safety_state == "normal"
    summary = result.summary()
    assert summary["safety_events"] == []
    feet = summary["patient_feet"]
    law = config.contact
    for side in ("left", "right"):
        force = feet["peak_ground_force_N"][side]
        depth = feet["max_penetration_m"][side]
        sole = (force / law.stiffness_N_per_m_n) ** (1.0 / law.exponent)
        print(f"{side}: peak {force:.1f} N, deepest {1e3 * depth:.2f} mm, sole {1e3 * sole:.2f} mm")
        assert force > 50.0
        assert 0.0 < depth <= sole


@pytest.mark.parametrize("controller", ["ct", "qp"])
def test_no_false_stop_with_ct_or_qp(controller) -> None:
    """CT and QP on the same scenario: the supervisor stays normal and the belt monitor
    never trips (CT's patient-load monitor may still warn: the warning is no stop).  The QP
    at the default scenario's bound, 200 N on the thighs and 120 N on the shanks, which
    leaves the gait's load (tests/control/qp/test_closed_loop.py)."""
    result = simulate(with_feet(controller))
    assert result.status == "completed"
    assert result.safety_state == "normal"
    assert [e for e in result.events if e.get("quantity") == QUANTITY] == []
    assert [e for e in result.events if e.get("kind") not in ("warning", None)] == []


def test_a_belt_stop_is_still_caught_with_the_patients_feet() -> None:
    """A belt stop at 2.0 s (the drive's 1000 N on the 20 kg belt): tripped within 14 ms, the
    bound of tests/safety/test_belt_monitor_load.py, and the device holds."""
    result = simulate(with_feet(faults=(Fault("belt_stop", 2.0),), duration_s=2.3))
    trips = [e for e in result.events if e.get("quantity") == QUANTITY]
    assert trips, result.events
    assert 0.0 < trips[0]["t"] - 2.0 <= 0.014 + 1e-9
    assert result.safety_state == "holding"


def test_the_threshold_counts_the_shoes_noise() -> None:
    """Four feet read: the noise term grows by √4/√2, the rest is unchanged."""
    n, dt, res, sigma, mass, limit = 10, 1e-3, 3.8e-5, 2.0, 20.0, 1000.0
    two = threshold_mps(n, dt, res, sigma, mass, limit)
    four = threshold_mps(n, dt, res, sigma, mass, limit, feet=4)
    g2 = sum((s - 0.5) ** 2 for s in range(1, n + 1)) * 2.0
    sigma_r = dt / n * math.sqrt(g2) * sigma / mass
    assert two == pytest.approx(BELT_DEVIATION_MPS, rel=1e-12)
    assert four - two == pytest.approx(6.0 * sigma_r * (2.0 - math.sqrt(2.0)), rel=1e-9)
