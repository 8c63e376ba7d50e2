r"""The patient's segment inertial parameters from a calibration run's encoders and torque sensors.

**Model.**  The cuffs are taken as rigid: exoskeleton and patient move as one
body per segment, with the patient's joint angles those of the exoskeleton
(coaxial joints).  That holds below the cuffs' natural frequency (about 8 Hz
for the shank on 8 N/mm) and without misalignment; the data are low-passed
well below it (:data:`DEFAULT_CUTOFF_HZ`), which also removes the cuffs' own
oscillation.  The patient's sag in the straps (25 mrad mean at the hip on
the default calibration with the default cuffs) is neglected: it shows as a
COM off the link's axis (the thigh's m c_x, about -0.04 kg·m there), and the
cuffs' dynamics still add a few percent to the shank's inertia (4 % on that
run).  The joint torque sensors (gearbox to link, the rotor on the far
side) then read

    τ_s = ID_exo(q, q̇, q̈) + b_e q̇ + f_e tanh(q̇/ε) + Y(q, q̇, q̈) π + b_p q̇,

with ID_exo the exoskeleton's link inverse dynamics (RNEA of its URDF, known),
b_e, f_e its URDF damping and dry friction (link side), Y Pinocchio's joint
torque regressor (``computeJointTorqueRegressor``) of the patient's model,
π its standard parameters (per link m, m c, I at the joint frame: 10) and
b_p the patient's joint damping.  The patient is taken as symmetric (both
legs one set of parameters: the generated patients' links have the same
frames on both sides), so the columns of the two thighs are summed, and of
the two shanks: 21 columns.

**Base parameters.**  QR of the stacked regressor (columns normalised, in
the order thigh π, shank π, b_p, so that the choice is the same on every
run): a column whose R_ii is not above :data:`RANK_TOL` of the largest
depends on those before it.  The r independent columns are W_b; the
others are W_d = W_b K, so W π = W_b β with β = π_b + K π_d, the base
parameters (7 in the sagittal plane: per segment I_yy, m c_x, m c_z, with the
shank's mass folded into the thigh's, and b_p).

**Estimate.**  β̂ = argmin ‖W_b β - y‖² / σ² + ‖β - β₀‖²_{Σ₀⁻¹}: the
nominal patient β₀ (de Leva, :func:`~exo_ctrl.model.nominal_patient`) as a
Gaussian prior, Σ₀ from the spreads of :class:`PriorSpread` mapped through
the base map; σ² from the residual of the unregularised fit, so that on
noise-free data the prior's weight vanishes.  The standard errors are the
square roots of the diagonal of σ² (W_bᵀW_b + σ² Σ₀⁻¹)⁻¹, taking the residual
white at the decimated rate (a lower bound where it is not).

**Physical consistency** (:mod:`exo_ctrl.estimation.segment_fit`).  The
URDF written is a :class:`~exo_ctrl.model.BodyParams`: per segment a mass
m, a centre of mass c L on the link's axis and a transverse radius of
gyration ρ L, fitted to β̂ (weighted by its covariance) with the prior on
them, m = m₀ e^μ and ρ, c bounded: every answer is a positive mass with a
positive-definite inertia.

**Not excited** (:mod:`exo_ctrl.estimation.excitation`).  With the hips
fixed, no motion and no joint-side sensor separates a segment's mass from
its COM and gyration ratios: per segment only m c L and the moment about
the joint m L² (ρ² + c²) are seen (the shank's mass also only through the
thigh's).  Two directions of (m, c, ρ) of the two segments leave every
joint torque unchanged; along them the answer is the prior's, with the
cohort's spreads (:class:`PriorSpread`: mass 10 %, COM ratio 4 %, gyration
ratio 5 %).  The masses are then as good as the prior's ratios: the
identification prints those directions (:attr:`Identification.excitation`).
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from .. import _validate as v
from ..exceptions import InvalidLog, InvalidParameter
from ..model import FRICTION_SMOOTHING_RAD_S, BodyModel, BodyParams, load_patient, write_urdf
from .excitation import ExcitationReport, excitation_report
from .segment_fit import (
    SEGMENTS,
    PriorSpread,
    body_params_of,
    jacobian,
    physical_fit,
    standard_of,
    theta_prior,
    theta_sigma,
)

__all__ = [
    "DEFAULT_CUTOFF_HZ",
    "CalibrationSamples",
    "Identification",
    "PriorSpread",
    "body_model",
    "calibration_samples",
    "identify_patient",
    "standard_parameters",
    "zero_phase_lowpass",
]

#: Cut-off of the fit's zero-phase low-pass [Hz]: above the calibration's
#: fastest sine (1.05 Hz), well below the cuffs' ~8 Hz (at 3 Hz the cuffs'
#: dynamics leak into the shank's inertia).
DEFAULT_CUTOFF_HZ = 2.0

#: Cut-off of the zero-phase low-pass on the encoder angles before they are
#: differentiated [Hz] (the fit's low-pass follows, :data:`DEFAULT_CUTOFF_HZ`).
DIFFERENTIATION_CUTOFF_HZ = 25.0

#: Samples kept per cut-off period after filtering (decimation).
SAMPLES_PER_CUTOFF = 10

#: Names of Pinocchio's 10 standard parameters of a link, in its order.
STANDARD_NAMES = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz")

#: Relative rank tolerance of the QR (columns normalised).
RANK_TOL = 1e-9


@dataclass(frozen=True)
class CalibrationSamples:
    """Joint motion and torque readings at a uniform rate, (N, 4) each, JOINT_NAMES order.

    Attributes:
        step_s: the sampling interval [s].
        q: joint angles [rad].
        dq: joint speeds [rad/s].
        ddq: joint accelerations [rad/s²].
        tau: joint torque sensor readings [N·m].
        cutoff_hz: the low-pass applied to the regressor and the torques
            before the fit (parallel filtering) [Hz]; None: none (exact data).
        source: where the samples come from (for messages).

    """

    step_s: float
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    tau: np.ndarray
    cutoff_hz: float | None = DEFAULT_CUTOFF_HZ
    source: str = "arrays"


def calibration_samples(
    t: np.ndarray,
    q: np.ndarray,
    tau: np.ndarray,
    cutoff_hz: float = DEFAULT_CUTOFF_HZ,
    source: str = "arrays",
) -> CalibrationSamples:
    """A logged calibration run made ready for :func:`identify_patient`.

    The series is resampled onto a uniform grid (linear interpolation); the
    encoder angles are smoothed by a zero-phase low-pass
    (:func:`zero_phase_lowpass`) at :data:`DIFFERENTIATION_CUTOFF_HZ`, and
    speeds and accelerations taken as central differences of them.
    The fit then low-passes the regressor's columns and the torques by the
    same filter at ``cutoff_hz`` (parallel filtering: the model is linear in
    the parameters, so the filtered torques are the filtered columns times
    the parameters exactly, where filtering the angles alone would not be).

    Args:
        t: sample times [s], strictly increasing, (N,).
        q: encoder angles [rad], (N, 4).
        tau: torque sensor readings [N·m], (N, 4).
        cutoff_hz: the low-pass cut-off of the fit [Hz].
        source: where the series comes from (for messages).

    Raises:
        InvalidLog: times not increasing, or a run too short for the filter.
        InvalidParameter: a cut-off not below the Nyquist rate, or above the
            differentiation's.

    """
    cutoff = v.positive("cutoff", cutoff_hz, "Hz")
    t = np.asarray(t, dtype=float)
    if t.size < 2 or not np.all(np.diff(t) > 0.0):
        raise InvalidLog(source, "its times must be strictly increasing (at least 2 samples)")
    h = float(np.median(np.diff(t)))
    smooth_hz = min(DIFFERENTIATION_CUTOFF_HZ, 0.4 / h)
    if cutoff >= smooth_hz:
        sampled = (
            f"; the log is sampled every {h:.4g} s" if smooth_hz < DIFFERENTIATION_CUTOFF_HZ else ""
        )
        raise InvalidParameter(
            "cutoff", cutoff_hz, f"< {smooth_hz:g} Hz (the differentiation's low-pass{sampled})"
        )
    lasts = t[-1] - t[0]
    # 4 cut-off periods, compared in seconds first: a step or cut-off so small
    # that the count of samples overflows is refused here
    if lasts < 4.0 / cutoff or lasts / h < 4 * _edge(cutoff, h):
        need = 4.0 / cutoff if lasts < 4.0 / cutoff else 4 * _edge(cutoff, h) * h
        least = f"{need:.4g} s" if math.isfinite(need) else "four periods"
        raise InvalidLog(
            source,
            f"it lasts {lasts:.4g} s; identification needs at least {least} "
            f"at a {cutoff:g} Hz cut-off",
        )
    grid = t[0] + h * np.arange(math.floor(lasts / h + 1e-9) + 1)
    q = np.asarray(q, dtype=float)
    tau = np.asarray(tau, dtype=float)
    qg = np.column_stack([np.interp(grid, t, q[:, j]) for j in range(4)])
    tg = np.column_stack([np.interp(grid, t, tau[:, j]) for j in range(4)])
    qf = zero_phase_lowpass(qg, smooth_hz, h)
    dq = np.gradient(qf, h, axis=0)
    ddq = np.gradient(dq, h, axis=0)
    return CalibrationSamples(h, qf, dq, ddq, tg, cutoff, source)


def zero_phase_lowpass(x: np.ndarray, cutoff_hz: float, step_s: float) -> np.ndarray:
    """Low-pass ``x`` along axis 0 with the gain of a 4th-order Butterworth filter run twice.

    The gain 1 / (1 + (f / f_c)^8), phase zero (what a forward-backward
    Butterworth filter gives), applied in the frequency domain to x extended
    at each end by its odd reflection about the end sample (three cut-off
    periods) less the straight line between the extension's ends, so that
    the periodic extension the transform assumes has no jump.

    Args:
        x: samples at a uniform rate, (N, ...).
        cutoff_hz: f_c [Hz].
        step_s: the sampling interval [s].

    """
    n = x.shape[0]
    pad = min(3 * _edge(cutoff_hz, step_s), n - 1)
    head = 2.0 * x[:1] - x[pad:0:-1]
    tail = 2.0 * x[-1:] - x[-2 : -pad - 2 : -1]
    ext = np.concatenate((head, x, tail), axis=0)
    m = ext.shape[0]
    shape = (-1,) + (1,) * (x.ndim - 1)
    ramp = np.linspace(0.0, 1.0, m).reshape(shape)
    line = ext[:1] + (ext[-1:] - ext[:1]) * ramp
    freq = np.fft.rfftfreq(m, step_s)
    gain = 1.0 / (1.0 + (freq / cutoff_hz) ** 8)
    spectrum = np.fft.rfft(ext - line, axis=0) * gain.reshape(shape)
    return (np.fft.irfft(spectrum, n=m, axis=0) + line)[pad : pad + n]


def _edge(cutoff_hz: float, step_s: float) -> int:
    """Samples dropped at each end after filtering: one cut-off period."""
    return math.ceil(1.0 / (cutoff_hz * step_s))


def _filtered(w: np.ndarray, y: np.ndarray, samples: CalibrationSamples):
    """The regressor (N, 4, 21) and torques (N, 4) low-passed, trimmed and decimated."""
    if samples.cutoff_hz is None:
        return w, y
    h, cutoff = samples.step_s, samples.cutoff_hz
    edge = _edge(cutoff, h)
    step = max(round(1.0 / (cutoff * h * SAMPLES_PER_CUTOFF)), 1)
    keep = slice(edge, w.shape[0] - edge, step)
    return zero_phase_lowpass(w, cutoff, h)[keep], zero_phase_lowpass(y, cutoff, h)[keep]


def body_model(params: BodyParams) -> BodyModel:
    """The model of generated patient parameters (written to a temporary file and loaded)."""
    with tempfile.TemporaryDirectory(prefix="exo_ctrl_patient_") as folder:
        return load_patient(str(write_urdf(params, Path(folder) / "patient.urdf")))


def standard_parameters(patient: BodyModel) -> np.ndarray:
    """The symmetric patient's parameters (21,): thigh π (10), shank π (10), damping b_p.

    π per segment is the mean of its left and right links' Pinocchio
    dynamic parameters (at the joint frame); b_p the mean URDF damping.
    """
    ids = patient.joint_ids
    out = np.empty(21)
    for s in range(2):
        pair = [patient.model.inertias[ids[2 * leg + s]].toDynamicParameters() for leg in range(2)]
        out[10 * s : 10 * s + 10] = 0.5 * (pair[0] + pair[1])
    out[20] = float(np.mean(patient.damping))
    return out


def _regressor(
    exo: BodyModel, patient: BodyModel, samples: CalibrationSamples
) -> tuple[np.ndarray, np.ndarray]:
    """Stacked regressor W (4M, 21) and the patient's torque y = τ_s - exo's (4M,), filtered."""
    em, ed = exo.model, exo.model.createData()
    pm, pd = patient.model, patient.model.createData()
    n = samples.q.shape[0]
    rows = np.empty((n, 4, 21))
    y = np.empty((n, 4))
    ids = [pm.joints[j].idx_v for j in patient.joint_ids]
    bodies = [j - 1 for j in patient.joint_ids]
    b_e, f_e = exo.damping, exo.friction
    for i in range(n):
        q, dq, ddq = samples.q[i], samples.dq[i], samples.ddq[i]
        tau_exo = pin.rnea(em, ed, exo.to_model_q(q), exo.to_model_q(dq), exo.to_model_q(ddq))
        y[i] = (
            samples.tau[i]
            - tau_exo[exo.q_index]
            - b_e * dq
            - f_e * np.tanh(dq / FRICTION_SMOOTHING_RAD_S)
        )
        full = pin.computeJointTorqueRegressor(
            pm, pd, patient.to_model_q(q), patient.to_model_q(dq), patient.to_model_q(ddq)
        )[ids]
        for s in range(2):
            cols = [
                full[:, 10 * bodies[2 * leg + s] : 10 * bodies[2 * leg + s] + 10] for leg in (0, 1)
            ]
            rows[i, :, 10 * s : 10 * s + 10] = cols[0] + cols[1]
        rows[i, :, 20] = dq
    rows, y = _filtered(rows, y, samples)
    return rows.reshape(-1, 21), y.reshape(-1)


def _column_name(k: int) -> str:
    return "b_p" if k == 20 else f"{SEGMENTS[k // 10]}.{STANDARD_NAMES[k % 10]}"


@dataclass
class Identification:
    """The result of :func:`identify_patient`.

    Attributes:
        names: the base parameters, each its independent column plus the
            dependent ones folded in (``thigh.Iyy + 0.27 shank.m``).
        estimate: β̂ [SI].
        standard_error: their standard errors [SI].
        prior: β₀, the nominal patient's [SI].
        condition_number: of the base regressor with normalised columns [-].
        residual_rms_Nm: RMS of y - W_b β̂ [N·m].
        samples: rows of the stacked regressor used (4 per sample).
        patient: the identified, physically consistent patient.
        physical: per segment mass [kg], COM and gyration ratios [-] and
            their standard errors, and the damping [N·m·s/rad].
        base_map: T (r, 21), β = T π.
        excitation: the parameters the run does not excite (and whose
            values are the prior's), :mod:`~exo_ctrl.estimation.excitation`.

    """

    names: list[str]
    estimate: np.ndarray
    standard_error: np.ndarray
    prior: np.ndarray
    condition_number: float
    residual_rms_Nm: float
    samples: int
    patient: BodyParams
    physical: dict[str, dict[str, float]] = field(default_factory=dict)
    base_map: np.ndarray = field(default_factory=lambda: np.zeros((0, 21)))
    excitation: ExcitationReport | None = None

    def base_of(self, patient: BodyModel) -> np.ndarray:
        """β = T π of a patient model (e.g. the truth, to compare)."""
        return self.base_map @ standard_parameters(patient)

    def summary(self) -> dict[str, Any]:
        """Plain-data form (JSON-able)."""
        return {
            "samples": self.samples // 4,
            "condition_number": self.condition_number,
            "residual_rms_Nm": self.residual_rms_Nm,
            "base_parameters": [
                {"name": n, "estimate": float(b), "std_err": float(se), "prior": float(p)}
                for n, b, se, p in zip(
                    self.names, self.estimate, self.standard_error, self.prior, strict=True
                )
            ],
            "physical": {k: {f: float(x) for f, x in d.items()} for k, d in self.physical.items()},
            "not_excited": self.excitation.summary() if self.excitation else None,
        }

    def table(self) -> str:
        """Estimates, standard errors and priors as text."""
        lines = [
            f"{self.samples // 4} samples, condition number {self.condition_number:.3g} "
            f"(columns normalised), residual {self.residual_rms_Nm:.3g} N·m RMS",
            f"{'base parameter':<44}{'estimate':>12}{'std err':>11}{'prior':>12}",
        ]
        for name, b, se, p in zip(
            self.names, self.estimate, self.standard_error, self.prior, strict=True
        ):
            lines.append(f"{name:<44}{b:>12.5g}{se:>11.3g}{p:>12.5g}")
        lines.append(f"{'physical (URDF)':<44}{'estimate':>12}{'std err':>11}{'prior':>12}")
        for name, d in self.physical.items():
            lines.append(
                f"{name:<44}{d['estimate']:>12.5g}{d['std_err']:>11.3g}{d['prior']:>12.5g}"
            )
        if self.excitation is not None:
            lines += self.excitation.lines()
        return "\n".join(lines)


def _base_map(w: np.ndarray, source: str) -> tuple[np.ndarray, np.ndarray, list[str], np.ndarray]:
    """T (r, 21) with β = T π, the base columns, their names and the column norms.

    Raises:
        InvalidLog: fewer than 7 base parameters excited, or no more rows than them.

    """
    norms = np.linalg.norm(w, axis=0)
    scale = np.where(norms > 0.0, norms, 1.0)
    diag = np.abs(np.diag(np.linalg.qr(w / scale, mode="r")))
    independent = diag > RANK_TOL * diag.max()
    base, dep = np.flatnonzero(independent), np.flatnonzero(~independent)
    rank = base.size
    if rank < 7 or w.shape[0] <= rank:
        raise InvalidLog(
            source,
            f"the calibration excites {rank} base parameters in {w.shape[0]} rows; "
            "the sagittal model has 7 (a run of the calibration exercise excites them all)",
        )
    k = np.linalg.lstsq(w[:, base], w[:, dep], rcond=None)[0]
    k[np.abs(k) < 1e-10] = 0.0
    t_map = np.zeros((rank, 21))
    t_map[np.arange(rank), base] = 1.0
    t_map[:, dep] = k
    names = []
    for i, col in enumerate(base):
        terms = [_column_name(col)]
        terms += [f"{k[i, d]:+.4g} {_column_name(c)}" for d, c in enumerate(dep) if k[i, d]]
        names.append(" ".join(terms))
    return t_map, base, names, scale


def identify_patient(
    samples: CalibrationSamples,
    exo: BodyModel,
    prior_model: BodyModel,
    prior: BodyParams,
    spread: PriorSpread | None = None,
) -> Identification:
    """Identify the patient's base and physical parameters (module docstring).

    Args:
        samples: the calibration's motion and readings (:func:`calibration_samples`).
        exo: the exoskeleton model (known).
        prior_model: the nominal patient's model (its kinematics define the regressor).
        prior: the nominal patient's parameters (the prior, and the fields not identified).
        spread: the prior's spreads (default :class:`PriorSpread`).

    Raises:
        InvalidLog: too few samples, or a motion that excites fewer base
            parameters than the sagittal model has (7).

    """
    spread = spread or PriorSpread()
    w, y = _regressor(exo, prior_model, samples)
    t_map, base, names, scale = _base_map(w, samples.source)
    wb = w[:, base]
    rank = base.size

    theta0 = theta_prior(prior)
    pi0 = standard_of(theta0, prior)
    beta0 = t_map @ pi0
    jac = jacobian(lambda th: t_map @ standard_of(th, prior), theta0)
    sig_theta = theta_sigma(theta0, spread)
    cov0 = jac @ np.diag(sig_theta**2) @ jac.T + np.diag((1e-9 * (1.0 + np.abs(beta0))) ** 2)

    ols = np.linalg.lstsq(wb, y, rcond=None)[0]
    dof = wb.shape[0] - rank
    sigma2 = float(np.sum((y - wb @ ols) ** 2) / dof)
    info = wb.T @ wb + sigma2 * np.linalg.inv(cov0)
    beta = np.linalg.solve(info, wb.T @ y + sigma2 * np.linalg.solve(cov0, beta0))
    cov = sigma2 * np.linalg.inv(info)
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    cond = float(np.linalg.cond(wb / scale[base]))
    resid = float(np.sqrt(np.mean((y - wb @ beta) ** 2)))

    theta, theta_se = physical_fit(beta, cov, theta0, sig_theta, t_map, prior)
    patient = body_params_of(theta, prior)
    physical = {}
    labels = ("mass [kg]", "COM ratio", "gyration ratio")
    for s, seg in enumerate(SEGMENTS):
        for q, label in enumerate(labels):
            i = 3 * s + q
            value, err, p = theta[i], theta_se[i], theta0[i]
            if q == 0:  # mass: θ is log(m / m0)
                m0 = getattr(prior, f"{seg}_mass")
                value, err, p = m0 * math.exp(value), m0 * math.exp(value) * err, m0
            physical[f"{seg} {label}"] = {"estimate": value, "std_err": err, "prior": p}
    physical["joint damping [N·m·s/rad]"] = {
        "estimate": theta[6],
        "std_err": theta_se[6],
        "prior": theta0[6],
    }
    excitation = excitation_report(
        t_map, names, _column_name, lambda th: t_map @ standard_of(th, prior), theta, sig_theta
    )
    return Identification(
        names, beta, se, beta0, cond, resid, wb.shape[0], patient, physical, t_map, excitation
    )
