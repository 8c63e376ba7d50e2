"""A hold the patient pushes against yields at once, before a cuff passes its estimated limit.

The patient: active, their own 0.30 m steps against tracking's 1.2 s, 0.35 m
plan, on a device that holds the published split cuff model (its estimate
right: a true stop).  With the default reflex (hip 100, knee 30 N·m/rad)
the healthy patient no longer loads a hold to its limits (its damping acts
at once: :mod:`exo_ctrl.plant.patient_active`; an emergency stop at 0.5 s
holds them within 140/115 N).  A patient with 2.5× the reflex stiffness
(250/75 N·m/rad) does: an emergency stop at 0.5 s, the hold from 0.7 s, and
the limb loads the cuffs.  The supervisor yields at once when a release
would still keep every cuff within its limit (safety/release.py: |f|² +
ḟᵀ Λ ḟ / k, the catch-up of the exoskeleton's link with the limb).

What holds and what does not (measured, printed with pytest -s): the yield
comes on the release bound, before the estimate reaches a limit; but a
patient this strong keeps accelerating the released limb, and the true
forces after the yield reach 186/191 N against the 220/130 N limits: the
bound counts the catch-up, not a patient who keeps pushing.  That part is
kept as a strict expected failure until the release bound accounts for it.

A passive patient's hold is unchanged (tests/sim/test_faults_injection.py,
tests/sim/test_golden.py).
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from exo_ctrl import SimConfig, simulate
from exo_ctrl.plant import CuffParams
from exo_ctrl.plant.patient_active import ActiveParams
from exo_ctrl.sim.belief import Belief

THIGH, SHANK = 220.0, 130.0  # ISO/TS 15066, the supervisor's defaults
#: Reflex stiffness K_p [N·m/rad] (hips, knees) of the patients who push.
STRONG = (250.0, 250.0, 75.0, 75.0)
FIRM = (200.0, 200.0, 60.0, 60.0)


def _walking_on(period_s: float, duration_s: float, stiffness, estop_at_s=None):
    """The active patient's own 0.30 m steps at ``period_s`` against tracking's plan, on a
    device that holds the published split cuff model (its estimate right: a true stop)."""
    config = SimConfig(
        patient_torque="active",
        patient_active=ActiveParams(
            period_s=period_s, step_length_m=0.30, stiffness_Nm_per_rad=stiffness
        ),
        duration_s=duration_s,
        estop_at_s=estop_at_s,
        belief=Belief(cuffs=CuffParams()),
    )
    return simulate(config)


@functools.cache
def _pushed_hold():
    return _walking_on(1.0, 2.5, STRONG, estop_at_s=0.5)


def test_a_patient_pushing_against_the_hold_gets_the_yield_before_the_limit() -> None:
    result = _pushed_hold()
    events = [e for e in result.events if e["kind"] == "state"]
    states = [e["value"] for e in events]
    messages = [e["message"] for e in events]
    assert states[:3] == ["stopping", "holding", "yielding"], messages
    assert "the patient pushes against the hold: yield at once" in messages[2]
    assert result.safety_state == "yielding"
    s, t = result.signals, result.t
    force = np.linalg.norm(s["cuff_force"], axis=-1)  # the truth
    estimate = np.linalg.norm(s["cuff_force_est"], axis=-1)
    switch = events[2]["t"]
    k = int(np.flatnonzero(t >= switch - 1e-9)[0])
    after = t >= switch
    print(
        f"\nyield at once from {switch:.3f} s on the release bound: estimated thigh/shank "
        f"{estimate[k, 0::2].max():.1f} / {estimate[k, 1::2].max():.1f} N at the switch "
        f"(true {force[k, 0::2].max():.1f} / {force[k, 1::2].max():.1f} N); worst true "
        f"thigh/shank after it {force[after][:, 0::2].max():.1f} / "
        f"{force[after][:, 1::2].max():.1f} N (limits {THIGH:.0f} / {SHANK:.0f} N)"
    )
    # The yield came before the limit: on the rate, not on the force over it.
    # (The truth at the switch: 153/131 N, the shank's estimate a tick behind it.)
    assert estimate[k, 0::2].max() < THIGH and estimate[k, 1::2].max() < SHANK


@pytest.mark.xfail(
    strict=True,
    reason="a patient who keeps pushing after the release: 186/191 N true after the yield "
    "against 220/130 N (the release bound counts the catch-up only)",
)
def test_after_the_yield_every_true_force_stays_within_its_limit() -> None:
    result = _pushed_hold()
    switch = [e for e in result.events if e["kind"] == "state"][2]["t"]
    force = np.linalg.norm(result.signals["cuff_force"][result.t >= switch], axis=-1)
    assert force[:, 0::2].max() < THIGH and force[:, 1::2].max() < SHANK


def test_a_patient_pushing_in_the_ramp_to_the_hold_gets_the_yield_there() -> None:
    """The ramp to the hold is a hold the patient can push against too.

    An active patient (reflex 200/60 N·m/rad) at 1.1 s steps against the
    plan's 1.2 s loads the left shank cuff past its 130 N limit (the stop)
    and keeps loading both left cuffs.  A cuff past its limit (the thigh) or
    past 1.05 × what the stop found (the shank) yields on the next tick,
    in the ramp, not at its end.  The shank's true force, over its limit at
    the stop (its estimate's lag), rises 14 N more after it: the catch-up
    and a patient who keeps pushing
    (:func:`test_after_the_yield_every_true_force_stays_within_its_limit`).
    """
    result = _walking_on(period_s=1.1, duration_s=2.6, stiffness=FIRM)
    events = [e for e in result.events if e["kind"] == "state"]
    assert [e["value"] for e in events[:2]] == ["stopping", "yielding"], events
    stop, switch = events[0]["t"], events[1]["t"]
    assert switch - stop < 0.2  # in the ramp, not at its end
    force = np.linalg.norm(result.signals["cuff_force"], axis=-1)  # the truth
    after = result.t >= stop
    k = int(np.flatnonzero(after)[0])
    thigh, shank = force[after][:, 0::2].max(), force[after][:, 1::2].max()
    print(
        f"\nstop {stop:.3f} s (true shank {force[k, 1::2].max():.1f} N), yield {switch:.3f} s; "
        f"worst true thigh/shank from the stop {thigh:.1f} / {shank:.1f} N"
    )
    assert force[k, 1::2].max() > SHANK  # a true stop: the shank past its limit
    assert thigh < THIGH  # the thigh never reaches its limit
