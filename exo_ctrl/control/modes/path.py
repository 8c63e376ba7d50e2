r"""Path control with free timing: a tunnel around the planned foot path (issue 18, ``path``).

The device lets the patient set the pace along the planned foot path and
only keeps the feet near it (after Duschau-Wicke et al. 2010's path
control).  Per control tick, on the device's own models:

1. **The feet.**  Forward kinematics of the device's exoskeleton legs at the
   encoder angles q (closed form, :mod:`exo_ctrl.plan.kinematics`): with the
   leg's φ1 = φ1⁰ + s_h q_h, φ2 = φ2⁰ + s_h q_h + s_k q_k,
   p = (l1 cos φ1 + l2 cos φ2, l1 sin φ1 + l2 sin φ2) [m] from the hip, and
   ṗ = J q̇ with q̇ the encoder's filtered difference (the free command's
   speed) and

   .. math::  J = \bigl[\,s_h (∂_{φ1} p + ∂_{φ2} p),\; s_k\,∂_{φ2} p\,\bigr],
              \quad ∂_{φ1} p = l_1(-\sin φ_1, \cos φ_1),\; ∂_{φ2} p = l_2(-\sin φ_2, \cos φ_2).

2. **The phase** σ, a row of the plan's gait period (P rows): free timing.
   Over the periodic rows, σ_k = argmin over r ∈ [σ_{k-1}, σ_{k-1} + W] of
   Σ_legs |p_leg − c_leg(r)|², c the planned foot path: the nearest point
   of the path ahead of the current phase, both legs together (they are half
   a period apart, which tells the swing from the stance), never backwards
   (W: ``search_window`` × P rows).  The phase waits for a slow patient and
   follows a fast one; ``progress`` counts the rows advanced [rows].  On the
   ramps' rows the phase is the clock's (the step length is still changing).
3. **The tunnel.**  Per leg, the nearest point c* of the path (its polyline
   between rows r ∈ [σ − W, σ + W]) at distance d = |p − c*| along
   n = (p − c*) / d.  Inside the tunnel (d ≤ w) the wall's force is exactly
   zero; outside, a spring–damper wall pushes the foot back:

   .. math::  F_{wall} = -\max\bigl(0,\; k (d - w) + b\,\dot d\bigr)\,n,
              \qquad \dot d = n \cdot \dot p,

   (it only pushes; a static foot at d > w meets k (d − w)).
4. **Support**: F_sup = f_s t(σ), t the path's unit tangent at the phase.
5. **Torques and volts**: τ_path = Jᵀ (F_wall + F_sup) per leg, added to
   ``transparent``'s free torque τ_free (the compensation of the device's
   own gravity, friction, back-EMF and, by force feedback K_f, its inertia;
   :mod:`exo_ctrl.control.modes.controller`), and through the drive model

   .. math::  U = \frac{R\,(τ_{free} + τ_{path})}{k_t\,η^{s}} + \frac{i_G}{k_E}\,\dot q,
              \qquad s = \operatorname{sign}(τ) \tanh(\dot q / ω_η).

All per-tick arithmetic is the compiled kernel :func:`path_command`, after
the transparent mode's own tick.

Reference:
    Duschau-Wicke A, von Zitzewitz J, Caprez A, Lünenburger L, Riener R
    (2010). Path control: a method for patient-cooperative robot-aided gait
    rehabilitation. IEEE Trans Neural Syst Rehabil Eng 18(1):38-48.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ... import _validate as v
from ..._jit import Status, check, kernel, record
from ...exceptions import InvalidParameter
from ...model import BodyModel
from ...model.leg_kernels import LEG_FIELDS, fill_legs, foot_point
from ...plan.kinematics import JointTrajectory
from ...plan.rows import plan_row
from ...plant.drive import MotorParams
from ...plant.motor import steady_voltage
from ...sensing.readings import SensorReadings
from ..base import COMMAND_FIELDS, CommandCounters
from .controller import InteractionController
from .params import ModeParams

__all__ = ["PATH_FIELDS", "PathController", "PathParams", "path_command"]


@dataclass(frozen=True)
class PathParams:
    """Parameters of ``path`` (module docstring).

    Attributes:
        tunnel_width_m: w ≥ 0, the tunnel's half-width around the foot path
            [m] (``--tunnel-width``).  Default 0.03 (choice: a few
            centimetres, the order of a foot's step-to-step variability).
        wall_stiffness_N_per_m: k > 0, the wall's stiffness [N/m].  Default
            2000 (choice: 1 cm beyond the tunnel meets 20 N at the foot).
        wall_damping_N_s_per_m: b ≥ 0, the wall's damping on the normal
            speed [N·s/m].  Default 100 (choice: ζ ≈ 0.5 for about 10 kg of
            leg and exoskeleton at the foot against 2000 N/m).
        support_N: f_s, the supportive force along the path's tangent at the
            phase [N] (``--path-support``; default 0).
        search_window: W / P, the share of the gait period searched for the
            phase ahead and for the nearest point either side (default 0.1).

    Raises:
        InvalidParameter: a value outside its range.

    """

    tunnel_width_m: float = 0.03
    wall_stiffness_N_per_m: float = 2000.0
    wall_damping_N_s_per_m: float = 100.0
    support_N: float = 0.0
    search_window: float = 0.1

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "tunnel_width_m", v.non_negative("tunnel_width", self.tunnel_width_m, "m"))
        k = v.positive("wall_stiffness", self.wall_stiffness_N_per_m, "N/m")
        set_(self, "wall_stiffness_N_per_m", k)
        b = v.non_negative("wall_damping", self.wall_damping_N_s_per_m, "N·s/m")
        set_(self, "wall_damping_N_s_per_m", b)
        set_(self, "support_N", v.finite("path_support", self.support_N))
        w = v.finite("search_window", self.search_window)
        if not 0.0 < w <= 0.5:
            raise InvalidParameter("search_window", self.search_window, "in (0, 0.5] of a period")
        set_(self, "search_window", w)


#: The path mode's part of the record (after COMMAND_FIELDS): the legs'
#: geometry (:data:`~exo_ctrl.model.leg_kernels.LEG_FIELDS`); k [N/m],
#: b [N·s/m], w [m], f_s [N]; the
#: search window W and the plan's row rule (rows); the phase σ (a row of
#: the period), progress (rows advanced in the periodic part), whether the
#: periodic part began; what the last tick computed: the feet p [m] and ṗ
#: [m/s] (leg, x/z), the nearest path points [m], the distances d [m], the
#: wall and support forces on the feet [N], τ_path [N·m], the phase row;
#: scratch for the kernel (a leg's kinematics, a nearest point).
PATH_FIELDS: list[tuple[Any, ...]] = [
    *LEG_FIELDS,
    ("stiffness", np.float64),
    ("damping", np.float64),
    ("width", np.float64),
    ("support", np.float64),
    ("window", np.int64),
    ("lead", np.int64),
    ("period", np.int64),
    ("tail", np.int64),
    ("phase", np.int64),
    ("progress", np.int64),
    ("in_cycle", np.int64),
    ("foot", np.float64, (2, 2)),
    ("foot_vel", np.float64, (2, 2)),
    ("nearest", np.float64, (2, 2)),
    ("distance", np.float64, (2,)),
    ("wall_force", np.float64, (2, 2)),
    ("support_force", np.float64, (2, 2)),
    ("tau_path", np.float64, (4,)),
    ("row", np.int64),
    ("kin", np.float64, (8,)),
    ("near", np.float64, (3,)),
]


class PathController(CommandCounters):
    """``path``: the tunnel around the planned foot path with free timing (module docstring).

    Args:
        params: the tunnel, wall and support.
        modes: the modes' parameters (K_f and the speed filter of the free command).
        plan: the joint plan; its foot path ``foot_pos`` and a gait period of
            whole ticks (``period_ticks``) are required.
        exo: the exoskeleton model the DEVICE holds.
        motor: the drive the device believes in.
        dt: the control period Δt [s].
        estimator: the run's live cuff-force estimator (``"kalman"`` or
            ``"momentum"``): the free part's force gains, lead and the
            filter's tuning are transparent's for it
            (:class:`~exo_ctrl.control.modes.InteractionController`).

    Raises:
        InvalidParameter: a plan without a periodic part.

    """

    def __init__(
        self,
        params: PathParams,
        modes: ModeParams,
        plan: JointTrajectory,
        exo: BodyModel,
        motor: MotorParams,
        dt: float = 1e-3,
        estimator: str = "kalman",
    ) -> None:
        lead, period, tail = plan.row_rule
        if period < 2:
            raise InvalidParameter(
                "plan period_ticks", plan.period_ticks, "a gait period of at least 2 ticks"
            )
        self.name = "path"
        self.params = params
        self.plan = plan
        self._free = InteractionController(
            "transparent", modes, plan, exo, motor, dt=dt, estimator=estimator
        )
        #: The Kalman filter's σ_d the free part runs with (transparent's).
        self.estimator_torque_rate_Nm_per_sqrt_s = self._free.estimator_torque_rate_Nm_per_sqrt_s
        self.tune_estimator = self._free.tune_estimator
        self.record = rec = record(COMMAND_FIELDS + PATH_FIELDS)
        s = rec[0]
        fill_legs(s, exo)
        s["stiffness"] = params.wall_stiffness_N_per_m
        s["damping"] = params.wall_damping_N_s_per_m
        s["width"] = params.tunnel_width_m
        s["support"] = params.support_N
        s["window"] = max(1, round(params.search_window * period))
        s["lead"], s["period"], s["tail"] = lead, period, tail
        self._pos = np.ascontiguousarray(plan.foot_pos, dtype=float)
        speed = np.linalg.norm(plan.foot_vel, axis=-1, keepdims=True)
        self._tan = np.divide(
            plan.foot_vel, speed, out=np.zeros_like(plan.foot_vel), where=speed > 1e-9
        )
        self._u = rec["u_cmd"][0]

    def command(self, k: int, sensors: SensorReadings) -> np.ndarray:
        """Drive voltages [V] for tick k: a view of ``record["u_cmd"]``.

        A non-finite angle or speed reading (a sensor fault) commands NaN volts
        and leaves the phase as it was: the safety supervisor,
        which checks the readings, replaces the command and stops the device,
        as it does PD's NaN command (tools/faults.py's ``nan_reading``).

        Raises:
            InvalidParameter: readings not of 4 joint values, a cuff-force
                estimate not (4, 2), or a tick beyond the plan.

        """
        self._free.command(k, sensors)
        status = path_command(self.record, self._free.record, k, sensors.q, self._pos, self._tan)
        if status:
            rows = self._pos.shape[0]
            if not 0 <= self.plan.row(k) < rows:  # as PD refuses it (control/pd.py)
                raise InvalidParameter("k", k, f"a tick whose plan row is within the plan's {rows}")
            check(status, f"{type(self).__name__}.command", sensors_q=sensors.q)
        return self._u


@kernel
def foot_kinematics(g, leg, qh, qk, wh, wk, out):  # pragma: no cover - compiled
    """Foot p, ṗ and the Jacobian J (module docstring) of leg ``leg`` into ``out`` (8,).

    ``g``: a record element with the legs' geometry (``LEG_FIELDS``;
    :func:`~exo_ctrl.model.leg_kernels.foot_point` computes p and J);
    ``out`` = (x, z, ẋ, ż, J₀₀, J₁₀, J₀₁, J₁₁): J's columns ∂p/∂q_h, ∂p/∂q_k.
    """
    out[0], out[1], out[4], out[6], out[5], out[7] = foot_point(g, leg, qh, qk)
    out[2] = out[4] * wh + out[6] * wk
    out[3] = out[5] * wh + out[7] * wk


@kernel
def _wrap_row(r, lead, period, last, periodic):  # pragma: no cover - compiled
    """Row r kept in the period's loop (periodic) or in [0, last]."""
    if periodic:
        return lead + (r - lead) % period
    if r < 0:
        return 0
    if r > last:
        return last
    return r


@kernel
def _nearest(pos, leg, px, pz, row, window, lead, period, periodic, out):  # pragma: no cover
    """Nearest point of leg's path polyline to (px, pz) within ``window`` rows of ``row``.

    ``out`` = (cx, cz, d²).  The closest vertex first, then the projections on
    the two segments either side of it.
    """
    last = pos.shape[0] - 1
    best, best_r = 1e300, row
    for i in range(-window, window + 1):
        r = _wrap_row(row + i, lead, period, last, periodic)
        dx, dz = px - pos[r, leg, 0], pz - pos[r, leg, 1]
        d2 = dx * dx + dz * dz
        if d2 < best:
            best, best_r = d2, r
    out[0], out[1], out[2] = pos[best_r, leg, 0], pos[best_r, leg, 1], best
    for side in (-1, 1):
        r2 = _wrap_row(best_r + side, lead, period, last, periodic)
        ax, az = pos[best_r, leg, 0], pos[best_r, leg, 1]
        ex, ez = pos[r2, leg, 0] - ax, pos[r2, leg, 1] - az
        length2 = ex * ex + ez * ez
        if length2 <= 0.0:
            continue
        u = ((px - ax) * ex + (pz - az) * ez) / length2
        if u <= 0.0 or u >= 1.0:
            continue
        cx, cz = ax + u * ex, az + u * ez
        d2 = (px - cx) ** 2 + (pz - cz) ** 2
        if d2 < out[2]:
            out[0], out[1], out[2] = cx, cz, d2


@kernel
def path_command(state, free, k, q, pos, tan):  # pragma: no cover - compiled
    """One tick of ``path`` (module docstring) into ``state[0].u_cmd`` [V]; returns a status.

    ``free``: the transparent mode's record after its tick (``tau_free``
    [N·m], ``speed`` [rad/s], ``drive``); ``q``: the encoder angles [rad];
    ``pos``, ``tan``: the planned foot path per row (rows, leg, x/z) [m] and
    its unit tangent.
    """
    if q.shape[0] != 4:
        return 1
    s = state[0]
    for j in range(4):  # a sensor fault: NaN volts, the phase kept; the supervisor stops
        if not np.isfinite(q[j]):
            for i in range(4):
                s.u_cmd[i] = np.nan
            return 0
    f = free[0]
    lead, period, tail, window = s.lead, s.period, s.tail, s.window
    kin = s.kin
    for leg in range(2):
        foot_kinematics(
            s, leg, q[2 * leg], q[2 * leg + 1], f.speed[2 * leg], f.speed[2 * leg + 1], kin
        )
        s.foot[leg, 0], s.foot[leg, 1] = kin[0], kin[1]
        s.foot_vel[leg, 0], s.foot_vel[leg, 1] = kin[2], kin[3]
    # The phase: free in the periodic rows, the clock's on the ramps.
    periodic = lead <= k < tail
    if periodic:
        if s.in_cycle == 0:
            s.in_cycle = 1
            s.phase = (k - lead) % period
        else:
            best, step = 1e300, 0
            for i in range(window + 1):
                r = lead + (s.phase + i) % period
                cost = 0.0
                for leg in range(2):
                    dx = s.foot[leg, 0] - pos[r, leg, 0]
                    dz = s.foot[leg, 1] - pos[r, leg, 1]
                    cost += dx * dx + dz * dz
                if cost < best:
                    best, step = cost, i
            s.phase = (s.phase + step) % period
            s.progress += step
        row = lead + s.phase
    else:
        row = plan_row(k, lead, period, tail)
        if row >= pos.shape[0]:  # a tick beyond the plan: the caller names it
            return Status.WRONG_LENGTH.value
    s.row = row
    near = s.near
    for leg in range(2):
        px, pz = s.foot[leg, 0], s.foot[leg, 1]
        _nearest(pos, leg, px, pz, row, window, lead, period, periodic, near)
        s.nearest[leg, 0], s.nearest[leg, 1] = near[0], near[1]
        d = np.sqrt(near[2])
        s.distance[leg] = d
        fx, fz = 0.0, 0.0
        if d > s.width:
            nx, nz = (px - near[0]) / d, (pz - near[1]) / d
            rate = nx * s.foot_vel[leg, 0] + nz * s.foot_vel[leg, 1]
            push = s.stiffness * (d - s.width) + s.damping * rate
            if push > 0.0:
                fx, fz = -push * nx, -push * nz
        s.wall_force[leg, 0], s.wall_force[leg, 1] = fx, fz
        sx, sz = s.support * tan[row, leg, 0], s.support * tan[row, leg, 1]
        s.support_force[leg, 0], s.support_force[leg, 1] = sx, sz
        foot_kinematics(s, leg, q[2 * leg], q[2 * leg + 1], 0.0, 0.0, kin)
        s.tau_path[2 * leg] = kin[4] * (fx + sx) + kin[5] * (fz + sz)
        s.tau_path[2 * leg + 1] = kin[6] * (fx + sx) + kin[7] * (fz + sz)
    dr = f.drive
    for j in range(4):
        w = f.speed[j]
        tau = f.tau_free[j] + s.tau_path[j]
        s.u_cmd[j] = steady_voltage(tau, w, dr)
    return 0
