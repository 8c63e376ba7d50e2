r"""Cuff forces from a Kalman filter on the coupled exoskeleton–cuff–patient model.

The momentum observer (:mod:`.observer`) sees only the exoskeleton: two joint torques per leg, and
an assumption on how the load shares between the two cuffs.  This estimator holds the device's
whole model instead: the exoskeleton's link model, the nominal patient (``setup.device_patient``)
and the cuff model (normal and shear stiffness and damping, :mod:`exo_ctrl.plant.cuffs`).  The cuff
forces are then functions of the relative displacement and velocity of the cuff points, f = f(q_e,
v_e, q_p, v_p), so estimating the patient's joint state estimates every component of every cuff
force, the along-link ones included.

**Model** (per leg; the legs hang from a fixed pelvis and do not couple).
State x = (q_e, q_p, v_e, v_p, d) ∈ ℝ¹⁰: exoskeleton and patient hip and
knee angles [rad] and speeds [rad/s], and d [N·m], the patient's joint
torques the model does not know (their own effort, the nominal model's
error), a random walk:

    M_e(q_e) v̇_e = τ_s − β − n_e(q_e, v_e) − b_e v_e − f_e tanh(v_e/ε) + J_eᵀ f + w_e,
    M_p(q_p) v̇_p = −J_pᵀ f − n_p(q_p, v_p) − b_p v_p − f_p tanh(v_p/ε) + d + w_p,
    ḋ = w_d,

τ_s the torque-sensor reading (an input, as in the momentum observer: the
sensors sit between gearbox and link, so the rotor is not in the model), β
a known sensor bias, and w_e, w_p, w_d white: the sensor's noise plus the
exoskeleton model's error [N·m], the patient's fast unknown torques [N·m],
and the rate of the slow ones [N·m/√s] (:class:`KalmanNoise`).  J_e and J_p
are the cuff points' Jacobians and f the device's cuff forces on the
exoskeleton (:func:`~exo_ctrl.plant.cuffs.forces_of`, the plant's kernel on
the device's own :class:`~exo_ctrl.plant.cuffs.CuffSet`).
The measurement is the encoder angle q_e (σ_q² = σ_n² + Δq²/12 from
the sensors' datasheet values, at least :data:`MIN_ANGLE_STD_RAD` squared).
The filtered encoder speed is not used (its low-pass lags and its noise is
coloured).

**Discrete filter** (step h, semi-implicit Euler, the readings of tick k:
τ_k over [t_{k−1}, t_k] and q_k at t_k).  Prediction: the nonlinear model
from the last posterior, v⁺ = v + h a(x, τ_k), q⁺ = q + h v⁺, d⁺ = d; its
covariance P⁻ = F P Fᵀ + Q with F the Jacobian of that step,

    F = [[I + h² A_q, h (I + h A_v), h² A_d],
         [h A_q,      I + h A_v,     h A_d],
         [0,          0,             I]],
    A_q = M⁻¹ ∂τ_c/∂q,   A_v = M⁻¹ (∂τ_c/∂v − B),   A_d = M⁻¹ [0; I],

where M = blockdiag(M_e, M_p), B the joint damping and ∂τ_c the cuffs'
generalised stiffness and damping linearised per tick with the links'
frames held, −J_Δᵀ K_c J_Δ and −J_Δᵀ C_c J_Δ (J_Δ = ∂(p_e − p_p)/∂(q_e, q_p),
K_c = k_n n nᵀ + k_u u uᵀ, C_c likewise; gravity's and the speed terms'
derivatives are left out: they are small against the cuffs' and only shape
the gain); Q = G Σ Gᵀ with G = [h² M⁻¹; h M⁻¹] for (w_e, w_p) and h σ_d² I
for d.  Update: the standard Kalman update with H = [I 0 0 0 0], R = σ_q² I.

**Outputs** (the same fields as the momentum observer's, so the tick logs
either): the device's cuff forces at the posterior, evaluated at the middle
of the step just taken (q − ½ h v, v: the estimand is the force over the
step, as the momentum observer's external torque over the step), their
normal and along-link components, and τ_ext = J_eᵀ f.

**What is observed** (:data:`COMPONENTS`).  Every component is estimated. The joint torques see the
shank's normal force and, per leg, one combination of the thigh's normal and the shank's along-link
force (:mod:`.cuff_geometry`); the remaining two components per leg — the thigh's along-thigh force
and how the hip torque splits between the thigh's normal and the shank's along-shank force — come
from the cuff model and the patient model through the patient's posture: they are model-driven,
right as far as the device's models are (a misaligned knee, a heavier patient than the nominal one,
cuffs other than the model's make them wrong).

**Instrumented cuffs** (``cuff_sensors``): their fresh readings are fused after the encoders, one
scalar update per axis, with a model-error force per measured axis added to the outputs and a bias
per measured axis (the sensor's offset and drift) told from it by the joint torques
(:mod:`.kalman_cuff`, :mod:`.kalman_check`); the sensors may be tared at the start on request.

**Bad readings.**  A non-finite angle skips that leg's measurement update
(the covariance grows, the prediction carries on); a non-finite torque
reading is replaced by the leg's last finite one.  A state that becomes
non-finite restarts the filter at the next finite readings.  A NaN reading
therefore costs the estimate only while it lasts.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .. import _validate as v
from .._jit import Status, check, record
from ..exceptions import ExoCtrlError
from ..model import CUFF_NAMES, FRICTION_SMOOTHING_RAD_S, BodyModel
from ..plant.cuffs import CuffParams, CuffSet
from ..plant.equilibrium import settle_patient
from ..sensing.cuff_load import CuffSensors
from ..sensing.readings import SensorReadings
from ..sensing.sensors import SensorParams
from .kalman_cuff import set_cuff_noise
from .kalman_step import KALMAN_FIELDS, kalman_outputs, kalman_step

__all__ = [
    "COMPONENTS",
    "CUFF_SENSOR_SOURCE",
    "ESTIMATORS",
    "MODEL_DRIVEN",
    "CuffForceKalman",
    "KalmanNoise",
    "kalman_components",
    "model_driven",
]

#: Floor of the encoder's std in the filter [rad].  Ideal sensors
#: (``SensorParams.ideal()``) give σ_q = 0: the update then divides by
#: S = P_qq, which an exact update leaves at zero up to rounding, and the gain
#: becomes rounding over rounding (measured: a transparent run's estimate
#: error 18.7 N RMS against 2.5 N with this floor).  1e-7 rad is 480 times
#: below the default 17-bit encoder's step (4.8e-5 rad), so realistic
#: sensors never reach it.
MIN_ANGLE_STD_RAD = 1e-7

#: The live estimators a run can use: the momentum observer (:mod:`.observer`)
#: and this filter.
ESTIMATORS = ("momentum", "kalman")

#: How each estimated component is obtained, per cuff (module docstring).
COMPONENTS: dict[str, dict[str, str]] = {
    cuff: (
        {
            "normal": "seen by the hip torque together with the shank's along-shank force; "
            "split between them by the cuff and patient models",
            "along": "model-driven: no joint torque sees it (from the cuff and patient models)",
        }
        if cuff.endswith("thigh")
        else {
            "normal": "observed: the knee torque",
            "along": "seen by the hip torque together with the thigh's normal force; "
            "split between them by the cuff and patient models",
        }
    )
    for cuff in CUFF_NAMES
}


#: What measures a component a cuff sensor set adds (:mod:`exo_ctrl.sensing.cuff_load`).
CUFF_SENSOR_SOURCE = {
    "normal": "observed: the cuff's load cell",
    "full": "observed: the cuff's 2-axis force sensor",
}


def kalman_components(cuff_sensors: str = "none") -> dict[str, dict[str, str]]:
    """Per cuff and component, where the filter's estimate comes from (a copy).

    :data:`COMPONENTS` (the joint torques alone), with each component a cuff
    sensor measures (``"normal"``: the normal ones; ``"full"``: both) named
    by that sensor (:data:`CUFF_SENSOR_SOURCE`): the filter corrects it by the
    sensor's reading (:mod:`~exo_ctrl.estimation.kalman_cuff`); the others
    keep the models' split.
    """
    out = {cuff: dict(parts) for cuff, parts in COMPONENTS.items()}
    source = CUFF_SENSOR_SOURCE.get(cuff_sensors)
    if source is not None:
        measured = ("normal", "along") if cuff_sensors == "full" else ("normal",)
        for parts in out.values():
            for part in measured:
                parts[part] = source
    return out


def model_driven(components: dict[str, dict[str, str]]) -> list[str]:
    """The components that come from the device's models, one line each ("cuff: part: how")."""
    return [
        f"{cuff}: {part}: {how}"
        for cuff, parts in components.items()
        for part, how in parts.items()
        if "model" in how
    ]


#: The components that come from the device's models rather than the joint
#: torques, one line per component ("cuff: part: how"), as a summary lists
#: them under ``cuff_force_estimate_unobservable`` (no cuff sensors).
MODEL_DRIVEN: list[str] = model_driven(COMPONENTS)


@dataclass(frozen=True)
class KalmanNoise:
    """The filter's process noise and initial uncertainty (module docstring).

    Attributes:
        exo_model_torque_Nm: std of the exoskeleton model's error per tick,
            added to the torque sensor's noise [N·m] (chosen: 0.3 N·m).
        patient_torque_Nm: std of the patient's fast unknown joint torques
            per tick, w_p [N·m] (chosen: 1 N·m).
        patient_torque_rate_Nm_per_sqrt_s: intensity of the random walk d of
            the patient's slow unknown torques, σ_d [N·m/√s] (chosen: 10,
            the best of 0.3, 1, 3, 10, 30 and 100 on the default gait with
            the truth's cuffs as the model, aligned, misaligned, a 20 %
            heavier patient and the spastic one; 0.3 lags the spastic
            patient's torques, 100 passes the encoders' noise).
        initial_angle_rad: initial std of the patient's angles [rad] (chosen:
            0.02, the sag of a patient in 8 N/mm cuffs is below 0.01).
        initial_speed_rad_s: initial std of the speeds [rad/s] (chosen: 0.1).
        initial_torque_Nm: initial std of d [N·m] (chosen: 5).

    Raises:
        InvalidParameter: a field that is not a finite number >= 0 (the
            initial ones > 0).

    """

    exo_model_torque_Nm: float = 0.3
    patient_torque_Nm: float = 1.0
    patient_torque_rate_Nm_per_sqrt_s: float = 10.0
    initial_angle_rad: float = 0.02
    initial_speed_rad_s: float = 0.1
    initial_torque_Nm: float = 5.0

    def __post_init__(self) -> None:
        v.non_negative("exo_model_torque", self.exo_model_torque_Nm, "N·m")
        v.non_negative("patient_torque", self.patient_torque_Nm, "N·m")
        v.non_negative("patient_torque_rate", self.patient_torque_rate_Nm_per_sqrt_s, "N·m/√s")
        v.positive("initial_angle", self.initial_angle_rad, "rad")
        v.positive("initial_speed", self.initial_speed_rad_s, "rad/s")
        v.positive("initial_torque", self.initial_torque_Nm, "N·m")


class CuffForceKalman:
    """Live cuff-force estimate from the coupled model, one update per tick (module docstring).

    The same per-tick interface as
    :class:`~exo_ctrl.estimation.observer.CuffForceEstimator`: :meth:`update`
    with the tick's readings, :attr:`record` with ``tau_ext``,
    ``cuff_normal`` and ``cuff_force``, :attr:`force`.  An update is four
    Pinocchio calls (``crba`` and ``nonLinearEffects`` of both models at the
    last posterior) and one compiled kernel.

    Args:
        exo: the exoskeleton model the device holds (its link model is used).
        patient: the patient model the device holds (``setup.device_patient``).
        dt: control period h [s].
        cuffs: the device's cuff model (default :class:`CuffParams`'s).
        sensors: the sensors' datasheet values (noise, resolution; default
            :class:`SensorParams`'s); the seed is not used.
        noise: process noise and initial uncertainty.
        torque_bias_Nm: a known torque-sensor bias to subtract [N·m], (4,) or scalar.
        cuff_sensors: the cuffs' force sensors whose readings are fused
            (:mod:`.kalman_cuff`; None or mode ``"none"``: none); the filter
            reads their readings record (:attr:`cuff_meas`) at each step, as
            the sensors' read or :func:`~.series.kalman_series` filled it.

    Attributes:
        record: parameters, state, covariance and outputs (one-element structured array).
        tau_ext: J_eᵀ f of the last update [N·m], (4,).
        normal: normal components [N], (4,), CUFF_NAMES order.
        along: along-link components [N], (4,) (joint → cuff).
        force: cuff forces on the exoskeleton (x, z) [N], (4, 2).
        force_std: σ_c, the standard deviation of each cuff force's estimate
            along its most uncertain direction, from the posterior covariance
            (:func:`~exo_ctrl.estimation.kalman_step.force_std`) [N], (4,).
        components: :data:`COMPONENTS`.

    Raises:
        InvalidModel: a model without exactly the four joints in JOINT_NAMES order.

    """

    components = COMPONENTS

    def __init__(
        self,
        exo: BodyModel,
        patient: BodyModel,
        dt: float,
        cuffs: CuffParams | None = None,
        sensors: SensorParams | None = None,
        noise: KalmanNoise | None = None,
        torque_bias_Nm: np.ndarray | float = 0.0,
        cuff_sensors: CuffSensors | None = None,
    ) -> None:
        for body in (exo, patient):
            body.require_legs_only("the estimator")
        self.dt = v.positive("dt", dt, "s")
        self.noise = noise if noise is not None else KalmanNoise()
        sensors = sensors if sensors is not None else SensorParams()
        bias = np.broadcast_to(np.asarray(torque_bias_Nm, dtype=float), (4,))
        for b in bias:
            v.finite("torque_bias", b, "N·m")
        self.record = rec = record(KALMAN_FIELDS)
        rec["damping"][0] = np.concatenate((exo.damping, patient.damping))
        rec["friction"][0] = np.concatenate((exo.friction, patient.friction))
        rec["friction_smoothing"] = FRICTION_SMOOTHING_RAD_S
        rec["torque_bias"][0] = bias
        rec["h"] = self.dt
        rec["var_q"] = max(
            sensors.encoder_noise_std_rad**2 + sensors.encoder_resolution_rad**2 / 12,
            MIN_ANGLE_STD_RAD**2,
        )
        rec["var_exo"] = (
            sensors.torque_noise_std_Nm**2
            + sensors.torque_resolution_Nm**2 / 12
            + self.noise.exo_model_torque_Nm**2
        )
        rec["var_patient"] = self.noise.patient_torque_Nm**2
        rec["var_rate"] = self.noise.patient_torque_rate_Nm_per_sqrt_s**2
        on = cuff_sensors is not None and cuff_sensors.params.on
        self._cuff_params = cuff_sensors.params if on else None
        if self._cuff_params is not None:
            set_cuff_noise(rec, self._cuff_params)
        #: The cuff sensors' readings record, or None (their update not compiled in).
        self.cuff_meas = cuff_sensors.readings if on else None
        rec["joints"][0] = [[0, 1, 4, 5], [2, 3, 6, 7]]
        self._model_e = pin.Model(exo.model)
        self._model_e.armature = np.zeros(self._model_e.nv)  # link side: no rotor inertia
        self._data_e = self._model_e.createData()
        self._model_p = patient.model
        self._data_p = patient.model.createData()
        #: The Pinocchio (model, data) pairs an update calls: exoskeleton, patient.
        self.models = ((self._model_e, self._data_e), (self._model_p, self._data_p))
        hip_e, hip_p = exo.legs["left"].hip_xz, patient.legs["left"].hip_xz
        self.cuffs = CuffSet(
            exo,
            patient,
            cuffs if cuffs is not None else CuffParams(),
            (hip_e[0] - hip_p[0], hip_e[1] - hip_p[1]),
        )
        self._q, self._v = rec["q"][0], rec["v"][0]
        self._q_e, self._q_p = self._q[:4], self._q[4:]
        self._v_e, self._v_p = self._v[:4], self._v[4:]
        self.tau_ext = rec["tau_ext"][0]
        self.normal = rec["cuff_normal"][0]
        self.along = rec["cuff_along"][0]
        self.force = rec["cuff_force"][0]
        self.force_std = rec["cuff_force_std"][0]
        self._started = False

    # ------------------------------------------------------------------ public

    def reset(self) -> None:
        """Restart the filter: the next update starts it at its readings (estimate zero now).

        With cuff sensors the tare, the model-error forces and the biases start again too.
        """
        self._started = False
        if self._cuff_params is not None:
            set_cuff_noise(self.record, self._cuff_params)
        for name in ("tau_ext", "cuff_normal", "cuff_along", "cuff_force"):
            self.record[name] = 0.0

    def set_torque_rate(self, rate_Nm_per_sqrt_s: float | None) -> None:
        """Set σ_d, the random walk's intensity of the patient's unknown torques [N·m/√s].

        From the next prediction on, Q's d block is h σ_d² (the state and
        covariance are kept).  None restores :attr:`noise`'s value.  An
        interaction mode that expects the patient's torques to change fast
        raises it (``transparent``:
        :meth:`~exo_ctrl.control.modes.InteractionController.tune_estimator`).

        Raises:
            InvalidParameter: a rate that is not a finite number >= 0.

        """
        if rate_Nm_per_sqrt_s is None:
            rate_Nm_per_sqrt_s = self.noise.patient_torque_rate_Nm_per_sqrt_s
        rate = v.non_negative("patient_torque_rate", rate_Nm_per_sqrt_s, "N·m/√s")
        self.record["var_rate"] = rate**2

    def update(self, sensors: SensorReadings) -> np.ndarray:
        """Advance by one control period with this tick's readings.

        Args:
            sensors: encoder angles q [rad], speeds dq [rad/s] (used only to
                start) and sensor torques tau [N·m] of this tick.

        Returns:
            The estimated cuff forces on the exoskeleton, (4, 2) [N]
            (:attr:`force`, overwritten by the next update).

        """
        return self.step(sensors.q, sensors.dq, sensors.tau)

    def step(self, q: np.ndarray, dq: np.ndarray, tau: np.ndarray) -> np.ndarray:
        """Advance by one period dt with readings (q, dq, tau); as :meth:`update`.

        The first step after construction or :meth:`reset` (or after the
        state became non-finite) starts the filter at these readings, if
        they are finite: q_e = q, v_e = v_p = dq, q_p the nominal patient at
        static equilibrium in the cuffs fitted slack at q
        (:func:`~exo_ctrl.plant.equilibrium.settle_patient`; q if that fails), d = 0.

        Raises:
            InvalidParameter: q, dq or tau is not of shape (4,) (nothing changed).

        """
        if not (type(q) is type(dq) is type(tau) is np.ndarray):
            q, dq, tau = v.arrays((4,), q=q, dq=dq, tau=tau)
        if q.shape != (4,) or dq.shape != (4,) or tau.shape != (4,):
            v.refuse_shapes((4,), q=q, dq=dq, tau=tau)
        if not self._started:
            self._start(q, dq, tau)
            return self.force
        qe, qp, ve, vp = self._q_e, self._q_p, self._v_e, self._v_p
        me, mp = self._model_e, self._model_p
        status = kalman_step(
            self.record,
            self.cuffs.record,
            pin.crba(me, self._data_e, qe),
            pin.nonLinearEffects(me, self._data_e, qe, ve),
            pin.crba(mp, self._data_p, qp),
            pin.nonLinearEffects(mp, self._data_p, qp, vp),
            q,
            tau,
            self.cuffs.split_switch,
            self.cuff_meas,
        )
        if status:
            self.answer(status, q, tau)
        return self.force

    def bind(self, sensors: SensorReadings) -> Callable[[], np.ndarray]:
        """:meth:`update` with ``sensors``, as a call without arguments, for the control tick.

        The readings' arrays are checked once, here; the call then makes
        :meth:`step`'s Pinocchio calls and kernel on them with nothing
        around (about 1 µs less a tick than :meth:`update`), and reads the
        arrays as they are at each call.

        Raises:
            InvalidParameter: q, dq or tau is not a float (4,) array.

        """
        q, dq, tau = sensors.q, sensors.dq, sensors.tau
        v.held_arrays((4,), q=q, dq=dq, tau=tau)
        rec, cuffs, split = self.record, self.cuffs.record, self.cuffs.split_switch
        meas = self.cuff_meas
        force = self.force
        me, mp, de, dp = self._model_e, self._model_p, self._data_e, self._data_p
        qe, qp, ve, vp = self._q_e, self._q_p, self._v_e, self._v_p
        crba, nle = pin.crba, pin.nonLinearEffects

        def update() -> np.ndarray:
            if not self._started:
                return self.step(q, dq, tau)
            status = kalman_step(
                rec, cuffs, crba(me, de, qe), nle(me, de, qe, ve), crba(mp, dp, qp),
                nle(mp, dp, qp, vp), q, tau, split, meas,
            )  # fmt: skip
            if status:
                self.answer(status, q, tau)
            return force

        return update

    @property
    def started(self) -> bool:
        """Whether the filter has started (its next update steps it)."""
        return self._started

    def step_arguments(self) -> tuple[tuple, tuple, tuple]:
        """What a fused tick (:mod:`exo_ctrl.sim.fused`) calls of :meth:`step`, once started.

        The models, data and state (q, v) of the exoskeleton's and the patient's
        CRBA and nonLinearEffects calls, then :func:`kalman_step`'s arguments
        before those four results and after the readings q, τ (and the fused
        tick's estimator switches: the filter, no observer).
        """
        me, de, mp, dp = self._model_e, self._data_e, self._model_p, self._data_p
        library = (me, de, self._q_e, self._v_e, mp, dp, self._q_p, self._v_p)
        after = (self.cuffs.split_switch, self.cuff_meas, True, None)
        return library, (self.record, self.cuffs.record), after

    def answer(self, status: int, q: np.ndarray, tau: np.ndarray) -> None:
        """A step's status other than OK: NOT_FINITE restarts the filter, the rest raise."""
        if status == Status.NOT_FINITE.value:
            self._started = False  # the state left the finite numbers: restart at the next readings
        else:
            check(status, "CuffForceKalman.step", q=q, tau=tau)

    def _start(self, q: np.ndarray, dq: np.ndarray, tau: np.ndarray) -> None:
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(dq))):
            return  # wait for finite readings
        try:
            q_p = settle_patient(self.cuffs, self._model_p, q)
        except ExoCtrlError:
            self.cuffs.fit(np.concatenate((q, q)))
            q_p = q
        rec = self.record
        self._q_e[:] = q
        self._q_p[:] = q_p
        self._v_e[:] = dq
        self._v_p[:] = dq
        rec["d"] = 0.0
        rec["tau_hold"][0] = np.where(np.isfinite(tau), tau, 0.0)
        n = self.noise
        diag = np.array(
            [rec["var_q"][0]] * 2
            + [n.initial_angle_rad**2] * 2
            + [n.initial_speed_rad_s**2] * 4
            + [n.initial_torque_Nm**2] * 2
        )
        rec["cov"][0] = np.diag(diag)
        kalman_outputs(rec, self.cuffs.record, self.cuffs.split_switch)
        self._started = True
