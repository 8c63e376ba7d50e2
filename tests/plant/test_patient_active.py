"""The active patient (exo_ctrl/plant/patient_active.py): reference, delay, strength, physics."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import load_patient
from exo_ctrl.plan import GaitParams, GaitPlan, plan_joints
from exo_ctrl.plant.patient_active import ActiveParams, ActivePatient

H = 1e-3  # plant step [s]


@pytest.fixture(scope="module")
def patient():
    return load_patient(None)


def _make(patient, duration=6.0, ramp=0.0, **kw) -> ActivePatient:
    return ActivePatient(ActiveParams(**kw), patient, GaitParams(), ramp, duration, H)


def test_reference_is_the_patients_own_gait(patient) -> None:
    """Without variability q_ref(t) is the planner's gait with the patient's step and period."""
    ap = _make(patient, period_s=1.0, step_length_m=0.3, period_cv=0.0, step_cv=0.0)
    gait = GaitParams(step_length=0.3, period=1.0)
    t = np.linspace(0.0, 3.0, 301)
    want = plan_joints(GaitPlan(gait), patient, t)
    got = ap.reference(t)
    # Linear interpolation of a 1000-sample table: error ≤ h²/8 max|q̈| ≈ 1e-5 rad.
    np.testing.assert_allclose(got, want.q, atol=2e-5)
    # Speeds and accelerations at the sample times.
    rec = ap.record
    for ti, dq, ddq in zip(t[::37], want.dq[::37], want.ddq[::37], strict=True):
        ap(ti, want.q[0], want.dq[0], np.zeros(4))
        np.testing.assert_allclose(rec["dq_ref"][0], dq, atol=2e-3)
        np.testing.assert_allclose(rec["ddq_ref"][0], ddq, atol=0.1 + 0.01 * np.abs(ddq).max())


def test_reference_speed_is_the_derivative_with_ramp_and_variability(patient) -> None:
    """q̇_ref and q̈_ref are the time derivatives of q_ref (central differences over 1 ms).

    The planned gait's acceleration steps where its cubic segments join, so
    the step d is kept at one table cell; the table's linear interpolation
    errs by about a cell times q̈ / 2 (≈ 0.03 rad/s) in the speed.
    """
    ap = _make(patient, ramp=1.2, period_s=1.1, period_cv=0.05, step_cv=0.05, seed=3)
    d = 1e-3
    for t in (0.3, 0.9, 1.7, 2.45, 3.3, ap.cycles[3, 0] + 0.5 * ap.cycles[3, 1]):
        q = ap.reference(np.array([t - d, t, t + d]))
        speeds = []
        for ti in (t - d, t, t + d):
            ap(ti, q[1], np.zeros(4), np.zeros(4))
            speeds.append(ap.record["dq_ref"][0].copy())
        ddq = ap.record["ddq_ref"][0].copy()
        ap(t, q[1], np.zeros(4), np.zeros(4))
        ddq = ap.record["ddq_ref"][0]
        scale = np.abs(speeds[1]).max()
        np.testing.assert_allclose((q[2] - q[0]) / (2 * d), speeds[1], atol=0.05 + 0.03 * scale)
        fd = (speeds[2] - speeds[0]) / (2 * d)
        np.testing.assert_allclose(fd, ddq, atol=0.5 + 0.05 * np.abs(ddq).max())


def test_reference_is_continuous_across_cycles(patient) -> None:
    """The excursion scale changes smoothly: no jump of q_ref where a cycle ends."""
    ap = _make(patient, period_cv=0.05, step_cv=0.05, seed=5)
    for start in ap.cycles[1:6, 0]:
        q = ap.reference(np.array([start - 1e-9, start + 1e-9]))
        np.testing.assert_allclose(q[0], q[1], atol=1e-6)


def test_ramp_starts_standing_still(patient) -> None:
    """At t = 0 with a ramp-in the patient wants to stand still at their standing posture."""
    ap = _make(patient, ramp=1.2)
    q0 = ap.reference(np.array([0.0]))[0]
    np.testing.assert_allclose(q0, ap.record["q_stand"][0], atol=1e-12)
    ap(0.0, q0, np.zeros(4), np.zeros(4))
    np.testing.assert_allclose(ap.record["dq_ref"][0], 0.0, atol=1e-12)


def test_variability_has_its_coefficient_of_variation(patient) -> None:
    ap = _make(patient, duration=600.0, period_cv=0.03, step_cv=0.02, seed=7)
    times, scale = ap.cycles[:, 1], ap.cycles[:, 2]
    assert len(times) > 500
    assert np.std(times) / np.mean(times) == pytest.approx(0.03, rel=0.1)
    assert np.std(scale) == pytest.approx(0.02, rel=0.1)
    again = _make(patient, duration=600.0, period_cv=0.03, step_cv=0.02, seed=7)
    np.testing.assert_array_equal(again.cycles, ap.cycles)
    # Cycles follow each other without gaps.
    np.testing.assert_allclose(ap.cycles[1:, 0], ap.cycles[:-1, 0] + times[:-1])
    # Cycle i is drawn the same in a run of any length: a 6 s run starts as the 600 s one.
    short = _make(patient, duration=6.0, period_cv=0.03, step_cv=0.02, seed=7)
    np.testing.assert_array_equal(short.cycles, ap.cycles[: len(short.cycles)])
    # Period and excursion are drawn independently of each other.
    assert abs(np.corrcoef(times, scale)[0, 1]) < 4.0 / np.sqrt(len(times))


def test_feedforward_is_the_inverse_dynamics_of_the_patients_legs(patient) -> None:
    """With no error the torque is RNEA along q_ref plus the URDF damping and friction."""
    ap = _make(patient, delay_s=0.0, period_s=1.0)
    out = np.zeros(4)
    model = pin.Model(patient.model)
    data = model.createData()
    for t in (0.2, 0.55, 1.4):
        ap(t, np.zeros(4), np.zeros(4), out)  # sets the reference
        q, dq, ddq = (ap.record[f][0].copy() for f in ("q_ref", "dq_ref", "ddq_ref"))
        ap(t, q, dq, out)
        want = pin.rnea(model, data, q, dq, ddq) + patient.damping * dq
        want += patient.friction * np.tanh(dq / 0.01)
        np.testing.assert_allclose(out, np.clip(want, -120.0, 120.0), rtol=1e-12, atol=1e-9)


def test_feedback_acts_after_the_delay_and_scales_with_strength(patient) -> None:
    """A position error appears in the torque exactly δ later, as K_p e, times the strength."""
    delay = 0.06
    full = _make(patient, delay_s=delay, period_cv=0.0, step_cv=0.0)
    weak = _make(patient, delay_s=delay, period_cv=0.0, step_cv=0.0, strength=(0.3, 0.5, 0.0, 1.0))
    err = np.array([0.01, -0.02, 0.015, 0.005])
    n0, steps = 500, round(delay / H)
    torques = {"full": [], "weak": [], "ff": []}
    probe = _make(patient, delay_s=delay, period_cv=0.0, step_cv=0.0)
    for n in range(n0 + steps + 3):
        t = n * H
        probe(t, np.zeros(4), np.zeros(4), np.zeros(4))
        q, dq = probe.record["q_ref"][0].copy(), probe.record["dq_ref"][0].copy()
        if n >= n0:
            q = q - err
        torques["full"].append(full(t, q, dq, np.zeros(4)).copy())
        torques["weak"].append(weak(t, q, dq, np.zeros(4)).copy())
        clean = probe(t, probe.record["q_ref"][0].copy(), dq, np.zeros(4))
        torques["ff"].append(clean.copy())
    full_t, weak_t, ff = (np.array(torques[k]) for k in ("full", "weak", "ff"))
    kp = np.array(full.params.stiffness_Nm_per_rad)
    # Before the delay has passed: the feedforward alone.
    np.testing.assert_allclose(full_t[: n0 + steps], ff[: n0 + steps], atol=1e-9)
    # From then on: + K_p e (the probe's own reference had no error).
    kick = np.broadcast_to(kp * err, (3, 4))
    np.testing.assert_allclose(full_t[n0 + steps :] - ff[n0 + steps :], kick, rtol=1e-9)
    np.testing.assert_allclose(weak_t, full_t * np.array([0.3, 0.5, 0.0, 1.0]), atol=1e-12)


def test_damping_acts_on_the_speed_error_at_once(patient) -> None:
    """A speed error appears in the torque on its own step as K_d ė (intrinsic viscosity).

    Only the reflex stiffness waits for the delay; the torque's change is
    K_d ė from the first step on, and K_d ė + K_p e once the delay has passed
    (the position error here stays zero).
    """
    delay = 0.06
    full = _make(patient, delay_s=delay, period_cv=0.0, step_cv=0.0)
    probe = _make(patient, delay_s=delay, period_cv=0.0, step_cv=0.0)
    slow = np.array([0.2, -0.1, 0.05, 0.3])  # ė [rad/s]
    n0, steps = 500, round(delay / H)
    kd = np.array(full.params.damping_Nms_per_rad)
    for n in range(n0 + steps + 3):
        t = n * H
        clean = probe(t, np.zeros(4), np.zeros(4), np.zeros(4))
        q, dq = probe.record["q_ref"][0].copy(), probe.record["dq_ref"][0].copy()
        clean = probe(t, q, dq, np.zeros(4)).copy()
        got = full(t, q, dq - slow if n >= n0 else dq, np.zeros(4))
        want = clean + (kd * slow if n >= n0 else 0.0)
        np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9, err_msg=f"step {n}")


def test_strength_changes_at_its_time(patient) -> None:
    ap = _make(patient, strength=0.2, strength_change_at_s=1.0, strength_after=0.8)
    before = ap(0.999, np.zeros(4), np.zeros(4), np.zeros(4)).copy()
    full = _make(patient)
    ref_before = full(0.999, np.zeros(4), np.zeros(4), np.zeros(4)).copy()
    np.testing.assert_allclose(before, 0.2 * ref_before, atol=1e-12)
    after = ap(1.0, np.zeros(4), np.zeros(4), np.zeros(4)).copy()
    ref_after = full(1.0, np.zeros(4), np.zeros(4), np.zeros(4)).copy()
    np.testing.assert_allclose(after, 0.8 * ref_after, atol=1e-12)


def test_the_patient_alone_walks_their_own_gait(patient) -> None:
    """Free legs (no exoskeleton) driven by their own torque follow their reference.

    The patient's dynamics, Pinocchio's ABA with the URDF's damping and
    friction, stepped at 1 kHz from standing through the ramp-in: the
    delayed PD with the internal model's feedforward keeps the RMS error
    below 30 mrad (3 % of the knee's 1 rad excursion; what is left comes
    from the friction's sign following the actual speed, not the
    reference's).  Without step-to-step variability: with it, the error
    depends on the seed's draws (the delayed loop lags each cycle's change
    of period and excursion).
    """
    ap = _make(
        patient, duration=5.0, ramp=1.2, period_s=1.0, step_length_m=0.3, period_cv=0.0, step_cv=0.0
    )
    model = pin.Model(patient.model)
    data = model.createData()
    q = ap.record["q_stand"][0].copy()
    v = np.zeros(4)
    tau = np.zeros(4)
    errors = []
    for n in range(4000):
        t = n * H
        ap(t, q, v, tau)
        if n >= 1200:
            errors.append(ap.record["q_ref"][0] - q)
        passive = patient.damping * v + patient.friction * np.tanh(v / 0.01)
        a = pin.aba(model, data, q, v, tau - passive)
        v = v + H * a
        q = q + H * v
    rms = np.sqrt(np.mean(np.square(errors), axis=0))
    assert np.all(rms < 0.03), rms


def test_bad_parameters_are_refused() -> None:
    with pytest.raises(InvalidParameter, match=r"patient_strength\[left_hip\] must be in \[0, 1\]"):
        ActiveParams(strength=1.5)
    with pytest.raises(InvalidParameter, match="patient_delay must be in"):
        ActiveParams(delay_s=2.0)
    with pytest.raises(InvalidParameter, match="strength_after"):
        ActiveParams(strength_change_at_s=1.0)
    with pytest.raises(InvalidParameter, match="patient_period must be > 0 s"):
        ActiveParams(period_s=0.0)
    assert dataclasses.replace(ActiveParams(), strength=0.0).strength == (0.0,) * 4
