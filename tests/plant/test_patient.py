"""Patient joint torques: the spastic law's shape, its parameters and its effect on the cuffs.

The law's derivatives are checked by finite differences against the
documented slopes (module docstring of exo_ctrl.plant.patient); the closed-loop
test runs the computed-torque controller, which does not know the patient
torque, on the default scenario with and without the spastic patient.
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from exo_ctrl.control import SensorReadings
from exo_ctrl.exceptions import InvalidParameter
from exo_ctrl.model import JOINT_NAMES
from exo_ctrl.plant.patient import (
    PATIENT_TORQUES,
    SpasticParams,
    SpasticPatient,
    make_patient_torque,
)
from exo_ctrl.sim import SimConfig, build, start_on_plan

Q = np.array([0.5, 1.2, 0.4, 1.0])  # a posture inside the gait's range [rad]
H = 1e-6  # finite-difference step [rad, rad/s]


def torque(patient: SpasticPatient, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    out = np.zeros(4)
    return patient(0.0, np.asarray(q, dtype=float), np.asarray(dq, dtype=float), out).copy()


def reflex(patient: SpasticPatient, dq: np.ndarray) -> np.ndarray:
    """The reflex part: the torque minus the documented hypertonic terms."""
    p = patient.params
    passive = -np.array(p.stiffness_Nm_per_rad) * (Q - np.array(p.rest_posture_rad))
    passive -= np.array(p.damping_Nms_per_rad) * dq
    return torque(patient, Q, dq) - passive


# --------------------------------------------------------------------------- the law


def test_reflex_is_zero_below_the_threshold() -> None:
    patient = SpasticPatient()
    th = np.array(patient.params.reflex_threshold_rad_s)
    for fraction in (-0.99, -0.5, 0.0, 0.5, 0.99):
        np.testing.assert_allclose(reflex(patient, fraction * th), 0.0, atol=1e-12)


@pytest.mark.parametrize("direction", [+1.0, -1.0])
def test_reflex_grows_linearly_above_the_threshold_with_the_documented_slope(direction) -> None:
    patient = SpasticPatient()
    p = patient.params
    th = np.array(p.reflex_threshold_rad_s)
    gain = np.array(
        p.reflex_gain_flexion_Nms_per_rad if direction > 0 else p.reflex_gain_extension_Nms_per_rad
    )
    b = np.array(p.damping_Nms_per_rad)
    for above in (0.1, 0.5, 1.0):  # rad/s past the threshold, below the cap
        dq = direction * (th + above)
        slope = (torque(patient, Q, dq + H) - torque(patient, Q, dq - H)) / (2 * H)
        np.testing.assert_allclose(slope, -(gain + b), rtol=1e-6)
        np.testing.assert_allclose(reflex(patient, dq), -direction * gain * above, rtol=1e-9)
    # Just below the threshold the slope is the viscous one alone.
    dq = direction * 0.9 * th
    slope = (torque(patient, Q, dq + H) - torque(patient, Q, dq - H)) / (2 * H)
    np.testing.assert_allclose(slope, -b, rtol=1e-6)


def test_reflex_opposes_the_motion_and_is_capped() -> None:
    patient = SpasticPatient()
    cap = np.array(patient.params.reflex_max_Nm)
    for speed in (0.6, 1.0, 2.0, 4.0, 50.0):
        for sign in (+1.0, -1.0):
            dq = np.full(4, sign * speed)
            r = reflex(patient, dq)
            assert np.all(np.sign(r) == -sign), (speed, sign, r)
            assert np.all(np.abs(r) <= cap + 1e-12)
    np.testing.assert_allclose(np.abs(reflex(patient, np.full(4, 50.0))), cap)


def test_symmetric_gains_give_the_sign_law() -> None:
    """Equal gains: τ_reflex = -k_r (|q̇| - q̇_th)₊ sign(q̇)."""
    k_r, th = 12.0, 0.4
    patient = SpasticPatient(
        SpasticParams(
            stiffness_Nm_per_rad=0.0,
            damping_Nms_per_rad=0.0,
            reflex_gain_flexion_Nms_per_rad=k_r,
            reflex_gain_extension_Nms_per_rad=k_r,
            reflex_threshold_rad_s=th,
            reflex_max_Nm=1e9,
        )
    )
    for dq in ([-2.0, -0.3, 0.3, 2.0], [1.0, -1.0, 0.0, 0.41]):
        dq = np.array(dq)
        expected = -k_r * np.maximum(np.abs(dq) - th, 0.0) * np.sign(dq)
        np.testing.assert_allclose(torque(patient, Q, dq), expected, atol=1e-12)


def test_one_direction_reflex() -> None:
    """A zero extension gain: no reflex when extending, however fast."""
    patient = SpasticPatient(SpasticParams(reflex_gain_extension_Nms_per_rad=0.0))
    np.testing.assert_allclose(reflex(patient, np.full(4, -3.0)), 0.0, atol=1e-12)
    assert np.all(reflex(patient, np.full(4, 3.0)) < 0.0)


def test_hypertonia_stiffness_is_minus_the_angle_derivative() -> None:
    patient = SpasticPatient()
    p = patient.params
    for dq in (np.zeros(4), np.array([1.5, -1.5, 0.7, -0.2])):
        jac = np.zeros((4, 4))
        for j in range(4):
            step = np.zeros(4)
            step[j] = H
            jac[:, j] = (torque(patient, Q + step, dq) - torque(patient, Q - step, dq)) / (2 * H)
        np.testing.assert_allclose(-jac, np.diag(p.stiffness_Nm_per_rad), atol=1e-6)
    # At rest in the rest posture the torque vanishes.
    np.testing.assert_allclose(
        torque(patient, np.array(p.rest_posture_rad), np.zeros(4)), 0.0, atol=1e-12
    )


def test_call_writes_into_out_and_allocates_nothing() -> None:
    patient = SpasticPatient()
    q, dq, out = Q.copy(), np.array([1.0, -1.0, 2.0, -2.0]), np.zeros(4)
    assert patient(0.0, q, dq, out) is out

    def nothing(t, q, dq, out):
        return out

    def allocating(t, q, dq, out):
        out[:] = 2.0 * q
        return out

    def peak(fn) -> int:
        for _ in range(10):
            fn(0.0, q, dq, out)
        tracemalloc.start()
        try:
            tracemalloc.reset_peak()
            base, _ = tracemalloc.get_traced_memory()
            for _ in range(2000):
                fn(0.0, q, dq, out)
            _, top = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
        return top - base

    floor = peak(nothing)
    assert peak(allocating) > floor + 64  # the probe sees a (4,) temporary
    assert peak(patient) <= floor + 64


# --------------------------------------------------------------------------- parameters


def test_params_are_stored_per_joint() -> None:
    p = SpasticParams(stiffness_Nm_per_rad=3, rest_posture_rad=(0.1, 0.2, 0.3, 0.4))
    assert p.stiffness_Nm_per_rad == (3.0, 3.0, 3.0, 3.0)
    assert p.rest_posture_rad == (0.1, 0.2, 0.3, 0.4)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (
            {"stiffness_Nm_per_rad": -1},
            "stiffness_Nm_per_rad[left_hip] must be >= 0 N·m/rad; got -1",
        ),
        (
            {"reflex_threshold_rad_s": (0.5, 0.5, -0.1, 0.5)},
            "reflex_threshold_rad_s[right_hip] must be >= 0 rad/s; got -0.1",
        ),
        (
            {"reflex_gain_flexion_Nms_per_rad": (1.0, float("nan"), 1.0, 1.0)},
            "reflex_gain_flexion_Nms_per_rad[left_knee] must be a finite number [N·m·s/rad]; "
            "got nan",
        ),
        (
            {"rest_posture_rad": (0.1, 0.2)},
            "rest_posture_rad must be a number or 4 numbers (one per joint: "
            f"{', '.join(JOINT_NAMES)}); got (0.1, 0.2)",
        ),
        (
            {"reflex_max_Nm": "big"},
            "reflex_max_Nm[left_hip] must be a finite number [N·m]; got 'big'",
        ),
    ],
)
def test_bad_params_are_refused_with_exact_messages(kwargs, message) -> None:
    with pytest.raises(InvalidParameter) as exc:
        SpasticParams(**kwargs)
    assert str(exc.value) == message


def test_a_negative_rest_posture_is_allowed() -> None:
    assert SpasticParams(rest_posture_rad=-0.2).rest_posture_rad == (-0.2,) * 4


def test_make_patient_torque() -> None:
    assert PATIENT_TORQUES == ("none", "spastic")
    assert make_patient_torque("none") is None
    assert make_patient_torque() is None
    assert isinstance(make_patient_torque("spastic"), SpasticPatient)
    custom = make_patient_torque("spastic", stiffness_Nm_per_rad=1.0)
    assert custom.params.stiffness_Nm_per_rad == (1.0,) * 4
    with pytest.raises(InvalidParameter) as exc:
        make_patient_torque("voluntary")
    assert str(exc.value) == "patient_torque must be one of none, spastic; got 'voluntary'"
    with pytest.raises(InvalidParameter) as exc:
        make_patient_torque("spastic", stifness=1.0)
    assert str(exc.value).startswith("spastic parameter must be one of damping_Nms_per_rad, ")
    assert str(exc.value).endswith("; got 'stifness'")
    with pytest.raises(InvalidParameter) as exc:
        make_patient_torque("none", stiffness_Nm_per_rad=1.0)
    assert str(exc.value) == (
        "patient_torque parameters must be empty for patient_torque 'none'; "
        "got ['stiffness_Nm_per_rad']"
    )


# --------------------------------------------------------------------------- closed loop


def peak_cuff_force(kind: str, duration_s: float = 2.4) -> float:
    """Peak cuff force magnitude [N] of a CT closed loop with the patient torque ``kind``."""
    config = SimConfig(controller="ct", duration_s=duration_s)
    setup = build(config)
    plant, ctrl = setup.plant, setup.controller
    start_on_plan(setup)
    model = make_patient_torque(kind)
    tau_p = np.zeros(4)
    sensors = SensorReadings(q=np.zeros(4), dq=np.zeros(4), tau=np.zeros(4))
    peak = 0.0
    for k in range(config.n_ticks):
        np.copyto(sensors.q, plant.q[:4])
        np.copyto(sensors.dq, plant.v[:4])
        np.copyto(sensors.tau, plant.sensor_torque)
        u = ctrl.command(k, sensors)
        if model is not None:
            model(k * config.dt, plant.q[4:], plant.v[4:], tau_p)
        plant.step(u, tau_p if model is not None else None)
        peak = max(peak, float(np.max(np.linalg.norm(plant.cuff_force, axis=1))))
    return peak


def test_spastic_patient_loads_the_cuffs_beyond_150_N() -> None:
    passive = peak_cuff_force("none")
    spastic = peak_cuff_force("spastic")
    print(f"\npeak cuff force, CT, default gait: none {passive:.1f} N, spastic {spastic:.1f} N")
    assert passive < 150.0
    assert spastic > 150.0
