"""The paper's gait planner (§III): foot paths synchronised with the belt.

Each foot point moves in the sagittal plane relative to its hip joint
(x forward, z up, metres).  One gait cycle of period T_s, for the left leg, in
phase time τ = mod(t, T_s):

========================  =====================  ==============================
phase                     τ                      foot path
========================  =====================  ==============================
swing, A → B              [0, T_sw/2)            cubic: x 0 → s/2, z -(H-h) → -H
stance, B → C → D         [T_sw/2, T_sw/2+T_st)  x = s/2 - v_f (τ - T_sw/2), z = -H
swing, D → A              [T_sw/2+T_st, T_s)     cubic: x -s/2 → 0, z -H → -(H-h)
========================  =====================  ==============================

with the stance time T_st = β T_s and swing time T_sw = (1 - β) T_s for a
duty factor β (stance fraction; the paper's four equal phases are β = 0.5).
The right leg runs the same path half a period later, so at t = 0 the left
foot is at the top of its swing (A) and the right foot at mid-stance (C).

Boundary conditions (paper §III): at A, x = 0, z = -(H_s - h_s), ẋ = v_b,
ż = 0; at B, x = s/2, z = -H_s, ẋ = -v_f, ż = 0; at D, x = -s/2, z = -H_s,
ẋ = -v_f, ż = 0.  The stance foot moves with the belt: ẋ = -v_f, so the belt
speed is v_f = s / (β T_s) (= 2 s / T_s for β = 0.5), and the top-of-swing
speed is v_b = v_f / k_v.  The paths are C¹ (positions and velocities
continuous; accelerations jump at B and D).

**Hip excursion** (beyond the paper, for a pelvis free to move vertically).
With e = ``pelvis_excursion`` > 0 the hip rises and falls over the cycle as in
normal gait: its height above the belt is H(t) = H_s + ΔH(φ), φ = t / T_s,

    ΔH = (e/2) cos(4π φ),   ΔḢ = -(e/2) ω sin(4π φ),   ΔḦ = -(e/2) ω² cos(4π φ),

ω = 4π / T_s.  Peak to peak e, mean H_s; highest at both mid-stances (φ = 0:
the right foot's, φ = ½: the left's, for any β), lowest at φ = ¼ and ¾, the
middle of each support transfer.  Each foot's path relative to the hip is
the path above with z - ΔH (ż - ΔḢ, z̈ - ΔḦ): relative to the belt it is
unchanged (stance on the belt line, the same lift), x is unchanged, and it
stays C¹ (ΔH is smooth).  The stance leg is then H_s + e/2 long at
mid-stance: the knee extends there.  ΔH has period T_s / 2, so both legs see
the same hip and a plan of one period still repeats.  e = 0 (default) is the
paper's fixed hip, bit for bit.  Sources: the hip's vertical motion in adult
walking is mostly the second harmonic of the cycle, one rise per step
(Ivanenko et al. 2004, J. Exp. Biol. 207:3797-3810, Fig. 2); its size, about
4-5 cm peak to peak for the body's centre of mass, is the gait literature's
usual figure (measured against speed by Gard, Miff & Kuo 2004, Hum. Mov.
Sci. 22:597-610).

**Landing approach** (beyond the paper; ``landing_speed_mps`` v_a > 0): the
swing foot crosses the belt line at v_a through touchdown instead of landing
at zero speed, moving with the belt along it over the approach
(:mod:`exo_ctrl.plan.landing`).

Each cubic segment q(τ) = Σ k_i τ^i meets (q0, q1, q̇0, q̇1) at its ends; the
paper writes the coefficients as the inverse of its 4×4 matrix applied to
those values.  Here each segment is evaluated in local time u = τ - τ0 ∈ [0, d],
where that inverse has the closed form
k0 = q0, k1 = q̇0, k2 = (3Δ - (2 q̇0 + q̇1) d) / d², k3 = (-2Δ + (q̇0 + q̇1) d) / d³,
Δ = q1 - q0.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .. import _validate as v
from ..exceptions import InvalidParameter, UnreachableFootTarget
from .landing import approach, checked, press, swing_end
from .loading import StanceSink, sink_samples

__all__ = ["MIN_PERIOD_S", "FootTrajectory", "GaitParams", "GaitPlan"]

#: Smallest knee flexion the plan may ask for [rad]; a straighter knee is
#: close to the kinematic singularity, where joint speeds blow up.
MIN_KNEE_FLEXION_RAD = 0.1


#: The shortest gait period the planner takes [s].
MIN_PERIOD_S = 0.1
#: The longest gait period the planner takes [s]: a cycle's sizes grow with it
#: (the cuff-load monitor's window of one period at the control rate: 29.8 GiB
#: at 1e7 s; the plan's cubic pieces overflow near 1e200 s).
MAX_PERIOD_S = 100.0

#: The smallest shape coefficient k_v the planner takes (at 1e-3 the default
#: gait's swing foot would run 26 m behind the hip: refused by reach).
MIN_SHAPE_COEFF = 1e-3


@dataclass(frozen=True)
class GaitParams:
    """Gait parameter vector s̄ = (s, h_s, H_s, k_v, T_s) of the paper, plus β.

    Attributes:
        step_length: s, distance the foot travels on the belt per stance [m].
        lift_height: h_s, foot lift at the top of the swing [m].
        hip_height: H_s, height of the hip joint above the belt [m].
        shape_coeff: k_v = v_f / v_b, belt speed over top-of-swing speed [-].
        period: T_s, duration of one gait cycle (one step of each leg) [s].
        duty_factor: β, fraction of the period a foot is on the belt [-];
            0.5 is the paper's schedule, above 0.5 gives double support.
        pelvis_excursion: e, the hip's peak-to-peak vertical excursion over the
            cycle [m] (module docstring; beyond the paper, for a pelvis free
            to move vertically; about 4-5 cm in normal gait); 0: the paper's
            fixed hip.  Below 2 (H_s - h_s), so that the lifted swing foot
            stays below the hip when the hip is lowest; whether the leg
            reaches the path is :meth:`GaitPlan.check_reach`'s question.
        landing_speed_mps: v_a, the landing approach's constant downward speed
            through touchdown [m/s], the foot moving with the belt along it
            over the approach (:mod:`exo_ctrl.plan.landing`; beyond the
            paper); 0: the paper's landing at zero speed, bit for bit.
        landing_depth_m: a, how far above and below the belt line the
            approach runs at v_a [m] (used with v_a > 0; capped by the
            swing's and the stance's durations).

    Raises:
        InvalidParameter: a value that is not finite or outside its range.

    """

    step_length: float = 0.35
    lift_height: float = 0.10
    hip_height: float = 0.90
    shape_coeff: float = 0.5
    period: float = 1.2
    duty_factor: float = 0.5
    pelvis_excursion: float = 0.0
    landing_speed_mps: float = 0.0
    landing_depth_m: float = 0.0012

    def __post_init__(self) -> None:
        for name, unit in (
            ("step_length", "m"),
            ("lift_height", "m"),
            ("hip_height", "m"),
            ("shape_coeff", ""),
            ("period", "s"),
        ):
            object.__setattr__(self, name, v.positive(name, getattr(self, name), unit))
        for name in ("step_length", "lift_height", "hip_height"):
            if getattr(self, name) > 10.0:  # a sanity bound, as BodyParams' link lengths
                raise InvalidParameter(name, getattr(self, name), "in (0, 10] m")
        if self.shape_coeff < MIN_SHAPE_COEFF:
            raise InvalidParameter(
                "shape_coeff",
                self.shape_coeff,
                f">= {MIN_SHAPE_COEFF:g}",
                "below it the swing foot's path runs metres behind the hip, "
                "and tends to NaN as k_v goes to 0",
            )
        if self.period < MIN_PERIOD_S:
            raise InvalidParameter(
                "period",
                self.period,
                f">= {MIN_PERIOD_S:g} s",
                "ten gait cycles a second is no gait, and the plan's cubic pieces need "
                "durations whose squares do not underflow",
            )
        if self.period > MAX_PERIOD_S:
            raise InvalidParameter(
                "period",
                self.period,
                f"<= {MAX_PERIOD_S:g} s",
                "one gait cycle sizes the plan and the monitors' windows: a longer one "
                "would not fit in memory, or overflow",
            )
        d = v.finite("duty_factor", self.duty_factor)
        if not 0.5 <= d < 1.0:
            raise InvalidParameter("duty_factor", self.duty_factor, "in [0.5, 1)")
        object.__setattr__(self, "duty_factor", d)
        if self.lift_height >= self.hip_height:
            raise InvalidParameter(
                "lift_height",
                self.lift_height,
                f"< hip_height = {self.hip_height:g} m",
                "the foot would rise to the hip",
            )
        e = v.non_negative("pelvis_excursion", self.pelvis_excursion, "m")
        object.__setattr__(self, "pelvis_excursion", e)
        room = 2.0 * (self.hip_height - self.lift_height)
        if e >= room:
            raise InvalidParameter(
                "pelvis_excursion",
                self.pelvis_excursion,
                f"< 2 (hip_height - lift_height) = {room:g} m",
                "the lifted swing foot would rise to the hip when the hip is at its lowest, "
                "H_s - e/2",
            )
        speed, depth = checked(self.landing_speed_mps, self.landing_depth_m, self.lift_height)
        object.__setattr__(self, "landing_speed_mps", speed)
        object.__setattr__(self, "landing_depth_m", depth)

    @property
    def belt_speed(self) -> float:
        """v_f: belt speed, equal to the stance foot's backward speed [m/s]."""
        return self.step_length / (self.duty_factor * self.period)

    @property
    def swing_top_speed(self) -> float:
        """v_b = v_f / k_v: forward foot speed at the top of the swing [m/s]."""
        return self.belt_speed / self.shape_coeff

    @property
    def stance_time(self) -> float:
        """T_st = β T_s [s]."""
        return self.duty_factor * self.period

    @property
    def swing_time(self) -> float:
        """T_sw = (1 - β) T_s [s]."""
        return (1.0 - self.duty_factor) * self.period


@dataclass(frozen=True)
class FootTrajectory:
    """Foot motion of both legs relative to their hips, sampled at times ``t``.

    Arrays have shape (N, 2, 2): sample, leg (0 left, 1 right), axis (0 x, 1 z).

    Attributes:
        t: sample times [s], shape (N,).
        pos: foot position [m].
        vel: foot velocity [m/s].
        acc: foot acceleration [m/s²].
        stance: True where the foot is on the belt, shape (N, 2).

    """

    t: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    stance: np.ndarray


class GaitPlan:
    """Analytic foot paths of both legs for a :class:`GaitParams`.

    Args:
        params: the gait.
        sink: the stance feet's loading sink (:mod:`exo_ctrl.plan.loading`;
            with a supported pelvis and double support, β > ½); None: the
            stance foot on the belt line (the paper's).

    """

    def __init__(self, params: GaitParams, sink: StanceSink | None = None) -> None:
        self.params = params
        self.sink = sink if sink is not None and params.duty_factor > 0.5 else None
        p = params
        half_swing = p.swing_time / 2.0
        self._half_swing = half_swing
        self._stance_end = half_swing + p.stance_time
        vf, vb, s, H, h = (
            p.belt_speed,
            p.swing_top_speed,
            p.step_length,
            p.hip_height,
            p.lift_height,
        )
        # (segment start τ0, duration d, x0, x1, ẋ0, ẋ1, z0, z1) for A→B and D→A.
        # the landing approach's last t_a of A -> B moves with the belt (exo_ctrl.plan.landing)
        self._t_a = approach(p.landing_speed_mps, p.landing_depth_m, half_swing, p.stance_time)[0]
        t_a = self._t_a
        self._ab = _Cubic2(half_swing - t_a, 0.0, s / 2 + vf * t_a, vb, -vf, -(H - h), -H)
        self._da = _Cubic2(half_swing, -s / 2, 0.0, -vf, vb, -H, -(H - h))

    # ------------------------------------------------------------------ evaluation

    def feet(self, t: np.ndarray | float) -> FootTrajectory:
        """Positions, velocities and accelerations of both feet at times ``t`` [s]."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if not np.all(np.isfinite(t)):
            bad = t[~np.isfinite(t)][0]
            raise InvalidParameter("t", float(bad), "finite (times in s)")
        n = t.shape[0]
        pos = np.empty((n, 2, 2))
        vel = np.empty((n, 2, 2))
        acc = np.empty((n, 2, 2))
        stance = np.empty((n, 2), dtype=bool)
        for leg, offset in enumerate((0.0, 0.5 * self.params.period)):
            tau = np.mod(t + offset, self.params.period)
            pos[:, leg], vel[:, leg], acc[:, leg], stance[:, leg] = self._leg(tau)
        if self.params.pelvis_excursion > 0.0:  # relative to the moving hip: z - ΔH
            for rows, d in zip((pos, vel, acc), self.hip(t), strict=True):
                rows[:, :, 1] -= d[:, None]
        if self.sink is not None:  # into the belt by the load's sink: z - Δs
            for leg, rows in enumerate(self.sinks(t)):
                pos[:, leg, 1] -= rows[:, 0]
                vel[:, leg, 1] -= rows[:, 1]
                acc[:, leg, 1] -= rows[:, 2]
        return FootTrajectory(t=t, pos=pos, vel=vel, acc=acc, stance=stance)

    def hip(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The hip's planned rise above H_s: ΔH [m], ΔḢ [m/s], ΔḦ [m/s²] at times ``t`` [s].

        ΔH = (e/2) cos(4π φ), φ = mod(t, T_s) / T_s (module docstring); zeros
        for e = 0.
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        p = self.params
        half, omega = 0.5 * p.pelvis_excursion, 4.0 * np.pi / p.period
        arg = omega * np.mod(t, p.period)
        c, s = np.cos(arg), np.sin(arg)
        return half * c, -half * omega * s, -half * omega * omega * c

    def since_lift_off(self, t: np.ndarray | float) -> np.ndarray:
        """Each leg's time since its planned lift-off (D) while it swings [s], (N, 2).

        u = τ − τ_D in the swing D → A and u = τ + T_s − τ_D in A → B (τ the
        leg's phase time, τ_D = T_sw/2 + T_st); +inf in stance.  At t = 0 the
        left leg is at A, so its first swing reads as if it had lifted off
        T_sw/2 before.  What the controllers need to blend the swing leg's
        acceleration feedforward in (:mod:`exo_ctrl.control.lift_off`).
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        p = self.params
        out = np.full((t.shape[0], 2), np.inf)
        for leg, offset in enumerate((0.0, 0.5 * p.period)):
            tau = np.mod(t + offset, p.period)
            late, early = tau >= self._stance_end, tau < self._half_swing
            out[late, leg] = tau[late] - self._stance_end
            out[early, leg] = tau[early] + p.period - self._stance_end
        return out

    def sinks(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each leg's planned sink Δs [m] and its rates [m/s, m/s²] at ``t``, (N, 3) each.

        Zeros without a :class:`~exo_ctrl.plan.loading.StanceSink`.
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        p = self.params
        out = (np.zeros((t.shape[0], 3)), np.zeros((t.shape[0], 3)))
        if self.sink is None:
            return out
        params = self.sink.kernel_params()
        hip = np.mod(t, p.period) / p.period
        for leg, offset in enumerate((0.0, 0.5 * p.period)):
            tau = np.mod(t + offset, p.period) / p.period
            rate = 1.0 / p.period
            sink_samples(params, tau, hip, p.duty_factor, rate, p.pelvis_excursion, out[leg])
        return out

    def _leg(self, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        p = self.params
        vf, s, H = p.belt_speed, p.step_length, p.hip_height
        n = tau.shape[0]
        pos = np.empty((n, 2))
        vel = np.empty((n, 2))
        acc = np.zeros((n, 2))
        ab = tau < self._half_swing
        st = (~ab) & (tau < self._stance_end)
        da = ~(ab | st)
        pos[ab], vel[ab], acc[ab] = self._ab(tau[ab])
        pos[da], vel[da], acc[da] = self._da(tau[da] - self._stance_end)
        u = tau[st] - self._half_swing
        pos[st, 0] = s / 2 - vf * u
        pos[st, 1] = -H
        vel[st, 0] = -vf
        vel[st, 1] = 0.0
        t_a = self._t_a
        if t_a > 0.0:  # the landing approach (exo_ctrl.plan.landing): A -> B's end, the press
            z, dz, ddz = swing_end(
                tau[ab], self._half_swing, p.lift_height, t_a, p.landing_speed_mps
            )
            pos[ab, 1], vel[ab, 1], acc[ab, 1] = z - H, dz, ddz
            late = ab & (tau >= self._half_swing - t_a)  # x with the belt
            pos[late, 0] = s / 2 - vf * (tau[late] - self._half_swing)
            vel[late, 0], acc[late, 0] = -vf, 0.0
            z, dz, ddz = press(u, t_a, p.landing_speed_mps)
            pos[st, 1], vel[st, 1], acc[st, 1] = z - H, dz, ddz
        return pos, vel, acc, st

    # ------------------------------------------------------------------ validation

    def check_reach(self, thigh_length: float, shank_length: float, side: str = "left") -> None:
        """Raise if any path point is out of reach.

        The path is sampled densely (4096 points per period, phase boundaries
        and the hip's extremes included).  A point is reachable if its
        distance r from the hip satisfies |l1 - l2| ≤ r ≤ r_max, where
        r_max = sqrt(l1² + l2² + 2 l1 l2 cos θ_min) is the hip-to-foot
        distance with the knee flexed by θ_min = :data:`MIN_KNEE_FLEXION_RAD`
        (a nearly straight knee is singular).  Both legs follow the same path,
        so checking one leg's path against its lengths suffices.

        Args:
            thigh_length: l1 [m].
            shank_length: l2 [m].
            side: leg named in the message.

        Raises:
            InvalidParameter: ``pelvis_excursion``, when the path with the hip
                fixed (e = 0) is reachable but the moving hip's is not; it
                names the largest e the leg reaches (the set of reachable e
                is an interval [0, e_max]: each point's |z| is monotone in e).
            UnreachableFootTarget: a point of the path out of reach otherwise.

        """
        error = self._reach_error(thigh_length, shank_length, side)
        if error is None:
            return
        p = self.params
        if p.pelvis_excursion > 0.0:
            fixed = GaitPlan(dataclasses.replace(p, pelvis_excursion=0.0), self.sink)
            if fixed._reach_error(thigh_length, shank_length, side) is None:
                lo, hi = 0.0, p.pelvis_excursion
                while hi - lo > 1e-6:
                    mid = 0.5 * (lo + hi)
                    trial = GaitPlan(dataclasses.replace(p, pelvis_excursion=mid), self.sink)
                    if trial._reach_error(thigh_length, shank_length, side) is None:
                        lo = mid
                    else:
                        hi = mid
                raise InvalidParameter(
                    "pelvis_excursion",
                    p.pelvis_excursion,
                    f"at most {math.floor(lo * 1e4) / 1e4:g} m for this gait and a "
                    f"{thigh_length:.4g} m + {shank_length:.4g} m leg",
                    str(error),
                )
        raise error

    def _reach_error(self, l1: float, l2: float, side: str) -> UnreachableFootTarget | None:
        """The :meth:`check_reach` error of the worst out-of-reach point, or None."""
        r_min = abs(l1 - l2)
        r_max = float(np.sqrt(l1**2 + l2**2 + 2 * l1 * l2 * np.cos(MIN_KNEE_FLEXION_RAD)))
        period = self.params.period
        t = np.linspace(0.0, period, 4097)
        t = np.union1d(t, [self._half_swing, self._stance_end, *(period * np.arange(1, 4) / 4)])
        feet = self.feet(t)
        r = np.hypot(feet.pos[:, 0, 0], feet.pos[:, 0, 1])
        bad = np.flatnonzero((r > r_max) | (r < r_min))
        if not bad.size:
            return None
        i = bad[np.argmax(np.maximum(r[bad] - r_max, r_min - r[bad]))]
        x, z = feet.pos[i, 0]
        p = self.params
        return UnreachableFootTarget(
            (float(x), float(z)),
            (r_min, r_max),
            time=float(t[i]),
            what=f"{side} foot path point",
            cause=f"set by step_length = {p.step_length:g} m, hip_height = {p.hip_height:g} m, "
            f"lift_height = {p.lift_height:g} m, pelvis_excursion = {p.pelvis_excursion:g} m, "
            f"shape_coeff = {p.shape_coeff:g}",
        )


class _Cubic2:
    """A cubic Hermite segment in x and z over local time u ∈ [0, d]."""

    def __init__(
        self, d: float, x0: float, x1: float, dx0: float, dx1: float, z0: float, z1: float
    ) -> None:
        self.d = d
        self.kx = _hermite(d, x0, x1, dx0, dx1)
        self.kz = _hermite(d, z0, z1, 0.0, 0.0)

    def __call__(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        pos = np.empty((u.shape[0], 2))
        vel = np.empty_like(pos)
        acc = np.empty_like(pos)
        for axis, k in enumerate((self.kx, self.kz)):
            pos[:, axis] = k[0] + u * (k[1] + u * (k[2] + u * k[3]))
            vel[:, axis] = k[1] + u * (2 * k[2] + 3 * k[3] * u)
            acc[:, axis] = 2 * k[2] + 6 * k[3] * u
        return pos, vel, acc


def _hermite(d: float, q0: float, q1: float, dq0: float, dq1: float) -> tuple[float, ...]:
    """Coefficients (k0..k3) of the cubic on [0, d] meeting (q0, q1, q̇0, q̇1)."""
    delta = q1 - q0
    return (
        q0,
        dq0,
        (3 * delta - (2 * dq0 + dq1) * d) / d**2,
        (-2 * delta + (dq0 + dq1) * d) / d**3,
    )
