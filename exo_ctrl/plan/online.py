r"""The gait generated tick by tick, synchronised with the measured belt speed.

The precomputed plan (:mod:`exo_ctrl.plan.gait`) assumes the belt runs at
v_f; when it slows under a foot's load, or a session changes its speed
(:mod:`exo_ctrl.plan.profile`), the stance foot of that plan slides.  This
generator plans each control tick from the belt encoder's reading v̂ and
writes the joint targets into a one-row plan that the controllers read
(row rule period 1: every tick reads row 0).

**Phase.**  One phase τ ∈ [0, 1) per cycle (left leg; the right leg τ + ½),
advanced at the rate r = 1 / T(v) of the adaptation law
(:mod:`exo_ctrl.plan.adapt`), v the session's set speed v(t) (the profile,
not ramped).  The cadence follows the commanded speed, which is smooth
(piecewise linear), not the encoder's reading, which is quantised
(3.8 mm/s) and dips at every touchdown: those dips are taken up by the
step length instead (below), where they cost nothing.  Segments as the
paper's: swing A → B on [0, τ_B), stance on [τ_B, τ_D), swing D → A on
[τ_D, 1), τ_B = (1 - β)/2, τ_D = (1 + β)/2.

**Stance foot** (x forward, relative to the hip): ẋ = -v_l, x integrated
from v_l = v̄ + (v_set − v̄_set): the measured speed v̂ low-passed to v̄ (time
constant τ_f = :data:`FILTER_S`) and the lag the same filter puts on the set
speed v_set = σ(t) v(t), added back (v̄_set: v_set low-passed alike; τ_f a
on a ramp of rate a, continuous where the profile's rate steps), z = -H_s.
It moves with the belt by construction; the filter keeps the encoder's
quantum (3.8 mm/s a count over its 10 ms window) out of the planned
velocity, and the lag it adds while the belt accelerates is cancelled as
far as the belt follows its set speed.  Without
that term the stance feet of the position-controlled legs, 20 ms behind a
belt ramping up under 50 % body-weight support, held it back with 50–90 N,
the belt's speed controller wound up and overshot the set speed by 18 %
after the ramp-in, and the first touchdowns landed at 0.70 m/s along the
belt (0.03 m/s with it; belt speed error RMS 0.047 → 0.019 m/s; measured
with computed torque, ``exo-ctrl simulate --controller ct --contact on
--pelvis supported --bws 0.5 --pelvis-excursion 0.05 --period 1.2 --cycles 3``).

**Swing foot, x**: a cubic re-solved every tick from the foot's present
(x, ẋ) to its segment's end point in the time the phase leaves: D → A ends
at the top (0, v_l / k_v), A → B at touchdown (L / 2, -v_l), with the step
L = v_l β T(v) the stance will cover at the measured speed (filtered: the
encoder's quantum would otherwise jolt the targets at the end of a segment,
where the cubic's curvature goes as 1 / d²).  Position and velocity carry over from the
present, so the paths are C¹ by construction; a cubic re-solved from a
point of itself to the same end is itself, so at a steady speed it is the
paper's path (k_v keeps its shape).  **Swing foot, z**: the paper's lift
cubic in phase, scaled by the ramp-in factor σ(t) (:mod:`exo_ctrl.plan.ramp`),
z = -H_s + σ Z(τ), with ż, z̈ by the chain rule through ṙ.

**Hip excursion** (``pelvis_excursion`` e > 0, :mod:`exo_ctrl.plan.gait`): the
hip rises by ΔH(τ) = (e/2) cos(4π τ) at the phase τ (highest at both
mid-stances, lowest at the support transfers), ramped in by the same σ, and
each foot's z relative to the hip is z = -H_s + σ (Z(τ) - ΔH(τ)), its rates
by the same chain rule (dτ/dt = r = 1 / T(t)).  The foot's path relative to
the belt is unchanged.  The planned rise σ ΔH and its rates are the record's
``hip`` (:meth:`OnlineGait.hip`).

**Start.**  At t = 0 the left foot is at A, the right at mid-stance, both
at x = 0.  With a ramp-in the belt starts at rest and the step L = v̄ β T
grows with the belt's speed: the gait ramps in with the belt and no foot
slides (the precomputed ramp's stance feet slide up to 0.27 m/s).

**Loading sink** (a supported pelvis with double support,
:mod:`exo_ctrl.plan.loading`): each foot's z relative to the hip also
subtracts its planned sink Δs(τ) at the rate r, z = -H_s + σ (Z - ΔH - Δs),
through the same chain rule.

**Landing approach** (``landing_speed_mps`` > 0, :mod:`exo_ctrl.plan.landing`):
the lift Z ends A → B with the constant-speed descent and the stance adds the
press, both in phase at the reference gait's rate, relative to the belt's surface as
the stance foot measures it (:mod:`exo_ctrl.plan.surface`).  **Inverse kinematics**:
the closed form of :mod:`exo_ctrl.plan.kinematics`, in the same compiled kernel.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import Status, kernel, leaf, record
from ..exceptions import InvalidParameter, SimulationDiverged
from ..model import SIDES, BodyModel
from ..model.leg_kernels import LEG_FIELDS, fill_legs
from .adapt import SpeedAdaptation
from .kinematics import JointTrajectory
from .landing import phase_constants, press_phase, swing_end_phase
from .loading import StanceSink, sink_phase
from .phase_curves import cubic, hip_rise, lift, phase_rate, ramp_factor
from .profile import SpeedProfile, profile_at
from .surface import surface_offsets

__all__ = [
    "FILTER_S",
    "FREEZE_S",
    "MAX_PROFILE_POINTS",
    "ONLINE_FIELDS",
    "OnlineGait",
    "write_plan",
]

#: Points of a speed profile the generator holds (its record's arrays).
MAX_PROFILE_POINTS = 256

#: Time constant of the low-pass on the measured belt speed [s].
FILTER_S = 0.02

#: The last time of a swing segment in which its end point is no longer
#: updated [s] (:func:`_swing`).
FREEZE_S = 0.02

#: No measurement (:meth:`OnlineGait.step`).
_NONE4 = np.full(4, np.nan)

#: Fields of the generator's record.  Parameters: ``dt`` [s], ``law`` (s_0,
#: v_0, a, s_max, β) (:meth:`~exo_ctrl.plan.adapt.SpeedAdaptation.kernel_params`),
#: ``kv``, ``H``, ``h`` [m], ``ramp_in`` T_r [s], ``filt`` [s], ``exc`` the hip
#: excursion e [m]; per leg ``l1``,
#: ``l2`` [m], ``s_h``, ``s_k``, ``phi1_0``, ``phi2_0``.  State: ``phase`` τ of
#: each leg (the right leg's τ + ½), ``rate`` r [1/s], ``vbar`` v̄ [m/s], ``vset_bar``
#: the set speed low-passed alike and ``vlead`` v̄ + v_set − v̄_set, the speed planned
#: [m/s], ``a_set`` the set speed's rate [m/s²], ``w``
#: the touchdown point's speed [m/s], per
#: leg ``x``, ``dx``, ``ddx`` [m, m/s, m/s²], the swing's end ``xe``, ``dxe``
#: [m, m/s] and its segment ``seg`` (0 A → B, 2 D → A).  Diagnostics: ``fail_leg``,
#: ``fail_r`` [m] (an unreachable point).  The profile: ``n_prof`` points
#: ``prof_t`` [s], ``prof_v`` [m/s].  ``out``: row 0 of the plan, q, q̇, q̈, φ
#: (4 each), foot position and velocity (2 × 2 each), flat; ``hip``: the hip's
#: planned rise σ ΔH [m] and its rates [m/s, m/s²] at the same tick; ``sink``
#: the loading sink's parameters (:meth:`~exo_ctrl.plan.loading.StanceSink.kernel_params`)
#: and ``sink_on`` 1 when the stance feet are planned into the belt; ``lift``
#: each leg's time since its lift-off while it swings, +inf in stance [s]
#: (the plan's ``lift_off_s``); ``land`` the landing approach's duration [-]
#: and speed [m] in phase units (:func:`~exo_ctrl.plan.landing.phase_constants`;
#: 0, 0 without one); ``eps`` each swing's surface offset ε [m] and ``surf`` the
#: offset added to its z [m, m/s, m/s²], ``held`` 1 once it bears load (plan/surface.py).
ONLINE_FIELDS = [
    ("dt", np.float64),
    ("law", np.float64, (5,)),
    *((name, np.float64) for name in ("kv", "H", "h", "ramp_in", "filt", "exc")),
    *LEG_FIELDS,
    ("phase", np.float64, (2,)),
    *((name, np.float64) for name in ("rate", "vbar", "vset_bar", "vlead", "a_set", "w")),
    *((name, np.float64, (2,)) for name in ("x", "dx", "ddx", "xe", "dxe")),
    ("seg", np.int64, (2,)),
    ("fail_leg", np.int64),
    ("fail_r", np.float64),
    ("n_prof", np.int64),
    ("prof_t", np.float64, (MAX_PROFILE_POINTS,)),
    ("prof_v", np.float64, (MAX_PROFILE_POINTS,)),
    ("out", np.float64, (24,)),
    ("hip", np.float64, (3,)),
    ("sink", np.float64, (5,)),
    ("sink_on", np.int64),
    ("lift", np.float64, (2,)),
    *((name, np.float64, (2,)) for name in ("land", "eps")),
    ("surf", np.float64, (2, 3)),
    ("held", np.int64, (2,)),
]


class OnlineGait:
    """The synchronised gait generator (module docstring) and its one-row plan.

    Args:
        law: step length and period for a speed (:class:`~exo_ctrl.plan.adapt.SpeedAdaptation`).
        profile: the session's set speed (None: the law's reference speed throughout).
        body: the model whose legs' geometry the inverse kinematics uses
            (the device's exoskeleton model).
        dt: control period Δt [s].
        ramp_in_s: T_r of the lift's ramp-in [s] (0: none).
        sink: the stance feet's loading sink (:mod:`exo_ctrl.plan.loading`;
            used with double support, β > ½); None: on the belt line.
        start: False: row 0 stays zero until :meth:`start` (the compile helper's build).

    Attributes:
        plan: the one-row plan the controllers read (overwritten each tick).

    """

    def __init__(
        self,
        law: SpeedAdaptation,
        profile: SpeedProfile | None,
        body: BodyModel,
        dt: float,
        ramp_in_s: float = 0.0,
        sink: StanceSink | None = None,
        start: bool = True,
    ) -> None:
        self.law = law
        gait = law.reference
        self.profile = profile or SpeedProfile.constant(gait.belt_speed)
        times, speeds = self.profile.arrays()
        if times.size > MAX_PROFILE_POINTS:
            raise InvalidParameter(
                "speed_profile", self.profile.text(), f"at most {MAX_PROFILE_POINTS} points"
            )
        self.record = record(ONLINE_FIELDS)
        g = self.record[0]
        g["n_prof"] = times.size
        g["prof_t"][: times.size], g["prof_v"][: times.size] = times, speeds
        self._times, self._speeds = times, speeds
        g["dt"], g["law"] = float(dt), law.kernel_params()
        g["kv"], g["H"], g["h"] = gait.shape_coeff, gait.hip_height, gait.lift_height
        g["ramp_in"], g["filt"] = float(ramp_in_s), FILTER_S
        g["exc"] = gait.pelvis_excursion
        g["land"] = phase_constants(
            gait.landing_speed_mps, gait.landing_depth_m, gait.period, gait.duty_factor
        )
        if sink is not None and gait.duty_factor > 0.5:
            g["sink"], g["sink_on"] = sink.kernel_params(), 1
        fill_legs(g, body)
        out = self.record["out"][0]  # the plan's arrays are views of the record's row
        self.plan = JointTrajectory(
            t=np.zeros(1),
            q=out[0:4].reshape(1, 4),
            dq=out[4:8].reshape(1, 4),
            ddq=out[8:12].reshape(1, 4),
            phi=out[12:16].reshape(1, 4),
            foot_pos=out[16:20].reshape(1, 2, 2),
            foot_vel=out[20:24].reshape(1, 2, 2),
            period_ticks=1,
            hip=self.record["hip"][0].reshape(1, 3) if gait.pelvis_excursion > 0.0 else None,
            lift_off_s=self.record["lift"][0].reshape(1, 2),
        )
        if start:
            self.start(self.belt_speed(0.0)[0])

    def hip(self) -> tuple[float, float, float]:
        """The hip's planned rise σ ΔH [m] and its rates [m/s, m/s²] at the present tick."""
        h = self.record["hip"][0]
        return float(h[0]), float(h[1]), float(h[2])

    def belt_speed(self, t: float) -> tuple[float, float]:
        """The belt's set speed σ(t) v(t) [m/s] and its rate [m/s²] at time ``t`` [s]."""
        sig, dsig, _ = ramp_factor(t, float(self.record[0]["ramp_in"]))
        v, a = profile_at(self._times, self._speeds, t)
        return sig * v, dsig * v + sig * a

    def start(self, belt_speed_mps: float) -> None:
        """Row 0 at t = 0 with the belt at ``belt_speed_mps`` [m/s] (module docstring).

        Raises:
            SimulationDiverged: a foot point out of the leg's reach.

        """
        status = online_start(self.record, belt_speed_mps)
        self._check(status, 0.0)

    def step(
        self,
        k: int,
        belt_speed_mps: float,
        q_meas: np.ndarray | None = None,
        load_z_N: np.ndarray | None = None,
    ) -> None:
        """Advance to tick ``k`` ≥ 1 with the measured belt speed [m/s]; row 0 gets its targets.

        Tick 0 is the start (:meth:`start`): nothing to do.  ``q_meas`` [rad] (4,) and
        ``load_z_N`` [N] (2,): the encoders and the foot plates' vertical loads, for a
        landing approach planned against the measured surface (:mod:`exo_ctrl.plan.surface`);
        None: against the plan's.

        Raises:
            SimulationDiverged: a foot point out of the leg's reach.

        """
        q = _NONE4 if q_meas is None else np.asarray(q_meas, dtype=float)
        f = _NONE4[:2] if load_z_N is None else np.asarray(load_z_N, dtype=float)
        status = online_step(self.record, k, belt_speed_mps, q, f)
        if status:
            self._check(status, k * float(self.record[0]["dt"]))

    def _check(self, status: int, t: float) -> None:
        if status == Status.OK:
            return
        g = self.record[0]
        leg = int(g["fail_leg"])
        where = f"{SIDES[leg]} foot's planned distance from the hip [m]"
        reach = float(g["l1"][leg] + g["l2"][leg])
        raise SimulationDiverged(t, where, float(g["fail_r"]), reach)


# ---------------------------------------------------------------------- kernels


@kernel
def _write_hip(g, tau: float, r: float, dr: float, t: float) -> None:  # pragma: no cover
    """The record's ``hip``: σ ΔH and its time derivatives at phase τ, rate r and ṙ (docstring)."""
    if g.exc <= 0.0:
        return
    sig, dsig, ddsig = ramp_factor(t, g.ramp_in)
    h, h1, h2 = hip_rise(tau, g.exc)
    g.hip[0] = sig * h
    g.hip[1] = dsig * h + sig * h1 * r
    g.hip[2] = ddsig * h + 2.0 * dsig * h1 * r + sig * (h2 * r * r + h1 * dr)


@kernel
def _target(g, tau: float, r: float) -> tuple[float, float]:  # pragma: no cover - compiled
    """The end (x, ẋ) of the swing segment τ is in: top (0, v_l/k_v) or touchdown (L/2, -v_l)."""
    beta = g.law[4]
    if tau >= 0.5 * (1.0 + beta):
        return 0.0, g.vlead / g.kv
    return g.vlead * (0.5 * beta + g.land[0]) / r, -g.vlead  # the approach's start: L/2 + v_l t_a


@leaf
def _swing(g, leg: int, tau: float, r: float, d: float, u: float):  # pragma: no cover - compiled
    """(x, ẋ, ẍ) at ``u`` of the cubic from the leg's (x, ẋ) to its segment's end in ``d`` s.

    The end point is the target now moved on at its present speed w for the
    ``d`` seconds left (the touchdown point moves while the step grows,
    L = v_l β / r; w = ``g.w``), and its speed on at the set speed's rate
    a_set (the stance will take v_l then, not now), so that re-solving each
    tick does not chase it; in the last :data:`FREEZE_S` of a segment the
    end stays as it was (the cubic then is followed as solved: its curvature
    grows as 1 / d²).
    """
    seg = 0 if tau < 0.5 * (1.0 - g.law[4]) else 2
    if d > FREEZE_S or g.seg[leg] != seg:
        xt, dxt = _target(g, tau, r)
        if seg == 0:
            g.xe[leg] = xt + g.w * d
            g.dxe[leg] = dxt - g.a_set * d
        else:
            g.xe[leg] = xt
            g.dxe[leg] = dxt + g.a_set * d / g.kv
        g.seg[leg] = seg
    return cubic(g.x[leg], g.dx[leg], g.xe[leg], g.dxe[leg], d, u)


@kernel
def _advance(g, leg: int, tau: float, r: float, v: float, h: float) -> float:  # pragma: no cover
    """Move leg ``leg``'s x over ``h`` seconds of phase rate ``r`` from phase ``tau``; new τ."""
    beta = g.law[4]
    t_b, t_d = 0.5 * (1.0 - beta) - g.land[0], 0.5 * (1.0 + beta)  # x: the approach with the belt
    rem = h
    while rem > 0.0:
        end = t_b if tau < t_b else (t_d if tau < t_d else 1.0)
        d = (end - tau) / r
        stance = t_b <= tau < t_d
        if d > rem:  # the step ends inside the segment
            if stance:
                g.x[leg] -= v * rem
                g.dx[leg] = -v
            else:
                x, dx, ddx = _swing(g, leg, tau, r, d, rem)
                g.x[leg], g.dx[leg], g.ddx[leg] = x, dx, ddx
            return tau + rem * r
        if stance:
            g.x[leg] -= v * d
            g.dx[leg] = -v
        else:
            x, dx, ddx = _swing(g, leg, tau, r, d, d)
            g.x[leg], g.dx[leg], g.ddx[leg] = x, dx, ddx
        rem -= d
        tau = 0.0 if end >= 1.0 else end
    if not t_b <= tau < t_d:  # ended on a boundary into a swing: its cubic's acceleration
        end = t_b if tau < t_b else 1.0
        g.ddx[leg] = _swing(g, leg, tau, r, (end - tau) / r, 0.0)[2]
    return tau


@kernel
def _write_leg(g, leg, tau, r, dr, a_belt, t) -> int:  # pragma: no cover - compiled
    """The foot's acceleration, lift and the inverse kinematics into row 0; 0 or a status."""
    beta = g.law[4]
    half = 0.5 * (1.0 - beta)
    x, dx = g.x[leg], g.dx[leg]
    ddx = g.ddx[leg]  # swing: the acceleration of the cubic it followed, at its end
    if half - g.land[0] <= tau < 1.0 - half:  # with the belt: stance and the landing approach
        ddx = -a_belt
    if half <= tau < 1.0 - half:
        g.lift[leg] = math.inf
    else:  # the time since lift-off at τ_D = 1 − half, at the present rate
        g.lift[leg] = (tau - (1.0 - half) + (1.0 if tau < half else 0.0)) / r
    sig, dsig, ddsig = ramp_factor(t, g.ramp_in)
    zz, z1, z2 = lift(tau, half, g.h)
    if g.land[0] > 0.0 and tau < 1.0 - half:  # the landing approach (exo_ctrl.plan.landing)
        if tau < half:
            zz, z1, z2 = swing_end_phase(tau, half, g.h, g.land[0], g.land[1])
        else:
            zz, z1, z2 = press_phase(tau - half, g.land[0], g.land[1])
    if g.exc > 0.0:  # relative to the moving hip: Z - ΔH
        h, h1, h2 = hip_rise(g.phase[0], g.exc)  # one hip: the left leg's phase (ΔH has period ½)
        zz, z1, z2 = zz - h, z1 - h1, z2 - h2
    if g.sink_on:  # into the belt by the load's sink: Z - ΔH - Δs
        s0, s1, s2 = sink_phase(g.sink, tau, g.phase[0], beta, r, g.exc)
        zz, z1, z2 = zz - s0, z1 - s1, z2 - s2
    z = -g.H + sig * zz + g.surf[leg, 0]  # and the measured surface's offset (surface.py)
    dz = dsig * zz + sig * z1 * r + g.surf[leg, 1]
    ddz = ddsig * zz + 2.0 * dsig * z1 * r + sig * (z2 * r * r + z1 * dr) + g.surf[leg, 2]
    out = g.out
    out[16 + 2 * leg], out[17 + 2 * leg] = x, z
    out[20 + 2 * leg], out[21 + 2 * leg] = dx, dz
    l1, l2 = g.l1[leg], g.l2[leg]
    r2 = x * x + z * z
    dist = math.sqrt(r2)
    if not (abs(l1 - l2) < dist < l1 + l2):
        g.fail_leg = leg
        g.fail_r = dist
        return Status.DIVERGED.value
    cos_a = min(max((l1 * l1 - l2 * l2 + r2) / (2.0 * l1 * dist), -1.0), 1.0)
    cos_g = min(max((l1 * l1 + l2 * l2 - r2) / (2.0 * l1 * l2), -1.0), 1.0)
    p1 = math.atan2(z, x) + math.acos(cos_a)
    p2 = p1 - (math.pi - math.acos(cos_g))
    s1, c1, s2, c2 = math.sin(p1), math.cos(p1), math.sin(p2), math.cos(p2)
    det = l1 * l2 * (c1 * s2 - s1 * c2)
    d1 = (l2 * c2 * dx + l2 * s2 * dz) / det
    d2 = (-l1 * c1 * dx - l1 * s1 * dz) / det
    ax = ddx + l1 * c1 * d1 * d1 + l2 * c2 * d2 * d2
    az = ddz + l1 * s1 * d1 * d1 + l2 * s2 * d2 * d2
    a1 = (l2 * c2 * ax + l2 * s2 * az) / det
    a2 = (-l1 * c1 * ax - l1 * s1 * az) / det
    j = 2 * leg
    out[12 + j], out[13 + j] = p1, p2
    two_pi = 2.0 * math.pi
    out[j] = (math.pi - (math.pi - (p1 - g.phi1_0[leg])) % two_pi) / g.s_h[leg]
    rel = (p2 - p1) - (g.phi2_0[leg] - g.phi1_0[leg])
    out[j + 1] = (math.pi - (math.pi - rel) % two_pi) / g.s_k[leg]
    out[4 + j], out[5 + j] = d1 / g.s_h[leg], (d2 - d1) / g.s_k[leg]
    out[8 + j], out[9 + j] = a1 / g.s_h[leg], (a2 - a1) / g.s_k[leg]
    return Status.OK.value


@kernel
def online_start(state: np.ndarray, v0: float) -> int:  # pragma: no cover - compiled
    """Row 0 of t = 0 (module docstring), the belt at ``v0`` [m/s]; a :class:`Status` value."""
    g = state[0]
    n = g.n_prof
    v_ref, a_ref = profile_at(g.prof_t[:n], g.prof_v[:n], 0.0)
    r, dr = phase_rate(g.law, v_ref, a_ref)
    sig, dsig, _ = ramp_factor(0.0, g.ramp_in)
    g.rate, g.vbar, g.vlead = r, v0, v0
    g.vset_bar = sig * v_ref
    g.phase[0], g.phase[1] = 0.0, 0.5
    g.x[0], g.dx[0] = 0.0, v0 / g.kv
    g.x[1], g.dx[1] = 0.0, -v0
    a_belt = dsig * v_ref + sig * a_ref
    g.a_set = a_belt
    g.w = (0.5 * g.law[4] + g.land[0]) * (a_belt - v0 * dr / r) / r
    g.seg[0], g.seg[1] = -1, -1
    g.ddx[0] = _swing(g, 0, 0.0, r, (0.5 * (1.0 - g.law[4]) - g.land[0]) / r, 0.0)[2]
    _write_hip(g, 0.0, r, dr, 0.0)
    for leg in range(2):
        status = _write_leg(g, leg, g.phase[leg], r, dr, a_belt, 0.0)
        if status:
            return status
    return Status.OK.value


@kernel
def online_step(
    state: np.ndarray, k: int, v_meas: float, q_meas: np.ndarray, f_z: np.ndarray
) -> int:  # pragma: no cover - compiled
    """Advance from tick k - 1 to k with the measured speed ``v_meas`` [m/s]; row 0's targets.

    ``q_meas`` [rad] (4,), ``f_z`` [N] (2,): the encoders and the plates' vertical loads
    for the landing approach's surface (:mod:`exo_ctrl.plan.surface`; NaN: none).
    """
    if k <= 0:
        return Status.OK.value
    g = state[0]
    t = k * g.dt
    n = g.n_prof
    v_ref, a_ref = profile_at(g.prof_t[:n], g.prof_v[:n], t)
    r, dr = phase_rate(g.law, v_ref, a_ref)
    r_mid = 0.5 * (g.rate + r)
    g.vbar += (v_meas - g.vbar) * g.dt / (g.filt + g.dt)
    sig, dsig, _ = ramp_factor(t, g.ramp_in)
    v_set = sig * v_ref
    g.vset_bar += (v_set - g.vset_bar) * g.dt / (g.filt + g.dt)
    g.vlead = g.vbar + (v_set - g.vset_bar)  # the filter's lag on the set speed, added back
    a_belt = dsig * v_ref + sig * a_ref
    g.a_set = a_belt
    # d/dt of the touchdown point L/2 = v_l β / (2 r) (the landing approach's start,
    # L/2 + v_l t_a, t_a = land[0] / r), with v_l' the planned belt rate
    g.w = (0.5 * g.law[4] + g.land[0]) * (a_belt - g.vlead * dr / r) / r
    for leg in range(2):
        tau = _advance(g, leg, g.phase[leg], r_mid, g.vlead, g.dt)
        g.phase[leg] = 0.0 if tau >= 1.0 else tau
    g.rate = r
    surface_offsets(g, q_meas, f_z, r)
    _write_hip(g, g.phase[0], r, dr, t)
    for leg in range(2):
        status = _write_leg(g, leg, g.phase[leg], r, dr, a_belt, t)
        if status:
            return status
    return Status.OK.value


@kernel
def write_plan(log, row, generator):
    """The synchronised plan's q*, q̇* (``generator``: its record, ``out``) into log row ``row``."""
    r = log[row]
    o = generator[0].out
    for j in range(4):
        r.q_des[j] = o[j]
        r.dq_des[j] = o[4 + j]
