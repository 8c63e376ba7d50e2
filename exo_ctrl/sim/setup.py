"""The pieces of a run, built from its configuration, and the state it starts in.

A run is built only for a plan the device can follow (:func:`check_followable`):
a gait whose planned joint speeds break a URDF speed limit, or need more
than the supply voltage for the back-EMF alone, is bad input, refused before
anything runs.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from ..control import (
    PDController,
    feedforward_torque,
)
from ..control.modes import InteractionController, PathController
from ..estimation import ESTIMATORS, Estimator
from ..estimation.plugin import users_estimator
from ..exceptions import InvalidParameter
from ..model import JOINT_NAMES, BodyModel, load_exo, load_patient
from ..plan import (
    NO_TAIL,
    GaitPlan,
    JointTrajectory,
    OnlineGait,
    RampedGait,
    StanceSink,
    calibration_plan,
    plan_joints,
)
from ..plant import (
    MotorParams,
    PatientTorque,
    Plant,
    make_patient_torque,
    misaligned_patient,
)
from ..plant.equilibrium import holding_torque, settle_patient
from ..plant.patient_active import ActivePatient
from .advice import run_notes, run_warnings
from .belief import device_exo, device_patient
from .config import SimConfig
from .session import session_controller
from .sync import online_gait, profile_runs, set_speeds
from .tracking import stance_load_for, tracking_controller

__all__ = [
    "Setup",
    "build",
    "check_followable",
    "drive_for",
    "patient_torque_for",
    "start_on_plan",
]

#: Samples per gait period (at least) of the speed check of :func:`check_followable`.
SPEED_SAMPLES_PER_PERIOD = 1000


@dataclass
class Setup:
    """The pieces of a run, built from a :class:`SimConfig` by :func:`build`."""

    config: SimConfig
    exo: BodyModel
    patient: BodyModel
    plan: JointTrajectory
    plant: Plant
    controller: PDController
    #: The models the device holds (:mod:`exo_ctrl.sim.belief`): the
    #: controller's, the estimator's and the supervisor's; ``exo`` and
    #: ``patient`` above are the truth the plant simulates.
    device_exo: BodyModel
    device_patient: BodyModel
    #: The drive the device believes in (its datasheet, capped as
    #: :func:`drive_for` caps it for the device's exoskeleton URDF): the
    #: controller's and the supervisor's motor model, a parameter set of its
    #: own; the plant's drive is ``plant.motor_params``.
    device_motor: MotorParams
    #: The belt's set speed and its rate at each control tick, (n, 2):
    #: σ(t_k) v_f [m/s] (the plan's, :meth:`~exo_ctrl.plan.RampedGait.belt_speed_at`)
    #: and σ̇(t_k) v_f [m/s²]; with contact on.
    belt_speed: np.ndarray | None = None
    #: The online gait generator whose one-row plan is ``plan`` (``config.synced``;
    #: :mod:`exo_ctrl.sim.sync`), stepped by the tick with the belt encoder's reading.
    online: OnlineGait | None = None
    #: What the user should know before trusting the run's figures, one sentence
    #: each: a device that does not fit its patient (:func:`~exo_ctrl.model.fit.fit_warnings`),
    #: what the nominal patient was read from (:func:`~.belief.nominal_stature`).
    warnings: tuple[str, ...] = ()
    #: A user's estimator (``config.estimator`` not a built-in name), built once: the
    #: tick's (:class:`~exo_ctrl.estimation.plugin.PluginEstimator`); None: a built-in.
    estimator: Estimator | None = None
    #: What the run does that the user should know, one sentence each (not a warning:
    #: the QP's departure stop with the feet over the belt; :func:`~.advice.run_notes`).
    notes: tuple[str, ...] = ()


def build(config: SimConfig, start: bool = True) -> Setup:
    """Load the models, plan the run and build the plant and controller.

    ``start``: False only for the compile helper (:mod:`exo_ctrl.sim.warmup`), which
    calls the tick's kernels and never runs: a synchronised plan is neither checked
    nor started, which leaves its kernels to the run's own process.

    Raises:
        ExoCtrlError: a model, a gait or a plan the device cannot follow
            (:func:`check_followable`) is refused; nothing has run.

    """
    exo = load_exo(config.exo)
    fitted = load_patient(config.patient)  # as the device is fitted to it: coaxial
    patient = misaligned_patient(fitted, config.misalignment)  # the truth
    motor = drive_for(config.motor, exo)
    online = None
    model_exo = device_exo(config.belief, config.exo)
    sink = stance_sink_for(config, model_exo)
    references: tuple[JointTrajectory, ...] = ()
    if not config.synced:  # the online plan's speeds are checked by online_gait
        plan = precomputed_plan(config, exo, sink)
        check_followable(config, plan, exo, patient, motor)
    model_patient = device_patient(config.belief, config.patient, fitted)
    if config.synced:  # generated each tick from the measured belt speed (sim/sync.py)
        online = online_gait(
            config, exo, patient, motor, model_exo, check_followable, sink, start=start
        )
        plan = online.plan
        if config.controller in ("qp", "ct"):  # the QP's margin, the drives' reach (warnings)
            runs = profile_runs(config, online.law)
            references = tuple(precomputed_plan(run, exo, sink) for run in runs)
    # The device's drive: its datasheet, a parameter set of its own (a copy
    # when it is the installed drive's nominal values).
    model_motor = drive_for(dataclasses.replace(config.belief.motor_model(config.motor)), model_exo)
    plant = Plant(
        exo,
        patient,
        dt=config.dt / config.plant_substeps,
        motors=motor,
        cuffs=config.true_cuffs,
        end_stops=config.end_stops,
        compliance=config.joint_compliance,
        contact=config.contact,
        belt_height_m=config.gait.hip_height,
        pelvis=config.pelvis_resolved,
    )
    belt_speed = None
    if config.contact.enabled:
        sigma = config.ramp.factor(np.arange(config.n_ticks) * config.dt)
        belt_speed = np.stack(sigma[:2], axis=1) * config.gait.belt_speed
        if config.speed_profile is not None:  # σ(t) v(t) of the session's profile
            belt_speed = set_speeds(config, sigma[:2])
    user_estimator = users_estimator(config.estimator, ESTIMATORS)  # None: a built-in
    controller = tracking = tracking_controller(
        config, plan, model_exo, model_patient, model_motor, user_estimator, references
    )
    if config.session is not None:  # one controller per segment, switched bumplessly
        controller = session_controller(  # type: ignore[assignment]
            config,
            plan,
            model_exo,
            model_motor,
            lambda: tracking_controller(
                config, plan, model_exo, model_patient, model_motor, references=references
            ),
            patient=model_patient,
        )
    elif config.mode == "path":  # the tunnel with free timing, on the device's models
        controller = PathController(  # type: ignore[assignment]
            config.path,
            config.modes,
            plan,
            model_exo,
            model_motor,
            dt=config.dt,
            estimator=config.estimator,
            patient=model_patient,
        )
    elif config.mode != "tracking":  # an interaction mode on the device's models
        controller = InteractionController(  # type: ignore[assignment]
            config.mode,
            config.modes,
            plan,
            model_exo,
            model_motor,
            tracking=controller if config.mode == "guidance" else None,
            dt=config.dt,
            estimator=config.estimator,
        )
    return Setup(
        config,
        exo,
        patient,
        plan,
        plant,
        controller,
        model_exo,
        model_patient,
        model_motor,
        belt_speed,
        online,
        tuple(
            run_warnings(
                config,
                exo,
                fitted,
                tracking,
                model_exo,
                model_motor,
                references,
                model_patient,
                precomputed_plan,
            )
        ),
        user_estimator,
        tuple(run_notes(config, tracking, model_exo)),
    )


def precomputed_plan(
    config: SimConfig, exo: BodyModel, sink: StanceSink | None = None
) -> JointTrajectory:
    """The run's plan at its control ticks, precomputed (``config`` not synchronised).

    The calibration motion, or the gait ramped in (:class:`~exo_ctrl.plan.RampedGait`)
    through the closed-form inverse kinematics on ``exo``, laid out as
    ``config.plan_layout`` says (a periodic part stored once).
    """
    rows = config.plan_layout
    times = rows.ticks() * config.dt
    if config.exercise == "calibration":
        return calibration_plan(exo, times, config.duration_s, config.gait.hip_height)
    plan = plan_joints(RampedGait(GaitPlan(config.gait, sink), config.ramp), exo, times)
    if rows.period:
        tail = None if rows.tail == NO_TAIL else rows.tail
        plan = dataclasses.replace(
            plan, period_ticks=rows.period, lead_ticks=rows.lead, tail_tick=tail
        )
    return plan


def drive_for(motor: MotorParams, exo: BodyModel) -> MotorParams:
    """The drive as configured for this exoskeleton.

    The driver's current limit is capped at the smallest URDF effort limit
    divided by i_G k_m, so that the torque a drive holds never exceeds its
    joint's rated effort (150 N·m → 32.4 A for the default drive, above its
    own 32 A; 8.57 A for the paper's printed one).  Braking, where the
    gearbox passes the motor torque over η, the plant holds the joint
    torque at the rating (:mod:`exo_ctrl.plant.plant`).
    """
    cap = float(np.min(exo.effort_limit)) / motor.torque_per_amp_Nm_per_A
    if motor.current_limit_A <= cap:
        return motor
    return dataclasses.replace(motor, current_limit_A=cap)


def stance_sink_for(config: SimConfig, model_exo: BodyModel) -> StanceSink | None:
    """The plan's loading sink (:mod:`exo_ctrl.plan.loading`): a supported pelvis, else None.

    The static load W₀ = M g − F_s and the moving mass M as the device holds
    them (:func:`stance_load_for`), k and n of the soles on the belt as the
    device holds them (:meth:`~exo_ctrl.sim.belief.Belief.sole_model`: the
    datasheet's).  The plan uses it with double support (β > ½) only.
    """
    load = stance_load_for(config, model_exo)
    if load is None or not config.contact.enabled:
        return None
    k, n = config.belief.sole_model(config.contact)
    return StanceSink(
        max(0.0, load.mass_kg * load.gravity_mps2 - load.support_N),
        load.mass_kg,
        k,
        n,
    )


def _pelvis_rest(plant: Plant, q0: np.ndarray) -> tuple[float, np.ndarray]:
    """The pelvis at rest on the feet of q₀ that touch the belt, and their normal forces [m, N].

    The feet within 1 mm of the deepest one share M g − F_s equally; each
    sinks δ = (F_n / k)^(1/n) (the contact law at rest), so z₀ = δ₀ − δ with
    δ₀ the deepest foot's penetration at z = 0.
    """
    pel, contact = plant.pelvis[0], plant.contact.params
    pen = plant.contact.penetration(q0)
    loaded = pen >= pen.max() - 1e-3
    load = float(pel["mass"]) * -float(plant.model.gravity.linear[2]) - float(pel["support"])
    fn = np.where(loaded, max(load, 0.0) / np.count_nonzero(loaded), 0.0)
    sink = (fn.max() / contact.stiffness_N_per_m_n) ** (1.0 / contact.exponent)
    return float(pen.max() - sink), fn


def start_on_plan(setup: Setup) -> None:
    """Put the plant on the plan's first row at t = 0, with the planned speed.

    The exoskeleton starts at the plan's q₀, q̇₀ (standing at rest after a
    ramp-in; on the gait at speed without one).  The cuffs
    (``config.cuff_fit``):

    - ``"equilibrium"``: fitted slack with the patient aligned, then the
      patient settled into them at static equilibrium
      (:func:`~exo_ctrl.plant.equilibrium.settle_patient`; with the patient's
      feet on the belt, standing on it), the patient at the exoskeleton's speed;
    - ``"slack"``: fitted slack with the patient in the exoskeleton's posture
      (the patient then drops into the straps).

    The drive currents (clipped to the driver's limit): at rest, the torque
    holding the exoskeleton still, its gravity less the cuffs' reaction
    (:func:`~exo_ctrl.plant.equilibrium.holding_torque`); on the gait at
    speed, the feedforward torque of t = 0, so that the legs do not sag.
    """
    plant, plan, config = setup.plant, setup.plan, setup.config
    motor = plant.motor_params
    q0, dq0 = plan.q[0], plan.dq[0]
    q_p = q0
    if config.cuff_fit == "equilibrium":
        own = patient_torque_for(config, setup.patient)
        feet = plant.patient_feet  # on the belt: the patient stands on it too
        ground = feet.rest_torque if feet.on else None
        q_p = settle_patient(plant.cuffs, setup.patient.model, q0, own, ground)
    if config.ramp_in > 0.0:
        tau0 = holding_torque(plant.cuffs, setup.exo.model, q0, q_p)
    else:
        tau0 = feedforward_torque(plan, setup.exo, setup.patient, motor, rows=1)[0]
    z0 = 0.0
    if config.pelvis.supported:  # the stance feet carry M g - F_s: the drives hold it
        z0, fn = _pelvis_rest(plant, q0)
        tau0 = tau0 - (plant.contact.normal_jacobian(q0) * fn[:, None]).reshape(4)
    limit = motor.current_limit_A
    i0 = np.clip(tau0 / motor.torque_per_amp_Nm_per_A, -limit, limit)
    fit = config.cuff_fit == "slack"
    if setup.belt_speed is not None:  # the belt runs at its first set speed
        plant.contact.belt["v_set"] = setup.belt_speed[0, 0]
    plant.reset(q0, dq0, q_p, dq0, current_A=i0, fit_cuffs=fit, pelvis_z_m=z0)


def patient_torque_for(config: SimConfig, patient: BodyModel) -> PatientTorque | None:
    """The patient's own joint torques of a run (``config.patient_torque``), a new instance.

    Args:
        config: the run.
        patient: the TRUE patient model (the active patient's own legs).

    """
    if config.patient_torque == "active":
        return ActivePatient(
            config.patient_active,
            patient,
            config.gait,
            config.ramp_in,
            config.duration_s,
            config.dt / config.plant_substeps,
        )
    return make_patient_torque(config.patient_torque)


def check_followable(
    config: SimConfig,
    plan: JointTrajectory,
    exo: BodyModel,
    patient: BodyModel,
    motor: MotorParams,
) -> None:
    r"""Refuse a gait whose planned joint speeds the device cannot follow.

    The planned speed ω_j(t) of each joint is taken from the run's ``plan``
    when its ticks sample a gait period at least
    :data:`SPEED_SAMPLES_PER_PERIOD` times, else from the ramped gait sampled
    that often over its ramp-in and first period after it, and over its
    ramp-out (the run's span if shorter): a coarse control rate does not hide
    a peak between its ticks.  Each joint may move
    at most at the smallest of

    - the exoskeleton URDF's speed limit ``<limit velocity>`` [rad/s],
    - the patient URDF's (the patient's joints follow the exoskeleton's),
    - the drive's no-load speed at the supply, ω₀ = U_max / (i_G / k_E)
      [rad/s]: there the back-EMF i_G ω / k_E alone takes the whole supply
      voltage, and any torque needs R I on top (5.18 rad/s with the
      defaults).

    A limit that is not a finite number > 0 is no limit.  The default
    scenario peaks at 2.15 rad/s (knees), 2.8 times within the 6 rad/s of
    the default exoskeleton.

    Args:
        config: the run (its gait, duration and control rate).
        plan: the run's joint plan (:func:`build`).
        exo: the exoskeleton model.
        patient: the patient model.
        motor: the drive as configured (:func:`drive_for`).

    Raises:
        InvalidParameter: the joint whose planned speed is furthest beyond its
            limit, with the speed [rad/s], the limit and where it comes from.

    """
    gait, ramp = config.gait, config.ramp
    calibration = config.exercise == "calibration"  # its plan holds every tick: checked as is
    if not calibration and config.dt > gait.period / SPEED_SAMPLES_PER_PERIOD:
        spans = [(0.0, min(config.duration_s, ramp.ramp_in_s + gait.period))]
        if ramp.ramp_out_s > 0.0:
            spans.append((ramp.out_start_s, ramp.end_s))
        times = []
        for start, end in spans:
            n = max(math.ceil(SPEED_SAMPLES_PER_PERIOD * (end - start) / gait.period), 1) + 1
            times.append(np.linspace(start, end, n))
        plan = plan_joints(RampedGait(gait, ramp), exo, np.concatenate(times))
    t, dq = plan.t, np.abs(plan.dq)
    kb = motor.back_emf_V_per_rad_s
    sources = (
        (exo.velocity_limit, "the exoskeleton URDF's speed limit"),
        (patient.velocity_limit, "the patient URDF's speed limit"),
        (
            np.full(4, motor.supply_voltage_V / kb),
            f"where the drive's back-EMF i_G ω / k_E ({kb:.4g} V·s/rad × ω) "
            f"takes the whole {motor.supply_voltage_V:.4g} V supply",
        ),
    )
    peak = dq.max(axis=0)
    worst = None
    for limits, reason in sources:
        for j, limit in enumerate(limits):
            if not (math.isfinite(limit) and limit > 0.0):
                continue
            ratio = peak[j] / limit
            if ratio > 1.0 and (worst is None or ratio > worst[0]):
                worst = (ratio, j, float(limit), reason)
    if worst is None:
        return
    _, j, limit, reason = worst
    at = float(t[np.argmax(dq[:, j])])
    remedy = "a longer period or a shorter step slows it"
    if calibration:
        remedy = "the calibration swing is too fast for this device"
    elif at < ramp.ramp_in_s or at > ramp.out_start_s:
        which = "ramp-in" if at < ramp.ramp_in_s else "ramp-out"
        span = ramp.ramp_in_s if which == "ramp-in" else ramp.ramp_out_s
        remedy = f"in its {span:g} s {which}: a longer {which} or a shorter step slows it"
    raise InvalidParameter(
        f"planned {JOINT_NAMES[j]} speed",
        float(f"{peak[j]:.4g}"),
        f"at most {limit:.4g} rad/s, {reason}",
        f"rad/s, at t = {at:.4g} s of a gait with period {gait.period:g} s and step_length "
        f"{gait.step_length:g} m: {remedy}",
    )
