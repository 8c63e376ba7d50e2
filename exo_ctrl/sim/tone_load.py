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
true shank force passes 130 N while the supervisor's estimate stays below it (below).

**What the supervisor cannot see.**  Without 2-axis cuff sensors the along-shank force
is the cuff model's (:mod:`exo_ctrl.estimation.kalman`, "What is observed"), and a knee
axis d off the exoskeleton's adds one the model does not hold: with the straps fitted
at the start, the shank cuff parts from the limb by Δp = A d,
A = (R(θ_s) − R(θ_t)) − (R(θ_s⁰) − R(θ_t⁰)) (:mod:`exo_ctrl.plant.misalignment`, at the
start's link angles θ⁰), whose along-shank part is at most ‖Aᵀu‖ |d| over every
direction of d (:func:`along_reach`; 0.41 at the swing's deepest flexion on the
``clinic-*`` presets' gait).  The device knows neither d nor its patient's shear
stiffness, only a fit tolerance d_max (``belief.knee_fit_tolerance_m``, default the
benchmark cohort's 3 cm) and the true stiffness's spread (within k_u (1 ± 2s)), so the
along force it cannot see is up to k_u (1 + 2s) d_max ‖Aᵀu‖: 64 N on ``clinic-spastic``.
Widening the predicted shank force's along component by that much, where the widened
force reaches the supervisor's limit a PD or CT run with its supervisor on is told so
before it starts, with the shortest period that keeps it below.  Checked against the
plant (tests/sim/test_tone_load.py): on the default scenario with the knee 2 cm up or
back and the exact published cuffs the estimate's along-shank error stays within
k_u |d| ‖Aᵀu‖ plus 3 N at every tick, and with the knee up reaches 65 % of it.  Over
the touchdown campaign's 64 spastic patients the 15 whose true shank force passes
130 N unseen are all told (every one of the 64 is, at 3 cm; at 2 cm 53, 14 of the 15).
It is a prediction on the nominal patient, not a bound: with each point's own offset as
the tolerance the widened load fell short of the true peak on 3 of the 15 (point 33:
136 N against 161 N), the patient's own segments and tone differing from the model's.
With 2-axis sensors (``--cuff-sensors full``) the supervisor sees the force: it stopped
points 33, 176 and 179 at 130 N on the estimate, the true force at 129–130 N.  With
``safety_widen`` the supervisor itself watches the estimate so widened
(:mod:`exo_ctrl.safety.unseen`), and the sentence says it will likely stop the run.

**The QP** holds its own bound by leaving the plan where the load passes what its
margin leaves under the bound, F_max − m_c (:mod:`exo_ctrl.control.qp.margin`), and
over the belt a leg off its plan stops the walk (:mod:`exo_ctrl.safety.departure`).
So with the feet over the belt the same load is judged against :data:`QP_RATIO`
times that room.  The ratio, from the touchdown campaign's 64 spastic patients
(``tools/touchdowns.py --points 200 --seed 0 --controller qp``, the QP at 200 N on
the thighs and 120 N on the shanks): the lowest ratio of its 22 stops on a departure
is 1.327, so 1.32; 32 are told, the 22 stops among them.  Checked where it was not
set, the 100 spastic patients of ``--points 100 --seed 1 --patients spastic``: 56
told, all 35 stops among them (the lowest at 1.352), none of the 44 untold
stopped.  The predicted load is above the room on every one of them (1.17–1.55
times): the rigid-leg prediction is not the QP's, only its order.  The period
named keeps the run's room (the margin along a slower plan is not recomputed).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np
import pinocchio as pin

from ..control.qp.cuff_knowledge import link_normals
from ..control.qp.margin import share_matrices
from ..control.qp.prediction import CuffHorizonModel
from ..exceptions import ExoCtrlError
from ..model import CUFF_NAMES, BodyModel
from ..plan.kinematics import JointTrajectory
from ..plant import MotorParams
from ..plant.patient import make_patient_torque
from ..safety.limits import resolve_limits
from ..safety.unseen import along_reach_into

__all__ = [
    "PREDICTION_SHARE",
    "along_reach",
    "swing_cuff_loads",
    "tone_applies",
    "tone_warnings",
    "unseen_along_N",
]

#: The share of the supervisor's cuff limit the predicted load may reach [-] (module
#: docstring: the prediction's measured error, and the estimate the supervisor reads).
PREDICTION_SHARE = 0.9
#: The shanks' prediction less the true peak over the touchdown campaign's 64 spastic
#: patients: mean and standard deviation [N] (module docstring), said with the sentence.
PREDICTION_ERROR_N = (4.1, 13.9)
#: The QP over the belt: the predicted shank load over what its margin leaves under its
#: bound at which the walk is told it is likely to stop on a departure [-] (module
#: docstring, "The QP"), and what that rule measured, said with the sentence.
QP_RATIO = 1.32
QP_RATIO_MEASURED = "57 of the 88 told stopped, none of the 76 untold"
#: The cuffs judged: the shanks (CUFF_NAMES order; the thighs' prediction runs high).
SHANKS = slice(1, None, 2)
#: Every this many plan rows are scanned (5 ms at the default 1 ms tick).
STRIDE = 5
#: The longest period the suggestion looks at, in gait periods of the run [-].
LONGEST = 2.0


def along_reach(model: CuffHorizonModel, q: np.ndarray, q_fit: np.ndarray) -> np.ndarray:
    """‖Aᵀ u_c‖ per shank cuff, (2,) left, right [-]: its along stretch per metre of knee offset.

    At ``q`` with the straps fitted at ``q_fit`` (the start), on ``model``'s cuffs
    (:func:`~exo_ctrl.safety.unseen.along_reach_into`; module docstring, "What the
    supervisor cannot see").
    """
    m = model.record[0]
    out = np.empty(2)
    along_reach_into(
        np.ascontiguousarray(m["select"][:4, :4]),
        np.ascontiguousarray(m["along0"]),
        np.asarray(q, dtype=float),
        np.asarray(q_fit, dtype=float),
        out,
    )
    return out


def swing_cuff_loads(
    plan: JointTrajectory, patient: BodyModel, cuffs: CuffHorizonModel, unseen_N: float = 0.0
) -> np.ndarray:
    """The largest |f_c| per cuff over its leg's swing rows [N], (3, 4) CUFF_NAMES order.

    Module docstring.  Row 0 the predicted load; row 1 the same with each shank's
    along-shank component widened by what the supervisor cannot see,
    |f| ≤ √(n² + (|a| + unseen_N ‖Aᵀu‖)²) (:func:`along_reach`, the fit at the plan's
    first row; the thighs as row 0); row 2 the largest unseen_N ‖Aᵀu‖ (the thighs 0).

    ``patient``: the device's patient model; ``cuffs``: the device's cuff model (linearised
    here at each row); ``unseen_N``: k_u (1 + 2s) d_max [N] (module docstring).  A plan
    without lift-offs (an exercise) gives zeros.
    """
    out = np.zeros((3, 4))
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
        normals = link_normals(cuffs, q)
        reach = unseen_N * along_reach(cuffs, q, plan.q[0])
        for leg in np.flatnonzero(swing):
            force = share[leg] @ need[2 * leg : 2 * leg + 2]  # thigh x, z, shank x, z
            thigh, shank = 2 * leg, 2 * leg + 1
            out[:, thigh] = np.maximum(out[:, thigh], np.hypot(*force[:2]))
            n_x, n_z = normals[shank]
            normal = n_x * force[2] + n_z * force[3]
            along = abs(n_x * force[3] - n_z * force[2])  # u = n turned by −90°
            out[0, shank] = max(out[0, shank], float(np.hypot(normal, along)))
            out[1, shank] = max(out[1, shank], float(np.hypot(normal, along + reach[leg])))
            out[2, shank] = max(out[2, shank], reach[leg])
    return out


def tone_applies(config: Any) -> bool:
    """Whether the run is checked: the spastic patient walked by PD, CT or the QP on its plan.

    (The QP only over the belt, where leaving its plan stops the walk: the caller's test.)
    """
    return (
        config.patient_torque == "spastic"
        and config.controller in ("pd", "ct", "qp")
        and config.mode == "tracking"
        and config.session is None
        and config.exercise == "gait"
    )


def unseen_along_N(config: Any) -> float:
    """k_u (1 + 2s) d_max [N]: the along-shank force a knee axis d_max off makes per unit ‖Aᵀu‖.

    k_u the device's cuff model's shear stiffness, s the spread it assumes for the true
    cuffs (a factor within 1 ± 2s), d_max its fit tolerance (:class:`~exo_ctrl.sim.Belief`).
    0 with 2-axis cuff sensors (``--cuff-sensors full``): they measure the along force.
    """
    if config.cuff_sensors.mode == "full":
        return 0.0
    belief = config.belief
    shear = belief.cuff_model_of(config.cuffs).shear_stiffness_N_per_m
    return shear * (1.0 + 2.0 * belief.cuff_spread()) * belief.knee_fit_tolerance()


def tone_warnings(
    config: Any,
    plan_for: Callable[[Any, BodyModel], JointTrajectory],
    exo: BodyModel,
    patient: BodyModel,
    motor: MotorParams,
    qp_room_N: np.ndarray | None = None,
) -> list[str]:
    """The sentences for a tracking run whose spastic patient's tone nears a shank cuff's limit.

    Args:
        config: the run (:class:`~exo_ctrl.sim.SimConfig`).
        plan_for: the precomputed plan of a run for an exoskeleton
            (:func:`~exo_ctrl.sim.setup.precomputed_plan`; raises
            :class:`~exo_ctrl.exceptions.ExoCtrlError` where the planner refuses it).
        exo: the device's exoskeleton model.
        patient: the device's patient model.
        motor: the device's drive.
        qp_room_N: for the QP over the belt, what its margin leaves under its bound per
            cuff, F_max − m_c [N], (4,): the load is judged against :data:`QP_RATIO` times
            it (module docstring, "The QP"); None: PD or CT, against the supervisor's limit.

    Returns:
        The sentences, none to two: the load near the limit; for PD and CT without
        2-axis cuff sensors, the true force able to pass the limit unseen by the
        supervisor (module docstring, "What the supervisor cannot see").

    """
    qp = qp_room_N is not None
    if not qp:
        limit = resolve_limits(config.safety_limits, exo, patient, motor).cuff_limit[SHANKS]
        ceiling = PREDICTION_SHARE * limit
    else:
        limit = np.asarray(qp_room_N, dtype=float)[SHANKS]
        ceiling = QP_RATIO * limit
    unseen = unseen_along_N(config) if not qp and config.safety else 0.0
    cuffs = CuffHorizonModel(
        exo, patient, motor, config.belief.cuff_model_of(config.cuffs), config.dt, (1,)
    )

    seen: dict[float, np.ndarray | None] = {}

    def loads(period: float) -> np.ndarray | None:
        if period in seen:
            return seen[period]
        gait = dataclasses.replace(config.gait, period=period)
        ramp = period if config.ramp_in_s is None else config.ramp_in_s
        run = dataclasses.replace(  # the ramp-in and one period and a half, whatever the run's
            config, gait=gait, sync=False, ramp_out_s=0.0, duration_s=ramp + 1.5 * period
        )
        try:
            plan = plan_for(run, exo)
            seen[period] = swing_cuff_loads(plan, patient, cuffs, unseen)[:, SHANKS]
        except ExoCtrlError:
            seen[period] = None
        return seen[period]

    period = config.gait.period
    now = loads(period)
    if now is None:
        return []
    out = []
    load, worst, reach = now
    if np.any(load >= ceiling):
        c = int(np.argmax(load / limit))  # left, right
        below = f"{ceiling.min():.0f} N"
        if qp:
            below = f"{QP_RATIO:g} times that room, {below}"
        hint = _shortest(loads, period, 0, ceiling, f"keeps the shank cuffs' load below {below}")
        what = (
            f"the spastic patient's tone loads the {CUFF_NAMES[1 + 2 * c]} cuff to about "
            f"{load[c]:.0f} N along the plan (the device's patient model moved through its "
            "stretch reflex at the planned speeds)"
        )
        if qp:
            out.append(
                f"{what}, {load[c] / limit[c]:.2f} times the {limit[c]:.0f} N the QP's margin "
                "leaves under its bound: the QP will leave its plan there and the walk is "
                f"likely to stop on a departure (over the touchdown campaign's spastic "
                f"patients: {QP_RATIO_MEASURED}); {hint} (docs/performance.md, touchdowns "
                "under load)"
            )
        else:
            stop = ", and the supervisor may stop the run" if config.safety else ""
            out.append(
                f"{what}, past {100 * PREDICTION_SHARE:.0f} % of its limit {limit[c]:.0f} N: "
                f"the true force can pass the limit in a swing{stop} (the prediction's error "
                f"over the cohort: {PREDICTION_ERROR_N[0]:+.0f} N, {PREDICTION_ERROR_N[1]:.0f} N "
                f"standard deviation); {hint} (docs/performance.md, touchdowns under load)"
            )
    if unseen > 0.0 and np.any(worst >= limit):
        c = int(np.argmax(worst / limit))
        cuff, tol = CUFF_NAMES[1 + 2 * c], 100 * config.belief.knee_fit_tolerance()
        hint = _shortest(loads, period, 1, limit, "keeps it below the limit")
        reach_at = (
            f"a knee axis up to {tol:.1f} cm off the device's (belief.knee_fit_tolerance_m) "
            f"puts up to {reach[c]:.0f} N along the {cuff} cuff"
        )
        if config.safety_widen:
            out.append(
                f"the supervisor watches the shank cuffs' estimate widened by the along force "
                f"it cannot see (--safety-widen): {reach_at}, so with the tone's load of about "
                f"{load[c]:.0f} N it reads up to about {worst[c]:.0f} N, past its limit "
                f"{limit[c]:.0f} N, and will likely stop the run; --cuff-sensors full measures "
                f"the along force, and {hint} (docs/safety.md, what the supervisor cannot see)"
            )
        else:
            out.append(
                f"the supervisor reads the shank cuffs' along force from its cuff model (no "
                f"2-axis cuff sensors): {reach_at} that it cannot see, so with the tone's load "
                f"of about {load[c]:.0f} N the true force can reach about {worst[c]:.0f} N, past "
                f"its limit {limit[c]:.0f} N, without a stop; --cuff-sensors full measures it, "
                f"--safety-widen stops on it, and {hint} (docs/safety.md, what the supervisor "
                "cannot see)"
            )
    return out


def _shortest(
    loads: Callable[[float], np.ndarray | None],
    period: float,
    row: int,
    below: np.ndarray,
    what: str,
) -> str:
    """The shortest gait period whose ``loads(T)[row]`` stays below ``below`` (bisection).

    Between ``period`` and :data:`LONGEST` times it, to 0.05 s; in words, ending "… ``what``".
    """
    low, high = period, LONGEST * period
    fits = loads(high)
    if fits is None or np.any(fits[row] >= below):
        return f"no gait period up to {high:.2g} s {what}"
    while high - low > 0.05:
        mid = 0.5 * (low + high)
        trial = loads(mid)
        if trial is not None and np.all(trial[row] < below):
            high = mid
        else:
            low = mid
    return f"a gait period of at least {high:.2f} s {what}"
