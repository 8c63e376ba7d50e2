"""The pieces of a run, built from its configuration, and the state it starts in."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..control import (
    ComputedTorqueController,
    PDController,
    QPController,
    feedforward_torque,
)
from ..model import BodyModel, load_exo, load_patient
from ..plan import GaitPlan, JointTrajectory, plan_joints
from ..plant import MotorParams, Plant
from .config import SimConfig

__all__ = ["Setup", "build", "drive_for", "plan_rows", "start_on_plan"]


@dataclass
class Setup:
    """The pieces of a run, built from a :class:`SimConfig` by :func:`build`."""

    config: SimConfig
    exo: BodyModel
    patient: BodyModel
    plan: JointTrajectory
    plant: Plant
    controller: PDController


def build(config: SimConfig) -> Setup:
    """Load the models, plan the run and build the plant and controller."""
    exo = load_exo(config.exo)
    patient = load_patient(config.patient)
    rows = plan_rows(config)
    plan = plan_joints(GaitPlan(config.gait), exo, np.arange(rows) * config.dt)
    if rows <= config.n_ticks:
        plan = dataclasses.replace(plan, period_ticks=rows)
    motor = drive_for(config.motor, exo)
    plant = Plant(
        exo, patient, dt=config.dt / config.plant_substeps, motors=motor, cuffs=config.cuffs
    )
    controller: PDController
    if config.controller == "ct":
        controller = ComputedTorqueController(plan, exo, patient, motor, config.gains)
    elif config.controller == "qp":
        controller = QPController(
            plan,
            exo,
            patient,
            motor,
            config.gains,
            cuff_force_limit_N=config.cuff_force_limit_N,
            cuffs=config.cuffs,
            dt=config.dt,
        )
    else:
        controller = PDController(plan, config.gains)
    return Setup(config, exo, patient, plan, plant, controller)


def plan_rows(config: SimConfig) -> int:
    """Rows of the joint plan: one gait period if it is a whole number of ticks.

    The gait is periodic, so tick k uses row k mod P; with P = T_s / Δt an
    integer (1200 for the default 1.2 s at 1 kHz) the plan's memory does not
    grow with the run's length.  Otherwise the plan covers every tick.
    """
    period = config.gait.period / config.dt
    p = round(period)
    if p >= 2 and abs(p - period) <= 1e-9 * period:
        return min(p, config.n_ticks + 1)
    return config.n_ticks + 1


def drive_for(motor: MotorParams, exo: BodyModel) -> MotorParams:
    """The drive as configured for this exoskeleton.

    The driver's current limit is capped at the smallest URDF effort limit
    divided by i_G k_m, so that no drive torque ever exceeds its joint's
    rated effort (150 N·m → 8.57 A with the defaults).
    """
    cap = float(np.min(exo.effort_limit)) / motor.torque_per_amp_Nm_per_A
    if motor.current_limit_A <= cap:
        return motor
    return dataclasses.replace(motor, current_limit_A=cap)


def start_on_plan(setup: Setup) -> None:
    """Put the plant on the plan at t = 0, with the planned speed.

    The drive currents carry the feedforward torque of t = 0 (clipped to the
    driver's limit), so the legs do not sag at the start; the patient starts
    in the exoskeleton's posture and the cuffs are fitted there.
    """
    plant, plan = setup.plant, setup.plan
    motor = plant.motor_params
    tau0 = feedforward_torque(plan, setup.exo, setup.patient, motor, rows=1)[0]
    limit = motor.current_limit_A
    i0 = np.clip(tau0 / motor.torque_per_amp_Nm_per_A, -limit, limit)
    plant.reset(plan.q[0], plan.dq[0], current_A=i0)
