"""The run's tracking controller (``SimConfig.controller``), built on the device's models.

What the device knows goes in: its exoskeleton and nominal patient
models, its drive datasheet, the plan; for the CT and the QP also what it
knows of its stance legs' load (a supported pelvis) and whether its feet
leave a belt (the lift-off blend).
"""

from __future__ import annotations

from ..control import Device, PDController, PluginController, QPController
from ..control.builtin import compiled_type
from ..control.lift_off import LIFT_OFF_BLEND_S
from ..control.plugin import load_controller
from ..control.qp import CuffKnowledge
from ..control.stance_load import StanceLoad
from ..estimation import Estimator
from ..model import BodyModel
from ..plan import JointTrajectory
from ..plant import MotorParams
from ..plant.pelvis import moving_mass_kg
from .config import SimConfig

__all__ = ["lift_off_blend_for", "stance_load_for", "tracking_controller"]


def tracking_controller(
    config: SimConfig,
    plan: JointTrajectory,
    model_exo: BodyModel,
    model_patient: BodyModel,
    model_motor: MotorParams,
    user_estimator: Estimator | None = None,
    references: tuple[JointTrajectory, ...] = (),
) -> PDController:
    """A new tracking controller of the run (``config.controller``) on the device's models.

    With a user's estimator the QP takes its estimate as the momentum
    observer's, a first-order lag at the class's ``bandwidth_per_s``.  The QP's
    bound margin is computed along ``references`` (a synchronised run: the
    precomputed plans of its profile's steady gaits,
    :func:`~exo_ctrl.sim.sync.profile_runs`), else along ``plan``.

    ``"pd"`` and ``"ct"`` are the classes :class:`~exo_ctrl.control.PD` and
    :class:`~exo_ctrl.control.CT` with ``config.gains``; an object of exactly
    one of these classes runs, with its own gains, the compiled tick
    controller its name runs (:mod:`exo_ctrl.control.builtin`).  Any other
    controller (:mod:`exo_ctrl.control.plugin`; a path is imported) is set
    up with what the device knows and called through the Python adapter.
    """
    if config.controller == "qp":
        gain = config.observer_gain_per_s
        if user_estimator is not None:
            gain = type(user_estimator).bandwidth_per_s
        return QPController(
            plan,
            model_exo,
            model_patient,
            model_motor,
            config.gains,
            cuff_force_limit_N=config.cuff_force_limit_N,
            margin_plans=references,
            cuffs=config.belief.cuff_model_of(config.cuffs),
            dt=config.dt,
            estimate_gain_per_s=gain,
            restored_bandwidth_per_s=config.qp_estimate_bandwidth_per_s,
            estimator="momentum" if user_estimator is not None else config.estimator,
            tighten=config.qp_tighten_bound,
            gait=_gait_words(config),
            stance_load=stance_load_for(config, model_exo),
            lift_off_blend_s=lift_off_blend_for(config),
            cuff_knowledge=CuffKnowledge(
                config.cuffs,
                config.belief.cuff_spread(),
                config.cuff_sensors.mode,
                tare=config.cuff_sensors.tared,
            ),
        )
    device = Device(
        model_exo,
        model_patient,
        plan,
        model_motor,
        config.dt,
        stance_load=stance_load_for(config, model_exo),
        lift_off_blend_s=lift_off_blend_for(config),
    )
    controller = load_controller(config.controller, config.gains)
    if compiled_type(controller):
        return controller.compiled(device)  # type: ignore[attr-defined]
    return PluginController(controller, device)  # type: ignore[return-value]


def _gait_words(config: SimConfig) -> str:
    """The gait in words, for a refusal's message (with the speed profile it adapts along)."""
    step = config.gait.step_length
    shown = f"{step:g} m" if isinstance(step, (int, float)) else str(step)
    words = f"the gait with period {config.gait.period:g} s and step_length {shown}"
    if config.synced and config.speed_profile is not None:
        words += f" adapted along speed_profile {config.speed_profile.text()}"
    return words


def lift_off_blend_for(config: SimConfig) -> float:
    """T_b of the swing leg's feedforward blend (:mod:`exo_ctrl.control.lift_off`) [s].

    With the belt (contact on) a foot leaves it at lift-off; without it no foot is
    loaded, and the plan's q̈* is fed forward as planned (0).
    """
    return LIFT_OFF_BLEND_S if config.contact.enabled else 0.0


def stance_load_for(config: SimConfig, model_exo: BodyModel) -> StanceLoad | None:
    """What the device knows of its stance legs' load: the pelvis supported, else None.

    The moving mass from the body mass entered at the device and its own
    exoskeleton model; the support it applies.
    """
    pelvis = config.pelvis_resolved
    if not pelvis.supported:
        return None
    return StanceLoad(
        moving_mass_kg(pelvis, model_exo.model),
        pelvis.support_N,
        -float(model_exo.model.gravity.linear[2]),
    )
