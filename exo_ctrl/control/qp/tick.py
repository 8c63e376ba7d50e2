"""The QP controller's record and its compiled tick, in the order of a tick.

A tick of :class:`~exo_ctrl.control.qp.controller.QPController` is
:func:`front` (CT+PD, the torque box, the state for Pinocchio), the cuff
model's CRBA and nonLinearEffects, :func:`tail` (linearisation, observer,
prediction, octagon rows, clip test); only when the clip test fails,
:func:`load`, proxsuite and :func:`widen_rows` (up to
:data:`~exo_ctrl.control.qp.screening.SCREEN_ROUNDS` times), then
:func:`take`, or a fallback (:func:`volts`).  Each kernel takes the
controller's record (:func:`qp_fields` after the CT's fields) and the
records of the cuff model, the observer or the QP workspace.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..._jit import Status, kernel, leaf
from ..pd import pd_law
from .margin import SETTLE_TICKS
from .observer import add_residual, observe
from .prediction import gather, pair, predict
from .screening import POLYGON_SIDES, bound_rows, clip_if_feasible, screen, widen
from .torque_box import TORQUE_BOX_FIELDS, drive_at_caps, torque_box, voltage
from .workspace import ACTIVE_TOL

__all__ = [
    "front",
    "horizon",
    "load",
    "load_all",
    "qp_fields",
    "tail",
    "take",
    "tighten",
    "volts",
    "widen_rows",
]


def qp_fields(n_rows: int, n_slots: int) -> list[tuple[Any, ...]]:
    """The QP's part of a :class:`~exo_ctrl.control.qp.controller.QPController`'s record.

    After the CT's fields (:data:`~exo_ctrl.control.base.COMMAND_FIELDS`,
    :data:`~exo_ctrl.control.pd.PD_FIELDS`).

    ``u_ct``: the CT+PD voltage [V]; the last tick's figures ``solve_time_us``,
    ``screen_rounds`` (proxsuite's solves), ``solved`` (False: fell back),
    ``needs_solve`` (the clip test failed: proxsuite is needed), ``observed`` (the
    prediction starts from the observer's cuff state), ``violated`` (rows the last
    answer violates); ``force_feedback``; ``sensed`` (the device carries cuff
    sensors: the estimate's measured split is held over the horizon,
    :func:`~exo_ctrl.control.qp.observer.add_residual`); the torque box
    (:data:`~exo_ctrl.control.qp.torque_box.TORQUE_BOX_FIELDS`); the answer
    ``torque`` [N·m] and ``slack`` [N]; ``fitted``: zeros, the cuff state
    taken without an estimate; the octagon's ``directions`` and ``radius``
    r_c per cuff [N]; the bound ``limit`` F_max per cuff [N], the margin's static
    part ``margin_static`` [N], the estimate's ``sigmas`` k, the largest
    margin so far ``margin_peak`` [N] (the tick's m_c is the common
    ``margin``), the
    cuffs' ``working`` force [N], the ``ticks`` tightened so far
    (:mod:`~exo_ctrl.control.qp.margin`); the cuff ``rows`` (n_rows, 8) and
    their ``upper`` bounds [N]; the screening's scratch ``value``, ``mark``
    and the QP row ``slots``.
    """
    f8 = np.float64
    return [
        ("u_ct", f8, (4,)),
        ("solve_time_us", f8),
        ("screen_rounds", f8),
        ("solved", np.bool_),
        ("needs_solve", np.bool_),
        ("observed", np.bool_),
        ("violated", np.int64),
        ("force_feedback", np.bool_),
        ("sensed", np.bool_),
        *TORQUE_BOX_FIELDS,
        ("torque", f8, (4,)),
        ("slack", f8, (4,)),
        ("fitted", f8, (4,)),
        ("directions", f8, (POLYGON_SIDES // 2, 2)),
        ("radius", f8, (4,)),
        ("limit", f8, (4,)),
        ("margin_static", f8, (4,)),
        ("sigmas", f8),
        ("margin_peak", f8, (4,)),
        ("working", f8, (4,)),
        ("ticks", np.int64),
        ("rows", f8, (n_rows, 8)),
        ("upper", f8, (n_rows,)),
        ("value", f8, (n_rows,)),
        ("mark", np.int64, (n_rows,)),
        ("slots", np.int64, (n_slots,)),
    ]


@kernel
def front(
    state: np.ndarray,
    model: np.ndarray,
    q_des: np.ndarray,
    dq_des: np.ndarray,
    u_ff: np.ndarray,
    k: int,
    q: np.ndarray,
    dq: np.ndarray,
) -> int:  # pragma: no cover - compiled
    """The tick before Pinocchio: CT+PD into ``u_ct``, the torque box, q_all and v_all.

    Returns :func:`~exo_ctrl.control.pd.pd_law`'s status (nothing done unless OK).
    """
    s = state[0]
    status, row = pd_law(
        s.kp, s.kd, s.lead, s.period, s.tail, q_des, dq_des, u_ff, k, q, dq, s.u_ct
    )
    if status != Status.OK.value:
        return status
    s.row = row
    torque_box(s, s.u_ct, dq)
    return pair(model[0], q, dq)


@kernel
def tail(
    state: np.ndarray,
    model: np.ndarray,
    observer: np.ndarray,
    mass: np.ndarray,
    nle: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray,
    force: np.ndarray,
    has_estimate: bool,
    split: bool | None,
    force_std: np.ndarray,
) -> int:  # pragma: no cover
    """The tick after Pinocchio, up to proxsuite (module docstring, "Cost").

    Linearisation, observer (force feedback on and an estimate given),
    prediction, the tightened bound (m_c = static part + k σ_c, ``force_std``
    σ_c [N], (4,); r_c = max(F_max − m_c, 0) cos(π/8)), octagon rows and the
    clip test.  If the clip meets every row,
    the tick is done: τ, zero slacks, the voltage ``u_cmd`` and the tick's
    figures written; else ``needs_solve``.  ``split``: the cuff model's switch
    (:attr:`~exo_ctrl.control.qp.prediction.CuffHorizonModel.split_switch`).
    Returns a :class:`~exo_ctrl._jit.Status` value: WRONG_LENGTH (nothing
    done) if ``force`` is not (4, 2), NOT_FINITE if the prediction is not finite.
    """
    s, m = state[0], model[0]
    if force.shape[0] != 4 or force.shape[1] != 2:
        return Status.WRONG_LENGTH.value
    gather(m, mass, nle, q, dq, split)
    for j in range(4):
        m.held[j] = 0.0
    s.observed = s.force_feedback and has_estimate and observe(observer[0], m, force, dq, split)
    tighten(s, force_std)
    s.solve_time_us = 0.0
    s.screen_rounds = 0.0
    status = horizon(state, model, observer, dq, split)
    if status or s.needs_solve:
        return status
    # The clipped command meets every row with the voltages held.  A drive whose command
    # is beyond the box gets its command's voltage, the driver holding the cap
    # (torque_box), if the clip meets every row with those drives held at their caps too.
    pushed = False
    for j in range(4):
        lo, hi, cmd = s.torque_lo[j], s.torque_hi[j], s.torque_cmd[j]
        if lo <= hi and (cmd > hi or cmd < lo):
            m.held[j] = 1.0
            pushed = True
    if not pushed:
        return status
    status = horizon(state, model, observer, dq, split)
    if status or s.needs_solve:  # not with the caps held: the voltages held, as first
        for j in range(4):
            m.held[j] = 0.0
        status = horizon(state, model, observer, dq, split)
    return status


@kernel
def horizon(
    state: np.ndarray, model: np.ndarray, observer: np.ndarray, dq: np.ndarray, split: bool | None
) -> int:  # pragma: no cover - compiled
    """The prediction with the drives held as ``held`` says, the octagon rows and the clip test.

    From the observer's cuff state (``observed``) or the cuffs as fitted; as
    :func:`tail` after the observer (its return values), and again with drives held.
    """
    s, m = state[0], model[0]
    if s.observed:
        o = observer[0]
        delta, ddelta, dist = o.delta, o.ddelta, o.disturbance
    else:  # the cuffs taken as fitted: δ = δ̇ = d = 0
        delta = ddelta = dist = s.fitted
    predict(m, delta, ddelta, dist, split)
    if s.observed and s.sensed:  # the measured split, held over the horizon
        add_residual(observer[0], m, split)
    if not math.isfinite(bound_rows(s.directions, m.A, m.b, s.radius, s.rows, s.upper)):
        return Status.NOT_FINITE.value
    feasible, active = clip_if_feasible(
        s.rows, s.upper, s.torque_cmd, s.torque_lo, s.torque_hi, s.torque
    )
    s.needs_solve = not feasible
    if feasible:
        for j in range(4):
            s.slack[j] = 0.0
        voltage(s, s.torque, dq, s.u_cmd)
        drive_at_caps(s, m.held, s.u_ct, s.u_cmd)
        s.active_constraints = active
        s.solved = True
    return Status.OK.value


@kernel
def tighten(s: np.void, force_std: np.ndarray) -> None:  # pragma: no cover - compiled
    """m_c = ``margin_static`` + k σ_c, at most F_max − F_work,c; r_c = (F_max − m_c) cos(π/8).

    The estimate's term applies after the filter's start-up, the first
    :data:`~exo_ctrl.control.qp.margin.SETTLE_TICKS` ticks (its covariance
    then is the initial guess, not the estimate's error, while the run
    starts from the cuffs fitted at rest), and is capped so that the bound
    never falls below the cuff's working force; ``margin_peak`` follows m_c
    after the start-up.
    """
    apothem = math.cos(math.pi / POLYGON_SIDES)
    s.ticks += 1
    settled = s.ticks > SETTLE_TICKS
    for c in range(4):
        sigma = force_std[c] if math.isfinite(force_std[c]) and settled else 0.0
        margin = min(s.margin_static[c] + s.sigmas * sigma, s.limit[c] - s.working[c])
        margin = max(margin, s.margin_static[c])
        s.margin[c] = margin
        if settled and margin > s.margin_peak[c]:
            s.margin_peak[c] = margin
        s.radius[c] = max(s.limit[c] - margin, 0.0) * apothem


@leaf
def hand_command(s: np.void, p: np.void, n_in: int) -> None:  # pragma: no cover - compiled
    """τ_cmd as the QP's target and the torque box as its bounds, after its ``n_in`` rows."""
    for j in range(4):
        p.target[j] = s.torque_cmd[j]
        p.lower[n_in + j] = s.torque_lo[j]
        p.upper[n_in + j] = s.torque_hi[j]


@kernel
def load(state: np.ndarray, workspace: np.ndarray) -> None:  # pragma: no cover - compiled
    """Hand the QP τ_cmd, the torque box and the screened rows."""
    s, p = state[0], workspace[0]
    hand_command(s, p, s.slots.shape[0])
    screen(s.rows, s.upper, s.torque_cmd, s.torque, s.value, s.mark, s.slots, p.C, p.upper)


@kernel
def load_all(state: np.ndarray, workspace: np.ndarray) -> None:  # pragma: no cover - compiled
    """Hand a workspace of every cuff row τ_cmd, the torque box and all the rows, unscreened."""
    s, p = state[0], workspace[0]
    n_in = s.rows.shape[0]
    hand_command(s, p, n_in)
    for i in range(n_in):
        for j in range(8):
            p.C[i, j] = s.rows[i, j]
        p.upper[i] = s.upper[i]


@kernel
def widen_rows(state: np.ndarray, workspace: np.ndarray) -> None:  # pragma: no cover - compiled
    """Check the QP's answer against every cuff row; violated rows into ``violated`` and the QP."""
    s, p = state[0], workspace[0]
    s.violated = widen(s.rows, s.upper, p.x, s.value, s.mark, s.slots, p.C, p.upper)


@kernel
def take(
    state: np.ndarray, workspace: np.ndarray, omega: np.ndarray
) -> None:  # pragma: no cover - compiled
    """Take the QP's answer: τ, slacks, active bounds (less the idle s ≥ 0), the voltage."""
    s, p = state[0], workspace[0]
    idle = 0  # the s >= 0 bounds of slacks at zero are not constraints of the problem
    for j in range(4):
        s.torque[j] = p.x[j]
        s.slack[j] = p.x[4 + j]
        if s.slack[j] <= ACTIVE_TOL:
            idle += 1
    s.active_constraints = p.active - idle
    s.solved = True
    voltage(s, s.torque, omega, s.u_cmd)


@kernel
def volts(state: np.ndarray, omega: np.ndarray) -> None:  # pragma: no cover - compiled
    """u_cmd := the voltage giving ``torque`` at speed ω (a fallback's)."""
    s = state[0]
    voltage(s, s.torque, omega, s.u_cmd)
