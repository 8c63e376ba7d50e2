"""A hold the patient pushes against ramps to the yield (safety/supervisor.py).

An active patient who prefers 1.0 s, 0.30 m steps walks against tracking's
1.2 s, 0.35 m plan until a thigh cuff reaches its 220 N limit: a true stop
(the device holds the published split cuff model, so its estimate is right).
The hold then meets a patient who keeps walking: a cuff over its limit while
holding.  The supervisor yields, and the true forces come back within the
limits; a passive patient's hold is unchanged (tests/sim/test_faults_injection.py,
tests/sim/test_golden.py).
"""

from __future__ import annotations

import numpy as np

from exo_ctrl import SimConfig, simulate
from exo_ctrl.plant import CuffParams
from exo_ctrl.plant.patient_active import ActiveParams
from exo_ctrl.sim.belief import Belief

THIGH, SHANK = 220.0, 130.0  # ISO/TS 15066, the supervisor's defaults


def test_a_patient_pushing_against_the_hold_gets_the_yield() -> None:
    config = SimConfig(
        patient_torque="active",
        patient_active=ActiveParams(period_s=1.0, step_length_m=0.30),
        duration_s=6.0,
        belief=Belief(cuffs=CuffParams()),
    )
    result = simulate(config)
    states = [e["value"] for e in result.events if e["kind"] == "state"]
    messages = [e["message"] for e in result.events if e["kind"] == "state"]
    assert states[:3] == ["stopping", "holding", "stopping"], messages
    assert "the patient pushes against the hold: ramp to yield" in messages[2]
    assert result.safety_state == "yielding"
    s, t = result.signals, result.t
    force = np.linalg.norm(s["cuff_force"], axis=-1)
    switch = next(
        e["t"] for e in result.events if e["kind"] == "state" and e["value"] == "yielding"
    )
    late = t > switch + 0.5  # half a second into the yield
    print(
        f"\nyield from {switch:.3f} s: worst true thigh/shank after it "
        f"{force[late][:, 0::2].max():.1f} / {force[late][:, 1::2].max():.1f} N"
    )
    assert force[late][:, 0::2].max() < THIGH and force[late][:, 1::2].max() < SHANK
