"""What a run tells its user before it starts: its warnings and its notes.

Warnings (:func:`run_warnings`): what to know before trusting the run's figures (a device
that does not fit its patient, a plan beyond the drives' reach, a spastic patient's tone near
the cuff limits, a bound not promised).  Notes (:func:`run_notes`): what the run does that
its user should know (how the QP keeps its bound with the feet over the belt).  The command
line prints both before the first tick; the summary and the recording keep both.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..control import ComputedTorqueController
from ..control.drive_reach import torque_reach_warning
from ..control.qp import QPController, contact_warning, departure_warning
from ..model import BodyModel
from ..model.fit import fit_warnings
from ..plan import JointTrajectory
from ..plant import MotorParams
from .belief import nominal_stature
from .config import SimConfig
from .supervision import departure_for
from .tone_load import tone_applies, tone_warnings

__all__ = ["run_notes", "run_warnings"]


def run_warnings(
    config: SimConfig,
    exo: BodyModel,
    fitted: BodyModel,
    controller: object = None,
    model_exo: BodyModel | None = None,
    model_motor: MotorParams | None = None,
    references: tuple[JointTrajectory, ...] = (),
    model_patient: BodyModel | None = None,
    plan_for: Callable[[SimConfig, BodyModel], JointTrajectory] | None = None,
) -> list[str]:
    """The run's warnings (:attr:`~exo_ctrl.sim.Setup.warnings`).

    The fit, then the nominal patient's notes, then a landing approach on a
    precomputed plan (:mod:`exo_ctrl.plan.surface` needs the synchronised one),
    then, for computed torque and the QP, a plan whose feedforward exceeds the
    drives' peak torque (:func:`~exo_ctrl.control.drive_reach.torque_reach_warning`;
    ``model_motor``: the device's drive, None: not checked; along ``references``, a
    synchronised run's steady gaits precomputed), then a spastic patient's tone near the
    cuff limits, or for the QP over the belt near what its margin leaves under its bound
    (:mod:`.tone_load`; ``model_patient``: the device's patient, ``plan_for``:
    :func:`~exo_ctrl.sim.setup.precomputed_plan`), then, for the QP, a bound its margin
    leaves below the plan's load (:func:`~exo_ctrl.control.qp.departure_warning`) and, with
    the feet over the belt and the bound not tightened, that it is not promised there
    (:func:`~exo_ctrl.control.qp.contact_warning`).
    """
    out = fit_warnings(exo, fitted)
    if config.belief.patient == "nominal":
        out += nominal_stature(config.belief, config.patient, fitted)[2]
    if config.gait.landing_speed_mps > 0.0 and not config.synced:
        out.append(
            f"the landing approach (landing_speed_mps {config.gait.landing_speed_mps:g}) runs on "
            "a precomputed plan here, which cannot place it on the stance foot's measured "
            "height: touchdowns under body-weight support can be harder than on the paper's "
            "path (docs/performance.md, touchdowns under load)"
        )
    if isinstance(controller, ComputedTorqueController) and model_motor is not None:
        table = controller.torque_ff_table
        if references:  # the one-row plan: the profile's steady gaits precomputed
            table = np.concatenate([controller.feedforward_along(p) for p in references])
        reach = torque_reach_warning(table, model_motor.peak_torque_Nm)
        if reach is not None:
            out.append(reach)
    qp = isinstance(controller, QPController)
    stop = departure_for(config, model_exo or exo) if qp else None  # the QP over the belt
    if tone_applies(config) and None not in (model_patient, model_motor, plan_for):
        device = (plan_for, model_exo or exo, model_patient, model_motor)
        if not qp:
            out += tone_warnings(config, *device)
        elif stop is not None:
            room = controller.cuff_limits_N - controller.margin.static_N
            out += tone_warnings(config, *device, qp_room_N=room)
    if qp:
        departure = departure_warning(
            controller.margin, controller.cuff_force_limit_N, config.cuff_sensors.mode
        )
        if departure is not None:
            out.append(departure)
        if config.contact.enabled and stop is None:
            out.append(contact_warning(controller.cuff_force_limit_N, None, config.synced))
    return out


def run_notes(config: SimConfig, controller: object, model_exo: BodyModel) -> list[str]:
    """What the run does that its user should know, one sentence each (``Setup.notes``).

    The QP's departure stop with the feet over the belt
    (:func:`~exo_ctrl.control.qp.contact_warning`; ``model_exo``: the device's
    exoskeleton, whose legs set the stop's limit): how the walk ends where the QP leaves
    its plan to hold its bound.  Not a warning: it says how the bound is kept, not that a
    figure may be wrong.
    """
    stop = departure_for(config, model_exo) if isinstance(controller, QPController) else None
    if stop is None:  # no QP, or not over the belt, or the bound not tightened
        return []
    limit = controller.cuff_force_limit_N
    return [contact_warning(limit, stop.limit_rad, config.synced, stop.lookahead_s)]
