r"""The margin by which the QP tightens each cuff's bound: what the device does not know.

The QP bounds the cuff forces it PREDICTS (:mod:`~exo_ctrl.control.qp.prediction`)
from a cuff state rebuilt from the live force ESTIMATE; the real force
differs from the prediction by what the device does not know.  The QP
therefore holds the prediction of cuff c within ``F_max − m_c`` instead of
F_max, with the margin

.. math::

    m_c(t) = e_{pred} + e_{patient,c} + e_{cuffs,c} + e_{est,c}(t),

each term an absolute force [N]:

- **the horizon's prediction error** e_pred = :data:`PREDICTION_ERROR_N`:
  the horizon model against the plant (nonlinear, elastic cuffs, drive
  current dynamics) stepped 40 ms with the voltage held, given the true cuff
  state and patient: at most 5.5 N with the split cuff model on split cuffs,
  7.2 N with the drives held at their caps (their torque held, as the driver
  holds a drive handed more than its cap: :mod:`~exo_ctrl.control.qp.torque_box`;
  both asserted in tests/control/qp/test_prediction.py);
- **the patient model's error** e_patient,c, from the cohort's spreads
  (:class:`~exo_ctrl.model.CohortSpread`, cited there: segment mass 10 %,
  centre-of-mass ratio 4 %, radius-of-gyration ratio 5 %; the leg lengths
  are measured, the exoskeleton is fitted to them).  A plausible true
  patient is any corner of the box ``x = x_0 (1 ± z_max s_x)``
  (z_max = :data:`~exo_ctrl.model.cohort.TRUNCATION_Z`, the cohort's
  truncation: every drawn patient lies inside) for the three parameters
  of each segment, 2⁶ = 64 patients.  Inverse dynamics is linear in the
  inertial parameters π (:func:`pinocchio.computeJointTorqueRegressor`,
  τ = Y(q, q̇, q̈) π), so along the plan (q*, q̇*, q̈*) the joint load a
  corner adds is Δτ(t) = Y(t) (π_corner − π_nominal).  The device's
  patient-torque estimates (the filter's d, the QP observer's d̂ at ω_d)
  absorb the slow part of Δτ; what is left at the first horizon point t₁ is

  .. math::

      r(t) = Δτ(t + t_1) - \mathrm{LP}_{ω_d}[Δτ](t),

  LP the first-order low-pass of d̂.  The cuffs share a joint-space load s
  as the device's cuff model does (quasi-static: G_K δ = s, f = −W_K δ,
  :mod:`~exo_ctrl.control.qp.split_cuffs`), so cuff c's share is
  ``D_c s`` with ``D = −W_K G_K^{-1}`` per leg (isotropic:
  ``−J (JᵀJ)^{-1}``).  The QP predicts afresh each tick from an estimate
  that sees the real force, so what the unabsorbed load r adds to the
  predicted force at t₁ is the response of the patient on its cuff springs
  to r applied as a step: ``(1 − cos ω t₁) D_c r``, ω² the largest
  eigenvalue of ``M_p^{-1} G_K`` (the leg's fastest cuff mode, the
  exoskeleton held; ω t₁ capped at π), and
  e_patient,c = max over t and corners of ``(1 − cos ω t₁) ‖D_c r‖``;
- **the cuff model's error** e_cuffs,c: the device holds a cuff model
  (by default the published split stiffness,
  :class:`~exo_ctrl.plant.cuffs.CuffParams`), a patient's true cuffs
  scatter around the published ones (:mod:`~exo_ctrl.plant.cuff_scatter`:
  factors f_n, f_u within 1 ± 2s).  How a leg's load s splits between its
  two cuffs depends only on the ratio k_n/k_u (a common factor scales G_K
  and W_K alike), so the two most unequal true cuffs the spread allows,
  (1 + 2s, 1 − 2s) and (1 − 2s, 1 + 2s), bound every patient's split.  The
  estimate sees the load the joint torques see (Jᵀ f = −s, for every
  model: Jᵀ D = −I), so the model's error (D^{model} − D^{true}) s_n lies
  in null(Jᵀ), where the torques never see it.  The cuff sensors see some of
  it: the Kalman filter corrects each measured component by a model-error
  force of its own, added to the estimate (:mod:`exo_ctrl.estimation.kalman_cuff`),
  so a measured component loses the model's error and the others keep it.
  What is left is U (D^{model} − D^{true}) s_n, per leg, U the projector
  onto the components not measured (:func:`unobserved`: no sensors I;
  normal load cells I − n_c n_cᵀ per cuff, the along-link components
  left; 2-axis sensors 0).  A device that tares its sensors at the
  standing start (reading less model, :mod:`exo_ctrl.estimation.kalman_cuff`)
  takes the standing model's error for an offset and keeps it on the
  measured components, (I − U) (D^{model} − D^{true}) s_n(t₀), t₀ the plan's
  first row, so
  e_cuffs,c = max over t and the two extremes of
  ‖(U (D^{model} − D^{true}) s_n(t) + (I − U) (D^{model} − D^{true}) s_n(t₀))_c‖,
  s_n(t) = Y(t) π_nominal the nominal patient's load along the plan.  With
  the defaults (s = 0.20) on the default gait: no cuff sensors, about 39 N
  on the thighs and 35 N on the shanks; normal load cells, 0 on the thighs
  (the thigh cuff sits on the thigh's axis: the hip's load does not load it
  along the thigh) and the shanks' along-link part; 2-axis sensors, 0;
- **the estimate's own uncertainty** e_est,c(t), per tick: with the
  Kalman filter (:mod:`exo_ctrl.estimation.kalman`) :data:`ESTIMATE_SIGMAS`
  times σ_c, the square root of the largest eigenvalue of cuff c's force
  covariance ``H_c P H_cᵀ`` (P the filter's posterior covariance, H_c the
  force's linearisation; ``cuff_force_std``); the momentum observer has no
  covariance: its measured lag error :data:`MOMENTUM_ERROR_N` at
  :data:`REFERENCE_PERIOD_S`, scaled by T_ref/T (the force's rate of rise
  is 1/T for a given step).  The filter's term applies after its start-up
  (:data:`SETTLE_TICKS`), when its covariance no longer is the initial guess.

**Working force.**  Whatever the bound, the cuffs must carry the leg: the
nominal patient's gravity load along the plan, shared the same way,
F_work,c = max_t ‖D_c g(q*)‖.  A bound whose margin leaves less,
``F_max − (e_pred + e_patient,c + e_cuffs,c) < F_work,c``, cannot be held
on that gait: :class:`~exo_ctrl.exceptions.CuffBoundTooTight` is raised
before the run, naming the bound, the margin and the gait.  A bound that
leaves more than the working force but less than the whole load the plan
puts on a cuff, F_load,c = max_t ‖D_c s_n‖, is held by leaving the plan:
:func:`departure_warning` says so before the run.

**Ground contact.**  The horizon's model holds the two bodies and their
cuffs, not the belt: the feet's loads and a foot striking the belt lie
outside it, and a QP that leaves the plan over the belt can let a foot
strike (measured: 10–45 % past the bound on the supported points of
``tools/load_held.py``; 263 N against 120 N with the pelvis fixed,
docs/performance.md).  So over the belt, with the pelvis fixed or
supported, where a leg leaves its plan the walk stops
(:mod:`exo_ctrl.safety.departure`), and with the pelvis supported the QP
may not leave the plan at all: the working force is the plan's whole load,
F_work,c = F_load,c (a lower bound is refused before the run).
:func:`contact_warning` says so before every run over the belt.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ...exceptions import CuffBoundTooTight
from ...model import CUFF_NAMES, BodyModel, CohortSpread
from ...model.cohort import TRUNCATION_Z
from ...plan.kinematics import JointTrajectory
from ...plant.cuffs import CuffParams
from ...plant.drive import MotorParams
from .bounds import bound_words, cuff_limits
from .cuff_knowledge import CuffKnowledge, link_normals, unobserved
from .prediction import CuffHorizonModel

__all__ = [
    "ESTIMATE_SIGMAS",
    "MOMENTUM_ERROR_N",
    "PREDICTION_ERROR_N",
    "REFERENCE_PERIOD_S",
    "SETTLE_TICKS",
    "BoundMargin",
    "bound_margin",
    "checked_margin",
    "contact_warning",
    "departure_warning",
    "share_matrices",
    "step_factors",
    "widest",
]

#: e_pred, the horizon model's error given the true cuff state and patient [N]
#: (split cuffs and model, the larger of the voltage held and the drives held at
#: their caps; tests/control/qp/test_prediction.py asserts both).
PREDICTION_ERROR_N = 7.2
#: k in e_est = k σ: three standard deviations of the filter's force estimate [-].
ESTIMATE_SIGMAS = 3.0
#: The momentum observer's estimate error at the reference period [N]: its
#: lag behind the cuff load (3–4 ms after the QP's lead–lag; issue 19's grid).
MOMENTUM_ERROR_N = 18.0
#: The gait period the momentum observer's error is stated at [s].
REFERENCE_PERIOD_S = 1.2
#: Ticks of the filter's start-up (its covariance converging from the initial
#: guess: σ_c from 86 N to below 2.4 N within 50 ms on the default run), after
#: which the estimate's term applies and the largest margin is kept [ticks].
SETTLE_TICKS = 100
#: Plan rows between the samples of the margin's scan [ticks].
SCAN_STRIDE = 2
#: e_cuffs from which the departure warning names the cuff sensors [N].
UNKNOWN_CUFFS_NOTED_N = 0.5


@dataclass(frozen=True)
class BoundMargin:
    """The static part of each cuff's margin and the working force, per cuff [N], (4,) each.

    Attributes:
        prediction_N: e_pred (the same for every cuff).
        patient_N: e_patient,c.
        cuffs_N: e_cuffs,c.
        estimate_N: the estimate's term when it is fixed (the momentum
            observer's), else zeros (the filter's term is per tick).
        working_N: F_work,c.
        load_N: F_load,c, the largest load the plan puts on the cuff.

    """

    prediction_N: np.ndarray
    patient_N: np.ndarray
    cuffs_N: np.ndarray
    estimate_N: np.ndarray
    working_N: np.ndarray
    load_N: np.ndarray

    @property
    def static_N(self) -> np.ndarray:
        """e_pred + e_patient + e_cuffs (+ the fixed estimate term), (4,) [N]."""
        return self.prediction_N + self.patient_N + self.cuffs_N + self.estimate_N


def share_matrices(model: CuffHorizonModel, split: bool) -> np.ndarray:
    """D per leg, (2, 4, 2): cuff forces (thigh x, z, shank x, z) per joint-space load [1/m].

    From ``model``'s last :meth:`~CuffHorizonModel.linearise`: ``−W_K G_K⁻¹``
    (split cuffs) or ``−J (JᵀJ)⁻¹`` (isotropic).
    """
    out = np.empty((2, 4, 2))
    for leg in range(2):
        if split:
            out[leg] = -model.wk[leg] @ np.linalg.inv(model.gk[leg])
        else:
            jac = model.jac[leg]
            out[leg] = -jac @ np.linalg.inv(jac.T @ jac)
    return out


def step_factors(model: CuffHorizonModel, split: bool, t1_s: float) -> np.ndarray:
    """1 − cos(ω t₁) per leg, (2,): ω² the largest eigenvalue of M_p⁻¹ G_K (module docstring)."""
    out = np.empty(2)
    for leg in range(2):
        j = slice(2 * leg, 2 * leg + 2)
        if split:
            stiffness = model.gk[leg]
        else:
            jac = model.jac[leg]
            stiffness = model.stiffness * (jac.T @ jac)
        omega2 = np.linalg.eigvals(np.linalg.solve(model.mass_patient[j, j], stiffness)).real.max()
        out[leg] = 1.0 - math.cos(min(math.sqrt(max(omega2, 0.0)) * t1_s, math.pi))
    return out


def _corner_parameters(patient: BodyModel, spread: CohortSpread) -> np.ndarray:
    """π of the nominal patient (column 0) and of the 64 corner patients, (10 n_bodies, 65)."""
    model = patient.model
    nominal = np.concatenate(
        [model.inertias[j].toDynamicParameters() for j in range(1, model.njoints)]
    )
    columns = [nominal]
    z = TRUNCATION_Z
    factors = [
        (1 + sm * spread.mass, 1 + sc * spread.com_ratio, 1 + sg * spread.gyration_ratio)
        for sm, sc, sg in itertools.product((-z, z), repeat=3)
    ]
    for thigh, shank in itertools.product(factors, repeat=2):
        params = []
        for j in range(1, model.njoints):
            inertia = model.inertias[j]
            mass, com, gyr = thigh if "hip" in model.names[j] else shank
            rotational = inertia.inertia * mass * gyr * gyr
            scaled = pin.Inertia(inertia.mass * mass, inertia.lever * com, rotational)
            params.append(scaled.toDynamicParameters())
        columns.append(np.concatenate(params))
    return np.stack(columns, axis=1)


def _scan_rows(plan: JointTrajectory) -> np.ndarray:
    """The plan rows in time order, the periodic part twice (the low-pass's steady state)."""
    n = plan.q.shape[0]
    if plan.period_ticks is None:
        rows = np.arange(n)
    else:
        period = np.arange(plan.lead_ticks, plan.lead_ticks + plan.period_ticks)
        rows = np.concatenate((np.arange(plan.lead_ticks + plan.period_ticks), period))
        rows = rows[rows < n]
    return rows[::SCAN_STRIDE]


def bound_margin(
    plan: JointTrajectory,
    patient: BodyModel,
    model: CuffHorizonModel,
    truths: Sequence[CuffHorizonModel],
    disturbance_bandwidth_per_s: float,
    estimator: str,
    gait_period_s: float,
    spread: CohortSpread | None = None,
    sensors: str = "none",
    tare: bool = False,
) -> BoundMargin:
    """The static margin terms, the working force and the load along ``plan`` (module docstring).

    Args:
        plan: the joint targets (q*, q̇*, q̈*).
        patient: the nominal patient the device holds.
        model: the QP's cuff model (the device's cuffs); re-linearised here.
        truths: the same on the plausible true cuffs
            (:meth:`CuffKnowledge.true_cuffs`); none: e_cuffs = 0.
        disturbance_bandwidth_per_s: ω_d of the patient-torque estimate [1/s].
        estimator: ``"kalman"`` (its term is per tick) or ``"momentum"``.
        gait_period_s: T [s], for the momentum observer's term.
        spread: the cohort's spreads (default :class:`CohortSpread`).
        sensors: the cuff sensors the device carries (:data:`SENSOR_SETS`).
        tare: the device tares its cuff sensors at the standing start
            (the plan's first row), which leaves the standing model's error
            on the measured components (module docstring, e_cuffs).

    """
    spread = spread or CohortSpread()
    params = _corner_parameters(patient, spread)
    pmodel = patient.model
    pdata = pmodel.createData()
    rows = _scan_rows(plan)
    h = plan.t[1] - plan.t[0] if plan.t.shape[0] > 1 else model.dt
    step = h * SCAN_STRIDE
    lead = max(round(model.horizon_ticks[0] / SCAN_STRIDE), 1)
    a_lp = -math.expm1(-step * disturbance_bandwidth_per_s)
    n = rows.shape[0]
    loads = np.empty((n, 4, params.shape[1]))
    gravity = np.empty((n, 4))
    shares = np.empty((n, 2, 4, 2))
    errors = np.zeros((n, len(truths), 2, 4))  # U (D_model − D_true) s_n per truth, leg
    bias = np.zeros((len(truths), 2, 4))  # the tare's, (I − U) (D_model − D_true) s_n(t₀)
    factors = np.empty((n, 2))
    t1 = model.horizon_s[0]
    for i, r in enumerate(rows):
        q, dq, ddq = plan.q[r], plan.dq[r], plan.ddq[r]
        reg = pin.computeJointTorqueRegressor(pmodel, pdata, q, dq, ddq)
        loads[i] = reg @ params
        gravity[i] = pin.computeGeneralizedGravity(pmodel, pdata, q)
        model.linearise(q, dq)
        shares[i] = share_matrices(model, model.split)
        factors[i] = step_factors(model, model.split, t1)
        if truths:
            normals = link_normals(model, q)
            projector = [unobserved(normals[2 * leg : 2 * leg + 2], sensors) for leg in range(2)]
        for k, truth in enumerate(truths):
            truth.linearise(q, dq)
            diff = shares[i] - share_matrices(truth, truth.split)
            for leg in range(2):
                split_error = diff[leg] @ loads[i, 2 * leg : 2 * leg + 2, 0]
                if tare and i == 0:  # the standing start: the tare's bias on measured axes
                    bias[k, leg] = split_error - projector[leg] @ split_error
                errors[i, k, leg] = projector[leg] @ split_error + bias[k, leg]
    delta = loads[:, :, 1:] - loads[:, :, :1]
    low = np.empty_like(delta)
    acc = delta[0].copy()
    for i in range(delta.shape[0]):
        acc += a_lp * (delta[i] - acc)
        low[i] = acc
    ahead = np.concatenate((delta[lead:], np.repeat(delta[-1:], lead, axis=0)))
    resid = ahead - low  # (rows, 4 joints, corners)
    patient_n, cuffs_n, working, load = np.zeros(4), np.zeros(4), np.zeros(4), np.zeros(4)
    for leg in range(2):
        j = slice(2 * leg, 2 * leg + 2)
        share = shares[:, leg]  # (rows, 4, 2)
        f_res = np.einsum("rij,rjk->rik", share, resid[:, j])  # (rows, 4 comps, corners)
        f_res *= factors[:, leg, None, None]
        f_grav = np.einsum("rij,rj->ri", share, gravity[:, j])
        f_load = np.einsum("rij,rj->ri", share, loads[:, j, 0])
        for k in range(2):  # thigh, shank
            c = 2 * leg + k
            comp = slice(2 * k, 2 * k + 2)
            patient_n[c] = np.linalg.norm(f_res[:, comp], axis=1).max()
            working[c] = np.linalg.norm(f_grav[:, comp], axis=1).max()
            load[c] = np.linalg.norm(f_load[:, comp], axis=1).max()
            if truths:
                cuffs_n[c] = np.linalg.norm(errors[:, :, leg, comp], axis=2).max()
    estimate = np.zeros(4)
    if estimator == "momentum":
        estimate[:] = MOMENTUM_ERROR_N * REFERENCE_PERIOD_S / gait_period_s
    prediction = np.full(4, PREDICTION_ERROR_N)
    return BoundMargin(prediction, patient_n, cuffs_n, estimate, working, load)


def checked_margin(
    plan: JointTrajectory,
    device: tuple[BodyModel, BodyModel, MotorParams, CuffParams],
    model: CuffHorizonModel,
    estimate: tuple[str, float],
    limit_N: float | tuple[float, float],
    gait: str | None,
    knowledge: CuffKnowledge | None = None,
    supported: bool = False,
) -> BoundMargin:
    """The QP's margin along ``plan``, the bound checked against it (module docstring).

    Args:
        plan: the joint targets.
        device: the exoskeleton, patient, drive and cuff models the device holds.
        model: the QP's cuff model (on ``device``'s cuffs).
        estimate: the live estimator's name and ω_d of the patient-torque estimate [1/s].
        limit_N: F_max [N]: one, or (thigh, shank) (:mod:`.bounds`).
        gait: the gait in words for the refusal's message ("": the plan's
            period); None: no tightening (every term zero).
        knowledge: what the device knows of the true cuffs (default
            :class:`CuffKnowledge`: the published cuffs, the literature's
            spread, no cuff sensors).
        supported: the pelvis is supported: the working force is the plan's
            whole load on the cuff (module docstring, "Ground contact").

    Raises:
        CuffBoundTooTight: F_max − (static margin) below a cuff's working force.

    """
    if gait is None:
        zero = np.zeros(4)
        return BoundMargin(zero, zero, zero, zero, zero, zero)
    exo, patient, motor, _ = device
    estimator, bandwidth = estimate
    knowledge = knowledge or CuffKnowledge()
    truths = [
        CuffHorizonModel(exo, patient, motor, cuffs, model.dt, model.horizon_ticks)
        for cuffs in knowledge.true_cuffs()
    ]
    period = (plan.period_ticks or plan.q.shape[0]) * model.dt
    margin = bound_margin(
        plan,
        patient,
        model,
        truths,
        bandwidth,
        estimator,
        period,
        sensors=knowledge.sensors,
        tare=knowledge.tare,
    )
    if supported:
        margin = dataclasses.replace(margin, working_N=np.maximum(margin.working_N, margin.load_N))
    for c, (name, limit) in enumerate(zip(CUFF_NAMES, cuff_limits(limit_N), strict=True)):
        if limit - margin.static_N[c] < margin.working_N[c]:
            where = gait or f"a plan of period {period:g} s"
            raise CuffBoundTooTight(
                limit, margin.static_N[c], margin.working_N[c], name, where, supported, limit_N
            )
    return margin


def widest(margins: Iterable[BoundMargin]) -> BoundMargin:
    """Each term of several plans' margins, the largest per cuff (at least one margin)."""
    terms = [dataclasses.astuple(m) for m in margins]
    return BoundMargin(*(np.max(np.stack(term), axis=0) for term in zip(*terms, strict=True)))


def departure_warning(
    margin: BoundMargin, limit_N: float | Sequence[float], sensors: str = "none"
) -> str | None:
    """A sentence when the tightened bound leaves a cuff less than its load along the plan.

    The QP then holds the bound by leaving the plan (module docstring,
    "Working force"); None when every cuff's load fits.
    """
    room, words = cuff_limits(limit_N) - margin.static_N, bound_words(limit_N)
    short = np.flatnonzero(room < margin.load_N)
    if short.size == 0:
        return None
    c = int(short[np.argmax((margin.load_N - room)[short])])
    text = (
        f"the QP will leave the plan to hold cuff_force_limit {words}: the gait loads "
        f"the {CUFF_NAMES[c]} cuff with up to {margin.load_N[c]:.0f} N, and the margin "
        f"{margin.static_N[c]:.1f} N leaves {room[c]:.1f} N"
    )
    if margin.cuffs_N[c] >= UNKNOWN_CUFFS_NOTED_N and sensors == "none":
        text += (
            f" ({margin.cuffs_N[c]:.1f} N of it for the patient's unknown cuff stiffness, "
            "which cuff sensors measure: --cuff-sensors full removes it, normal its part "
            "across the link)"
        )
    return text


def contact_warning(
    limit_N: float | Sequence[float],
    departure_rad: float | None,
    synced: bool = False,
    lookahead_s: float = 0.0,
) -> str:
    """The sentence a QP run with the feet over the belt (contact on) gets (module docstring).

    ``departure_rad``: δ of the departure stop (:mod:`exo_ctrl.safety.departure`); None:
    the bound is not tightened, and nothing is promised; ``lookahead_s`` its look-ahead
    T [s] (the harness's arrest with the pelvis supported).  ``synced``: on the synchronised
    plan, which places the swing foot against the stance leg as measured, a stance leg the
    QP lets sag can take the plan out of the leg's reach (where nothing stops the walk
    first).
    """
    words = bound_words(limit_N)
    if departure_rad is None:
        reach = (
            "; on the synchronised plan, which follows the measured legs, the plan can then "
            "leave the leg's reach and the run end"
            if synced
            else ""
        )
        return (
            f"cuff_force_limit {words} is not promised with the feet over the belt: the "
            "QP's horizon holds no ground contact, and where it leaves the plan a foot can "
            f"strike the belt{reach} (docs/performance.md, the QP's cuff-force bound)"
        )
    ahead = (
        f", or a knee folds there within the harness's arrest ({1e3 * lookahead_s:.0f} ms)"
        if lookahead_s > 0.0
        else ""
    )
    return (
        f"with the feet over the belt the walk stops (yield) where a leg leaves its plan by more "
        f"than {departure_rad:.3f} rad{ahead}: the QP holds cuff_force_limit {words} by leaving "
        f"the plan where the patient loads the cuffs beyond it, and a leg off its plan can "
        f"strike the belt (docs/performance.md, the QP's cuff-force bound)"
    )
