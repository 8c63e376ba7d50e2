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
   between rows r ∈ [σ − W, σ + W]; with the default W = P/2 the whole
   closed foot path, so no error of the phase moves the tunnel; on the
   ramps, whose timing is the clock's, the polyline through every row of
   the plan: the ramps' paths and the gait's, so a patient who starts at
   their own pace is not held to the clock's) at distance
   d = |p − c*| along n = (p − c*) / d.  Inside the tunnel (d ≤ w) the
   wall's force is exactly zero; outside, a spring–damper wall, bounded,
   pushes the foot back:

   .. math::  F_{wall} = -\min\Bigl(F_{max},\;\max\bigl(0,\; k δ
              + \min(1, δ/δ_b)\, b_n \dot d\bigr)\Bigr)\,n,
              \qquad δ = d - w,\; \dot d = n \cdot \dot p,

   a static foot at depth δ meets k δ up to F_max; the damping grows over
   the first δ_b of depth, so the force is continuous in the foot's
   position (no step where the wall begins).  The damping is the wall's
   ratio ζ on the leg's effective mass at the foot along n (the device's
   models at the plan's posture of the nearest row r*):

   .. math::  b_n = 2 ζ \sqrt{k\, m_n},\quad m_n = n^T Λ n,\quad
              Λ = (J M^{-1} J^T)^{-1},\quad
              M = M_p + D (M_e + i_G^2 J_r I) D,\; D = (I + K_f)^{-1/2},

   M_p the nominal patient's leg, M_e the exoskeleton's and its drives'
   reflected rotor inertia, felt divided by 1 + K_f under the free part's
   force feedback (1.7–10.7 kg at the foot with the default models,
   :mod:`exo_ctrl.control.modes.path_mass`).
4. **Support**: F_sup = f_s t(r*), t the path's unit tangent at each leg's
   nearest row; optionally a share α of the nominal patient's leg weight,
   τ_w = α g_p(q) (``leg_weight_support``, default 0).
5. **Torques and volts**: τ_path = Jᵀ (F_wall + F_sup) per leg is the
   torque the wall should put on the PATIENT.  It is added to
   ``transparent``'s free torque τ_free (the compensation of the device's
   own gravity, friction, back-EMF and, by force feedback K_f on the
   estimated interaction torque τ̂_int, its inertia;
   :mod:`exo_ctrl.control.modes.controller`) as the force loop's
   reference:

   .. math::  τ = τ_{free} + (1 + K_f)\,(τ_{path} + τ_w)
              = τ_{comp} + τ_{ref} + K_f (τ_{ref} + \hat τ_{int}),
              \quad τ_{ref} = τ_{path} + τ_w,

   so that at rest τ_int = −τ_ref: the patient meets the wall's force.
   Added without the factor, the force feedback cancels it (it drives
   τ̂_int to zero): the patient would feel τ_path / (1 + K_f), a 2000 N/m
   wall as 133 N/m (measured with that wall: the weak and spastic patients'
   feet 94 and 90 mm RMS from the path, the wall pushing 145 and 152 N RMS
   at the feet, the cuffs carrying 7 and 9 N).  Then through the drive
   model

   .. math::  U = \frac{R\,τ}{k_t\,η^{s}} + \frac{i_G}{k_E}\,\dot q,
              \qquad s = \operatorname{sign}(τ) \tanh(\dot q / ω_η).

All per-tick arithmetic is the compiled kernel :func:`path_command`, after
the transparent mode's own tick.

**What limits the wall** (``tools/path_wall.py``; healthy, weak (0.3) and
spastic active patients).  Not its stability: with F_max every wall from 2
to 40 kN/m and ζ from 0.3 to 1 ran 6–12 s without growth or a stop.
Without the bound a stiff, damped wall met a foot entering at up to 1 m/s
with hundreds of newtons, which the force loop multiplies by 1 + K_f = 15
on the drives' command (the effort limit, 150 N·m, and the current limit,
32 A, clip it for a few ticks): 20 kN/m with 443 N·s/m grew from 14 to
80 mm RMS on the healthy patient and tripped the supervisor.  What holds the
weak patient is the force the cuffs may carry: the weak leg's push exceeds
F_max (derived from the shank cuff's limit), so beyond about 5 kN/m a
stiffer wall takes little off the distance.  The drive's electrical
bandwidth (L/R = 0.7 ms) is not a limit; the estimate's lag is the force
loop's (transparent's lead makes it up with the Kalman filter; with the
momentum observer's lag the healthy patient, who walks 20 mm RMS from the
path in transparent's loop, meets the wall on 13–20 % of the ticks).

Reference:
    Duschau-Wicke A, von Zitzewitz J, Caprez A, Lünenburger L, Riener R
    (2010). Path control: a method for patient-cooperative robot-aided gait
    rehabilitation. IEEE Trans Neural Syst Rehabil Eng 18(1):38-48.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from ... import _validate as v
from ..._jit import Status, check, kernel, record
from ...exceptions import InvalidParameter
from ...model import BodyModel
from ...model.leg_kernels import LEG_FIELDS, fill_legs, foot_point, legs_record
from ...plan.kinematics import JointTrajectory
from ...plan.rows import plan_row
from ...plant.drive import MotorParams
from ...plant.motor import steady_voltage
from ...sensing.readings import SensorReadings
from ..base import COMMAND_FIELDS, CommandCounters
from .controller import InteractionController
from .params import ModeParams
from .path_mass import foot_mass_table
from .path_search import STRIDE, nearest_point, phase_step

__all__ = ["PATH_FIELDS", "PathController", "PathParams", "path_command"]


@dataclass(frozen=True)
class PathParams:
    """Parameters of ``path`` (module docstring).

    Attributes:
        tunnel_width_m: w ≥ 0, the tunnel's half-width around the foot path
            [m] (``--tunnel-width``).  Default 0.03 (choice: a few
            centimetres, the order of a foot's step-to-step variability).
        wall_stiffness_N_per_m: k > 0, the wall's stiffness [N/m].  Default
            5000 (derived: the wall reaches F_max at 18 mm, within the 2 cm
            beyond the tunnel the device tolerates, k ≥ F_max / 2 cm; measured
            with ``tools/path_wall.py``, 12 s, seeds 1–3: the weak (0.3)
            patient's feet 31 mm RMS from the path, beyond w + 2 cm on
            0.3–1.1 % of the ticks, against 35 mm and 7.5 % at 2000 N/m; the
            spastic patient's 25 mm, never beyond; stiffer walls, stable up to
            40 kN/m, take 1–2 mm off the RMS but the weak patient, whose
            push exceeds F_max, leaves the band more often: 1.3–3.3 %).
        wall_damping_ratio: ζ ≥ 0, the wall's damping ratio on the leg's
            effective mass at the foot (module docstring).  Default 0.7.
        wall_damping_N_s_per_m: b ≥ 0, a fixed damping [N·s/m] in place of
            the ratio's (None, default: from ζ).
        wall_damping_depth_m: δ_b > 0, the depth over which the damping
            grows to b [m] (default 0.005: a foot entering at 1 m/s meets
            the damping within 5 ms).
        wall_force_max_N: F_max > 0, the wall's largest force [N].  Default 90
            (derived: the shank cuff takes up to l2 / c = 0.52 / 0.45 = 1.16
            times a force at the foot, so 90 N is 104 N, 80 % of the
            supervisor's 130 N ISO/TS 15066 lower-leg limit, the rest left
            to the patient's own push; ``tests/control/test_path.py``
            checks the statics on the device's cuff geometry).
        support_N: f_s, the supportive force along the path's tangent at
            each foot's nearest point [N] (``--path-support``; default 0).
        search_window: W / P, the share of the gait period searched for the
            phase ahead and for the nearest point either side (default 0.5:
            the whole foot path; at 0.1 the healthy patient, whose own
            phase the device's lags, met the wall 15 mm RMS from the path
            against 9.4 mm without a wall contact at 0.5).
        leg_weight_support: α ∈ [0, 1], the share of the nominal patient's
            leg weight the device carries, g_p(q) the gravity torque of the
            device's patient model at the encoder angles, added to the force
            loop's reference as τ_path is (default 0: inside the tunnel the
            force is zero).  For a weak patient (strength 0.3: α = 0.5 keeps
            the feet within w + 2 cm, 48 mm at most against 56); a healthy
            patient, who carries their own legs, is pushed out of the tunnel
            by it.  Needs the device's patient model.

    Raises:
        InvalidParameter: a value outside its range.

    """

    tunnel_width_m: float = 0.03
    wall_stiffness_N_per_m: float = 5000.0
    wall_damping_ratio: float = 0.7
    wall_damping_N_s_per_m: float | None = None
    wall_damping_depth_m: float = 0.005
    wall_force_max_N: float = 90.0
    support_N: float = 0.0
    search_window: float = 0.5
    leg_weight_support: float = 0.0

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "tunnel_width_m", v.non_negative("tunnel_width", self.tunnel_width_m, "m"))
        k = v.positive("wall_stiffness", self.wall_stiffness_N_per_m, "N/m")
        set_(self, "wall_stiffness_N_per_m", k)
        zeta = v.non_negative("wall_damping_ratio", self.wall_damping_ratio)
        set_(self, "wall_damping_ratio", zeta)
        if self.wall_damping_N_s_per_m is not None:
            b = v.non_negative("wall_damping", self.wall_damping_N_s_per_m, "N·s/m")
            set_(self, "wall_damping_N_s_per_m", b)
        depth = v.positive("wall_damping_depth", self.wall_damping_depth_m, "m")
        set_(self, "wall_damping_depth_m", depth)
        set_(self, "wall_force_max_N", v.positive("wall_force_max", self.wall_force_max_N, "N"))
        set_(self, "support_N", v.finite("path_support", self.support_N))
        w = v.finite("search_window", self.search_window)
        if not 0.0 < w <= 0.5:
            raise InvalidParameter("search_window", self.search_window, "in (0, 0.5] of a period")
        set_(self, "search_window", w)
        a = v.finite("leg_weight_support", self.leg_weight_support)
        if not 0.0 <= a <= 1.0:
            raise InvalidParameter("leg_weight_support", self.leg_weight_support, "in [0, 1]")
        set_(self, "leg_weight_support", a)


#: The path mode's part of the record (after COMMAND_FIELDS): the legs'
#: geometry (:data:`~exo_ctrl.model.leg_kernels.LEG_FIELDS`); k [N/m], ζ,
#: the fixed b [N·s/m] (−1: from ζ), δ_b [m], F_max [N], w [m], f_s [N]; the
#: search window W and the plan's row rule (rows); the phase σ (a row of
#: the period), progress (rows advanced in the periodic part), whether the
#: periodic part began; what the last tick computed: the feet p [m] and ṗ
#: [m/s] (leg, x/z), the nearest path points [m] and their rows, the
#: distances d [m], the damping b_n [N·s/m], the wall and support forces on
#: the feet [N], τ_path and the leg-weight support α g_p [N·m], the phase
#: row; scratch for the kernel (a leg's kinematics, a nearest point: x, z,
#: d², its row).
PATH_FIELDS: list[tuple[Any, ...]] = [
    *LEG_FIELDS,
    ("stiffness", np.float64),
    ("damping_ratio", np.float64),
    ("damping", np.float64),
    ("damping_depth", np.float64),
    ("force_max", np.float64),
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
    ("nearest_row", np.int64, (2,)),
    ("distance", np.float64, (2,)),
    ("wall_damping", np.float64, (2,)),
    ("wall_force", np.float64, (2, 2)),
    ("support_force", np.float64, (2, 2)),
    ("tau_path", np.float64, (4,)),
    ("tau_weight", np.float64, (4,)),
    ("row", np.int64),
    ("kin", np.float64, (8,)),
    ("near", np.float64, (4,)),
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
        patient: the patient model the DEVICE holds (the nominal patient),
            whose legs' inertia the wall's damping is derived from; None:
            the exoskeleton's rendered inertia alone (a lower bound).

    Attributes:
        foot_mass: Λ per plan row and leg, (rows, 2, 3): Λ_xx, Λ_xz, Λ_zz [kg]
            (module docstring).

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
        patient: BodyModel | None = None,
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
        s["damping_ratio"] = params.wall_damping_ratio
        fixed = params.wall_damping_N_s_per_m
        s["damping"] = -1.0 if fixed is None else fixed
        s["damping_depth"] = params.wall_damping_depth_m
        s["force_max"] = params.wall_force_max_N
        s["width"] = params.tunnel_width_m
        s["support"] = params.support_N
        s["window"] = max(1, round(params.search_window * period))
        s["lead"], s["period"], s["tail"] = lead, period, tail
        self._pos = np.ascontiguousarray(plan.foot_pos, dtype=float)
        speed = np.linalg.norm(plan.foot_vel, axis=-1, keepdims=True)
        self._tan = np.divide(
            plan.foot_vel, speed, out=np.zeros_like(plan.foot_vel), where=speed > 1e-9
        )
        gains = self._free.record["force_gain"][0]
        self.foot_mass = foot_mass_table(plan.q, exo, patient, motor, gains, legs_record(exo)[0])
        #: The nominal patient for the leg-weight support (None: no support).
        self._weight = None
        if patient is not None and params.leg_weight_support > 0.0:
            model = patient.model
            self._weight = (model, model.createData(), pin.neutral(model), list(patient.q_index))
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
        if self._weight is not None and np.all(np.isfinite(sensors.q)):
            model, data, q_full, index = self._weight
            q_full[index] = sensors.q  # the device's models are aligned: q_patient = q
            g = pin.computeGeneralizedGravity(model, data, q_full)
            self.record["tau_weight"][0] = self.params.leg_weight_support * g[index]
        status = path_command(
            self.record, self._free.record, k, sensors.q, self._pos, self._tan, self.foot_mass
        )
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
def _wall_push(s, leg, d, nx, nz, mass):  # pragma: no cover - compiled
    """The wall's push along −n [N] (module docstring) and the damping b_n it used."""
    depth = d - s.width
    r = s.nearest_row[leg]
    b = s.damping
    if b < 0.0:  # from ζ on the leg's effective mass along n
        m = nx * nx * mass[r, leg, 0] + 2.0 * nx * nz * mass[r, leg, 1] + nz * nz * mass[r, leg, 2]
        b = 2.0 * s.damping_ratio * np.sqrt(s.stiffness * max(m, 0.0))
    rate = nx * s.foot_vel[leg, 0] + nz * s.foot_vel[leg, 1]
    push = s.stiffness * depth + min(1.0, depth / s.damping_depth) * b * rate
    return min(max(push, 0.0), s.force_max), b


@kernel
def path_command(state, free, k, q, pos, tan, mass):  # pragma: no cover - compiled
    """One tick of ``path`` (module docstring) into ``state[0].u_cmd`` [V]; returns a status.

    ``free``: the transparent mode's record after its tick (``tau_free``
    [N·m], ``speed`` [rad/s], ``force_gain``, ``drive``); ``q``: the encoder
    angles [rad]; ``pos``, ``tan``: the planned foot path per row (rows, leg,
    x/z) [m] and its unit tangent; ``mass``: Λ per row and leg (rows, 2, 3) [kg].
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
            step = phase_step(s, pos, 0, window, STRIDE)  # coarse, then about the best
            step = phase_step(s, pos, max(0, step - STRIDE), min(window, step + STRIDE), 1)
            s.phase = (s.phase + step) % period
            s.progress += step
        row = lead + s.phase
    else:
        row = plan_row(k, lead, period, tail)
        if row >= pos.shape[0]:  # a tick beyond the plan: the caller names it
            return Status.WRONG_LENGTH.value
    s.row = row
    last = pos.shape[0] - 1
    near = s.near
    # The tunnel's path: the loop about the phase, or on the ramps every row of the plan.
    centre, reach = (row, window) if periodic else (last // 2, last // 2 + 1)
    for leg in range(2):
        px, pz = s.foot[leg, 0], s.foot[leg, 1]
        nearest_point(pos, leg, px, pz, centre, reach, lead, period, periodic, near)
        s.nearest[leg, 0], s.nearest[leg, 1] = near[0], near[1]
        s.nearest_row[leg] = int(near[3])
        d = np.sqrt(near[2])
        s.distance[leg] = d
        fx, fz, b = 0.0, 0.0, 0.0
        if d > s.width:
            nx, nz = (px - near[0]) / d, (pz - near[1]) / d
            push, b = _wall_push(s, leg, d, nx, nz, mass)
            fx, fz = -push * nx, -push * nz
        s.wall_damping[leg] = b
        s.wall_force[leg, 0], s.wall_force[leg, 1] = fx, fz
        r = s.nearest_row[leg]
        sx, sz = s.support * tan[r, leg, 0], s.support * tan[r, leg, 1]
        s.support_force[leg, 0], s.support_force[leg, 1] = sx, sz
        foot_kinematics(s, leg, q[2 * leg], q[2 * leg + 1], 0.0, 0.0, kin)
        s.tau_path[2 * leg] = kin[4] * (fx + sx) + kin[5] * (fz + sz)
        s.tau_path[2 * leg + 1] = kin[6] * (fx + sx) + kin[7] * (fz + sz)
    dr = f.drive[:]  # a plain array: steady_voltage has one signature (exo_ctrl/_jit.py)
    for j in range(4):  # the wall as the force loop's reference (module docstring)
        tau = f.tau_free[j] + (1.0 + f.force_gain[j]) * (s.tau_path[j] + s.tau_weight[j])
        s.u_cmd[j] = steady_voltage(tau, f.speed[j], dr)
    return 0
