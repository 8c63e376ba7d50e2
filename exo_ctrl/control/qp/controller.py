r"""QP torque distribution: the CT+PD command, limited by the drives and the cuffs.

Each tick the controller computes the computed-torque + PD voltage ``U_cmd``
(:class:`~exo_ctrl.control.computed_torque.ComputedTorqueController`), turns it
into the steady-state drive torque at the measured joint speed ω,

.. math::

    τ_{cmd} = i_G k_m \, \frac{U_{cmd} - i_G ω / k_E}{R},

and solves, with proxsuite, over the torques τ and one slack s_c per cuff,

.. math::

    \min_{τ, s} \tfrac12 (τ - τ_{cmd})^T W (τ - τ_{cmd}) + \tfrac12 ρ\, s^T s
    \quad \text{s.t.} \quad τ_{lo} \le τ \le τ_{hi}, \quad s \ge 0, \quad
    |n_k^T f_c(τ)| \le F_{max} \cos(π/8) + s_c \;\; (k = 0..3,\ c = \text{4 cuffs}),

then converts back, ``U = R τ / (i_G k_m) + i_G ω / k_E``.  With no bound
active the answer is τ_cmd and the command is the CT+PD voltage itself.

**Torque box** (per joint, at the present speed).  The URDF effort limit,
``|τ| ≤ τ_eff``, and what the drive can deliver: a steady-state current
``I = τ / (i_G k_m)`` within the driver's limit ``[-I_max, I_max]`` and
within the supply, ``[(-U_max - i_G ω/k_E)/R, (U_max - i_G ω/k_E)/R]``.  The
box is the intersection of the three; if it is empty for some joint (a speed
above ``(U_max + R I_max) k_E / i_G`` ≈ 12.9 rad/s with the defaults) no
command meets the limits and the tick falls back (below).

**Cuff forces, affine in τ, over a horizon** (design.md §5).  The cuffs
are springs with the patient's leg on them (modes 5–12 Hz): a one-tick
rigid-cuff prediction (the first version of this controller) cannot
bound their force — measured with it: spastic patient, 150 N
bound, real peak 194 N; passive, 80 N, 109 N.  The controller instead
predicts the elastic cuffs' forces at P horizon points (default 5, 10, 20,
30, 40 ms) with the drive voltage for τ held
(:class:`~exo_ctrl.control.qp.prediction.CuffHorizonModel`: the coupled
exo–patient–cuff system linearised at the measured state, back-EMF damping
included, solved exactly by a matrix exponential), ``f(t_i) = A_i τ + b_i``,
and bounds every point.  Its initial state — the patient's lag δ behind the
exoskeleton, δ̇, and the patient's own torque d — comes from the live cuff
force estimate (``sensors.cuff_force_est``) through
:class:`~exo_ctrl.control.qp.prediction.CuffStateObserver` (``C δ̇ = s − K δ``
is the cuff law itself; d from the patient's equation of motion, filtered at
30 1/s).  Without an estimate (or ``force_feedback=False``) the cuffs are
taken as fitted (δ = δ̇ = d = 0).

**Cuff-force bound.**  ``|f_c(t_i)| ≤ F_max`` is replaced by a regular
octagon inscribed in the circle: ``|n_kᵀ f_c| ≤ F_max cos(π/8)`` for
``n_k = (cos kπ/4, sin kπ/4)``, each as two one-sided rows (32 P rows; the
absent lower bounds are ``-NO_BOUND``); the vertices lie on the circle, so
it is at most 7.6 % conservative.  The bound is SOFT: one slack s_c ≥ 0 per
cuff, shared by the horizon points, costs ρ s_c² (ρ = :data:`SLACK_WEIGHT`
= 1e4, 1 N over the bound costs as much as 100 N·m off the command).

**What the bound achieves — measured** (default 2.4 s run, default sensors,
safety off, tests/test_qp.py):

- spastic patient, F_max = 150 N: real peak 158.7 N (+5.8 %; CT: 180.8 N),
  RMS error 2.1/17.7 mrad hip/knee, no fallback;
- passive patient, F_max = 80 N: real peak 90.3 N (+12.9 %; CT: 106.0 N),
  RMS 9.2/2.4 mrad, no fallback;
- passive patient, 120 N (default): the bound does not bind; RMS
  0.62/0.99 mrad against CT's 0.69/0.99.

Margin, stated in the tests: 10 % at 150 N from the error budget of the
compliant prediction — the horizon model's own error given the true cuff
state (≤ 4.6 N ≈ 3 %, test) plus the error of the cuff state reconstructed
from the force estimate, which lags by the observer's 10 ms (4.5 % RMS of
the peak, :mod:`exo_ctrl.estimation.observer`), about 7 % at the peak.  At 80 N the
same absolute errors are a larger fraction: 15 % is asserted there.

**Row screening.**  Of the 32 P rows (160 by default) only a few can bind
at once, and proxsuite's cost grows with the rows it carries (measured on
2,400 recorded ticks of the spastic run: 8 rows ≈ 44 µs, 16 ≈ 51 µs, 160
≈ 148 µs a solve).  Each tick the controller hands proxsuite the
:data:`SCREENED_ROWS` rows most nearly binding — the largest
``n_kᵀ f_c(τ) − r`` at τ_cmd or at the last tick's torque — solves, and
checks the answer against every row (a compiled kernel, independent of the
solver).  A QP over a subset of the rows is a relaxation of the full one:
if its optimum meets every row it is the optimum of the full problem.
Otherwise the violated rows replace the slackest screened ones and the QP
is solved again, at most :data:`SCREEN_ROUNDS` times in all; after that the
tick falls back (1. below).  A row keeps its slot from tick to tick while
it stays screened, so the warm start's multipliers stay with their rows.

**Ticks without proxsuite.**  With W diagonal, the QP without its cuff
rows is solved by clipping τ_cmd into the torque box (slacks zero).  That
QP is a relaxation of the full one, so when the clipped τ_cmd meets every
cuff row (exactly, no tolerance) it is the full QP's optimum, and the tick
takes it without calling proxsuite (one compiled kernel,
:func:`_clip_if_feasible`).  Measured on the 2.4 s runs (tools/bench.py):
proxsuite is called on none of the default run's ticks (120 N) and on
29.5 % of the spastic patient's at 150 N.  Its warm start stays with the
last tick that called it.

**Fallback** (the tick is counted in :attr:`QPController.failures`):

1. solver failed twice, or the screened rows did not cover the bound
   after :data:`SCREEN_ROUNDS` solves: τ_cmd clipped into the torque box.  The drive
   limits are kept (they are physical); the cuff bound is given up for that
   tick;
2. the torque box is empty for a joint: that joint gets zero torque, the
   others τ_cmd clipped into their box, and the voltage is clipped to the
   supply (at such speeds the driver's current limit decides anyway);
3. a non-finite reading or command, or an unexpected error: zero volts (the
   windings short through the driver and the back-EMF brakes the joints).

**Cost.**  Each tick: CT+PD, the box, the linearisation (one CRBA and one
nonLinearEffects of a model holding both bodies; the patient's cuff
Jacobians in closed form from the cuff points of
:class:`~exo_ctrl.plant.cuffs.CuffSet`), the observer and the horizon prediction
(two compiled kernels: a 9×9 matrix exponential and its powers per leg),
the octagon rows and the clipped command's check against them.  Only on
ticks where that check fails: the screening and the QP (8 variables,
:data:`SCREENED_ROWS` rows) with its independent checks (two kernels).
Timings: tools/bench.py.

:meth:`QPController.command` never raises and never returns NaN.
"""

from __future__ import annotations

import math
import time

import numpy as np
import proxsuite

from ... import _validate as v
from ..._addresses import address_table, kernel, matrix_at, tensor_at, vector_at
from ...exceptions import InvalidModel, InvalidParameter
from ...model.body import BodyModel
from ...plan.kinematics import JointTrajectory
from ...plant.cuffs import CuffParams
from ...plant.motor import MotorParams
from ...sensing.readings import SensorReadings
from ..base import PDGains
from ..computed_torque import ComputedTorqueController
from .prediction import (
    DEFAULT_HORIZON_TICKS,
    CuffHorizonModel,
    CuffStateObserver,
    _gather,
    _observe,
    _predict,
)

__all__ = ["POLYGON_SIDES", "SCREENED_ROWS", "QPController", "TorqueQP", "polygon_rows"]

#: Sides of the regular polygon inscribed in each cuff's force circle (even).
POLYGON_SIDES = 8
#: Feasibility tolerance of the independent check of a QP answer [N·m or N].
FEASIBILITY_TOL = 1e-6
#: Weight ρ of a cuff's slack in the cost [(N·m)²/N²]: exceeding the bound by
#: 1 N costs as much as deviating 100 N·m from the command, so the bound is
#: met whenever the drive limits allow and exceeded as little as they force.
SLACK_WEIGHT = 1e4
#: Stand-in for an absent bound (the QP refuses non-finite data) [N or N·m].
NO_BOUND = 1e9
#: proxsuite's absolute accuracy in the controller's QP [N·m or N]: 1e-9 was out
#: of reach at this problem's scale (ρ = 1e4 multiplies slack errors into the dual
#: residual) and made solves that had found the optimum stop at max_iter.
CONTROLLER_EPS_ABS = 1e-7
#: A row or box bound within this of its limit counts as active [N·m or N].
ACTIVE_TOL = 1e-6
#: Cuff rows handed to proxsuite each tick (of 32 per horizon point; see
#: "Row screening" in the module docstring).
SCREENED_ROWS = 16
#: Solves per tick with the screened rows widened by the violated ones, at most.
SCREEN_ROUNDS = 4

_Output = proxsuite.proxqp.QPSolverOutput
_SOLVED = _Output.PROXQP_SOLVED
_STATUS = {
    _Output.PROXQP_SOLVED: "solved",
    _Output.PROXQP_MAX_ITER_REACHED: "max_iter_reached",
    _Output.PROXQP_PRIMAL_INFEASIBLE: "primal_infeasible",
    _Output.PROXQP_DUAL_INFEASIBLE: "dual_infeasible",
    _Output.PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE: "closest_primal_feasible",
    _Output.PROXQP_NOT_RUN: "not_run",
}
_WARM = proxsuite.proxqp.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT
_COLD = proxsuite.proxqp.InitialGuess.EQUALITY_CONSTRAINED_INITIAL_GUESS


def polygon_rows(n_cuffs: int = 4) -> np.ndarray:
    """Row directions of the inscribed polygons, (n_cuffs·S/2, 2·n_cuffs).

    With S = :data:`POLYGON_SIDES`, row ``c·S/2 + k`` holds
    ``n_k = (cos 2πk/S, sin 2πk/S)`` in cuff c's (f_x, f_z) columns
    ``2c, 2c+1``.  Taken with both signs, ``|n_kᵀ f_c| ≤ r`` for
    k = 0 … S/2 − 1 are the S edges of a regular S-gon of apothem r.
    """
    half = POLYGON_SIDES // 2
    rows = np.zeros((n_cuffs * half, 2 * n_cuffs))
    for c in range(n_cuffs):
        for k in range(half):
            angle = k * math.pi / half
            rows[c * half + k, 2 * c] = math.cos(angle)
            rows[c * half + k, 2 * c + 1] = math.sin(angle)
    return rows


class TorqueQP:
    """Persistent proxsuite workspace for ``min ½ (x − x_t)ᵀ W (x − x_t)``.

    Subject to ``lower ≤ C x ≤ upper`` and ``lo ≤ x ≤ hi``.  The problem data
    live in one buffer, exposed as writable views (:attr:`target`, :attr:`C`,
    :attr:`lower`, :attr:`upper`, :attr:`lo`, :attr:`hi`); fill them and call
    :meth:`solve_in_place`, or pass arrays to :meth:`solve`.  Each solve
    updates g, C, the bounds and the box and solves warm-started from the
    previous result (the first solve, and the first after a failure,
    initialise).  Before solving: every entry finite, ``lower ≤ upper`` and
    ``lo ≤ hi``.  An answer is accepted only if proxsuite says SOLVED and x
    (finite) meets every row and box bound within :data:`FEASIBILITY_TOL`,
    checked here; otherwise the QP is re-initialised cold and solved once
    more.  An accepted x is rounded into the box exactly.

    Args:
        weights: diagonal of W, (n,), each finite and > 0.
        n_in: number of rows of C.
        max_iter: proxsuite's outer iteration limit (bounds a failing solve).
        eps_abs: proxsuite's absolute accuracy.

    Attributes:
        x: the accepted solution of the last solve (stale after a failure).
        status: ``"solved"`` or why the last solve failed.
        active: active rows plus active box bounds of the accepted solution.
        solve_time_us: wall time of the last solve, checks included [µs].
        reinits: re-initialisations after a failed warm-started solve.

    Raises:
        InvalidParameter: a weight not finite and > 0, or max_iter not an
            integer in [1, 10000].

    """

    def __init__(
        self, weights: np.ndarray, n_in: int, max_iter: int = 100, eps_abs: float = 1e-9
    ) -> None:
        w = np.asarray(weights, dtype=float)
        if w.ndim != 1 or w.size < 1 or not np.all(np.isfinite(w)) or not np.all(w > 0):
            raise InvalidParameter("torque_weights", weights, "finite and > 0, one per joint")
        if isinstance(max_iter, bool) or not isinstance(max_iter, (int, np.integer)):
            raise InvalidParameter("max_iter", max_iter, "an integer in [1, 10000]")
        if not 1 <= max_iter <= 10_000:
            raise InvalidParameter("max_iter", max_iter, "an integer in [1, 10000]")
        n, n_in = w.size, int(n_in)
        m = n_in + n
        self.n, self.n_in = n, n_in
        self._neg_w = -w
        self._H = np.diag(w)
        # One buffer: [C; I] (m×n), lower bounds (m), upper bounds (m), target (n).
        self._buf = np.zeros(m * n + 2 * m + n)
        self._c_all = self._buf[: m * n].reshape(m, n)
        self._c_all[n_in:] = np.eye(n)
        self._lower_all = self._buf[m * n : m * n + m]
        self._upper_all = self._buf[m * n + m : m * n + 2 * m]
        #: Views to fill before :meth:`solve_in_place`.
        self.C = self._c_all[:n_in]
        self.lower = self._lower_all[:n_in]
        self.upper = self._upper_all[:n_in]
        self.lo = self._lower_all[n_in:]
        self.hi = self._upper_all[n_in:]
        self.target = self._buf[m * n + 2 * m :]
        self._g = np.zeros(n)
        qp = proxsuite.proxqp.dense.QP(n, 0, n_in, True)
        s = qp.settings
        s.eps_abs = float(eps_abs)
        s.eps_rel = 0.0
        s.max_iter = int(max_iter)
        s.max_iter_in = 200
        s.check_duality_gap = True
        # The slack weight (1e4) scales the duals, so an absolute gap of 1e-8
        # stalled solves already at the optimum; the relative term follows
        # the scale of the cost.
        s.eps_duality_gap_abs = 1e-6
        s.eps_duality_gap_rel = 1e-10
        # The default 1e-4 reported feasible problems of this scale (bounds of
        # ~100 N) as PRIMAL_INFEASIBLE (~0.1 % of random instances).
        s.eps_primal_inf = 1e-10
        s.verbose = False
        s.initial_guess = _WARM
        self._qp = qp
        self._ready = False
        self.x = np.zeros(n)
        self.status = "not_run"
        self.active = 0
        self.solve_time_us = 0.0
        self.reinits = 0

    def solve(
        self,
        target: np.ndarray,
        C: np.ndarray,
        lower: np.ndarray,
        upper: np.ndarray,
        lo: np.ndarray,
        hi: np.ndarray,
    ) -> bool:
        """Copy the problem into the workspace and :meth:`solve_in_place`.

        Args:
            target: x_t, (n,).
            C: constraint rows, (n_in, n).
            lower: lower row bounds, (n_in,).
            upper: upper row bounds, (n_in,).
            lo: lower box bounds, (n,).
            hi: upper box bounds, (n,).

        Returns:
            Whether :attr:`x` holds an accepted, feasible optimum.

        """
        self.target[:] = target
        self.C[:] = C
        self.lower[:] = lower
        self.upper[:] = upper
        self.lo[:] = lo
        self.hi[:] = hi
        return self.solve_in_place()

    def solve_in_place(self) -> bool:
        """Solve the problem held in the workspace views; True if accepted (see class)."""
        start = time.perf_counter_ns()
        ok = self._solve()
        self.solve_time_us = (time.perf_counter_ns() - start) * 1e-3
        return ok

    def _solve(self) -> bool:
        g = self._g
        bad = _prepare(self._buf, self._lower_all, self._upper_all, self._neg_w, self.target, g)
        if bad:
            self.status = (
                "non-finite problem data"
                if bad == 1
                else "infeasible bounds (lower > upper or lo > hi)"
            )
            return False
        qp = self._qp
        first = ""
        if self._ready:
            self.update_and_solve()
            if self._accept():
                return True
            first = self.status
            self.reinits += 1
        qp.settings.initial_guess = _COLD
        try:
            qp.init(self._H, g, None, None, self.C, self.lower, self.upper, self.lo, self.hi)
            qp.solve()
        finally:
            qp.settings.initial_guess = _WARM
        self._ready = self._accept()
        if not self._ready and first:
            self.status = f"{first}; after re-init: {self.status}"
        return self._ready

    def update_and_solve(self) -> None:
        """Warm-update proxsuite with the workspace's data, then solve (no checks).

        The equilibration computed at init is kept (the problem's scale
        changes slowly from tick to tick; recomputing it every tick cost
        about a third of the solve); a re-init recomputes it.
        """
        self._qp.update(
            g=self._g,
            C=self.C,
            l=self.lower,
            u=self.upper,
            l_box=self.lo,
            u_box=self.hi,
            update_preconditioner=False,
        )
        self._qp.solve()

    def _accept(self) -> bool:
        res = self._qp.results
        info_status = res.info.status
        if info_status != _SOLVED:
            self.status = _STATUS.get(info_status, "unknown solver status")
            return False
        active = _check_answer(
            self._c_all, self._lower_all, self._upper_all, res.x, self.lo, self.hi, self.x
        )
        if active < 0:  # also for a NaN
            self.status = "solution violates the constraints or is not finite"
            return False
        self.active = active
        self.status = "solved"
        return True


def _check_legs(body: BodyModel) -> None:
    model = body.model
    if model.nq != 4 or model.nv != 4 or not np.array_equal(body.q_index, np.arange(4)):
        raise InvalidModel(
            body.source, "", "the QP controller needs exactly the four driven joints, in order"
        )
    for leg in (0, 1):
        hip, knee = body.joint_ids[2 * leg], body.joint_ids[2 * leg + 1]
        thigh, shank = body.cuff_frame_ids[2 * leg], body.cuff_frame_ids[2 * leg + 1]
        if (
            model.parents[hip] != 0
            or model.parents[knee] != hip
            or model.frames[thigh].parentJoint != hip
            or model.frames[shank].parentJoint != knee
        ):
            raise InvalidModel(
                body.source,
                model.names[hip],
                "the QP cuff model needs each leg as hip (on the fixed frame) → knee, "
                "with the thigh cuff on the thigh and the shank cuff on the shank",
            )


class QPController(ComputedTorqueController):
    """CT+PD command made to respect the drive limits and a cuff-force bound (module docstring).

    Args:
        plan: joint targets at the control ticks.
        exo: the exoskeleton model the controller believes in.
        patient: the patient model the controller believes in (required).
        motor: the drive model (as configured for the exo: see
            :func:`exo_ctrl.sim.loop.drive_for`).
        gains: the PD gains.
        cuff_force_limit_N: F_max, bound on each cuff's force magnitude [N].
        torque_weights: diagonal of W, one per joint, > 0 [-].
        max_iter: proxsuite's iteration limit per solve.
        force_feedback: start the horizon prediction from the cuff state
            reconstructed from the estimated cuff forces
            (``sensors.cuff_force_est``); off, or without an estimate, the
            cuffs are taken as fitted (δ = δ̇ = d = 0).
        cuffs: the cuffs' K and C the controller believes in (default
            :class:`~exo_ctrl.plant.cuffs.CuffParams`).
        dt: control period [s].
        horizon_ticks: horizon points of the prediction, in ticks.
        disturbance_bandwidth_per_s: bandwidth of the patient-torque estimate
            [1/s] (0: none).
        screened_rows: cuff rows handed to proxsuite per tick, an integer
            ≥ 1 (module docstring, "Row screening"); more than the 32 P rows
            means all of them, unscreened.

    Attributes:
        solver_ticks: ticks that called proxsuite (the others met every
            bound with τ_cmd clipped into the torque box; module docstring,
            "Ticks without proxsuite").
        failures, last_status, active_constraints, solve_time_us,
            screen_rounds: the run's fallbacks and the last tick's figures
            (properties).
        torque_cmd: τ_cmd of the last tick [N·m].
        torque: the torque commanded in the last tick [N·m].
        slack: the cuff slacks s_c of the last tick [N], (4,).
        torque_lo: lower torque bounds of the last tick [N·m].
        torque_hi: upper torque bounds of the last tick [N·m].
        cuff_model: the affine cuff-force prediction of the last tick.
        cuff_rows: every cuff row of the last tick, (32 P, 8): row
            ``16 p + 4 c + k`` is ``n_kᵀ (A τ + b)_c − s_c ≤ r`` at horizon
            point p, cuff c, edge normal n_k; the next 16 P rows the same
            with −n_k.  Columns: the four τ, then the four slacks.
        cuff_upper: their upper bounds r − n_kᵀ b_c (and r + n_kᵀ b_c), (32 P,) [N].
        screened: which of :attr:`cuff_rows` each QP row holds, last tick.
        qp: the proxsuite workspace.

    Raises:
        InvalidParameter: a bad limit, weight or iteration count, or no patient.
        InvalidModel: a model the cuff model cannot use (:func:`_check_legs`),
            or an effort limit that is not > 0.

    """

    name = "qp"

    def __init__(
        self,
        plan: JointTrajectory,
        exo: BodyModel,
        patient: BodyModel,
        motor: MotorParams,
        gains: PDGains | None = None,
        cuff_force_limit_N: float = 150.0,
        torque_weights: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0),
        max_iter: int = 100,
        force_feedback: bool = True,
        cuffs: CuffParams | None = None,
        dt: float = 1e-3,
        horizon_ticks: tuple[int, ...] = DEFAULT_HORIZON_TICKS,
        disturbance_bandwidth_per_s: float = 30.0,
        screened_rows: int = SCREENED_ROWS,
    ) -> None:
        if patient is None:
            raise InvalidParameter("patient", None, "a patient model (the cuff model needs one)")
        self.cuff_force_limit_N = v.positive("cuff_force_limit", cuff_force_limit_N, "N")
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
        super().__init__(plan, exo, patient, motor, gains)
        _check_legs(exo)
        _check_legs(patient)
        cuffs = cuffs or CuffParams()
        self.cuff_model = CuffHorizonModel(exo, patient, motor, cuffs, dt, horizon_ticks)
        self.observer = CuffStateObserver(
            cuffs.stiffness_N_per_m, cuffs.damping_N_s_per_m, dt, disturbance_bandwidth_per_s
        )
        n_points = len(self.cuff_model.horizon_ticks)
        half = POLYGON_SIDES // 2
        self._directions = polygon_rows(1)  # (S/2, 2): n_k of one cuff
        n_poly = n_points * 4 * half
        n_screened = min(int(screened_rows), 2 * n_poly)
        # Variables x = (τ, s): the four torques and one slack per cuff, shared by
        # the horizon points, the bound softened to |n_kᵀ f_c(t_i)| ≤ r + s_c with
        # s_c ≥ 0 and the cost ρ s_c².  Rows: +N(Aτ + b) - E s ≤ r and -N(Aτ + b) - E s ≤ r,
        # all of them in cuff_rows; the screened ones in the QP.
        self.qp = TorqueQP(
            np.concatenate((weights, np.full(4, SLACK_WEIGHT))),
            n_screened,
            max_iter,
            eps_abs=CONTROLLER_EPS_ABS,
        )
        radius = self.cuff_force_limit_N * math.cos(math.pi / POLYGON_SIDES)
        self._radius = radius
        self.cuff_rows = np.zeros((2 * n_poly, 8))
        self.cuff_upper = np.zeros(2 * n_poly)
        for p in range(n_points):
            for c in range(4):
                row = p * 4 * half + c * half
                self.cuff_rows[row : row + half, 4 + c] = -1.0
                self.cuff_rows[n_poly + row : n_poly + row + half, 4 + c] = -1.0
        self.screened = np.arange(n_screened, dtype=np.int64)
        self._row_value = np.zeros(2 * n_poly)  # scratch of the screening kernels
        self._row_mark = np.zeros(2 * n_poly, dtype=np.int64)
        self.qp.lower[:] = -NO_BOUND
        self.qp.lo[4:] = 0.0
        self.qp.hi[4:] = NO_BOUND
        # Torque box at speed ω: hi = min(cap, c0 − c1 ω), lo = max(−cap, −c0 − c1 ω).
        kt, kb, r = motor.torque_per_amp_Nm_per_A, motor.back_emf_V_per_rad_s, motor.resistance_ohm
        self._u_max = motor.supply_voltage_V
        self._cap = np.minimum(effort, kt * motor.current_limit_A)
        self._c0 = kt * motor.supply_voltage_V / r
        self._c1 = np.full(4, kt * kb / r)  # N·m per rad/s
        self._c2 = np.full(4, kt / r)  # N·m per V
        self._out = np.zeros(4)
        self.torque_cmd = self.qp.target[:4]  # τ_cmd is written straight into the QP
        self.torque_lo = self.qp.lo[:4]
        self.torque_hi = self.qp.hi[:4]
        self.slack = np.zeros(4)
        self.torque = np.zeros(4)
        self.solver_ticks = 0
        # The last tick's active_constraints, solve_time_us, screen_rounds and
        # status (0: "solved", 1: _status_text), then failures: where _qp_step
        # writes them and a compiled tick reads them.
        self._info = np.zeros(5)
        self._status_text = "not_run"
        self.last_status = "not_run"
        self.force_feedback = bool(force_feedback)
        self._zero4 = np.zeros(4)
        self._zero_force = np.zeros((4, 2))
        model, obs = self.cuff_model, self.observer
        params = np.zeros(_QP_N_PARAMS)
        params[:] = (
            self._c0, radius, self.force_feedback, obs.stiffness, obs.damping, obs._a_delta,
            obs._a_dist, obs.dt, model.stiffness, model.damping, model._block,
        )  # fmt: skip
        mass, nle = model.data_terms
        tables = dict(
            params=params, c1=self._c1, c2=self._c2, cap=self._cap, target=self.torque_cmd,
            lo=self.torque_lo, hi=self.torque_hi, mass=mass, nle=nle, losses=model._losses,
            points=model._points, select=model._select, mass_e=model.mass_exo,
            mass_p=model.mass_patient, bias_e=model.bias_exo, bias_p=model.bias_patient,
            jac=model.jac, damp_e=model._damp_e, damp_p=model._damp_p, delta=obs.delta,
            ddelta=obs.ddelta, vp=obs._vp, dist=obs.disturbance, first=obs.first, A=model.A,
            b=model.b, work=model._work, directions=self._directions, rows=self.cuff_rows,
            upper=self.cuff_upper, torque=self.torque, out=self._out, zero4=self._zero4,
            slack=self.slack, info=self._info,
        )  # fmt: skip
        self._arrays = [tables[name] for name in _QP_ROWS]
        #: The addresses of the tick's buffers (:func:`_qp_step`, rows :data:`_QP_ROWS`).
        self.table = address_table(self._arrays)
        self._powers = model._powers

    @property
    def failures(self) -> int:
        """Ticks that used the fallback (module docstring)."""
        return int(self._info[4])

    @failures.setter
    def failures(self, value: int) -> None:
        self._info[4] = value

    @property
    def active_constraints(self) -> int:
        """Active box bounds plus active cuff rows, last tick."""
        return int(self._info[0])

    @active_constraints.setter
    def active_constraints(self, value: int) -> None:
        self._info[0] = value

    @property
    def solve_time_us(self) -> float:
        """The QP's wall time in the last tick, checks included [µs]."""
        return float(self._info[1])

    @solve_time_us.setter
    def solve_time_us(self, value: float) -> None:
        self._info[1] = value

    @property
    def screen_rounds(self) -> int:
        """Solves the last tick took (0: no proxsuite; 1 unless rows were added)."""
        return int(self._info[2])

    @screen_rounds.setter
    def screen_rounds(self, value: int) -> None:
        self._info[2] = value

    @property
    def last_status(self) -> str:
        """``"solved"`` or why the last tick fell back."""
        return "solved" if self._info[3] == 0.0 else self._status_text

    @last_status.setter
    def last_status(self, value: str) -> None:
        self._info[3] = 0.0 if value == "solved" else 1.0
        self._status_text = value

    @property
    def cuff_force_pred(self) -> np.ndarray:
        """Predicted cuff forces on the exo at the horizon points, last torque, (P, 4, 2) [N]."""
        return self.cuff_model.forces(self.torque)

    # ------------------------------------------------------------------ tick

    def command(self, k: int, sensors: SensorReadings) -> np.ndarray:
        """Drive voltages [V], (4,), for tick k; never raises, never NaN (module docstring)."""
        try:
            return self._command(k, sensors)
        except Exception as exc:  # the tick must return a safe command
            return self._zero_volts(f"error: {type(exc).__name__}: {exc}")

    def _command(self, k: int, sensors: SensorReadings) -> np.ndarray:
        u_cmd = ComputedTorqueController.command(self, k, sensors)
        omega = sensors.dq
        try:
            self.cuff_model.terms(sensors.q, omega)
        except (np.linalg.LinAlgError, ValueError, RuntimeError) as exc:
            return self._fallback(u_cmd, omega, f"cuff model failed: {exc}")
        est = sensors.cuff_force_est
        force = self._zero_force if est is None else est
        code = _qp_step(self.table, self._powers, sensors.q, omega, u_cmd, force, est is not None)
        return self.finish(code, u_cmd, omega)

    def resume(self, code: int, omega: np.ndarray) -> np.ndarray:
        """:meth:`finish` for a tick whose :func:`_qp_step` a caller's kernel ran; never raises."""
        try:
            return self.finish(code, self._u, omega)
        except Exception as exc:  # the tick must return a safe command
            return self._zero_volts(f"error: {type(exc).__name__}: {exc}")

    def finish(self, code: int, u_cmd: np.ndarray, omega: np.ndarray) -> np.ndarray:
        """The tick after :func:`_qp_step` returned ``code`` (its docstring): the voltages [V].

        Raises:
            ValueError: readings or command not of 4 entries (code -1).

        """
        if code == _STEP_SHAPE:
            raise ValueError(f"readings of shape {np.shape(omega)}, command {np.shape(u_cmd)}")
        if code == _STEP_NON_FINITE:
            return self._fallback(u_cmd, omega, "cuff model failed: non-finite prediction")
        if code >= 0:  # τ_cmd clipped into the box met every row: the optimum, slacks 0
            return self._out  # (and _qp_step wrote the tick's figures)
        self.solve_time_us = 0.0
        self.screen_rounds = 0
        qp = self.qp
        tgt, rows, upper = self.torque_cmd, self.cuff_rows, self.cuff_upper
        self.solver_ticks += 1
        value, mark, slots = self._row_value, self._row_mark, self.screened
        _screen(rows, upper, tgt, self.torque, value, mark, slots, qp.C, qp.upper)
        for rounds in range(1, SCREEN_ROUNDS + 1):
            ok = qp.solve_in_place()
            self.solve_time_us += qp.solve_time_us
            self.screen_rounds = rounds
            if not ok:
                return self._fallback(u_cmd, omega, qp.status)
            if _widen(rows, upper, qp.x, value, mark, slots, qp.C, qp.upper) == 0:
                break
        else:
            why = f"the screened rows did not cover the bound after {SCREEN_ROUNDS} solves"
            return self._fallback(u_cmd, omega, why)
        np.copyto(self.torque, qp.x[:4])
        np.copyto(self.slack, qp.x[4:])
        self.last_status = "solved"
        # The s >= 0 bounds of slacks at zero are not constraints of the problem.
        self.active_constraints = qp.active - int(np.count_nonzero(self.slack <= ACTIVE_TOL))
        return self._volts(omega)

    def _volts(self, omega: np.ndarray) -> np.ndarray:
        """The voltage giving :attr:`torque` at speed ω in steady state, U = (τ + c1 ω)/c2 [V]."""
        _voltage(self._c1, self._c2, self.torque, omega, self._out)
        return self._out

    # ------------------------------------------------------------------ fallbacks

    def _fallback(self, u_cmd: np.ndarray, omega: np.ndarray, why: str) -> np.ndarray:
        """The safe command of the module docstring, counted in :attr:`failures`."""
        if not (np.isfinite(u_cmd).all() and np.isfinite(omega).all()):
            return self._zero_volts(f"non-finite reading or command ({why})")
        lo, hi = self.torque_lo, self.torque_hi
        empty = lo > hi
        self.failures += 1
        self.active_constraints = 0
        if empty.any():
            np.clip(self.torque_cmd, np.minimum(lo, hi), hi, out=self.torque)
            self.torque[empty] = 0.0
            joints = ", ".join(str(j) for j in np.flatnonzero(empty))
            self.last_status = f"fallback: empty torque box at joint(s) {joints} ({why})"
            out = self._volts(omega)
            return np.clip(out, -self._u_max, self._u_max, out=out)
        np.clip(self.torque_cmd, lo, hi, out=self.torque)
        self.last_status = f"fallback: τ_cmd clipped to the torque box ({why})"
        return self._volts(omega)

    def _zero_volts(self, why: str) -> np.ndarray:
        self.failures += 1
        self.active_constraints = 0
        self.solve_time_us = 0.0
        self._out.fill(0.0)
        self.torque.fill(0.0)
        self.last_status = f"fallback: zero volts ({why})"
        return self._out


#: The rows of a QP controller's address table (:func:`_qp_step`), in order.
_QP_ROWS = (
    "params",  # :data:`_QP_N_PARAMS` scalars, see QPController.__init__
    "c1", "c2", "cap", "target", "lo", "hi",  # the torque box
    "mass", "nle", "losses", "points", "select",  # _gather's inputs
    "mass_e", "mass_p", "bias_e", "bias_p", "jac", "damp_e", "damp_p",  # the linearisation
    "delta", "ddelta", "vp", "dist", "first",  # the cuff-state observer
    "A", "b", "work",  # the prediction
    "directions", "rows", "upper", "torque", "out", "zero4", "slack", "info",
)  # fmt: skip
(
    _QP_PARAMS, _QP_C1, _QP_C2, _QP_CAP, _QP_TARGET, _QP_LO, _QP_HI,
    _QP_MASS, _QP_NLE, _QP_LOSSES, _QP_POINTS, _QP_SELECT,
    _QP_MASS_E, _QP_MASS_P, _QP_BIAS_E, _QP_BIAS_P, _QP_JAC, _QP_DAMP_E, _QP_DAMP_P,
    _QP_DELTA, _QP_DDELTA, _QP_VP, _QP_DIST, _QP_FIRST,
    _QP_A, _QP_B, _QP_WORK, _QP_DIRECTIONS, _QP_ROWS_C, _QP_UPPER, _QP_TORQUE, _QP_OUT,
    _QP_ZERO4, _QP_SLACK, _QP_INFO,
) = range(len(_QP_ROWS))  # fmt: skip
#: params: c0 [N·m], r [N], force feedback (0/1), the observer's K [N/m], C
#: [N·s/m], a_δ, a_d, h [s], the prediction's K, C and block step [s].
_QP_N_PARAMS = 11
#: What :func:`_qp_step` returns besides a count of active bounds (≥ 0).
_STEP_SHAPE, _STEP_NON_FINITE, _STEP_SOLVE = -1, -2, -3


@kernel
def _qp_step(t, powers, q, dq, u_cmd, force_est, has_estimate):
    """The QP tick up to proxsuite, on the buffers of address table ``t`` (:data:`_QP_ROWS`).

    After the cuff model's Pinocchio terms (:meth:`CuffHorizonModel.terms`):
    τ_cmd and the torque box (:func:`_torque_box`), the linearisation
    (``_gather``), the cuff-state observer when force feedback is on and an
    estimate came (``_observe``), the prediction (``_predict``), the cuff rows
    (:func:`_bound_rows`) and the check of τ_cmd clipped into the box
    (:func:`_clip_if_feasible`) — :meth:`QPController._command`'s steps in its
    order.  Returns the number of active bounds (≥ 0) when the clip met every
    row (τ, zero slacks, the voltage and the tick's figures — active bounds,
    no solve, status solved — written), or :data:`_STEP_SHAPE`
    (readings or command not of length 4), :data:`_STEP_NON_FINITE` (a
    non-finite prediction) or :data:`_STEP_SOLVE` (proxsuite must solve).
    """
    p = vector_at(t, _QP_PARAMS)
    c1, c2 = vector_at(t, _QP_C1), vector_at(t, _QP_C2)
    target, lo, hi = vector_at(t, _QP_TARGET), vector_at(t, _QP_LO), vector_at(t, _QP_HI)
    if _torque_box(p[0], c1, c2, vector_at(t, _QP_CAP), u_cmd, dq, target, lo, hi) < 0:
        return _STEP_SHAPE
    mass_e, mass_p = matrix_at(t, _QP_MASS_E), matrix_at(t, _QP_MASS_P)
    bias_e, bias_p, jac = vector_at(t, _QP_BIAS_E), vector_at(t, _QP_BIAS_P), tensor_at(t, _QP_JAC)
    _gather(
        matrix_at(t, _QP_MASS), vector_at(t, _QP_NLE), q, dq, matrix_at(t, _QP_LOSSES),
        matrix_at(t, _QP_POINTS), matrix_at(t, _QP_SELECT), mass_e, mass_p, bias_e, bias_p, jac,
    )  # fmt: skip
    delta, ddelta, dist = vector_at(t, _QP_DELTA), vector_at(t, _QP_DDELTA), vector_at(t, _QP_DIST)
    observed = False
    if p[2] != 0.0 and has_estimate:
        observed = _observe(
            mass_p, bias_p, jac, force_est, dq, p[3], p[4], p[5], p[6], p[7], delta, ddelta,
            vector_at(t, _QP_VP), dist, vector_at(t, _QP_FIRST),
        )  # fmt: skip
    if not observed:  # the cuffs taken as fitted: δ = δ̇ = d = 0
        delta = ddelta = dist = vector_at(t, _QP_ZERO4)
    a, b = matrix_at(t, _QP_A), vector_at(t, _QP_B)
    _predict(
        mass_e, mass_p, jac, bias_e, bias_p, vector_at(t, _QP_DAMP_E), vector_at(t, _QP_DAMP_P),
        p[8], p[9], p[10], powers, delta, ddelta, dist, a, b, tensor_at(t, _QP_WORK),
    )  # fmt: skip
    rows, upper = matrix_at(t, _QP_ROWS_C), vector_at(t, _QP_UPPER)
    total = _bound_rows(matrix_at(t, _QP_DIRECTIONS), a, b, p[1], rows, upper)
    if not math.isfinite(total):
        return _STEP_NON_FINITE
    torque = vector_at(t, _QP_TORQUE)
    active = _clip_if_feasible(rows, upper, target, lo, hi, torque)
    if active < 0:
        return _STEP_SOLVE
    slack = vector_at(t, _QP_SLACK)
    for j in range(4):
        slack[j] = 0.0
    _voltage(c1, c2, torque, dq, vector_at(t, _QP_OUT))
    info = vector_at(t, _QP_INFO)
    info[0] = active
    info[1] = info[2] = info[3] = 0.0
    return active


@kernel
def _prepare(
    buf: np.ndarray,
    lower_all: np.ndarray,
    upper_all: np.ndarray,
    neg_w: np.ndarray,
    target: np.ndarray,
    g: np.ndarray,
) -> int:
    """Check a :class:`TorqueQP` problem and form g = −W x_t.

    Returns 1 if an entry of the problem is not finite, 2 if a lower bound
    exceeds its upper bound, else 0 (and g written).
    """
    for i in range(buf.shape[0]):
        if not math.isfinite(buf[i]):
            return 1
    for i in range(lower_all.shape[0]):
        if not upper_all[i] >= lower_all[i]:
            return 2
    for j in range(g.shape[0]):
        g[j] = neg_w[j] * target[j]
    return 0


@kernel
def _torque_box(
    c0: float,
    c1: np.ndarray,
    c2: np.ndarray,
    cap: np.ndarray,
    u_cmd: np.ndarray,
    omega: np.ndarray,
    target: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
) -> int:
    """τ_cmd = c2 U_cmd − c1 ω; box hi = min(cap, c0 − c1 ω), lo = max(−cap, −c0 − c1 ω).

    A NaN speed gives a NaN box.  Returns -1 (nothing written) unless
    ``u_cmd`` and ``omega`` have 4 entries, else 0.
    """
    if u_cmd.shape[0] != 4 or omega.shape[0] != 4:
        return -1
    for j in range(4):
        t = c1[j] * omega[j]
        target[j] = c2[j] * u_cmd[j] - t
        if t != t:
            hi[j] = lo[j] = t
        else:
            hi[j] = min(c0 - t, cap[j])
            lo[j] = max(-c0 - t, -cap[j])
    return 0


@kernel
def _voltage(
    c1: np.ndarray, c2: np.ndarray, torque: np.ndarray, omega: np.ndarray, out: np.ndarray
) -> None:
    """U = (τ + c1 ω) / c2, the inverse of τ_cmd's map in :func:`_torque_box` [V].

    Called only after :func:`_torque_box` accepted ω's length (4).
    """
    for j in range(4):
        out[j] = (torque[j] + c1[j] * omega[j]) / c2[j]


@kernel
def _bound_rows(
    directions: np.ndarray,
    A: np.ndarray,
    b: np.ndarray,
    radius: float,
    rows_C: np.ndarray,
    rows_upper: np.ndarray,
) -> float:
    """Fill the cuff rows ±n_kᵀ(A τ + b)_c ≤ r (τ columns) and their bounds.

    Row ``16 p + 4 c + k`` (and the same plus half the rows, negated) holds
    n_k = ``directions[k]`` on cuff c's (f_x, f_z) rows ``8 p + 2c, +1`` of
    (A, b); only the τ columns (0-3) of ``rows_C`` are written.  Returns the
    sum of every entry written: finite iff they all are.
    """
    half = directions.shape[0]
    n_poly = rows_C.shape[0] // 2
    total = 0.0
    for p in range(A.shape[0] // 8):
        for c in range(4):
            ix = 8 * p + 2 * c
            for k in range(half):
                cx, cz = directions[k, 0], directions[k, 1]
                row = p * 4 * half + c * half + k
                for j in range(4):
                    na = cx * A[ix, j] + cz * A[ix + 1, j]
                    rows_C[row, j] = na
                    rows_C[n_poly + row, j] = -na
                    total += na
                nb = cx * b[ix] + cz * b[ix + 1]
                rows_upper[row] = radius - nb
                rows_upper[n_poly + row] = radius + nb
                total += nb
    return total


@kernel
def _clip_if_feasible(
    rows: np.ndarray,
    upper: np.ndarray,
    target: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    torque: np.ndarray,
) -> int:
    """τ = τ_cmd clipped into the box, if it meets every cuff row with zero slack.

    With W diagonal the clip is the optimum of the QP without its cuff rows;
    if it meets them all (exactly: n_kᵀ f_c(τ) ≤ r, no tolerance) it is the
    optimum of the full QP, slacks zero.  Returns the number of box bounds
    and rows within ACTIVE_TOL of their limit, and writes τ to ``torque``;
    returns -1 (``torque`` untouched) if a row is violated, the box is empty
    or an entry is not finite.
    """
    for j in range(4):
        if not (lo[j] <= hi[j] and math.isfinite(target[j])):
            return -1
    active = 0
    for j in range(4):
        t = min(max(target[j], lo[j]), hi[j])
        if t - lo[j] <= ACTIVE_TOL or hi[j] - t <= ACTIVE_TOL:
            active += 1
    for i in range(rows.shape[0]):
        acc = 0.0
        for j in range(4):
            acc += rows[i, j] * min(max(target[j], lo[j]), hi[j])
        room = upper[i] - acc
        if not room >= 0.0:
            return -1
        if room <= ACTIVE_TOL:
            active += 1
    for j in range(4):
        torque[j] = min(max(target[j], lo[j]), hi[j])
    return active


@kernel
def _screen(
    rows: np.ndarray,
    upper: np.ndarray,
    tau_a: np.ndarray,
    tau_b: np.ndarray,
    value: np.ndarray,
    mark: np.ndarray,
    slots: np.ndarray,
    qp_C: np.ndarray,
    qp_upper: np.ndarray,
) -> None:
    """Put the ``len(slots)`` cuff rows most nearly binding into the QP's rows.

    A row's measure is max over τ ∈ {τ_a, τ_b} of its τ part at τ minus its
    bound (slacks at zero).  A row already in a slot that is chosen again
    keeps that slot; the others take the freed slots in row order.
    ``value`` and ``mark`` are scratch, one entry per cuff row.
    """
    n = rows.shape[0]
    for i in range(n):
        a = 0.0
        b = 0.0
        for j in range(4):
            a += rows[i, j] * tau_a[j]
            b += rows[i, j] * tau_b[j]
        value[i] = max(a, b) - upper[i]
        mark[i] = 0
    for _ in range(slots.shape[0]):
        best = -1
        for i in range(n):
            if mark[i] == 0 and (best < 0 or value[i] > value[best]):
                best = i
        mark[best] = 1
    for s in range(slots.shape[0]):  # chosen and already in place: keep
        if mark[slots[s]] == 1:
            mark[slots[s]] = 2
        else:
            slots[s] = -1
    nxt = 0
    for s in range(slots.shape[0]):
        if slots[s] < 0:
            while mark[nxt] != 1:
                nxt += 1
            slots[s] = nxt
            mark[nxt] = 2
    _copy_rows(rows, upper, slots, qp_C, qp_upper)


@kernel
def _widen(
    rows: np.ndarray,
    upper: np.ndarray,
    x: np.ndarray,
    value: np.ndarray,
    mark: np.ndarray,
    slots: np.ndarray,
    qp_C: np.ndarray,
    qp_upper: np.ndarray,
) -> int:
    """Check x against every cuff row; swap violated ones into the QP's rows.

    Returns the number of rows not in the QP that x violates by more than
    FEASIBILITY_TOL (0: x meets every row, and the screened QP's optimum is
    the full QP's).  Those rows, most violated first, replace the screened
    rows with the most room at x (as many as there are slots).
    """
    n = rows.shape[0]
    m = slots.shape[0]
    for i in range(n):
        mark[i] = 0
    for s in range(m):
        mark[slots[s]] = 2
    violated = 0
    for i in range(n):
        acc = 0.0
        for j in range(rows.shape[1]):
            acc += rows[i, j] * x[j]
        value[i] = acc - upper[i]
        if mark[i] == 0 and not value[i] <= FEASIBILITY_TOL:
            mark[i] = 1
            violated += 1
    for _ in range(min(violated, m)):
        worst = -1
        for i in range(n):
            if mark[i] == 1 and (worst < 0 or value[i] > value[worst]):
                worst = i
        roomy = -1
        for s in range(m):
            if mark[slots[s]] == 2 and (roomy < 0 or value[slots[s]] < value[slots[roomy]]):
                roomy = s
        mark[slots[roomy]] = 0
        slots[roomy] = worst
        mark[worst] = 3  # just added: stays
    if violated:
        _copy_rows(rows, upper, slots, qp_C, qp_upper)
    return violated


@kernel
def _copy_rows(
    rows: np.ndarray, upper: np.ndarray, slots: np.ndarray, qp_C: np.ndarray, qp_upper: np.ndarray
) -> None:
    """QP row s := cuff row ``slots[s]`` (all columns) and its bound."""
    for s in range(slots.shape[0]):
        r = slots[s]
        for j in range(rows.shape[1]):
            qp_C[s, j] = rows[r, j]
        qp_upper[s] = upper[r]


@kernel
def _check_answer(
    c_all: np.ndarray,
    lower_all: np.ndarray,
    upper_all: np.ndarray,
    x: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    x_out: np.ndarray,
) -> int:
    """Check lower ≤ [C; I] x ≤ upper within FEASIBILITY_TOL, independently of the solver.

    Returns -1 if a row or box bound is violated or not finite; otherwise
    writes x rounded into the box ``[lo, hi]`` to ``x_out`` and returns the
    number of rows and box bounds within ACTIVE_TOL of a limit.
    """
    active = 0
    for i in range(c_all.shape[0]):
        acc = 0.0
        for j in range(c_all.shape[1]):
            acc += c_all[i, j] * x[j]
        room = min(acc - lower_all[i], upper_all[i] - acc)
        if not room >= -FEASIBILITY_TOL:
            return -1
        if room <= ACTIVE_TOL:
            active += 1
    for j in range(x.shape[0]):
        x_out[j] = max(min(x[j], hi[j]), lo[j])
    return active
