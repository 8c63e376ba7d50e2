"""The patient-load monitor (exo_ctrl/safety/cuff_load.py): its statistic, bounds and reaction.

- The statistic against a hand derivation: a leg held still at knee angles θ_i reads the
  nominal shank's gravity alone, p_i = m g (l_x cos θ_i + l_z sin θ_i) (the knee about +y,
  the hip straight), and an estimate e_i = β p_i + n_i gives α = β + Σ n p / Σ p² and
  P = √(Σ p² / W) exactly; below P_min nothing is judged; one warning per episode, the
  next only after α came back to α_r = ¾.
- The threshold's premise, E: the estimated knee torque's RMS error over a window against
  the true shank cuff's knee torque (J_eᵀ f at the true posture), on the default run and
  from a shank cuff's slip on, with the Kalman filter and the momentum observer, is below
  E; and the gait's predicted load is above P_min (the window judges every sample of the
  gait).
- No warning on the normal runs (PD, CT, QP; the momentum observer; the spastic patient,
  with the cuff limits raised so that the run reaches the gait: its default run stops at
  1.0 s on the estimated shank force; contact on): α > α_th on every judged window.
- A slipped shank cuff is warned within one window and a sample, T_s + N Δt (derived:
  once a whole window lies after the slip |α| ≤ E/P ≤ α_th/2), the state staying normal;
  a slipped thigh cuff is not (its load moves to the shank cuff: the joint torques do not
  change), and the campaign says why.
- An active patient in tracking carries their own shanks: both warned at the first full
  window, with the message naming both causes.
- Off in transparent, aan, path and guidance with G < 1 (the Runner builds none), on in
  tracking and guidance with G = 1; a session's segments switch it and restart its window.
"""

from __future__ import annotations

import math

import fault_campaign as campaign  # tools/faults.py, loaded by tests/conftest.py
import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.control.modes import ModeParams
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import JOINT_NAMES, load_exo, load_patient
from exo_ctrl.plant import ContactParams
from exo_ctrl.safety import SafetyLimits
from exo_ctrl.safety.cuff_load import (
    ESTIMATE_ERROR_NM,
    LOAD_FRACTION,
    MIN_LOAD_NM,
    RESTORED_FRACTION,
    CuffLoadMonitor,
    cuff_load_schedule,
    detection_bound_s,
    off_reason,
)
from exo_ctrl.sim import SimConfig, build, simulate
from exo_ctrl.sim.belief import Belief, device_patient
from exo_ctrl.sim.faults import Fault
from exo_ctrl.sim.session import Segment, SessionParams
from exo_ctrl.sim.tick import Runner

DT = 1e-3
KNEE = JOINT_NAMES.index("left_knee")
PERIOD = SimConfig().gait.period
NOMINAL = device_patient(Belief(), None, load_patient(None))


def run_monitored(config: SimConfig) -> tuple[Runner, np.ndarray]:
    """Run ``config`` tick by tick; the monitor's (t, α_L, α_R, P_L, P_R) at each sample."""
    runner = Runner(build(config))
    mon = runner.cuff_load
    assert mon is not None
    trace = []
    for k in range(config.n_ticks):
        runner.tick(k, k % runner.chunk)
        if k % mon.every == 0:
            r = mon.record[0]
            trace.append((k * config.dt, *r["alpha"], *r["load"]))
    return runner, np.array(trace)


def warnings(events: list[dict]) -> list[dict]:
    return [e for e in events if e["kind"] == "warning"]


# --- the statistic, by hand ---


def knee_gravity(theta: np.ndarray) -> np.ndarray:
    """p = −τ_p,knee = m g (l_x cos θ + l_z sin θ): the shank held still at knee angle θ.

    With the hip straight and the knee's axis +y, the shank's centre of mass (lever l in the
    knee's frame) sits at r = (l_x cos θ + l_z sin θ, ·, ·) from the knee; gravity's moment
    about +y is (r × (0, 0, −m g))_y = m g r_x, so the patient's joint needs τ_p = −m g r_x,
    which the cuff supplies, and the exoskeleton feels the reaction p = −τ_p = m g r_x.
    """
    model = NOMINAL.model
    jid = NOMINAL.joint_ids[KNEE]
    assert model.joints[jid].shortname() == "JointModelRY"  # the knee about +y
    for j in (NOMINAL.joint_ids[0], jid):  # hip and knee frames not rotated at q = 0
        np.testing.assert_allclose(model.jointPlacements[j].rotation, np.eye(3), atol=1e-12)
    inertia = model.inertias[jid]
    lx, _, lz = inertia.lever
    g = -model.gravity.linear[2]
    return inertia.mass * g * (lx * np.cos(theta) + lz * np.sin(theta))


def feed(mon: CuffLoadMonitor, thetas, estimates, k0: int = 0) -> list[dict]:
    """One still sample per knee angle (both legs alike), the estimate given; the events."""
    events: list[dict] = []
    tau_ext = mon._tau_ext
    for i, (theta, est) in enumerate(zip(thetas, estimates, strict=True)):
        k = k0 + i * mon.every
        q = np.array([0.0, theta, 0.0, theta])
        tau_ext[:] = [0.0, est, 0.0, est]
        mon.step(k, k * DT, q, np.zeros(4), events)
    return events


def test_the_statistic_is_the_least_squares_share_of_the_predicted_load() -> None:
    tau_ext = np.zeros(4)
    mon = CuffLoadMonitor(NOMINAL, tau_ext, DT, 0.1)
    w = int(mon.record["window"][0])
    assert mon.every == 10 and w == 10 and math.isclose(mon.window_s, 0.1)
    rng = np.random.default_rng(3)
    theta = np.linspace(0.3, 1.1, w + 1)  # the first sample only keeps its speeds
    p = knee_gravity(theta)
    beta, noise = 0.8, rng.normal(0.0, 0.5, w + 1)
    events = feed(mon, theta, beta * p + noise)
    assert events == []
    pw, nw = p[1:], noise[1:]
    alpha = beta + (nw @ pw) / (pw @ pw)
    r = mon.record[0]
    np.testing.assert_allclose(r["alpha"], alpha, rtol=1e-12)
    np.testing.assert_allclose(r["load"], math.sqrt(pw @ pw / w), rtol=1e-12)
    np.testing.assert_allclose(mon.ring[0, 0], pw, rtol=1e-12)  # the RNEA's gravity
    assert np.all(np.abs(pw) >= MIN_LOAD_NM)  # judged: above the gate


def test_below_the_gate_nothing_is_judged_and_a_warning_comes_once_per_episode() -> None:
    tau_ext = np.zeros(4)
    mon = CuffLoadMonitor(NOMINAL, tau_ext, DT, 0.1)
    w = int(mon.record["window"][0])
    small = np.full(w + 1, 0.02)  # |p| ≈ 0.2 N·m < P_min: not judged, whatever the estimate
    assert np.all(np.abs(knee_gravity(small)) < MIN_LOAD_NM)
    assert feed(mon, small, np.zeros(w + 1)) == []
    assert np.all(np.isnan(mon.record["alpha"][0]))
    theta = np.full(3 * w, 0.8)
    p = knee_gravity(theta)
    k = (w + 1) * mon.every
    for share, expected in ((0.6, 0), (0.3, 2), (0.6, 0), (0.3, 0), (0.8, 0), (0.3, 2)):
        events = feed(mon, theta, share * p, k)  # a whole new window at this share
        k += 3 * w * mon.every
        np.testing.assert_allclose(mon.record["alpha"][0], share, rtol=1e-12)
        assert len(events) == expected, (share, events)
    assert 0.6 < RESTORED_FRACTION < 0.8  # 0.6 does not re-arm, 0.8 does
    event = events[0]
    assert event["kind"] == "warning" and event["quantity"] == "cuff load left_shank"
    assert 0.3 <= event["value"] < LOAD_FRACTION == event["limit"]  # α where it crossed
    assert event["message"].startswith(
        "cuff unloaded left_shank: slipped cuff or the patient carries the segment"
    )


def test_a_non_finite_reading_or_estimate_skips_its_sample() -> None:
    tau_ext = np.zeros(4)
    mon = CuffLoadMonitor(NOMINAL, tau_ext, DT, 0.1)
    theta = np.full(5, 0.8)
    feed(mon, theta, knee_gravity(theta))
    count = int(mon.record["count"][0])
    feed(mon, [0.8], [math.nan], 50)
    feed(mon, [math.nan], [1.0], 60)
    assert int(mon.record["count"][0]) == count
    assert mon.record["has_prev"][0] == 0.0  # the next sample keeps only its speeds


def test_bad_arguments_are_refused_by_name() -> None:
    with pytest.raises(InvalidParameter, match="tau_ext must be the estimator's"):
        CuffLoadMonitor(NOMINAL, np.zeros(3), DT, 1.2)
    with pytest.raises(InvalidParameter, match="period_s must be > 0"):
        CuffLoadMonitor(NOMINAL, np.zeros(4), DT, 0.0)


# --- the threshold's premise and the normal runs ---


def true_knee_torque(result) -> np.ndarray:
    """The true shank cuffs' knee torques on the exoskeleton, J_eᵀ f at the true posture."""
    exo = load_exo(None)
    model, data = exo.model, exo.model.createData()
    s = result.signals
    out = np.zeros((s["q"].shape[0], 2))
    for k in range(out.shape[0]):
        pin.computeJointJacobians(model, data, s["q"][k])
        pin.updateFramePlacements(model, data)
        for leg, (cuff, knee) in enumerate(((1, 1), (3, 3))):
            jac = pin.getFrameJacobian(
                model, data, exo.cuff_frame_ids[cuff], pin.LOCAL_WORLD_ALIGNED
            )
            f = s["cuff_force"][k, cuff]
            out[k, leg] = jac[0, exo.q_index[knee]] * f[0] + jac[2, exo.q_index[knee]] * f[1]
    return out


def window_rms(x: np.ndarray, n: int) -> np.ndarray:
    return np.sqrt(np.convolve(x**2, np.ones(n), "valid") / n)


@pytest.mark.parametrize("estimator", ["kalman", "momentum"])
@pytest.mark.parametrize("slipped", [False, True])
def test_the_knee_estimate_is_within_e_of_the_truth_over_a_window(
    slipped: bool, estimator: str
) -> None:
    at = 2.0
    faults = (Fault("cuff_slip", at, "left_shank"),) if slipped else ()
    result = simulate(SimConfig(faults=faults, estimator=estimator))
    truth = true_knee_torque(result)
    est = result.signals["tau_ext_est"][:, [1, 3]]
    n = round(PERIOD / DT)
    start = round((at if slipped else PERIOD) / DT)  # after the ramp-in, or the slip
    worst = max(window_rms(est[start:, leg] - truth[start:, leg], n).max() for leg in (0, 1))
    assert worst <= ESTIMATE_ERROR_NM, worst
    if slipped:  # the slipped cuff's true load is zero: its estimate is its error
        assert np.all(truth[round(at / DT) + 1 :, 0] == 0.0)


BIG = SafetyLimits(cuff_force_N=(1e4,) * 4)
NORMAL = {
    "pd": {},
    "ct": {"controller": "ct"},
    "qp": {"controller": "qp"},
    "momentum": {"estimator": "momentum"},
    "spastic": {"patient_torque": "spastic", "safety_limits": BIG},
    "contact": {"contact": ContactParams(enabled=True)},
}


@pytest.mark.parametrize("name", list(NORMAL))
def test_no_warning_on_a_normal_run(name: str) -> None:
    runner, trace = run_monitored(SimConfig(**NORMAL[name]))
    assert warnings(runner.supervisor.events) == []
    assert runner.supervisor.state == "normal"
    gait = trace[trace[:, 0] >= runner.cuff_load.window_s]  # the first full window on
    assert np.all(gait[:, 3:5] >= MIN_LOAD_NM)  # P: the gait is judged throughout
    alpha_min = runner.cuff_load.record["alpha_min"][0]
    assert np.all(alpha_min > LOAD_FRACTION), alpha_min
    print(f"{name}: least alpha {alpha_min.round(3)} (threshold {LOAD_FRACTION})")


# --- the slipped cuffs ---


@pytest.mark.parametrize(("target", "at"), [("left_shank", 2.0), ("right_shank", 1.653)])
def test_a_slipped_shank_cuff_is_warned_within_a_window(target: str, at: float) -> None:
    result = simulate(SimConfig(faults=(Fault("cuff_slip", at, target),)))
    warned = warnings(result.events)
    assert [e["quantity"] for e in warned] == [f"cuff load {target}"]
    after = warned[0]["t"] - at
    bound = detection_bound_s(PERIOD, DT)
    assert 0.0 <= after <= bound, (after, bound)
    assert result.safety_state == "normal"
    assert warned[0]["value"] < LOAD_FRACTION
    fault = Fault("cuff_slip", at, target)
    row = campaign.analyse(result, fault)
    assert row.detected and row.channel == f"cuff load {target} (warning)"
    assert row.state == "normal" and math.isclose(row.detection_s, after)
    print(f"{target}: warned {1e3 * after:.0f} ms after the slip (bound {1e3 * bound:.0f} ms)")


def test_a_slipped_thigh_cuff_leaves_the_joint_torques_and_is_not_warned() -> None:
    fault = Fault("cuff_slip", 2.0, "left_thigh")
    result = simulate(SimConfig(faults=(fault,)))
    assert warnings(result.events) == []
    k0 = round(2.0 / DT)
    assert np.all(result.signals["cuff_force"][k0 + 1 :, 0] == 0.0)
    note = campaign.not_detected_note(result, fault, "tracking")
    assert note == campaign.NOT_DETECTED["cuff_slip"]


def test_an_active_patient_in_tracking_carries_the_shanks_and_is_warned_why() -> None:
    config = SimConfig(patient_torque="active", duration_s=PERIOD + 0.3)
    runner, trace = run_monitored(config)
    warned = warnings(runner.supervisor.events)
    assert sorted(e["quantity"] for e in warned) == [
        "cuff load left_shank",
        "cuff load right_shank",
    ]
    assert all(e["t"] <= PERIOD + 2 * runner.cuff_load.every * DT for e in warned)
    assert all("or the patient carries the segment" in e["message"] for e in warned)
    assert np.nanmax(trace[:, 1:3]) < LOAD_FRACTION / 2


# --- where it is off ---


@pytest.mark.parametrize(
    ("mode", "guidance", "on"),
    [
        ("tracking", 1.0, True),
        ("guidance", 1.0, True),
        ("guidance", 0.5, False),
        ("transparent", 1.0, False),
        ("aan", 1.0, False),
        ("path", 1.0, False),
    ],
)
def test_on_only_where_the_device_carries_the_legs(mode: str, guidance: float, on: bool) -> None:
    config = SimConfig(
        mode=mode, modes=ModeParams(guidance=guidance), patient_torque="active", duration_s=2.4
    )
    runner = Runner(build(config))
    assert (runner.cuff_load is not None) == on
    assert (off_reason(mode, guidance) == "") == on
    if mode == "transparent":
        assert "drives the cuff forces to zero" in off_reason(mode)
        result = simulate(config)
        fault = Fault("cuff_slip", 0.5, "left_shank")
        note = campaign.not_detected_note(result, fault, mode)
        assert note.startswith("not detected: the cuff-load monitor is off (transparent")


def test_a_session_switches_it_and_restarts_its_window() -> None:
    session = SessionParams(
        (Segment(1.0, "tracking"), Segment(1.0, "transparent"), Segment(1.0, "guidance"))
    )
    schedule = cuff_load_schedule("tracking", 1.0, session)
    assert [t for t, _ in schedule] == [0.0, 1.0, 2.0]
    assert [why == "" for _, why in schedule] == [True, False, True]
    tau_ext = np.zeros(4)
    mon = CuffLoadMonitor(NOMINAL, tau_ext, DT, 0.1, schedule=((0.0, ""), (0.2, "off"), (0.4, "")))
    theta = np.full(15, 0.8)
    feed(mon, theta, knee_gravity(theta))  # 0 … 0.14 s: counted
    assert int(mon.record["count"][0]) == 10
    feed(mon, np.full(10, 0.8), np.zeros(10), 200)  # 0.2 … 0.29 s: off, nothing counted
    assert mon.off == "off" and int(mon.record["count"][0]) == 0
    feed(mon, np.full(4, 0.8), np.zeros(4), 400)  # from 0.4 s: a fresh window
    assert mon.off == "" and int(mon.record["count"][0]) == 3
