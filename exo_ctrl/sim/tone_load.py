r"""Before a run: the cuff load a spastic patient's tone adds along the plan.

The spastic patient (:mod:`exo_ctrl.plant.patient`) resists the swing's speeds: the
knee's stretch reflex (20 N·m·s/rad above 0.5 rad/s while it flexes, up to 40 N·m)
at the swing's flexion speed (3.2 rad/s on the ``clinic-bws`` preset's 1.6 s gait)
and its extra viscosity.  A controller that tracks the plan (PD, computed torque)
moves the legs through that tone, so the cuffs carry the leg's inverse dynamics plus
the tone, per leg

.. math::  f = D(q^*, \dot q^*)\,\bigl(τ_{ID}(q^*, \dot q^*, \ddot q^*)
           - τ_{tone}(q^*, \dot q^*)\bigr),

D the device's cuff model's share of a joint-space load between the leg's two cuffs
(:func:`~exo_ctrl.control.qp.margin.share_matrices`), τ_ID the device's patient
model's inverse dynamics, τ_tone the run's spastic model at the planned posture and
speeds, over the rows where the leg swings (in stance the belt carries it).  Where
the largest |f| of a shank cuff comes within :data:`PREDICTION_SHARE` of the
supervisor's cuff limit, the run is told before it starts, with the shortest period
(the other gait parameters kept; bisection) that keeps both shank cuffs below that share.

**How well it predicts** (CT, the patient's feet on the belt, safety on).  The
default patient's shanks: ``clinic-spastic`` at T = 2.0 s 110.8 N predicted against
108–116 N true, T = 1.8 s 122.8 N against 128–129 N (the supervisor, reading the
estimate, stopped two runs of three), ``clinic-bws`` at T = 1.6 s 138.0 N (the run
stopped in its first swing, the shank cuff's estimate at 130 N).  Over the 64
spastic patients of the touchdown campaign (``tools/touchdowns.py --points 200 --seed
0``: the cohort, the knee 0–2 cm off, the true cuffs scattered; ``clinic-spastic``'s
gait in proportion) the prediction less the true peak is +4.1 N on the shanks
(13.9 N standard deviation) and +34.7 N on the thighs (17.7 N): the thighs are not
judged.  With the share at 0.9, 43 of the 64 are told, 23 of them with a true shank
peak of 117 N or more and 12 past 130 N; 3 untold pass 130 N.  On 15 of the 64 the
true shank force passes 130 N while the supervisor's estimate stays below it: the
along-shank force a misaligned knee adds is the cuff model's without 2-axis cuff
sensors; with them (``--cuff-sensors full``) the supervisor stops points 33, 176 and
179 at 130 N on the estimate, the true force at 129–130 N.  Not the QP: it holds
its own bound by leaving the plan (its margin and its departure stop,
:mod:`exo_ctrl.control.qp.margin`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin

from ..control.qp.margin import share_matrices
from ..control.qp.prediction import CuffHorizonModel
from ..exceptions import ExoCtrlError
from ..model import CUFF_NAMES, BodyModel
from ..plan.kinematics import JointTrajectory
from ..plant import MotorParams
from ..plant.patient import make_patient_torque
from ..safety.limits import resolve_limits

__all__ = ["PREDICTION_SHARE", "swing_cuff_loads", "tone_applies", "tone_warnings"]

#: The share of the supervisor's cuff limit the predicted load may reach [-] (module
#: docstring: the prediction's measured error, and the estimate the supervisor reads).
PREDICTION_SHARE = 0.9
#: The shanks' prediction less the true peak over the touchdown campaign's 64 spastic
#: patients: mean and standard deviation [N] (module docstring), said with the sentence.
PREDICTION_ERROR_N = (4.1, 13.9)
#: The cuffs judged: the shanks (CUFF_NAMES order; the thighs' prediction runs high).
SHANKS = slice(1, None, 2)
#: Every this many plan rows are scanned (5 ms at the default 1 ms tick).
STRIDE = 5
#: The longest period the suggestion looks at, in gait periods of the run [-].
LONGEST = 2.0


def swing_cuff_loads(
    plan: JointTrajectory, patient: BodyModel, cuffs: CuffHorizonModel
) -> np.ndarray:
    """The largest |f_c| per cuff over its leg's swing rows [N], (4,) CUFF_NAMES order.

    Module docstring.

    ``patient``: the device's patient model; ``cuffs``: the device's cuff model (linearised
    here at each row).  A plan without lift-offs (an exercise) gives zeros.
    """
    out = np.zeros(4)
    if plan.lift_off_s is None:
        return out
    tone = make_patient_torque("spastic")
    model, data = patient.model, patient.model.createData()
    tau_tone = np.zeros(4)
    for r in range(0, plan.q.shape[0], STRIDE):
        swing = np.isfinite(plan.lift_off_s[r])
        if not swing.any():
            continue
        q, dq, ddq = plan.q[r], plan.dq[r], plan.ddq[r]
        need = pin.rnea(model, data, q, dq, ddq) - tone(0.0, q, dq, tau_tone)
        cuffs.linearise(q, dq)
        share = share_matrices(cuffs, cuffs.split)
        for leg in np.flatnonzero(swing):
            force = share[leg] @ need[2 * leg : 2 * leg + 2]  # thigh x, z, shank x, z
            for k in range(2):
                c = 2 * leg + k
                out[c] = max(out[c], float(np.hypot(*force[2 * k : 2 * k + 2])))
    return out


def tone_applies(config: Any) -> bool:
    """Whether the run is checked: the spastic patient walked by PD or CT tracking its plan."""
    return (
        config.patient_torque == "spastic"
        and config.controller in ("pd", "ct")
        and config.mode == "tracking"
        and config.session is None
        and config.exercise == "gait"
    )


def tone_warnings(
    config: Any,
    plan_for: Callable[[Any, BodyModel], JointTrajectory],
    exo: BodyModel,
    patient: BodyModel,
    motor: MotorParams,
) -> list[str]:
    """The sentence for a tracking run whose spastic patient's tone nears a shank cuff's limit.

    Args:
        config: the run (:class:`~exo_ctrl.sim.SimConfig`).
        plan_for: the precomputed plan of a run for an exoskeleton
            (:func:`~exo_ctrl.sim.setup.precomputed_plan`; raises
            :class:`~exo_ctrl.exceptions.ExoCtrlError` where the planner refuses it).
        exo: the device's exoskeleton model.
        patient: the device's patient model.
        motor: the device's drive.

    Returns:
        The sentence, one or none (both shank cuffs below :data:`PREDICTION_SHARE` of their
        limit).

    """
    limit = resolve_limits(config.safety_limits, exo, patient, motor).cuff_limit[SHANKS]
    cuffs = CuffHorizonModel(
        exo, patient, motor, config.belief.cuff_model_of(config.cuffs), config.dt, (1,)
    )

    def loads(period: float) -> np.ndarray | None:
        gait = dataclasses.replace(config.gait, period=period)
        ramp = period if config.ramp_in_s is None else config.ramp_in_s
        run = dataclasses.replace(  # the ramp-in and one period and a half, whatever the run's
            config, gait=gait, sync=False, ramp_out_s=0.0, duration_s=ramp + 1.5 * period
        )
        try:
            plan = plan_for(run, exo)
            return swing_cuff_loads(plan, patient, cuffs)[SHANKS]
        except ExoCtrlError:
            return None

    period = config.gait.period
    load = loads(period)
    if load is None or np.all(load < PREDICTION_SHARE * limit):
        return []
    c = int(np.argmax(load / limit))  # left, right
    low, high = period, LONGEST * period
    fits = loads(high)
    if fits is None or np.any(fits >= PREDICTION_SHARE * limit):
        hint = f"no gait period up to {high:.2g} s keeps the shank cuffs below that share"
    else:
        while high - low > 0.05:
            mid = 0.5 * (low + high)
            trial = loads(mid)
            if trial is not None and np.all(trial < PREDICTION_SHARE * limit):
                high = mid
            else:
                low = mid
        hint = (
            f"a gait period of at least {high:.2f} s keeps the shank cuffs below "
            f"{PREDICTION_SHARE * limit.min():.0f} N"
        )
    stop = ", and the supervisor may stop the run" if config.safety else ""
    if config.cuff_sensors.mode != "full":  # the along-shank force is the cuff model's
        hint += (
            "; without 2-axis cuff sensors the supervisor reads the shank's along force from "
            "its cuff model and can miss the excess (--cuff-sensors full measures it)"
        )
    return [
        f"the spastic patient's tone loads the {CUFF_NAMES[1 + 2 * c]} cuff to about "
        f"{load[c]:.0f} N along the plan (the device's patient model moved through its stretch "
        f"reflex at the planned speeds), past {100 * PREDICTION_SHARE:.0f} % of its limit "
        f"{limit[c]:.0f} N: the true force can pass the limit in a swing{stop} (the "
        f"prediction's error over the cohort: {PREDICTION_ERROR_N[0]:+.0f} N, "
        f"{PREDICTION_ERROR_N[1]:.0f} N standard deviation); {hint} "
        "(docs/performance.md, touchdowns under load)"
    ]
