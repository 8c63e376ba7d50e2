"""Closed-loop runs with the live estimator, shared by the estimation tests.

Every run here is the closed loop that :func:`exo_ctrl.sim.loop.simulate`
runs (CT controller, default gait: 2 cycles, 2.4 s), with the sensors and the
estimator in the loop: per tick, readings = sensors.read(k, plant state),
estimate = estimator.update(readings), u = controller.command(k, readings),
plant.step(u).  The truth logged with row k is what the reading of tick k
reflects: the cuff force over the previous plant step (plant.cuff_force
before stepping).

Independent references: the true external joint torque J_eᵀ f is computed
with Pinocchio's frame Jacobians at the posture where the plant evaluated
the cuffs (mid-step), not with the plant's own cuff code.

Errors are RMS over the run after a start-up of SKIP_S = 50 ms (five
observer time constants at K_O = 100 1/s), per cuff, relative to the peak
|true normal component| of that cuff.  "Raw" compares with the truth
itself; "vs filtered truth" compares with the truth passed through the
observer's own first-order filter, which separates the observer's lag
(1/K_O) from its errors.

The helpers are fixtures (``closed_loop``, ``true_tau_ext``, ``show``,
``check_accuracy``, ``coupled_torques``) as test modules cannot import each other.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
import pytest

from exo_ctrl.estimation import (
    DEFAULT_GAIN_PER_S,
    CuffForceEstimator,
    cuff_normal_components,
    first_order_filter,
    normal_component_errors,
)
from exo_ctrl.model import CUFF_NAMES, FRICTION_SMOOTHING_RAD_S, BodyModel
from exo_ctrl.plant.cuff_scatter import CuffScatter
from exo_ctrl.plant.cuffs import CuffParams
from exo_ctrl.sensing.sensors import SensorParams, Sensors
from exo_ctrl.sim import SimConfig, build, start_on_plan
from exo_ctrl.sim.belief import Belief

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


def run_closed_loop(
    sensor_params: SensorParams,
    gain: float = DEFAULT_GAIN_PER_S,
    *,
    patient: str | None = None,
    cuffs: CuffParams | None = None,
    patient_torque: str | None = None,
    torque_bias_Nm: np.ndarray | float = 0.0,
) -> Run:
    """Run the CT closed loop on the default gait with sensors and estimator in the loop."""
    config = SimConfig(
        controller="ct",
        patient=patient,
        cuffs=cuffs or CuffParams.isotropic(),
        cuff_scatter=CuffScatter.exact(),  # the true cuffs are the given ones, unscattered
        belief=Belief("truth"),  # the figures of these tests: CT knowing its patient
    )
    setup = build(config)
    plant = setup.plant
    start_on_plan(setup)  # as simulate() starts
    sensors = Sensors(sensor_params, config.dt)
    estimator = CuffForceEstimator(setup.device_exo, config.dt, gain, torque_bias_Nm)
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


def compute_true_tau_ext(exo: BodyModel, q: np.ndarray, force: np.ndarray) -> np.ndarray:
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


def exact_coupled_torques(exo: BodyModel, patient: BodyModel, q, dq, ddq) -> np.ndarray:
    """τ_s of the rigidly coupled bodies along (q, q̇, q̈): both RNEAs, URDF damping and friction."""
    ed, pd = exo.model.createData(), patient.model.createData()
    tau = np.empty_like(q)
    for i in range(q.shape[0]):
        e = pin.rnea(
            exo.model, ed, exo.to_model_q(q[i]), exo.to_model_q(dq[i]), exo.to_model_q(ddq[i])
        )
        p = pin.rnea(
            patient.model,
            pd,
            patient.to_model_q(q[i]),
            patient.to_model_q(dq[i]),
            patient.to_model_q(ddq[i]),
        )
        tau[i] = (
            e[exo.q_index]
            + p[patient.q_index]
            + exo.damping * dq[i]
            + exo.friction * np.tanh(dq[i] / FRICTION_SMOOTHING_RAD_S)
            + patient.damping * dq[i]
        )
    return tau


def rel_errors(est: np.ndarray, truth: np.ndarray, peak: np.ndarray) -> np.ndarray:
    err = est[SKIP:] - truth[SKIP:]
    return np.sqrt(np.mean(err**2, axis=0)) / peak


def show_values(label: str, values: np.ndarray, unit: str = "%") -> None:
    scale = 100.0 if unit == "%" else 1.0
    body = ", ".join(f"{c} {scale * x:.2f}" for c, x in zip(CUFF_NAMES, values, strict=True))
    print(f"{label}: {body} {unit}")


def accuracy(run: Run, label: str) -> tuple[np.ndarray, np.ndarray]:
    """Raw and filtered-truth relative RMS errors of the normal components (printed)."""
    true_n = cuff_normal_components(run.q_true, run.force_true, run.exo)
    errors = normal_component_errors(run.q_true, run.force_true, run.normal, run.exo, skip=SKIP)
    filtered = first_order_filter(true_n, DT, run.gain)
    vs_filtered = rel_errors(run.normal, filtered, errors.peak_true_N)
    print(f"\n[{label}] K_O = {run.gain:g} 1/s ({run.gain / 2 / math.pi:.1f} Hz), skip {SKIP_S} s")
    show_values("  peak true normal component", errors.peak_true_N, "N")
    show_values("  RMS error raw", errors.rms_error_rel)
    show_values("  RMS error raw", errors.rms_error_N, "N")
    show_values("  RMS error vs filtered truth", vs_filtered)
    show_values("  max error raw", errors.max_error_N, "N")
    return errors.rms_error_rel, vs_filtered


# --------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="session")
def ideal_run() -> Run:
    return run_closed_loop(SensorParams.ideal())


@pytest.fixture(scope="session")
def noisy_run() -> Run:
    return run_closed_loop(SensorParams())


@pytest.fixture
def closed_loop() -> Callable[..., Run]:
    """:func:`run_closed_loop`: a closed-loop run with other sensors, patient or cuffs."""
    return run_closed_loop


@pytest.fixture
def true_tau_ext() -> Callable[[BodyModel, np.ndarray, np.ndarray], np.ndarray]:
    """:func:`compute_true_tau_ext`: Σ J_cᵀ f_c from Pinocchio's frame Jacobians."""
    return compute_true_tau_ext


@pytest.fixture
def show() -> Callable[..., None]:
    """:func:`show_values`: print one value per cuff."""
    return show_values


@pytest.fixture
def check_accuracy() -> Callable[[Run, str], tuple[np.ndarray, np.ndarray]]:
    """:func:`accuracy`: raw and filtered-truth relative RMS errors (printed)."""
    return accuracy


@pytest.fixture
def coupled_torques() -> Callable[..., np.ndarray]:
    """:func:`exact_coupled_torques`: the torque sensors' exact reading along a motion."""
    return exact_coupled_torques
