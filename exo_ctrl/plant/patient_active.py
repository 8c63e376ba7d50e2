r"""An active, impaired patient: their own gait, tracked with a delay, scaled by strength.

The patient of :mod:`exo_ctrl.plant.patient` only resists.  This one walks:
the patient has a healthy reference gait of their own (their preferred step
length and period, which need not be the device's plan) and their nervous
system drives their hips and knees along it.  Per joint j the patient's
active torque is

.. math::

    τ_a = s_j(t)\,\mathrm{clip}\bigl(τ_{ff}(t) + K_p e(t - δ) + K_d \dot e(t),
          \ ±τ_{max}\bigr),\qquad e = q_{ref} - q,

- ``q_ref``: the reference gait (below), the patient's intent;
- ``τ_ff``: the internal model's feedforward, the inverse dynamics of the
  patient's own legs along ``q_ref`` (Pinocchio's RNEA on the true patient
  model, with the URDF's joint damping and friction): the feedforward motor
  command the nervous system plans from an internal model of the limb
  (Wolpert & Kawato 1998; Kawato 1999).  Without it a feedback loop with a
  physiological delay could not both be stable and carry the leg against
  gravity;
- a stiffness on the position error δ seconds ago: the long-latency
  (transcortical) stretch reflex, 50–100 ms after a stretch (Matthews 1991;
  Lee & Tatton 1975), slower voluntary corrections after 100–150 ms.
  Default δ = 60 ms (choice inside that range);
- a damping on the speed error now: the active muscles' intrinsic
  viscosity, which acts without a neural delay (the intrinsic pathway of the
  parallel-cascade model of joint impedance, Kearney, Stein & Parameswaran
  1997).  Delayed as well, the damping feeds the cuffs' modes (5–12 Hz,
  where δ = 60 ms is a lag of 110–260°) instead of damping them: with the
  patient's legs in the cuffs of a device that tracks its plan, patients
  other than the default one then shook the cuffs to 0.3–1.2 kN (computed
  torque, the cuff campaign's points of ``tools/load_held.py``);
- gains: chosen for the delay (the tests run them): a crossover ω_c of
  about 5 rad/s at the hip (leg inertia ≈ 4 kg·m² about the hip) and 9 rad/s at
  the knee (≈ 0.6 kg·m²), where the delay costs ω_c δ ≈ 17–31° of a PD's
  55–60° phase lead;
- τ_max: the healthy joint's capacity, about 1.5 times the largest sagittal
  moments of normal walking (≈ 1.0 N·m/kg at the hip, ≈ 0.7 N·m/kg at the
  knee for an 80 kg adult: Winter 2009, Appendix A, the normal-gait moment
  tables): 120 N·m hip, 90 N·m knee (choice);
- ``s_j`` ∈ [0, 1]: strength per joint (1 healthy, 0 paralysed), optionally
  changed once at a given time (a patient who starts to take part).

**Reference gait.**  The paper's gait planner (:class:`~exo_ctrl.plan.GaitPlan`)
with the patient's step length and period and the device's other gait
parameters, mapped to the patient's joints by the inverse kinematics of the
patient's own legs, tabulated over one cycle against the phase φ ∈ [0, 1).
Cycle i lasts T_i = T (1 + c_T ξ_i) and its joint excursions about the
cycle's mean are scaled by a_i = 1 + c_s η_i (ξ, η standard normal, seeded):
the step-to-step variability of healthy gait, whose stride time and length
vary by about 2 % (coefficient of variation; Hausdorff 2005).  The scale
moves from a_i to a_{i+1} over cycle i along a C2 smoothstep, so q_ref is
continuous; its speed steps by the ratio T_i / T_{i+1} (about 2 %) where a
cycle ends.  The reference
ramps in from standing with the run's ramp (σ(t), :mod:`exo_ctrl.plan.ramp`):
q_ref = q_s + σ (q_cyc − q_s), q_s the standing posture; both start at the
device's t = 0 phase (left foot at the top of its swing).

Spasticity (:class:`~exo_ctrl.plant.patient.SpasticPatient`) adds to the
active torque when asked for.  The URDF's passive joint damping and friction
are the plant's, as for every patient.

References:
    Lee RG, Tatton WG (1975). Motor responses to sudden limb displacements in
    primates with specific CNS lesions and in human patients with motor
    system disorders. Can J Neurol Sci 2(3):285–293.
    Matthews PBC (1991). The human stretch reflex and the motor cortex.
    Trends Neurosci 14(3):87–91.
    Wolpert DM, Kawato M (1998). Multiple paired forward and inverse models
    for motor control. Neural Netw 11(7–8):1317–1329.
    Kawato M (1999). Internal models for motor control and trajectory
    planning. Curr Opin Neurobiol 9(6):718–727.
    Kearney RE, Stein RB, Parameswaran L (1997). Identification of
    intrinsic and reflex contributions to human ankle stiffness dynamics.
    IEEE Trans Biomed Eng 44(6):493–504.
    Hausdorff JM (2005). Gait variability: methods, modeling and meaning.
    J NeuroEng Rehabil 2:19.
    Winter DA (2009). Biomechanics and Motor Control of Human Movement, 4th
    ed., Wiley, Appendix A (normal gait: joint moments per body mass).

"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from .. import _validate as v
from .._jit import kernel, record
from ..exceptions import InvalidParameter
from ..model import FRICTION_SMOOTHING_RAD_S, JOINT_NAMES, BodyModel
from ..plan import GaitParams, GaitPlan, plan_joints
from ..plan.kinematics import inverse_kinematics
from .patient import PATIENT_TORQUES, SpasticParams, SpasticPatient

__all__ = ["ACTIVE_FIELDS", "PATIENT_KINDS", "ActiveParams", "ActivePatient"]

#: The patient-torque kinds of a run (``SimConfig.patient_torque``,
#: ``--patient-torque``): those of :data:`~exo_ctrl.plant.patient.PATIENT_TORQUES`
#: and ``active`` (this module; spastic on top with ``ActiveParams.spastic``).
PATIENT_KINDS = (*PATIENT_TORQUES, "active")

#: Phase samples of the tabulated reference cycle.
PHASE_SAMPLES = 1000


@dataclass(frozen=True)
class ActiveParams:
    """Parameters of :class:`ActivePatient` (module docstring; per joint: one number or four).

    Attributes:
        strength: s, 0 (paralysed) … 1 (healthy), per joint.
        step_length_m: the patient's preferred step length [m] (None: the device's).
        period_s: the patient's preferred gait period [s] (None: the device's).
        delay_s: δ, the reflex stiffness's delay [s] (default 0.06, long-latency
            reflex; the damping acts without delay).
        stiffness_Nm_per_rad: K_p per joint [N·m/rad] (default hip 100, knee 30).
        damping_Nms_per_rad: K_d per joint [N·m·s/rad] (default hip 35, knee 5).
        torque_max_Nm: τ_max, the healthy joint's capacity [N·m] (default hip
            120, knee 90).
        period_cv: c_T, coefficient of variation of the cycle time (default 0.02).
        step_cv: c_s, coefficient of variation of the excursions (default 0.02).
        seed: seed of the step-to-step variability [-].
        spastic: add the spastic torques of :class:`SpasticPatient`.
        strength_change_at_s: time the strength changes [s] (None: never).
        strength_after: the strength from then on, per joint.

    Raises:
        InvalidParameter: a value outside its range (strength in [0, 1],
            gains and capacities >= 0, delay in [0, 1] s, coefficients in [0, 0.2]).

    """

    strength: tuple[float, ...] | float = 1.0
    step_length_m: float | None = None
    period_s: float | None = None
    delay_s: float = 0.06
    stiffness_Nm_per_rad: tuple[float, ...] | float = (100.0, 30.0, 100.0, 30.0)
    damping_Nms_per_rad: tuple[float, ...] | float = (35.0, 5.0, 35.0, 5.0)
    torque_max_Nm: tuple[float, ...] | float = (120.0, 90.0, 120.0, 90.0)
    period_cv: float = 0.02
    step_cv: float = 0.02
    seed: int = 0
    spastic: bool = False
    strength_change_at_s: float | None = None
    strength_after: tuple[float, ...] | float | None = None
    spastic_params: SpasticParams = field(default_factory=SpasticParams)

    def __post_init__(self) -> None:
        def unit(name: str, x: object, u: str) -> float:
            y = v.finite(name, x, u)
            if not 0.0 <= y <= 1.0:
                raise InvalidParameter(name, x, "in [0, 1] (0 paralysed, 1 healthy)")
            return y

        set_ = object.__setattr__
        set_(
            self,
            "strength",
            v.per_item("patient_strength", self.strength, "", JOINT_NAMES, check=unit),
        )
        if self.strength_after is not None:
            set_(
                self,
                "strength_after",
                v.per_item("strength_after", self.strength_after, "", JOINT_NAMES, check=unit),
            )
        for name, u in (
            ("stiffness_Nm_per_rad", "N·m/rad"),
            ("damping_Nms_per_rad", "N·m·s/rad"),
            ("torque_max_Nm", "N·m"),
        ):
            set_(
                self,
                name,
                v.per_item(name, getattr(self, name), u, JOINT_NAMES, check=v.non_negative),
            )
        if self.step_length_m is not None:
            set_(self, "step_length_m", v.positive("patient_step_length", self.step_length_m, "m"))
        if self.period_s is not None:
            set_(self, "period_s", v.positive("patient_period", self.period_s, "s"))
        d = v.non_negative("patient_delay", self.delay_s, "s")
        if d > 1.0:
            raise InvalidParameter("patient_delay", self.delay_s, "in [0, 1] s")
        set_(self, "delay_s", d)
        for name in ("period_cv", "step_cv"):
            c = v.non_negative(name, getattr(self, name))
            if c > 0.2:
                raise InvalidParameter(name, getattr(self, name), "in [0, 0.2]")
            set_(self, name, c)
        if isinstance(self.seed, bool) or not isinstance(self.seed, int):
            raise InvalidParameter("patient_seed", self.seed, "an integer")
        if self.strength_change_at_s is not None:
            set_(
                self,
                "strength_change_at_s",
                v.non_negative("strength_change_at", self.strength_change_at_s, "s"),
            )
            if self.strength_after is None:
                raise InvalidParameter("strength_after", None, "given with strength_change_at_s")

    def gait(self, device: GaitParams) -> GaitParams:
        """The patient's own gait: the device's with their step length and period."""
        step = self.step_length_m if self.step_length_m is not None else device.step_length
        period = self.period_s if self.period_s is not None else device.period
        # Every other parameter the device's (the shared pelvis rises as the device's).
        return dataclasses.replace(device, step_length=step, period=period)


#: The active patient's record: parameters, the reference of the last call
#: (``q_ref`` [rad], ``dq_ref`` [rad/s], ``ddq_ref`` [rad/s²], ``phase`` φ,
#: ``cycle`` i) and its active torque ``tau_active`` [N·m].
ACTIVE_FIELDS = [
    ("kp", np.float64, (4,)),
    ("kd", np.float64, (4,)),
    ("tau_max", np.float64, (4,)),
    ("strength", np.float64, (4,)),
    ("strength_after", np.float64, (4,)),
    ("t_change", np.float64),
    ("q_mean", np.float64, (4,)),
    ("q_stand", np.float64, (4,)),
    ("damping", np.float64, (4,)),
    ("friction", np.float64, (4,)),
    ("ramp_in", np.float64),
    ("h", np.float64),
    ("delay_steps", np.int64),
    ("cursor", np.int64),
    ("q_ref", np.float64, (4,)),
    ("dq_ref", np.float64, (4,)),
    ("ddq_ref", np.float64, (4,)),
    ("phase", np.float64),
    ("cycle", np.int64),
    ("tau_active", np.float64, (4,)),
]


class ActivePatient:
    """The active patient's joint torques (module docstring), a :class:`PatientTorque`.

    Args:
        params: the patient's parameters.
        patient: the TRUE patient model (the plant's: this is the truth).
        device_gait: the device's gait (the patient's gait takes its lift,
            hip height, shape and duty factor).
        ramp_in_s: the run's ramp-in time [s] (the patient starts with the device).
        duration_s: the run's duration [s] (the variability is drawn for it).
        step_s: the plant's step h [s] (the delay is counted in steps).

    Raises:
        InvalidParameter: the patient's gait leaves their reach or range.

    """

    def __init__(
        self,
        params: ActiveParams,
        patient: BodyModel,
        device_gait: GaitParams,
        ramp_in_s: float,
        duration_s: float,
        step_s: float,
    ) -> None:
        self.params = p = params
        self.gait = gait = p.gait(device_gait)
        period = gait.period
        phase = np.arange(PHASE_SAMPLES + 1) / PHASE_SAMPLES
        plan = plan_joints(GaitPlan(gait), patient, phase * period)
        # Tables against the phase: Q(φ), dQ/dφ = T q̇, d²Q/dφ² = T² q̈.
        self._table = np.ascontiguousarray(
            np.stack((plan.q, plan.dq * period, plan.ddq * period**2))
        )
        self.record = rec = record(ACTIVE_FIELDS)
        s = rec[0]
        s["kp"], s["kd"], s["tau_max"] = (
            p.stiffness_Nm_per_rad,
            p.damping_Nms_per_rad,
            p.torque_max_Nm,
        )
        s["strength"] = p.strength
        s["strength_after"] = p.strength_after if p.strength_after is not None else p.strength
        s["t_change"] = p.strength_change_at_s if p.strength_change_at_s is not None else math.inf
        s["q_mean"] = plan.q[:-1].mean(axis=0)
        s["q_stand"] = _standing(patient, gait.hip_height)
        s["damping"], s["friction"] = patient.damping, patient.friction
        s["ramp_in"], s["h"] = ramp_in_s, step_s
        s["delay_steps"] = round(p.delay_s / step_s)
        rng = np.random.default_rng(p.seed)
        n = math.ceil(duration_s / (period * 0.5)) + 4
        # One (period, excursion) pair of draws per cycle, cycle by cycle: cycle i's
        # draws are the same in a run of any length.
        draws = rng.standard_normal((n, 2))
        times = period * np.clip(1.0 + p.period_cv * draws[:, 0], 0.5, 1.5)
        scale = np.clip(1.0 + p.step_cv * draws[:, 1], 0.5, 1.5)
        #: Cycle i: start [s], duration T_i [s], excursion scale a_i.
        self.cycles = np.ascontiguousarray(
            np.column_stack((np.concatenate(([0.0], np.cumsum(times[:-1]))), times, scale))
        )
        self._errors = np.zeros((int(s["delay_steps"]) + 1, 8))
        self._pm = pin.Model(patient.model)
        self._pd = self._pm.createData()
        self._spastic = SpasticPatient(p.spastic_params) if p.spastic else None
        self._tmp = np.zeros(4)
        self.q_ref = rec["q_ref"][0]
        self.dq_ref = rec["dq_ref"][0]
        self.ddq_ref = rec["ddq_ref"][0]
        self.tau_active = rec["tau_active"][0]

    def __call__(self, t: float, q: np.ndarray, dq: np.ndarray, out: np.ndarray) -> np.ndarray:
        """Patient joint torques [N·m] at time t [s] into ``out`` (see :class:`PatientTorque`)."""
        rec = self.record
        active_reference(rec, self._table, self.cycles, t)
        tau_ff = pin.rnea(self._pm, self._pd, self.q_ref, self.dq_ref, self.ddq_ref)
        active_torque(rec, self._errors, t, q, dq, tau_ff, out)
        if self._spastic is not None:
            np.add(out, self._spastic(t, q, dq, self._tmp), out=out)
        return out

    def reference(self, t: np.ndarray) -> np.ndarray:
        """q_ref at times t [s], (N, 4) [rad] (for analysis; allocates)."""
        out = np.empty((len(t), 4))
        rec = self.record.copy()
        rec["cursor"] = 0
        for i, ti in enumerate(np.asarray(t, dtype=float)):
            active_reference(rec, self._table, self.cycles, ti)
            out[i] = rec["q_ref"][0]
        return out


def _standing(patient: BodyModel, hip_height: float) -> np.ndarray:
    """The patient's joint angles with both feet straight below the hips at ``hip_height`` [rad]."""
    out = np.empty(4)
    for s, side in enumerate(("left", "right")):
        leg = patient.legs[side]
        p1, p2 = inverse_kinematics(0.0, -hip_height, leg.thigh_length, leg.shank_length)
        hip, knee = leg.absolute_to_joint(p1, p2)
        out[2 * s], out[2 * s + 1] = float(hip), float(knee)
    return out


@kernel
def active_reference(state, table, cycles, t):  # pragma: no cover - compiled
    """q_ref, q̇_ref, q̈_ref at time ``t`` [s] into ``state[0]`` (module docstring).

    ``table``: (3, M + 1, 4), Q(φ), dQ/dφ, d²Q/dφ² over φ = 0 … 1;
    ``cycles``: (n, 3), start [s], T_i [s] and a_i per cycle.  The ramp-in
    σ(t) is the smoothstep S(t / T_r) of :mod:`exo_ctrl.plan.ramp`.
    """
    s = state[0]
    n = cycles.shape[0]
    i = s.cursor
    while i + 1 < n and t >= cycles[i + 1, 0]:
        i += 1
    while i > 0 and t < cycles[i, 0]:
        i -= 1
    s.cursor = i
    period = cycles[i, 1]
    phase = (t - cycles[i, 0]) / period
    if phase < 0.0:
        phase = 0.0
    if phase > 1.0:
        phase = 1.0
    # The excursion scale moves from a_i to a_{i+1} over the cycle (C2 smoothstep).
    a0 = cycles[i, 2]
    da = (cycles[i + 1, 2] if i + 1 < n else a0) - a0
    p1 = 1.0 - phase
    a = a0 + da * phase * phase * phase * (10.0 - 15.0 * phase + 6.0 * phase * phase)
    da1 = da * 30.0 * (phase * p1) ** 2 / period
    da2 = da * 60.0 * phase * p1 * (1.0 - 2.0 * phase) / (period * period)
    m = table.shape[1] - 1
    x = phase * m
    k = int(x)
    if k >= m:
        k = m - 1
    w = x - k
    # Ramp-in σ, σ̇, σ̈ (quintic smoothstep in t / T_r).
    sg, dsg, ddsg = 1.0, 0.0, 0.0
    if s.ramp_in > 0.0 and t < s.ramp_in:
        r = 1.0 / s.ramp_in
        u = t * r
        if u < 0.0:
            u = 0.0
        v = 1.0 - u
        sg = u * u * u * (10.0 - 15.0 * u + 6.0 * u * u)
        dsg = 30.0 * (u * v) ** 2 * r
        ddsg = 60.0 * u * v * (1.0 - 2.0 * u) * r * r
    for j in range(4):
        qc = table[0, k, j] + w * (table[0, k + 1, j] - table[0, k, j])
        d1 = table[1, k, j] + w * (table[1, k + 1, j] - table[1, k, j])
        d2 = table[2, k, j] + w * (table[2, k + 1, j] - table[2, k, j])
        qm = s.q_mean[j]
        qcyc = qm + a * (qc - qm)
        dq = da1 * (qc - qm) + a * d1 / period
        ddq = da2 * (qc - qm) + 2.0 * da1 * d1 / period + a * d2 / (period * period)
        rel = qcyc - s.q_stand[j]
        s.q_ref[j] = s.q_stand[j] + sg * rel
        s.dq_ref[j] = dsg * rel + sg * dq
        s.ddq_ref[j] = ddsg * rel + 2.0 * dsg * dq + sg * ddq
    s.phase = phase
    s.cycle = i


@kernel
def active_torque(state, errors, t, q, dq, tau_ff, out):  # pragma: no cover - compiled
    """τ_a of the module docstring into ``out`` and ``state[0].tau_active`` [N·m].

    ``errors``: the ring of (e, ė) of the last ``delay_steps + 1`` plant
    steps, (D + 1, 8), indexed by the step round(t / h) (ė is used now,
    e after the delay); ``tau_ff``: the
    inverse dynamics along q_ref [N·m] (the URDF damping and friction are
    added here).
    """
    s = state[0]
    d = errors.shape[0]
    n = round(t / s.h)
    now = n % d
    past = (n - s.delay_steps) % d
    if n < s.delay_steps:
        past = -1
    for j in range(4):
        errors[now, j] = s.q_ref[j] - q[j]
        errors[now, 4 + j] = s.dq_ref[j] - dq[j]
    strong = s.strength if t < s.t_change else s.strength_after
    for j in range(4):
        dr = s.dq_ref[j]
        tau = tau_ff[j] + s.damping[j] * dr + s.friction[j] * np.tanh(dr / FRICTION_SMOOTHING_RAD_S)
        tau += s.kd[j] * errors[now, 4 + j]  # intrinsic: no delay
        if past >= 0:
            tau += s.kp[j] * errors[past, j]  # the reflex, δ late
        cap = s.tau_max[j]
        if tau > cap:
            tau = cap
        elif tau < -cap:
            tau = -cap
        tau *= strong[j]
        s.tau_active[j] = tau
        out[j] = tau
