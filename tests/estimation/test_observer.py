"""Momentum observer and cuff-force estimation, checked on real closed-loop runs.

Every run here is the closed loop that :func:`exo_ctrl.sim.loop.simulate`
runs (CT controller, default gait: 2 cycles, 2.4 s), with the sensors and the
estimator in the loop: per tick, readings = sensors.read(k, plant state),
estimate = estimator.update(readings), u = controller.command(k, readings),
plant.step(u).  The truth logged with row k is what the reading of tick k
reflects: the cuff force over the previous plant step (plant.cuff_force
before stepping).

Independent references: the true external joint torque J_eᵀ f is computed
with Pinocchio's frame Jacobians at the posture where the plant evaluated
the cuffs (mid-step), not with the plant's own cuff code; a constant torque
on a static posture has the closed-form response τ (1 − e^{−K t}); a free
swing without interaction must give zero.

Errors are RMS over the run after a start-up of SKIP_S = 50 ms (five
observer time constants at K_O = 100 1/s), per cuff, relative to the peak
|true normal component| of that cuff.  "Raw" compares with the truth
itself; "vs filtered truth" compares with the truth passed through the
observer's own first-order filter, which separates the observer's lag
(1/K_O) from its errors.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.estimation.observer import (
    CSV_REQUIRED_COLUMNS,
    DEFAULT_GAIN_PER_S,
    CuffForceEstimator,
    CuffGeometry,
    EstimateErrorStats,
    InvalidLog,
    bias_effect_bound,
    cuff_components,
    cuff_forces_from_torque,
    cuff_normal_components,
    estimate_bias,
    estimate_series,
    first_order_filter,
    normal_component_errors,
    read_csv_log,
    write_csv_log,
)
from exo_ctrl.exceptions import ExoCtrlError, InvalidParameter
from exo_ctrl.model.body import CUFF_NAMES, BodyModel
from exo_ctrl.plant.cuffs import CuffParams
from exo_ctrl.plant.plant import Plant
from exo_ctrl.sensing.readings import SensorReadings
from exo_ctrl.sensing.sensors import SensorParams, Sensors
from exo_ctrl.sim.loop import SimConfig, build, start_on_plan

DT = 1e-3
SKIP_S = 0.05
SKIP = round(SKIP_S / DT)
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@dataclass
class Run:
    """A closed-loop run with the sensors and the live estimator."""

    exo: BodyModel
    t: np.ndarray
    q_true: np.ndarray  # (N, 4) exo joint angles at t_k
    q_mid: np.ndarray  # (N, 4) posture at which the plant evaluated force_true[k]
    q: np.ndarray  # sensor readings
    dq: np.ndarray
    tau: np.ndarray
    force_true: np.ndarray  # (N, 4, 2) cuff force over [t_{k-1}, t_k]
    normal: np.ndarray  # live estimate
    force: np.ndarray
    tau_ext: np.ndarray
    gain: float


def closed_loop(
    sensor_params: SensorParams,
    gain: float = DEFAULT_GAIN_PER_S,
    *,
    patient: str | None = None,
    cuffs: CuffParams | None = None,
    patient_torque: str | None = None,
    torque_bias_Nm: np.ndarray | float = 0.0,
) -> Run:
    """Run the CT closed loop on the default gait with sensors and estimator in the loop."""
    config = SimConfig(controller="ct", patient=patient, cuffs=cuffs or CuffParams())
    setup = build(config)
    plant = setup.plant
    start_on_plan(setup)  # as simulate() starts
    sensors = Sensors(sensor_params, config.dt)
    estimator = CuffForceEstimator(setup.exo, config.dt, gain, torque_bias_Nm)
    torque_model = None
    torque_buf = np.zeros(4)
    if patient_torque is not None:
        from exo_ctrl.plant.patient import make_patient_torque

        torque_model = make_patient_torque(patient_torque)
    n = config.n_ticks
    out = {
        name: np.zeros((n, *shape))
        for name, shape in (
            ("q_true", (4,)),
            ("q_mid", (4,)),
            ("q", (4,)),
            ("dq", (4,)),
            ("tau", (4,)),
            ("force_true", (4, 2)),
            ("normal", (4,)),
            ("force", (4, 2)),
            ("tau_ext", (4,)),
        )
    }
    q_mid = plant.q[:4].copy()
    h = plant.dt
    for k in range(n):
        readings = sensors.read(k, plant.q[:4], plant.v[:4], plant.sensor_torque)
        estimator.update(readings)
        out["q_true"][k] = plant.q[:4]
        out["q_mid"][k] = q_mid
        out["q"][k] = readings.q
        out["dq"][k] = readings.dq
        out["tau"][k] = readings.tau
        out["force_true"][k] = plant.cuff_force
        out["normal"][k] = estimator.normal
        out["force"][k] = estimator.force
        out["tau_ext"][k] = estimator.tau_ext
        u = setup.controller.command(k, readings)
        q_mid = plant.q[:4] + 0.5 * h * plant.v[:4]  # the plant's drift to mid-step
        if torque_model is not None:
            torque_model(k * config.dt, plant.q[4:], plant.v[4:], torque_buf)
            plant.step(u, torque_buf)
        else:
            plant.step(u)
    return Run(exo=setup.exo, t=np.arange(n) * config.dt, gain=gain, **out)


def true_tau_ext(exo: BodyModel, q: np.ndarray, force: np.ndarray) -> np.ndarray:
    """Σ J_cᵀ f_c with Pinocchio's frame Jacobians (x, z rows), (N, 4) [N·m]."""
    model = exo.model
    data = model.createData()
    out = np.zeros((q.shape[0], 4))
    for k in range(q.shape[0]):
        pin.computeJointJacobians(model, data, q[k])
        pin.updateFramePlacements(model, data)
        for c, fid in enumerate(exo.cuff_frame_ids):
            jac = pin.getFrameJacobian(model, data, fid, LWA)[[0, 2]]
            out[k] += jac.T @ force[k, c]
    return out


def rel_errors(est: np.ndarray, truth: np.ndarray, peak: np.ndarray) -> np.ndarray:
    err = est[SKIP:] - truth[SKIP:]
    return np.sqrt(np.mean(err**2, axis=0)) / peak


def show(label: str, values: np.ndarray, unit: str = "%") -> None:
    scale = 100.0 if unit == "%" else 1.0
    body = ", ".join(f"{c} {scale * x:.2f}" for c, x in zip(CUFF_NAMES, values, strict=True))
    print(f"{label}: {body} {unit}")


def check_accuracy(run: Run, label: str) -> tuple[np.ndarray, np.ndarray]:
    """Raw and filtered-truth relative RMS errors of the normal components (printed)."""
    true_n = cuff_normal_components(run.q_true, run.force_true, run.exo)
    errors = normal_component_errors(run.q_true, run.force_true, run.normal, run.exo, skip=SKIP)
    filtered = first_order_filter(true_n, DT, run.gain)
    vs_filtered = rel_errors(run.normal, filtered, errors.peak_true_N)
    print(f"\n[{label}] K_O = {run.gain:g} 1/s ({run.gain / 2 / math.pi:.1f} Hz), skip {SKIP_S} s")
    show("  peak true normal component", errors.peak_true_N, "N")
    show("  RMS error raw", errors.rms_error_rel)
    show("  RMS error raw", errors.rms_error_N, "N")
    show("  RMS error vs filtered truth", vs_filtered)
    show("  max error raw", errors.max_error_N, "N")
    return errors.rms_error_rel, vs_filtered


# --------------------------------------------------------------------------- runs


@pytest.fixture(scope="module")
def ideal_run() -> Run:
    return closed_loop(SensorParams.ideal())


@pytest.fixture(scope="module")
def noisy_run() -> Run:
    return closed_loop(SensorParams())


# --------------------------------------------------------------------------- observer


def test_observer_converges_to_the_true_external_torque(ideal_run: Run) -> None:
    """r follows J_eᵀ f_true (Pinocchio, mid-step posture) through the filter ṙ = K (τ − r)."""
    run = ideal_run
    truth = true_tau_ext(run.exo, run.q_mid, run.force_true)
    peak = np.max(np.abs(truth), axis=0)
    err = np.max(np.abs(run.tau_ext - first_order_filter(truth, DT, run.gain))[SKIP:], axis=0)
    print(f"\npeak true external torque {np.round(peak, 2)} N·m")
    print(f"max |r − filtered J_eᵀ f| {np.round(err, 4)} N·m (K_O = {run.gain:g})")
    assert np.all(err < 2e-3 * peak)
    # With a fast observer r is the external torque itself.
    fast = estimate_series(run.t, run.q, run.dq, run.tau, run.exo, 1000.0, dt=DT)
    err_fast = np.sqrt(np.mean((fast.tau_ext - truth)[SKIP:] ** 2, axis=0))
    print(f"RMS |r − J_eᵀ f| with K_O = 1000 (1 ms lag): {np.round(err_fast, 3)} N·m")
    assert np.all(err_fast < 0.005 * peak)


def test_constant_external_torque_on_a_static_posture_is_the_exact_filter_step(exo) -> None:
    """Held still, τ_s = g(q) − τ_ext: r_k = τ_ext (1 − e^{−K t_k}) exactly."""
    q = np.array([0.4, 0.9, -0.2, 0.3])
    tau_ext = np.array([12.0, -5.0, 3.0, 8.0])
    gravity = pin.computeGeneralizedGravity(exo.model, exo.model.createData(), q)
    n, gain = 200, 80.0
    t = np.arange(n) * DT
    series = estimate_series(
        t, np.tile(q, (n, 1)), np.zeros((n, 4)), np.tile(gravity - tau_ext, (n, 1)), exo, gain
    )
    expected = tau_ext * (1.0 - np.exp(-gain * t))[:, None]
    assert np.allclose(series.tau_ext, expected, rtol=0, atol=1e-9)
    # Uneven time stamps (a user's log): the same closed form at the actual times.
    t = np.cumsum(np.random.default_rng(4).uniform(0.2e-3, 3e-3, n)) - 0.1e-3
    series = estimate_series(
        t, np.tile(q, (n, 1)), np.zeros((n, 4)), np.tile(gravity - tau_ext, (n, 1)), exo, gain
    )
    expected = tau_ext * (1.0 - np.exp(-gain * (t - t[0])))[:, None]
    assert np.allclose(series.tau_ext, expected, rtol=0, atol=1e-9)


def test_free_swing_without_interaction_gives_no_external_torque(exo) -> None:
    """A passive exoskeleton swinging fast under gravity: r stays at zero.

    Exercises M (and its change along the path, the Ṁ q̇ term), n = C q̇ + g,
    damping and friction of the observer's link model (no drives, cuffs of
    negligible stiffness, so τ_ext = 0 and τ_s = 0).
    """
    from exo_ctrl.model.body import default_urdf_path, load_body

    patient = load_body(default_urdf_path("patient"), name="patient")
    plant = Plant(exo, patient, motors=None, cuffs=CuffParams(1e-9, 0.0))
    plant.reset(np.array([1.2, 0.2, -0.4, 1.5]), np.array([2.0, -3.0, 1.0, 0.0]))
    est = CuffForceEstimator(exo, plant.dt, 200.0)
    s = Sensors(SensorParams.ideal(), plant.dt)
    r = np.zeros((1000, 4))
    speed = 0.0
    for k in range(1000):
        est.update(s.read(k, plant.q[:4], plant.v[:4], plant.sensor_torque))
        r[k] = est.tau_ext
        speed = max(speed, float(np.max(np.abs(plant.v[:4]))))
        plant.step(np.zeros(4))
    print(f"\nfree swing: peak speed {speed:.1f} rad/s, max |r| {np.abs(r).max():.4f} N·m")
    assert speed > 3.0
    assert np.abs(r).max() < 0.05


def _smooth_readings(exo: BodyModel, h: float, tau_ext: np.ndarray) -> tuple[np.ndarray, ...]:
    """Readings along q(t) = q₀ + A sin(ωt + φ) (2 s), exact but for the sampling.

    τ_s = RNEA of the link model (no armature) + b q̇ + f_c tanh(q̇/ε) − τ_ext,
    reading k its mean over [t_{k-1}, t_k] (5-point Gauss–Legendre), as the
    plant's sensor torque is.
    """
    from exo_ctrl.model.body import FRICTION_SMOOTHING_RAD_S

    model = pin.Model(exo.model)
    model.armature = np.zeros(model.nv)
    data = model.createData()
    q0, amp = np.array([0.2, 0.6, -0.1, 0.5]), np.array([0.5, 0.5, 0.4, 0.6])
    omega, phase = 2 * np.pi * np.array([0.9, 1.3, 1.1, 0.7]), np.array([0.0, 1.0, 2.0, 0.5])

    def state(t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        x = omega * t + phase
        return q0 + amp * np.sin(x), amp * omega * np.cos(x), -amp * omega**2 * np.sin(x)

    def sensor(t: float) -> np.ndarray:
        q, dq, ddq = state(t)
        friction = exo.friction * np.tanh(dq / FRICTION_SMOOTHING_RAD_S)
        return pin.rnea(model, data, q, dq, ddq) + exo.damping * dq + friction - tau_ext

    nodes, weights = np.polynomial.legendre.leggauss(5)

    def reading(t_k: float) -> np.ndarray:  # the mean over [t_k − h, t_k]
        pairs = zip(nodes, weights, strict=True)
        return sum(w / 2 * sensor(t_k - h / 2 + u * h / 2) for u, w in pairs)

    t = np.arange(round(2.0 / h)) * h
    q = np.array([state(x)[0] for x in t])
    dq = np.array([state(x)[1] for x in t])
    tau = np.array([reading(x) for x in t])
    return t, q, dq, tau


@pytest.mark.parametrize("tau_ext", [(0.0, 0.0, 0.0, 0.0), (12.0, -5.0, 3.0, 8.0)])
def test_smooth_trajectory_gives_the_filtered_external_torque(exo, tau_ext) -> None:
    """Along a smooth motion (4 rad/s peak, sensor torques up to 61 N·m) r = τ_ext (1 − e^{−K t}).

    Independent of the plant: the readings come from Pinocchio's RNEA along an
    analytic q(t).  The observer's discretisation error (the trapezoid on
    ∫ Ṁ q̇ and on n) is second order in h: max |r − τ_ext (1 − e^{−K t})|
    measured 0.0099 N·m at h = 1 ms, 0.0023 at 0.5 ms.  Without the Ṁ q̇
    term (M_k − M_{k-1}) ½ (q̇_{k-1} + q̇_k) it would be 13.5 N·m.
    """
    tau_ext = np.array(tau_ext)
    err = {}
    for h in (1e-3, 0.5e-3):
        t, q, dq, tau = _smooth_readings(exo, h, tau_ext)
        series = estimate_series(t, q, dq, tau, exo, DEFAULT_GAIN_PER_S, dt=h)
        expected = tau_ext * -np.expm1(-DEFAULT_GAIN_PER_S * t)[:, None]
        err[h] = np.abs(series.tau_ext - expected).max()
    print(
        f"\nsmooth motion, τ_ext {tau_ext}: max |r − filtered τ_ext| "
        f"{err[1e-3]:.4f} N·m (h = 1 ms), {err[0.5e-3]:.4f} N·m (0.5 ms)"
    )
    assert err[1e-3] < 0.02
    assert err[0.5e-3] < 0.35 * err[1e-3]  # second order in h


# --------------------------------------------------------------------------- observability


def test_cuff_components_signs_on_hanging_links(exo) -> None:
    """Links hanging straight down: n = +x (forward), u = −z (down), for every cuff."""
    q = np.zeros(4)
    forward = np.tile([10.0, 0.0], (4, 1))
    up = np.tile([0.0, 10.0], (4, 1))
    assert np.allclose(cuff_normal_components(q, forward, exo), 10.0)
    normal, along = cuff_components(q, up, exo)
    assert np.allclose(normal, 0.0, atol=1e-12) and np.allclose(along, -10.0)
    # A forward push on the thigh cuff flexes the hip (s_h = +1), on the shank
    # cuff it extends the knee (s_k = −1): τ = A f⊥.
    a = CuffGeometry.from_body(exo).torque_per_normal_force(q, stiffness_ratio=0.0)
    assert a[0, 0, 0] == pytest.approx(0.39) and a[0, 1, 1] == pytest.approx(-0.45)


def test_normal_components_reproduce_the_external_torque(ideal_run: Run) -> None:
    """What the torques see: normal parts exactly, the thigh's along part not at all."""
    run = ideal_run
    exo = run.exo
    q = run.q_true[::10]
    force = run.force_true[::10]
    g = CuffGeometry.from_body(exo)
    normal, along = cuff_components(q, force, exo)
    # 1. Forces with their along-link parts removed: J_eᵀ (f⊥ n) is solved
    #    back to f⊥ exactly (κ = 0, the normal-only map).
    f_perp = normal[..., None] * g.normals(q)
    tau = true_tau_ext(exo, q, f_perp)
    back, back_force = cuff_forces_from_torque(q, tau, exo, stiffness_ratio=0.0)
    assert np.allclose(back, normal, rtol=0, atol=1e-9)
    assert np.allclose(back_force, f_perp, rtol=0, atol=1e-9)
    # 2. A force along the thigh (hip → cuff) gives no joint torque at all.
    f_thigh = np.zeros_like(force)
    f_thigh[:, 0::2] = 50.0 * g.alongs(q)[:, 0::2]
    assert np.allclose(true_tau_ext(exo, q, f_thigh), 0.0, atol=1e-10)
    # 3. The coaxial structure (f_t = F1 a n_t, f_s = F1 l1 n_k + F2 c n_s) is recovered
    #    in full with κ = 1, including the shank's along component.
    rng = np.random.default_rng(3)
    big_f = rng.normal(0.0, 100.0, size=(q.shape[0], 2, 2))  # (F1, F2) per leg
    _, psi_k, _ = g.directions(q)
    n_k = np.stack((-np.sin(psi_k), np.cos(psi_k)), axis=-1)  # (N, 2 legs, 2)
    nrm = g.normals(q)
    coax = np.zeros_like(force)
    coax[:, 0::2] = big_f[..., :1] * g.thigh_arm[:, None] * nrm[:, 0::2]
    coax[:, 1::2] = (
        big_f[..., :1] * g.knee_arm[:, None] * n_k
        + big_f[..., 1:] * g.shank_arm[:, None] * nrm[:, 1::2]
    )
    got_n, got_f = cuff_forces_from_torque(q, true_tau_ext(exo, q, coax), exo, stiffness_ratio=1.0)
    assert np.allclose(got_f, coax, rtol=0, atol=1e-8)
    assert np.allclose(got_n, cuff_normal_components(q, coax, exo), rtol=0, atol=1e-8)
    # 4. The true forces of the default run: how big the invisible parts are.
    peak_n = np.max(np.abs(normal), axis=0)
    peak_a = np.max(np.abs(along), axis=0)
    print("\ndefault run, peak |along-link component| / peak |normal component|:")
    for c, name in enumerate(CUFF_NAMES):
        print(f"  {name}: {peak_a[c]:.1f} N / {peak_n[c]:.1f} N = {peak_a[c] / peak_n[c]:.2f}")
    assert np.all(peak_a[0::2] < 0.02 * peak_n[0::2])  # thighs: ~1 %, invisible anyway
    assert np.all(peak_a[1::2] > 1.5 * peak_n[1::2])  # shanks: large, hence κ = 1


def test_live_mapping_equals_the_vectorised_one(ideal_run: Run) -> None:
    run = ideal_run
    normal, force = cuff_forces_from_torque(run.q, run.tau_ext, run.exo)
    assert np.allclose(normal, run.normal, rtol=0, atol=1e-10)
    assert np.allclose(force, run.force, rtol=0, atol=1e-10)


# --------------------------------------------------------------------------- accuracy


def test_noise_free_estimate_is_within_one_percent(ideal_run: Run) -> None:
    """Ideal sensors: < 1 % beyond the observer's lag at the default gain; < 1 % raw at 1000/s."""
    raw, vs_filtered = check_accuracy(ideal_run, "ideal sensors, default gain")
    assert np.all(vs_filtered < 0.01)
    # The lag alone (1/K_O = 10 ms) costs a few per cent raw:
    assert np.all(raw < 0.06)
    run = ideal_run
    fast = estimate_series(run.t, run.q, run.dq, run.tau, run.exo, 1000.0, dt=DT)
    errors = normal_component_errors(run.q_true, run.force_true, fast.normal, run.exo, skip=SKIP)
    print(f"\n[ideal sensors, K_O = 1000 1/s ({1000 / 2 / math.pi:.0f} Hz)]")
    show("  RMS error raw", errors.rms_error_rel)
    assert np.all(errors.rms_error_rel < 0.01)
    # The 2-D force (shank: with its along component from the assumption).
    err2 = np.sqrt(np.mean(np.sum((fast.force - run.force_true)[SKIP:] ** 2, axis=-1), axis=0))
    peak2 = np.max(np.linalg.norm(run.force_true, axis=-1), axis=0)
    show("  RMS 2-D force error / peak |f|", err2 / peak2)
    assert np.all(err2 / peak2 < 0.01)


def test_default_sensor_noise_estimate_is_within_five_percent(noisy_run: Run) -> None:
    raw, vs_filtered = check_accuracy(noisy_run, "default sensors, default gain")
    assert np.all(raw < 0.05)
    assert np.all(vs_filtered < 0.05)
    summary = normal_component_errors(
        noisy_run.q_true, noisy_run.force_true, noisy_run.normal, noisy_run.exo, skip=SKIP
    ).summary()
    assert set(summary) == {"cuff_force_estimate_rms_error_N", "cuff_force_estimate_rms_error_rel"}
    assert list(summary["cuff_force_estimate_rms_error_rel"]) == list(CUFF_NAMES)


def test_gain_trade_off_with_default_sensors(noisy_run: Run) -> None:
    """Higher gains cut the lag but pass more speed noise: the default is near the optimum."""
    run = noisy_run
    print("\ndefault sensors, worst-cuff raw RMS error by observer gain:")
    worst = {}
    for gain in (50.0, 100.0, 200.0, 400.0):
        series = estimate_series(run.t, run.q, run.dq, run.tau, run.exo, gain, dt=DT)
        e = normal_component_errors(run.q_true, run.force_true, series.normal, run.exo, skip=SKIP)
        worst[gain] = float(e.rms_error_rel.max())
        print(f"  K_O = {gain:5.0f} 1/s ({gain / 2 / math.pi:4.1f} Hz): {100 * worst[gain]:.2f} %")
    assert worst[100.0] < worst[50.0] and worst[100.0] < worst[400.0]


def test_normal_only_assumption_fails_on_this_device(ideal_run: Run) -> None:
    """κ = 0 (straps carry only normal force) misreads the thigh; the shank is exact either way."""
    run = ideal_run
    by_kappa = {}
    for kappa in (0.0, 1.0):
        s = estimate_series(
            run.t, run.q, run.dq, run.tau, run.exo, 1000.0, dt=DT, stiffness_ratio=kappa
        )
        by_kappa[kappa] = normal_component_errors(
            run.q_true, run.force_true, s.normal, run.exo, skip=SKIP
        ).rms_error_rel
        show(f"\nideal sensors, K_O = 1000, κ = {kappa:g}: RMS error raw", by_kappa[kappa])
    assert np.all(by_kappa[0.0][0::2] > 0.3)
    assert np.allclose(by_kappa[0.0][1::2], by_kappa[1.0][1::2])


def test_human_patient_shank_stays_exact_thigh_is_approximate() -> None:
    """Other anatomy (example-robot-data's human): shank exact, thigh limited by the assumption."""
    run = closed_loop(SensorParams.ideal(), patient="human")
    normal, along = cuff_components(run.q_true, run.force_true, run.exo)
    show(
        "\nhuman patient, peak |along| / peak |normal|",
        np.abs(along).max(0) / np.abs(normal).max(0),
        "",
    )
    errs = {}
    for kappa in (0.0, 1.0):
        s = estimate_series(
            run.t, run.q, run.dq, run.tau, run.exo, 1000.0, dt=DT, stiffness_ratio=kappa
        )
        errs[kappa] = normal_component_errors(
            run.q_true, run.force_true, s.normal, run.exo, skip=SKIP
        ).rms_error_rel
        show(f"human patient, K_O = 1000, κ = {kappa:g}: RMS error raw", errs[kappa])
    assert np.all(errs[1.0][1::2] < 0.01)
    assert np.all(errs[1.0][0::2] < errs[0.0][0::2])


def test_spastic_patient_estimates_stay_within_the_same_bounds() -> None:
    """Noise-free < 1 % raw at K_O = 1000 1/s; default sensors < 5 % raw at the default gain.

    (Against the filtered truth at K_O = 100 the thigh shows 1.1 %: the
    normal component is a nonlinear map of τ_ext whose geometry moves within
    the filter's 10 ms, so filtering the truth's normal component is not
    exactly the observer's output; printed, not asserted.)
    """
    pytest.importorskip("exo_ctrl.plant.patient")
    ideal = closed_loop(SensorParams.ideal(), patient_torque="spastic")
    check_accuracy(ideal, "spastic patient, ideal sensors")
    fast = estimate_series(ideal.t, ideal.q, ideal.dq, ideal.tau, ideal.exo, 1000.0, dt=DT)
    errors = normal_component_errors(
        ideal.q_true, ideal.force_true, fast.normal, ideal.exo, skip=SKIP
    )
    show("  K_O = 1000 1/s: RMS error raw", errors.rms_error_rel)
    assert np.all(errors.rms_error_rel < 0.01)
    noisy = closed_loop(SensorParams(), patient_torque="spastic")
    raw, _ = check_accuracy(noisy, "spastic patient, default sensors")
    assert np.all(raw < 0.05)
    # The spastic patient does load the cuffs more than the passive one.
    assert np.abs(cuff_normal_components(ideal.q_true, ideal.force_true, ideal.exo)).max() > 100.0


# --------------------------------------------------------------------------- bias


def test_bias_effect_bound_numbers(exo) -> None:
    bound = bias_effect_bound([1.0, 0.0, 0.0, 1.0], exo)
    # Thigh: |β_hip| / a; shank: |β_knee| / c (a = 0.39 m, c = 0.45 m, l1 = 0.52 m).
    assert bound == pytest.approx([1 / 0.39, 0.0, (0.97 / 0.45) / 0.39, 1 / 0.45])


def test_torque_bias_shifts_the_estimate_by_its_bounded_effect(ideal_run: Run) -> None:
    """A live run with biased (otherwise ideal) torque sensors against the unbiased one."""
    beta = np.array([1.0, -0.8, 0.5, 0.6])
    biased = closed_loop(dataclasses.replace(SensorParams.ideal(), torque_bias_Nm=tuple(beta)))
    assert np.allclose(biased.tau - ideal_run.tau, beta, atol=1e-9)
    shift = (biased.normal - ideal_run.normal)[300:]  # after 30 observer time constants
    # r → τ_ext − β: the estimate moves by the forces that explain −β.
    exact = cuff_forces_from_torque(biased.q[300:], np.broadcast_to(-beta, (shift.shape[0], 4)))[0]
    bound = bias_effect_bound(beta, biased.exo)
    show("\nbias (1.0, -0.8, 0.5, 0.6) N·m: max |shift of the estimate|", np.abs(shift).max(0), "N")
    show("bound", bound, "N")
    assert np.allclose(shift, exact, atol=1e-6)
    assert np.all(np.abs(shift).max(0) <= bound + 1e-9)
    # The shank's effect is exactly |β_knee| / c.
    assert np.allclose(np.abs(shift[:, 1::2]), np.abs(beta[1::2]) / 0.45, atol=1e-6)


def test_bias_is_detected_from_a_zero_interaction_run_and_removed() -> None:
    """Walk with the straps open (cuffs of negligible stiffness): the mean of r is the bias."""
    beta = (1.0, -0.8, 0.5, 0.6)
    open_straps = CuffParams(stiffness_N_per_m=1e-9, damping_N_s_per_m=0.0)
    calib = closed_loop(SensorParams(torque_bias_Nm=beta), cuffs=open_straps)
    found = estimate_bias(calib.tau_ext[100:], calib.exo)
    print("\nzero-interaction run with default sensors and a bias:\n" + found.report())
    assert np.all(found.detected)
    assert np.allclose(found.bias_Nm, beta, atol=0.05)
    clean = closed_loop(SensorParams(seed=1), cuffs=open_straps)
    none = estimate_bias(clean.tau_ext[100:], clean.exo)
    print("same without a bias:\n" + none.report())
    assert not np.any(none.detected)
    # Strapped run with the same biased sensors: uncorrected vs corrected.
    strapped = closed_loop(SensorParams(torque_bias_Nm=beta))
    raw_biased, _ = check_accuracy(strapped, "biased sensors, uncorrected")
    fixed = estimate_series(
        strapped.t,
        strapped.q,
        strapped.dq,
        strapped.tau,
        strapped.exo,
        dt=DT,
        torque_bias_Nm=found.bias_Nm,
    )
    errors = normal_component_errors(
        strapped.q_true, strapped.force_true, fixed.normal, strapped.exo, skip=SKIP
    )
    show("  corrected with the estimated bias: RMS error raw", errors.rms_error_rel)
    assert np.all(errors.rms_error_rel < 0.05)
    # The uncorrected bias was visible (shanks: |β_knee| / c ≈ 1.3–1.8 N constant offset).
    assert np.max(raw_biased) > 0.05
    assert np.all(raw_biased[1::2] > errors.rms_error_rel[1::2] + 0.005)


# --------------------------------------------------------------------------- offline


def test_offline_series_equals_the_live_estimate(noisy_run: Run) -> None:
    run = noisy_run
    series = estimate_series(run.t, run.q, run.dq, run.tau, run.exo, run.gain, dt=DT)
    assert np.max(np.abs(series.normal - run.normal)) < 1e-12
    assert np.max(np.abs(series.force - run.force)) < 1e-12
    assert np.max(np.abs(series.tau_ext - run.tau_ext)) < 1e-12


def test_csv_log_round_trip_gives_the_same_estimate(noisy_run: Run, tmp_path: Path) -> None:
    run = noisy_run
    path = write_csv_log(tmp_path / "log.csv", run.t, run.q, run.dq, run.tau)
    assert path.read_text().splitlines()[0] == ",".join(
        [*CSV_REQUIRED_COLUMNS, "left_hip_dq", "left_knee_dq", "right_hip_dq", "right_knee_dq"]
    )
    t, q, dq, tau = read_csv_log(path)
    assert np.array_equal(t, run.t) and np.array_equal(q, run.q)
    assert np.array_equal(dq, run.dq) and np.array_equal(tau, run.tau)
    series = estimate_series(t, q, dq, tau, run.exo, run.gain, dt=DT)
    assert np.max(np.abs(series.normal - run.normal)) < 1e-12
    # Steps taken from t itself differ from dt by rounding only.
    series_t = estimate_series(t, q, dq, tau, run.exo, run.gain)
    assert np.max(np.abs(series_t.normal - run.normal)) < 1e-6


def test_csv_log_written_by_hand_with_extra_columns(noisy_run: Run, tmp_path: Path) -> None:
    """A user's file: documented header in another order, an extra column, no dq."""
    run = noisy_run
    n = 400
    header = (
        "right_knee_tau,t,left_hip_q,left_knee_q,right_hip_q,right_knee_q,"
        "left_hip_tau,left_knee_tau,right_hip_tau,comment"
    )
    lines = [header]
    for k in range(n):
        vals = [run.tau[k, 3], run.t[k], *run.q[k], *run.tau[k, :3]]
        lines.append(",".join(repr(float(x)) for x in vals) + ",ok")
    (tmp_path / "user.csv").write_text("\n".join(lines) + "\n")
    t, q, dq, tau = read_csv_log(tmp_path / "user.csv")
    assert dq is None
    assert np.array_equal(q, run.q[:n]) and np.array_equal(tau, run.tau[:n])
    # Without speeds, q is differentiated: close to the live estimate, not equal.
    series = estimate_series(t, q, None, tau, run.exo, run.gain)
    err = np.sqrt(np.mean((series.normal - run.normal[:n])[SKIP:] ** 2, axis=0))
    show("\nCSV without dq (speed by differentiation) vs live: RMS difference", err, "N")
    assert np.all(err < 5.0)


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


HEADER = ",".join(CSV_REQUIRED_COLUMNS)
ROW = "0.0,0.1,0.2,0.3,0.4,1,2,3,4"


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("", "the file is empty; expected a header line"),
        (
            "t,left_hip_q,left_knee_q,right_hip_q,right_knee_q,left_hip_tau\n",
            "line 1: missing column(s) left_knee_tau, right_hip_tau, right_knee_tau",
        ),
        (
            HEADER + ",left_hip_dq\n" + ROW + ",0\n",
            "line 1: has left_hip_dq but not left_knee_dq: give all four *_dq or none",
        ),
        (HEADER + "\n" + ROW + "\n", "needs at least 2 data rows; got 1"),
        (
            HEADER
            + "\n"
            + ROW
            + "\n"
            + ROW.replace("0.0,", "0.001,", 1).replace("0.3", "nan")
            + "\n",
            "line 3, column 'right_hip_q': not a finite number: 'nan'",
        ),
        (
            HEADER + "\n" + ROW + "\n" + ROW.replace("0.2", "abc") + "\n",
            "line 3, column 'left_knee_q': not a number: 'abc'",
        ),
        (
            HEADER + "\n" + ROW + "\n" + ROW.replace("0.0,", "0.002,", 1) + "\n" + ROW + "\n",
            "line 4, column 't': t must be strictly increasing; t = 0.0 s follows t = 0.002 s",
        ),
        (HEADER + "\n" + ROW + "\n0.001,1,2\n", "line 3: 3 fields, the header has 9"),
    ],
)
def test_csv_errors_name_the_line_and_column(tmp_path: Path, text: str, message: str) -> None:
    path = _write(tmp_path / "bad.csv", text)
    with pytest.raises(InvalidLog) as info:
        read_csv_log(path)
    assert str(info.value).startswith(f"invalid log {path}")
    assert message in str(info.value)
    assert isinstance(info.value, ExoCtrlError) and isinstance(info.value, ValueError)


def test_missing_csv_file(tmp_path: Path) -> None:
    with pytest.raises(InvalidLog, match="file not found"):
        read_csv_log(tmp_path / "nope.csv")


def test_bad_series_and_parameters_are_refused(exo) -> None:
    t = np.arange(5) * DT
    q = np.zeros((5, 4))
    with pytest.raises(InvalidLog, match=r"q must have shape \(5, 4\) like t; got \(5, 3\)"):
        estimate_series(t, q[:, :3], None, q, exo)
    with pytest.raises(InvalidLog, match=r"t must be strictly increasing; t\[2\] = 0.001"):
        estimate_series(np.array([0, 1e-3, 1e-3, 2e-3, 3e-3]), q, None, q, exo)
    bad = q.copy()
    bad[3, 1] = np.nan
    with pytest.raises(InvalidLog, match="tau has a non-finite value in row 3"):
        estimate_series(t, q, None, bad, exo)
    with pytest.raises(InvalidLog, match=r"t is not sampled every dt = 0\.002 s"):
        estimate_series(t, q, None, q, exo, dt=2e-3)
    with pytest.raises(InvalidParameter, match=r"gain must be > 0 1/s; got 0\.0"):
        CuffForceEstimator(exo, DT, 0.0)
    with pytest.raises(InvalidParameter, match=r"stiffness_ratio must be >= 0; got -1\.0"):
        CuffForceEstimator(exo, DT, stiffness_ratio=-1.0)
    with pytest.raises(InvalidParameter, match="shapes"):
        cuff_normal_components(np.zeros(4), np.zeros((4, 3)), exo)
    with pytest.raises(InvalidParameter, match=r"tau_ext must be shape \(N, 4\) with N >= 10"):
        estimate_bias(np.zeros((5, 4)), exo)


# --------------------------------------------------------------------------- cost


def test_reset_and_update_cost(exo, ideal_run: Run) -> None:
    """Per-tick cost against the floor of its two Pinocchio calls (printed, loose bound)."""
    run = ideal_run
    est = CuffForceEstimator(exo, DT)
    est.reset(run.q[0], run.dq[0])
    assert np.all(est.normal == 0)

    readings = [SensorReadings(run.q[k], run.dq[k], run.tau[k]) for k in range(1, 1001)]
    start = time.perf_counter()
    for r in readings:
        est.update(r)
    tick = (time.perf_counter() - start) / len(readings)
    # reset(q0, dq0) then updates from row 1 is the live run started at row 0.
    assert np.allclose(est.normal, run.normal[1000], rtol=0, atol=1e-12)
    model = pin.Model(exo.model)
    data = model.createData()
    start = time.perf_counter()
    for r in readings:
        pin.crba(model, data, r.q)
        pin.nonLinearEffects(model, data, r.q, r.dq)
    floor = (time.perf_counter() - start) / len(readings)
    print(
        f"\nestimator update {tick * 1e6:.1f} µs, Pinocchio floor {floor * 1e6:.1f} µs, "
        f"ratio {tick / floor:.1f}"
    )
    assert tick / floor < 25


def test_running_error_stats_match_the_offline_errors(noisy_run: Run) -> None:
    """Fed with simulate()'s rows in chunks (cuff_force row k = force over [t_k, t_k+1))."""
    run = noisy_run
    n = run.t.shape[0] - 1
    q_sim, force_sim, normal_sim = run.q_true[:n], run.force_true[1:], run.normal[:n]
    stats = EstimateErrorStats(run.exo, DT, skip_s=SKIP_S)
    for lo, hi in ((0, 30), (30, 700), (700, 1400), (1400, n)):
        stats.update(q_sim[lo:hi], force_sim[lo:hi], normal_sim[lo:hi])
    offline = normal_component_errors(
        run.q_true[:n], run.force_true[:n], run.normal[:n], run.exo, skip=SKIP
    )
    lagged = normal_component_errors(q_sim, force_sim, normal_sim, run.exo, skip=SKIP, lag=1)
    got = stats.result()
    assert got.rows == offline.rows == lagged.rows == n - SKIP
    for ref in (offline, lagged):
        assert np.allclose(got.rms_error_N, ref.rms_error_N, rtol=1e-12)
        assert np.allclose(got.peak_true_N, ref.peak_true_N, rtol=1e-12)
        assert np.allclose(got.max_error_N, ref.max_error_N, rtol=1e-12)
    summary = stats.summary()
    assert summary["cuff_force_estimate_rms_error_rel"]["left_shank"] == pytest.approx(
        offline.rms_error_rel[1]
    )


def test_readings_of_the_wrong_length_are_refused_by_name() -> None:
    setup = build(SimConfig())
    est = CuffForceEstimator(setup.exo, 1e-3)
    q = setup.plan.q[0].copy()
    est.update(SensorReadings(q=q, dq=np.zeros(4), tau=np.zeros(4)))
    before = est.outputs_flat.copy()
    with pytest.raises(InvalidParameter, match=r"^tau must be an array of shape \(4,\)"):
        est.step(q, np.zeros(4), np.zeros(3), 1e-3)
    with pytest.raises(InvalidParameter, match=r"^dq must be an array of shape \(4,\)"):
        est.step(q, np.zeros(5), np.zeros(4), 1e-3)
    np.testing.assert_array_equal(est.outputs_flat, before)  # no effect
