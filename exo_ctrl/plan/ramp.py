r"""A bumpless start and stop: the gait ramped in from standing, and out to it.

A session starts with the device standing: both feet on the belt line under
the hips, p₀ = (0, -H_s) relative to each hip, everything at rest.  The gait
then grows out of that posture over the ramp-in time T_r, and an optional
ramp-out over the last T_o seconds brings it back to standing at the end
time t_e.  With the quintic smoothstep (u clipped to [0, 1])

.. math::

    S(u) = 10u^3 - 15u^4 + 6u^5, \quad S'(u) = 30u^2(1-u)^2, \quad
    S''(u) = 60u(1-u)(1-2u),

which has S(0) = 0, S(1) = 1 and S', S'' zero at both ends, the ramp factor
is

.. math::

    σ(t) = S(t / T_r)\,S((t_e - t) / T_o)

(a factor is 1 without its ramp), and each foot follows

.. math::

    p_r = p_0 + σ (p - p_0), \quad
    \dot p_r = \dot σ (p - p_0) + σ \dot p, \quad
    \ddot p_r = \ddot σ (p - p_0) + 2 \dot σ \dot p + σ \ddot p,

p(t) being the gait's own path (:class:`~exo_ctrl.plan.gait.GaitPlan`),
relative to the hip.  With a hip excursion (``pelvis_excursion`` e > 0) p
holds z - ΔH, so the ramp scales the hip's rise and fall by the same σ: the
hip is planned at H_s + σ ΔH (:meth:`RampedGait.hip`), at H_s and at rest
at t = 0, its rates continuous, and a stance foot stays on the belt line
(z_r + σ ΔH = -H_s).

Properties (tests/plan/test_ramp.py checks each):

- at t = 0: p_r = p₀ and ṗ_r = p̈_r = 0 (σ = σ̇ = σ̈ = 0): standing at rest;
- σ is C² and equals 1 with σ̇ = σ̈ = 0 from T_r to t_e - T_o: the ramp adds
  no discontinuity of its own; where the gait's acceleration jumps (B and D,
  its paths are C¹ only) the ramped one jumps by σ times as much;
- a stance foot (z = -H_s - σ ΔH) stays on the belt line, and the lift at the top of
  the swing is σ h_s; the step length grows as σ s;
- after the ramp-in the path is the gait's, bit for bit (samples with σ = 1
  are the gait's own numbers).

The belt speed the plan assumes is σ(t) v_f (:meth:`RampedGait.belt_speed_at`).
During a ramp a stance foot moves at σ̇ x - σ v_f relative to its hip: it
slides on the belt by σ̇ x, at most (15 / 8) (s / 2) / T_r (0.27 m/s for the
default gait and a 1.2 s ramp).  No choice of one belt speed removes it:
a step that grows during its stance cannot keep the foot still on the belt.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import _validate as v
from ..exceptions import InvalidParameter, UnreachableFootTarget
from .gait import MIN_KNEE_FLEXION_RAD, FootTrajectory, GaitParams, GaitPlan

__all__ = ["MIN_RAMP_S", "Ramp", "RampedGait", "ramp_time", "smoothstep"]


def smoothstep(u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """S(u), S'(u), S''(u) of the module docstring, u clipped to [0, 1] (derivatives 0 outside)."""
    u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
    w = 1.0 - u
    return (
        u**3 * (10.0 - 15.0 * u + 6.0 * u * u),
        30.0 * (u * w) ** 2,
        60.0 * u * w * (1.0 - 2.0 * u),
    )


#: The shortest ramp other than none [s]: the ramp's shape goes as 1/T_r and
#: (t/T_r)^n, which overflow for T_r near 1e-300 s (NaN commands).
MIN_RAMP_S = 1e-6


def ramp_time(name: str, value: float) -> float:
    """A ramp time [s]: 0 (no ramp) or a finite time >= :data:`MIN_RAMP_S`.

    Raises:
        InvalidParameter: naming ``name``.

    """
    t = v.non_negative(name, value, "s")
    if 0.0 < t < MIN_RAMP_S:
        raise InvalidParameter(
            name, value, f"0 (no ramp) or at least {MIN_RAMP_S:g} s", "a shorter ramp overflows"
        )
    return t


@dataclass(frozen=True)
class Ramp:
    """When the gait ramps in from standing and out to it.

    Attributes:
        ramp_in_s: T_r, the ramp-in time from t = 0 [s]; 0: the run starts on
            the gait at speed.  Without a ramp-out it may outlast ``end_s``
            (a plan that ends within its ramp-in).
        ramp_out_s: T_o, the ramp-out time before ``end_s`` [s]; 0: none.
        end_s: t_e, the time the ramp-out ends, standing [s] (the run's
            duration); needed only with a ramp-out.

    Raises:
        InvalidParameter: a time that is not a finite number >= 0, a ramp-out
            longer than ``end_s``, or a ramp-in that overlaps the ramp-out.

    """

    ramp_in_s: float = 0.0
    ramp_out_s: float = 0.0
    end_s: float = float("inf")

    def __post_init__(self) -> None:
        t_in = ramp_time("ramp_in", self.ramp_in_s)
        t_out = ramp_time("ramp_out", self.ramp_out_s)
        end = float(self.end_s)
        if not end > 0.0:
            raise InvalidParameter("end", self.end_s, "> 0 s")
        object.__setattr__(self, "ramp_in_s", t_in)
        object.__setattr__(self, "ramp_out_s", t_out)
        object.__setattr__(self, "end_s", end)
        if t_out > 0.0 and not np.isfinite(end):
            raise InvalidParameter("end", self.end_s, "a finite time [s] with a ramp-out")
        if t_out > end:
            raise InvalidParameter(
                "ramp_out", t_out, f"at most {end:g} s, within the run", f"the run lasts {end:g} s"
            )
        if t_out > 0.0 and t_in + t_out > end:
            raise InvalidParameter(
                "ramp_in",
                t_in,
                f"at most {end - t_out:g} s, within the run",
                f"the run lasts {end:g} s"
                + (f", of which the ramp-out takes the last {t_out:g} s" if t_out else ""),
            )

    @property
    def out_start_s(self) -> float:
        """t_e - T_o: when the ramp-out begins [s] (inf: never)."""
        return self.end_s - self.ramp_out_s if self.ramp_out_s > 0.0 else float("inf")

    def factor(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """σ(t), σ̇(t) [1/s], σ̈(t) [1/s²] of the module docstring at times ``t`` [s]."""
        t = np.asarray(t, dtype=float)
        s = np.ones_like(t)
        ds = np.zeros_like(t)
        dds = np.zeros_like(t)
        if self.ramp_in_s > 0.0:
            k = 1.0 / self.ramp_in_s
            s, d1, d2 = smoothstep(t * k)
            ds, dds = d1 * k, d2 * k * k
        if self.ramp_out_s > 0.0:
            k = 1.0 / self.ramp_out_s
            o, d1, d2 = smoothstep((self.end_s - t) * k)
            d1, d2 = -d1 * k, d2 * k * k  # d/dt of S((t_e - t) / T_o)
            s, ds, dds = s * o, ds * o + s * d1, dds * o + 2.0 * ds * d1 + s * d2
        return s, ds, dds


class RampedGait:
    """A :class:`~exo_ctrl.plan.gait.GaitPlan` ramped in from standing and out to it.

    It plans like the gait it wraps (:meth:`feet`, :meth:`check_reach`,
    ``params``), so :func:`~exo_ctrl.plan.kinematics.plan_joints` takes either.

    Args:
        gait: the gait.
        ramp: the ramps (default: none, the gait itself).

    """

    def __init__(self, gait: GaitPlan | GaitParams, ramp: Ramp | None = None) -> None:
        self.gait = gait if isinstance(gait, GaitPlan) else GaitPlan(gait)
        self.params = self.gait.params
        self.ramp = ramp if ramp is not None else Ramp()
        #: p₀, the standing foot point relative to each hip, (x, z) [m].
        self.standing_point = np.array([0.0, -self.params.hip_height])

    def feet(self, t: np.ndarray | float) -> FootTrajectory:
        """The ramped paths of both feet at times ``t`` [s] (module docstring)."""
        base = self.gait.feet(t)
        s, ds, dds = self.ramp.factor(base.t)
        ramped = s < 1.0
        if not np.any(ramped):
            return base
        pos, vel, acc = base.pos.copy(), base.vel.copy(), base.acc.copy()
        p0 = self.standing_point
        s, ds, dds = (a[ramped, None, None] for a in (s, ds, dds))
        rel = base.pos[ramped] - p0
        pos[ramped] = p0 + s * rel
        vel[ramped] = ds * rel + s * base.vel[ramped]
        acc[ramped] = dds * rel + 2.0 * ds * base.vel[ramped] + s * base.acc[ramped]
        stance = base.stance.copy()
        above_belt = pos[ramped, :, 1]  # the foot's height above the belt, less H_s
        if self.params.pelvis_excursion > 0.0:
            above_belt = above_belt + s[:, :, 0] * self.gait.hip(base.t[ramped])[0][:, None]
        stance[ramped] |= np.isclose(above_belt, p0[1], rtol=0.0, atol=1e-12)
        return FootTrajectory(t=base.t, pos=pos, vel=vel, acc=acc, stance=stance)

    def hip(self, t: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The hip's planned rise above H_s, ramped: σ ΔH [m] and its rates [m/s, m/s²].

        (σ ΔH, σ̇ ΔH + σ ΔḢ, σ̈ ΔH + 2 σ̇ ΔḢ + σ ΔḦ) at times ``t`` [s], ΔH of
        :meth:`~exo_ctrl.plan.gait.GaitPlan.hip`.
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        h, dh, ddh = self.gait.hip(t)
        s, ds, dds = self.ramp.factor(t)
        return s * h, ds * h + s * dh, dds * h + 2.0 * ds * dh + s * ddh

    def since_lift_off(self, t: np.ndarray | float) -> np.ndarray:
        """The gait's :meth:`~exo_ctrl.plan.gait.GaitPlan.since_lift_off` [s], (N, 2).

        The ramps scale the path, not its timing: a foot lifts off when the
        gait's does.
        """
        return self.gait.since_lift_off(t)

    def belt_speed_at(self, t: np.ndarray | float) -> np.ndarray:
        """σ(t) v_f: the belt speed the plan assumes at times ``t`` [m/s]."""
        return self.ramp.factor(np.atleast_1d(np.asarray(t, dtype=float)))[0] * (
            self.params.belt_speed
        )

    def check_reach(self, thigh_length: float, shank_length: float, side: str = "left") -> None:
        """The gait's reach check, and the standing point's.

        Every ramped point lies on the segment from p₀ to a gait point; the
        reachable set r ≤ r_max is a disc, so the segment is inside it when
        both ends are.  The inner bound |l1 - l2| is checked on the ramped
        paths sampled densely (4096 points per ramp).

        Raises:
            UnreachableFootTarget: a gait point, p₀ or a ramped point out of reach.

        """
        self.gait.check_reach(thigh_length, shank_length, side)
        l1, l2 = thigh_length, shank_length
        r_max = float(np.sqrt(l1**2 + l2**2 + 2 * l1 * l2 * np.cos(MIN_KNEE_FLEXION_RAD)))
        r_min = abs(l1 - l2)
        r0 = float(np.hypot(*self.standing_point))
        if not r_min <= r0 <= r_max:
            raise UnreachableFootTarget(
                tuple(float(c) for c in self.standing_point),
                (r_min, r_max),
                time=0.0,
                what=f"{side} foot's standing point",
            )
        spans = []
        if self.ramp.ramp_in_s > 0.0:
            spans.append(np.linspace(0.0, self.ramp.ramp_in_s, 4097))
        if self.ramp.ramp_out_s > 0.0:
            spans.append(np.linspace(self.ramp.out_start_s, self.ramp.end_s, 4097))
        for t in spans:
            pos = self.feet(t).pos[:, 0]
            r = np.hypot(pos[:, 0], pos[:, 1])
            bad = np.flatnonzero(r < r_min)
            if bad.size:
                i = bad[np.argmin(r[bad])]
                raise UnreachableFootTarget(
                    (float(pos[i, 0]), float(pos[i, 1])),
                    (r_min, r_max),
                    time=float(t[i]),
                    what=f"{side} foot path point of the ramp",
                )
