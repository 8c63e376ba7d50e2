"""The fused tick (exo_ctrl/sim/fused.py) is the stage-by-stage tick, bit for bit.

Each case runs one configuration twice, fused and stage by stage
(``Runner(setup, fuse=False)``), tick for tick, and compares every log row's
bytes, the plant's state and the supervisor's events: the default scenario
(PD on the belt, synchronised plan, Kalman filter, supervisor), PD and CT
with the pelvis fixed and no belt, CT on the belt's precomputed plan, the
pelvis supported, the patient's feet on the belt, a run without the
supervisor; and the branches where a composed call stops and the tick goes
on stage by stage: the supervisor's stop (an e-stop; with the pelvis
supported its lock and the belt's run-down), a drive at its current limit
(the plant kicks again), a tick that fails.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from exo_ctrl import SimConfig
from exo_ctrl.control import PDGains
from exo_ctrl.exceptions import ExoCtrlError
from exo_ctrl.plant import ContactParams, PelvisParams
from exo_ctrl.scenario.load import load_scenario
from exo_ctrl.sim import Runner, build
from exo_ctrl.sim.faults import Fault
from exo_ctrl.sim.fused import FusedTick

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the golden runs' set-up, beside

from test_golden import LEGACY
from test_golden import SCENARIOS as GOLDEN

BELT = ContactParams(enabled=True)

CASES = {
    "default": load_scenario().config,
    "pd": SimConfig(controller="pd"),
    "ct": SimConfig(controller="ct"),
    "ct-belt-precomputed": SimConfig(controller="ct", contact=BELT, sync=False),
    "pelvis-supported": SimConfig(
        controller="ct",
        contact=BELT,
        sync=False,
        pelvis=PelvisParams(supported=True, bws_fraction=0.5),
    ),
    "patient-feet": SimConfig(contact=ContactParams(enabled=True, patient_feet=True)),
    # CT's row on the synchronised plan: two calls around its feedforward's RNEA
    "ct-synchronised": SimConfig(controller="ct", contact=BELT, sync=True),
    "clinic-bws": load_scenario(preset="clinic-bws").config,
    # the supervisor stops, the harness locks the pelvis, the belt runs down
    "pelvis-e-stop": SimConfig(
        contact=BELT, pelvis=PelvisParams(supported=True, bws_fraction=0.4), estop_at_s=1.5
    ),
    "no-supervisor": SimConfig(controller="ct", safety=False),
    "e-stop": SimConfig(controller="ct", estop_at_s=0.5, duration_s=1.5),
    # gains ten times the default's: drives at their current limit
    "current-limit": SimConfig(controller="pd", gains=PDGains(kp=3000.0, kd=20.0)),
    # the momentum observer: its library calls on this tick's readings, after the read
    "momentum": SimConfig(controller="ct", estimator="momentum"),
    "momentum-belt": SimConfig(controller="pd", estimator="momentum", contact=BELT),
}


def _twins(config: SimConfig) -> tuple[Runner, Runner]:
    fused, staged = Runner(build(config)), Runner(build(config), fuse=False)
    assert fused.fused is not None and staged.fused is None
    return fused, staged


def _run_both(config: SimConfig, kicked: list[bool] | None = None) -> tuple[Runner, Runner]:
    fused, staged = _twins(config)
    plant = fused.setup.plant
    if kicked is not None:  # each kick the fused tick left to the plant: a drive at its limit?
        own = plant.kicked

        def counted(status: int) -> None:
            kicked.append(bool(plant.record["resolve"][0]))
            own(status)

        plant.kicked = counted
    for start in range(0, config.n_ticks, fused.chunk):
        rows = min(fused.chunk, config.n_ticks - start)
        for i in range(rows):
            fused.tick(start + i, i)
            staged.tick(start + i, i)
        assert fused.log[:rows].tobytes() == staged.log[:rows].tobytes(), f"ticks from {start}"
    return fused, staged


@pytest.mark.parametrize("case", list(CASES))
def test_the_fused_tick_logs_what_the_stages_log(case: str) -> None:
    config = CASES[case]
    kicked: list[bool] = []
    fused, staged = _run_both(config, kicked)
    a, b = fused.setup.plant, staged.setup.plant
    assert np.array_equal(a.q, b.q) and np.array_equal(a.v, b.v) and a.t == b.t
    if fused.supervisor is not None:
        assert fused.supervisor.events == staged.supervisor.events
        assert fused.supervisor.state == staged.supervisor.state
    if case in ("e-stop", "pelvis-e-stop"):  # the stop's branch was taken
        assert fused.supervisor.state != "normal"
    if case == "current-limit":  # the plant's kick again was taken
        assert any(kicked)


@pytest.mark.parametrize("name", ["pd", "ct", "pd_estop", "ct_estop"])
def test_the_golden_runs_are_the_same_fused(name: str) -> None:
    """The golden PD and CT runs (the momentum observer; test_golden.py holds them to the
    stored runs stage by stage or fused, whichever a run uses) fused and stage by stage."""
    fused, staged = _run_both(SimConfig(**LEGACY, **GOLDEN[name][0]))
    assert np.array_equal(fused.setup.plant.q, staged.setup.plant.q)


def test_a_tick_that_fails_fails_as_the_stages_do() -> None:
    """A non-finite state under the sensors: the same error, the same rows before it."""
    config = SimConfig(controller="pd", duration_s=0.2)
    errors = []
    runners = _twins(config)
    for runner in runners:
        for k in range(50):
            runner.tick(k, k)
        runner.setup.plant.q[1] = np.nan
        with pytest.raises(ExoCtrlError) as info:
            for k in range(50, 60):
                runner.tick(k, k)
        errors.append((type(info.value), str(info.value), k))
    assert errors[0] == errors[1]
    assert runners[0].log[:60].tobytes() == runners[1].log[:60].tobytes()


@pytest.mark.parametrize(
    "change",
    [
        {"controller": "qp"},
        {"faults": (Fault("encoder_freeze", 0.1, "left_knee"),)},
        {"patient_torque": "spastic"},
    ],
    ids=["qp", "faults", "patient-model"],
)
def test_a_configuration_not_covered_runs_stage_by_stage(change: dict) -> None:
    config = dataclasses.replace(SimConfig(duration_s=0.3), **change)
    assert FusedTick.of(Runner(build(config))) is None
