r"""QP torque distribution: the CT+PD command, limited by the drives and the cuffs.

Each tick the controller computes the computed-torque + PD voltage ``U_cmd``
(:class:`~exo_ctrl.control.computed_torque.ComputedTorqueController`), turns it
into the steady-state drive torque at the measured joint speed ω,

.. math::

    τ_{cmd} = i_G k_m \, \frac{U_{cmd} - i_G ω / k_E}{R},

and solves, with proxsuite (:class:`~exo_ctrl.control.qp.workspace.TorqueQP`),
over the torques τ and one slack s_c per cuff,

.. math::

    \min_{τ, s} \tfrac12 (τ - τ_{cmd})^T W (τ - τ_{cmd}) + \tfrac12 ρ\, s^T s
    \quad \text{s.t.} \quad τ_{lo} \le τ \le τ_{hi}, \quad s \ge 0, \quad
    |n_k^T f_c(τ)| \le (F_{max} - m_c) \cos(π/8) + s_c \;\; (k = 0..3,\ c = \text{4 cuffs}),

then converts back, ``U = R τ / (i_G k_m) + i_G ω / k_E``, except where the
clipped command meets every cuff row also with the drives whose τ_cmd is beyond
the torque box held at their caps in the horizon: those get U_cmd within the
supply, which their drivers hold at the cap (:mod:`~exo_ctrl.control.qp.torque_box`).
With no cuff bound near, the command is the CT+PD voltage itself, at the drives'
limits too.

**Torque box** (per joint, at the present speed).  The URDF effort limit,
``|τ| ≤ τ_eff``, and what the drive can deliver: a steady-state current
``I = τ / (i_G k_m)`` within the driver's limit ``[-I_max, I_max]`` and
within the supply, ``[(-U_max - i_G ω/k_E)/R, (U_max - i_G ω/k_E)/R]``.  The
box is the intersection of the three; if it is empty for some joint (a speed
above ``(U_max + R I_max) k_E / i_G`` ≈ 5.9 rad/s with the defaults) no
command meets the limits and the tick falls back (below).

**Cuff forces, affine in τ, over a horizon** (design.md §5).  The cuffs
are springs with the patient's leg on them (modes 5–12 Hz), which a
one-tick rigid-cuff prediction cannot bound.  The controller
predicts the elastic cuffs' forces at P horizon points (default 5, 10, 20,
30, 40 ms) with the drive voltage for τ held
(:class:`~exo_ctrl.control.qp.prediction.CuffHorizonModel`), ``f(t_i) = A_i τ
+ b_i``, and bounds every point.  Its initial state — the patient's lag δ
behind the exoskeleton, δ̇, and the patient's own torque d — comes from the
live cuff force estimate (``sensors.cuff_force_est``) through a lead–lag
(:data:`RESTORED_BANDWIDTH_PER_S`: the momentum observer's 10 ms lag
shortened to 5 ms; on the lag-free Kalman filter a 5 ms lead), with d̂
filtered at the estimator's ω_d (:data:`DISTURBANCE_BANDWIDTH_PER_S`), by
:class:`~exo_ctrl.control.qp.observer.CuffStateObserver`.  That state carries
the joint-space load of the estimate, split between a leg's cuffs by the
model; with cuff sensors (``cuff_knowledge``) the estimate's measured split
is held over the horizon on top (:func:`~exo_ctrl.control.qp.observer.add_residual`).  Without an
estimate (or ``force_feedback=False``) the cuffs are taken as fitted
(δ = δ̇ = d = 0).  The bound is an octagon inscribed in the circle
(:mod:`~exo_ctrl.control.qp.screening`), SOFT: one slack s_c ≥ 0 per cuff,
shared by the horizon points, costs ρ s_c² (ρ = :data:`SLACK_WEIGHT` = 1e4:
1 N over the bound costs as much as 100 N·m off the command).

**The bound, tightened** (:mod:`~exo_ctrl.control.qp.margin`).  Each
cuff's prediction is held within ``F_max − m_c``, m_c what the device does
not know: the horizon model's own error, the patient model's (the cohort's
spreads), the cuff model's (0 with the published split cuffs, the QP's
default model: :meth:`~exo_ctrl.sim.belief.Belief.cuff_model_of`) and the
estimate's (three standard deviations from the Kalman filter's covariance,
per tick, ``sensors.cuff_force_std``).  The static part is computed along
the plan when the controller is built; a bound whose margin leaves less
than the cuff's working force is refused then
(:class:`~exo_ctrl.exceptions.CuffBoundTooTight`).  ``record["margin"]``
holds the tick's m_c, ``record["margin_peak"]`` its largest so far.
Measured peaks against the bound: docs/performance.md ("The QP's cuff-force bound").

**Ticks without proxsuite.**  When τ_cmd clipped into the torque box meets
every cuff row it is the QP's optimum (the clip test of
:mod:`~exo_ctrl.control.qp.screening`) and the tick takes it without calling
proxsuite (how often: docs/performance.md, "Speed of a tick" and "The QP's
cuff-force bound").  Otherwise proxsuite solves over
the :data:`SCREENED_ROWS` rows most nearly binding, widened by violated rows at most
:data:`SCREEN_ROUNDS` times (the screening of the same module).

**Fallback** (the tick is counted in :attr:`QPController.failures`):

1. the solver failed twice (:class:`~exo_ctrl.control.qp.workspace.TorqueQP`:
   not SOLVED, or an answer that fails the independent check), or the
   screened rows did not cover the bound after :data:`SCREEN_ROUNDS` solves
   and a last solve over every row (:attr:`QPController.full_rows`) failed:
   τ_cmd clipped into the torque box.  The drive limits are kept (they are
   physical); the cuff bound is given up for that tick;
2. the torque box is empty for a joint: that joint gets zero torque, the
   others τ_cmd clipped into their box, and the voltage is clipped to the
   supply (at such speeds the driver's current limit decides anyway);
3. a non-finite reading or command (non-finite problem data): zero volts
   (the windings short through the driver and the back-EMF brakes the joints).

A programming error is not a fallback: readings of the wrong length or a
tick beyond the plan raise :class:`~exo_ctrl.exceptions.InvalidParameter`.

**Cost.**  Each tick: two compiled kernels around the cuff model's CRBA and
nonLinearEffects (one model holding both bodies): CT+PD, the box and the
state for Pinocchio; then the linearisation, the observer, the horizon
prediction (a 9×9 matrix exponential and its powers per leg), the octagon
rows and the clip test.  Only on ticks whose clip test fails: the screening
and proxsuite (8 variables, :data:`SCREENED_ROWS` rows) with its independent
checks.  Timings: tools/bench.py.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pinocchio as pin

from ... import _validate as v
from ..._jit import Status, check
from ...estimation import DEFAULT_GAIN_PER_S
from ...exceptions import InvalidModel, InvalidParameter
from ...model import BodyModel
from ...plan.kinematics import JointTrajectory
from ...plant.cuffs import CuffParams
from ...plant.drive import MotorParams
from ...sensing.readings import SensorReadings
from ..base import PDGains
from ..computed_torque import ComputedTorqueController
from ..lift_off import LIFT_OFF_BLEND_S
from ..stance_load import StanceLoad
from .bounds import cuff_limits
from .cuff_knowledge import CuffKnowledge
from .fallback import QPFallbacks
from .margin import ESTIMATE_SIGMAS, checked_margin, widest
from .observer import CuffStateObserver
from .prediction import DEFAULT_HORIZON_TICKS, CuffHorizonModel
from .screening import POLYGON_SIDES, SCREEN_ROUNDS, SCREENED_ROWS, polygon_rows
from .tick import front, load, load_all, qp_fields, tail, take, widen_rows
from .torque_box import box_constants
from .workspace import TorqueQP

__all__ = [
    "CONTROLLER_EPS_ABS",
    "DISTURBANCE_BANDWIDTH_PER_S",
    "NO_BOUND",
    "RESTORED_BANDWIDTH_PER_S",
    "SLACK_WEIGHT",
    "QPController",
]

#: Weight ρ of a cuff's slack in the cost [(N·m)²/N²]: exceeding the bound by
#: 1 N costs as much as deviating 100 N·m from the command, so the bound is
#: met whenever the drive limits allow and exceeded as little as they force.
SLACK_WEIGHT = 1e4
#: ω_f, the bandwidth the force estimate is brought to before the cuff state
#: is rebuilt from it [1/s] (:mod:`~exo_ctrl.control.qp.observer`): measured
#: over tools/load_held.py's grid (30 points, ω_f = 100, 200, 300), 200 lowered
#: every point's overshoot (worst +21.9 → +18.4 %); 300 let the estimate's
#: noise through (worst +34 %).
RESTORED_BANDWIDTH_PER_S = 200.0
#: ω_d, the bandwidth of the patient-torque estimate d̂ per live force estimator [1/s]
#: (:mod:`~exo_ctrl.control.qp.observer`): d̂, a filtered residual with a speed
#: difference in it, trades its lag 1/ω_d against its noise.  The spastic reflex
#: follows the joint speed: d̂ at 30 1/s (33 ms behind) was the Kalman filter's
#: largest error at the 0.9 s gait.  Over the 0.9 s row of tools/load_held.py's
#: grid and 6 slower points: Kalman 30 → 120 1/s, worst +11.3 → +7.1 % (60: 9.0,
#: 200: 6.4, 300: 8.8, 500: 15.3 %, noise through); the momentum observer's
#: noisier, lagged estimate wants the slow one (15: 25.6, 30: 30.1, 120: 32.2 %).
#: The filter takes 60 1/s, not 120: d̂ also follows the estimate's start-up
#: transient, and the default QP run's first 200 ms then reached 125–128 N·m at
#: the hips at 120 1/s (92 at 90, 68 at 60, 59 at 30; tests/sim/test_start.py
#: keeps it below 60 % of the 148 N·m limit); the whole grid at 60 1/s: worst
#: +9.0 % (0.9 s, 0.25 m, 100 N), within 10 % everywhere.
DISTURBANCE_BANDWIDTH_PER_S = {"momentum": 30.0, "kalman": 60.0}
#: Stand-in for an absent bound (the QP refuses non-finite data) [N or N·m].
NO_BOUND = 1e9
#: proxsuite's absolute accuracy in the controller's QP [N·m or N]: 1e-9 was out
#: of reach at this problem's scale (ρ = 1e4 multiplies slack errors into the dual
#: residual) and made solves that had found the optimum stop at max_iter.
CONTROLLER_EPS_ABS = 1e-7


class QPController(QPFallbacks, ComputedTorqueController):
    """CT+PD command made to respect the drive limits and a cuff-force bound (module docstring).

    Args:
        plan: joint targets at the control ticks.
        exo: the exoskeleton model the controller believes in.
        patient: the patient model the controller believes in (required).
        motor: the drive model (as configured for the exo: see
            :func:`exo_ctrl.sim.setup.drive_for`).
        gains: the PD gains.
        cuff_force_limit_N: F_max, bound on each cuff's force magnitude [N]: one,
            or (thigh, shank) (:func:`~exo_ctrl.control.qp.bounds.cuff_limits`).
        torque_weights: diagonal of W, one per joint, > 0 [-].
        max_iter: proxsuite's iteration limit per solve.
        force_feedback: start the horizon prediction from the cuff state
            reconstructed from the estimated cuff forces
            (``sensors.cuff_force_est``); off, or without an estimate, the
            cuffs are taken as fitted (δ = δ̇ = d = 0).
        cuffs: the cuff model the controller believes in, normal and shear
            stiffness and damping (default ``CuffParams.isotropic()``; a run
            gives it the device's, the published cuffs: ``Belief.cuff_model_of``).
        dt: control period [s].
        horizon_ticks: horizon points of the prediction, in ticks.
        disturbance_bandwidth_per_s: bandwidth of the patient-torque estimate
            [1/s] (0: none; default: the estimator's,
            :data:`DISTURBANCE_BANDWIDTH_PER_S`).
        screened_rows: cuff rows handed to proxsuite per tick, an integer
            ≥ 1 (:mod:`~exo_ctrl.control.qp.screening`); more than the 32 P
            rows means all of them, unscreened.
        estimate_gain_per_s: K_O, the bandwidth of the force estimate the
            controller is given [1/s] (the estimator's default).
        restored_bandwidth_per_s: ω_f, the bandwidth the estimate is brought
            to before the cuff state is rebuilt from it [1/s] (below K_O:
            K_O, the estimate as it is).
        estimator: the live force estimator (``SimConfig.estimator``), ``"kalman"``
            (default, a run's) or ``"momentum"``: it sets the default ω_d.
        tighten: tighten each cuff's bound by its margin (default; False:
            the bound as given, for tests of the QP itself).
        gait: the gait in words, for the refusal's message.
        stance_load: the stance legs' load in the CT feedforward, with the
            pelvis on its guide (:mod:`exo_ctrl.control.stance_load`; None:
            the pelvis fixed), as computed torque's.
        lift_off_blend_s: T_b of :mod:`exo_ctrl.control.lift_off` [s], as
            computed torque's (0: none).
        cuff_knowledge: what the device knows of the patient's true cuffs,
            for the margin's e_cuffs (default
            :class:`~exo_ctrl.control.qp.cuff_knowledge.CuffKnowledge`: the
            published cuffs, the literature's spread, no cuff sensors).
        margin_plans: the plans the margin's static part is computed along, the
            widest per cuff kept (default: ``plan``; a synchronised one-row plan
            gives the precomputed plans of its steady gaits).

    Attributes:
        margin: the margin's static terms and working force (:class:`BoundMargin`).
        record: the tick's state and figures: the CT's fields, then
            :func:`~exo_ctrl.control.qp.tick.qp_fields`; ``u_cmd`` is the
            command returned last.  The arrays below are views of its fields.
        solver_ticks: ticks that called proxsuite (the others met every
            bound with τ_cmd clipped into the torque box).
        failures, last_status, active_constraints, solve_time_us,
            screen_rounds: the run's fallbacks and the last tick's figures
            (properties).
        torque_cmd: τ_cmd of the last tick [N·m].
        torque: the torque commanded in the last tick [N·m].
        slack: the cuff slacks s_c of the last tick [N], (4,).
        torque_lo: lower torque bounds of the last tick [N·m].
        torque_hi: upper torque bounds of the last tick [N·m].
        cuff_model: the affine cuff-force prediction of the last tick.
        observer: the cuff state reconstructed from the force estimate.
        cuff_rows: every cuff row of the last tick, (32 P, 8): row
            ``16 p + 4 c + k`` is ``n_kᵀ (A τ + b)_c − s_c ≤ r`` at horizon
            point p, cuff c, edge normal n_k; the next 16 P rows the same
            with −n_k.  Columns: the four τ, then the four slacks.
        cuff_upper: their upper bounds r − n_kᵀ b_c (and r + n_kᵀ b_c), (32 P,) [N].
        screened: which of :attr:`cuff_rows` each QP row holds, last solve.
        qp: the proxsuite workspace of the screened rows.
        full_rows: the workspace of every cuff row, for the ticks whose
            screening did not converge (the same as :attr:`qp` when every
            row is screened in).

    Raises:
        InvalidParameter: a bad limit, weight, iteration count or estimator, or no patient.
        CuffBoundTooTight: a bound whose margin leaves less than a cuff's
            working force on this plan (:mod:`~exo_ctrl.control.qp.margin`).
        InvalidModel: a model the cuff model cannot use
            (:meth:`~exo_ctrl.model.BodyModel.require_leg_chains`), or an effort limit
            that is not > 0.

    """

    name = "qp"

    def __init__(
        self,
        plan: JointTrajectory,
        exo: BodyModel,
        patient: BodyModel,
        motor: MotorParams,
        gains: PDGains | None = None,
        cuff_force_limit_N: float | tuple[float, float] = 150.0,
        torque_weights: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0),
        max_iter: int = 100,
        force_feedback: bool = True,
        cuffs: CuffParams | None = None,
        dt: float = 1e-3,
        horizon_ticks: tuple[int, ...] = DEFAULT_HORIZON_TICKS,
        disturbance_bandwidth_per_s: float | None = None,
        screened_rows: int = SCREENED_ROWS,
        estimate_gain_per_s: float = DEFAULT_GAIN_PER_S,
        restored_bandwidth_per_s: float = RESTORED_BANDWIDTH_PER_S,
        estimator: str = "kalman",
        tighten: bool = True,
        gait: str = "",
        stance_load: StanceLoad | None = None,
        lift_off_blend_s: float = LIFT_OFF_BLEND_S,
        cuff_knowledge: CuffKnowledge | None = None,
        margin_plans: tuple[JointTrajectory, ...] = (),
    ) -> None:
        if estimator not in DISTURBANCE_BANDWIDTH_PER_S:
            allowed = ", ".join(DISTURBANCE_BANDWIDTH_PER_S)
            raise InvalidParameter("estimator", estimator, f"one of {allowed}")
        if disturbance_bandwidth_per_s is None:
            disturbance_bandwidth_per_s = DISTURBANCE_BANDWIDTH_PER_S[estimator]
        if patient is None:
            raise InvalidParameter("patient", None, "a patient model (the cuff model needs one)")
        self.cuff_limits_N = cuff_limits(cuff_force_limit_N)  # F_max per cuff [N]
        self.cuff_force_limit_N = cuff_force_limit_N
        weights = np.asarray(torque_weights, dtype=float)
        if weights.shape != (4,):
            raise InvalidParameter("torque_weights", torque_weights, "four numbers > 0")
        if (
            isinstance(screened_rows, bool)
            or not isinstance(screened_rows, (int, np.integer))
            or screened_rows < 1
        ):
            raise InvalidParameter("screened_rows", screened_rows, "an integer ≥ 1")
        effort = exo.effort_limit
        if np.isnan(effort).any() or (effort <= 0).any():
            raise InvalidModel(exo.source, "", f"effort limits must be > 0 N·m; got {effort}")
        exo.require_leg_chains("the QP cuff model")
        patient.require_leg_chains("the QP cuff model")
        cuffs = cuffs or CuffParams.isotropic()
        self.cuff_model = CuffHorizonModel(exo, patient, motor, cuffs, dt, horizon_ticks)
        self.observer = CuffStateObserver(
            cuffs.stiffness_N_per_m,
            cuffs.damping_N_s_per_m,
            dt,
            disturbance_bandwidth_per_s,
            estimate_gain_per_s,
            max(restored_bandwidth_per_s, estimate_gain_per_s),
        )
        half = POLYGON_SIDES // 2
        n_points = len(self.cuff_model.horizon_ticks)
        n_poly = n_points * 4 * half
        self._n_rows = 2 * n_poly
        self._n_slots = min(int(screened_rows), 2 * n_poly)
        super().__init__(plan, exo, patient, motor, gains, stance_load, lift_off_blend_s)
        # Variables x = (τ, s): the four torques and one slack per cuff, shared by
        # the horizon points, the bound softened to |n_kᵀ f_c(t_i)| ≤ r + s_c with
        # s_c ≥ 0 and the cost ρ s_c².  Rows: +N(Aτ + b) - E s ≤ r and -N(Aτ + b) - E s ≤ r,
        # all of them in cuff_rows; the screened ones in the QP.
        cost = np.concatenate((weights, np.full(4, SLACK_WEIGHT)))
        self.qp = TorqueQP(cost, self._n_slots, max_iter, eps_abs=CONTROLLER_EPS_ABS)
        self.full_rows = self.qp
        if self._n_slots < self._n_rows:
            self.full_rows = TorqueQP(cost, self._n_rows, max_iter, eps_abs=CONTROLLER_EPS_ABS)
        for qp in (self.qp, self.full_rows):
            qp.lower[:] = -NO_BOUND
            qp.lo[4:] = 0.0
            qp.hi[4:] = NO_BOUND
        rec = self.record
        for name, value in box_constants(motor, effort).items():
            rec[name] = value
        rec["force_feedback"] = bool(force_feedback)
        rec["sensed"] = cuff_knowledge is not None and cuff_knowledge.sensors != "none"
        rec["limit"] = self.cuff_limits_N
        self.margin = widest(
            checked_margin(
                along,
                (exo, patient, motor, cuffs),
                self.cuff_model,
                (estimator, disturbance_bandwidth_per_s),
                cuff_force_limit_N,
                gait if tighten else None,
                cuff_knowledge,
                supported=stance_load is not None,
            )
            for along in margin_plans or (plan,)
        )
        rec["margin_static"] = self.margin.static_N
        rec["working"] = self.margin.working_N
        rec["margin"] = self.margin.static_N
        rec["sigmas"] = ESTIMATE_SIGMAS if tighten and estimator == "kalman" else 0.0
        rec["radius"] = (self.cuff_limits_N - self.margin.static_N) * math.cos(
            math.pi / POLYGON_SIDES
        )
        rec["directions"] = polygon_rows(1)  # (S/2, 2): n_k of one cuff
        rec["slots"] = np.arange(self._n_slots)
        view = self._view
        self.cuff_rows, self.cuff_upper = view("rows"), view("upper")
        for p in range(n_points):
            for c in range(4):
                row = p * 4 * half + c * half
                self.cuff_rows[row : row + half, 4 + c] = -1.0
                self.cuff_rows[n_poly + row : n_poly + row + half, 4 + c] = -1.0
        self.screened = view("slots")
        self.torque_cmd, self.torque_lo, self.torque_hi = (
            view("torque_cmd"),
            view("torque_lo"),
            view("torque_hi"),
        )
        self.torque, self.slack = view("torque"), view("slack")
        self.force_feedback = bool(force_feedback)
        self.solver_ticks = 0
        self._u_max = motor.supply_voltage_V
        self._status_text = "not_run"
        self._needs_solve, self._violated = rec["needs_solve"], rec["violated"]
        self._model_rec, self._obs_rec = self.cuff_model.record, self.observer.record
        self._pin = (self.cuff_model.model, self.cuff_model.data)
        self._q_all, self._v_all = self.cuff_model.q_all, self.cuff_model.v_all
        self._no_force = np.zeros((4, 2))
        self._no_std = np.zeros(4)

    def _fields(self) -> list[tuple[Any, ...]]:
        return super()._fields() + qp_fields(self._n_rows, self._n_slots)

    def _view(self, name: str) -> np.ndarray:
        return self.record[name][0]

    @property
    def solve_time_us(self) -> float:
        """The QP's wall time in the last tick, checks included [µs]."""
        return float(self.record["solve_time_us"][0])

    @property
    def screen_rounds(self) -> int:
        """Solves the last tick took (0: no proxsuite; 1 unless rows were added)."""
        return int(self.record["screen_rounds"][0])

    @property
    def last_status(self) -> str:
        """``"solved"`` or why the last tick fell back."""
        return "solved" if self.record["solved"][0] else self._status_text

    @property
    def cuff_force_pred(self) -> np.ndarray:
        """Predicted cuff forces on the exo at the horizon points, last torque, (P, 4, 2) [N]."""
        return self.cuff_model.forces(self.torque)

    # ------------------------------------------------------------------ tick

    def command(self, k: int, sensors: SensorReadings) -> np.ndarray:
        """Drive voltages [V], (4,), for tick k: a view of ``record["u_cmd"]``; never NaN.

        A solver failure is answered by the stated fallback and counted
        (module docstring).

        Raises:
            InvalidParameter: readings of the wrong shape, or a tick beyond the plan.

        """
        q, dq = sensors.q, sensors.dq
        if not (type(q) is type(dq) is np.ndarray):
            q, dq = v.arrays((4,), sensors_q=q, sensors_dq=dq)
        rec, model, sw = self.record, self._model_rec, self.cuff_model.split_switch
        status = front(rec, model, self._q_des, self._dq_des, self._u_ff, k, q, dq)
        if status:
            self.refuse(status, k, q, dq)
        pin_model, pin_data = self._pin
        mass = pin.crba(pin_model, pin_data, self._q_all)
        nle = pin.nonLinearEffects(pin_model, pin_data, self._q_all, self._v_all)
        est, std = sensors.cuff_force_est, getattr(sensors, "cuff_force_std", None)
        if std is None:
            std = self._no_std
        if est is None:
            status = tail(
                rec, model, self._obs_rec, mass, nle, q, dq, self._no_force, False, sw, std
            )
        else:
            status = tail(rec, model, self._obs_rec, mass, nle, q, dq, est, True, sw, std)
        if status:
            return self._refused(status, dq, est)
        if not self._needs_solve[0]:
            return self._u
        self.solver_ticks += 1
        return self._solve(dq)

    def _refused(self, status: int, omega: np.ndarray, est: np.ndarray | None) -> np.ndarray:
        """A tick :func:`~exo_ctrl.control.qp.tick.tail` refused.

        A non-finite prediction falls back (counted); a bad shape raises.
        """
        if status == Status.NOT_FINITE:
            self.record["solve_time_us"] = 0.0
            self.record["screen_rounds"] = 0.0
            return self._fallback(omega, "cuff model failed: non-finite prediction")
        v.refuse_shapes((4, 2), sensors_cuff_force_est=est)
        check(status, "QPController.command", sensors_cuff_force_est=est)
        raise AssertionError(f"unreachable: status {status!r}")  # pragma: no cover

    def _solve(self, omega: np.ndarray) -> np.ndarray:
        """The QP over the screened rows, widened until every row holds (module docstring)."""
        qp, rec = self.qp, self.record
        load(rec, qp.record)
        for _ in range(SCREEN_ROUNDS):
            ok = qp.solve_in_place()
            rec["solve_time_us"] += qp.solve_time_us
            rec["screen_rounds"] += 1
            if not ok:
                return self._fallback(omega, qp.status)
            widen_rows(rec, qp.record)
            if self._violated[0] == 0:
                break
        else:
            qp = self.full_rows
            load_all(rec, qp.record)
            ok = qp.solve_in_place()
            rec["solve_time_us"] += qp.solve_time_us
            rec["screen_rounds"] += 1
            if not ok:
                why = f"the screened rows did not cover the bound after {SCREEN_ROUNDS} solves"
                return self._fallback(omega, f"{why}; every row: {qp.status}")
        take(rec, qp.record, omega)
        return self._u
