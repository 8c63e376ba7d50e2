r"""The landing approach: the swing foot's last millimetres at a small constant speed.

The paper's swing path lands with zero speed along a cubic, so near its
touchdown the foot's height above its landing point goes as 3 h_s (δ/d)² in
the time δ before it (d = T_sw/2): a foot ε lower than planned meets the belt
at 2 √(3 h_s ε) / d, 0.14 m/s for ε = 1 mm (docs/performance.md, "Touchdowns
under load").  The landing depends on tenths of a millimetre.  With a landing
approach of speed v_a > 0 (``GaitParams.landing_speed_mps``) and depth a
(``GaitParams.landing_depth_m``) the foot instead crosses the belt line at
constant speed v_a from a' above it to a' below it, so a foot up to a' off its
planned height meets the belt at v_a (the belt's and sole's compliance takes
the a' below), then comes back to its stance path:

- **swing end** (A → B, local time u ∈ [0, d], Z the height above the belt
  line): the lift cubic from (Z, Ż) = (h_s, 0) at u = 0 to (a', -v_a) at
  u = d - t_a, then Z = a' - v_a (u - d + t_a), 0 at the planned touchdown u = d;
- **press** (stance, u = time since the planned touchdown), added to the
  stance foot's path (belt line or loading sink, both at zero speed there):
  ℓ = -v_a u down to -a' at u = t_a, then the cubic from (-a', -v_a) to (0, 0)
  over 3 t_a, ℓ = -a' (1 + 3s - 9s² + 5s³), s = (u - t_a) / (3 t_a) (deepest
  -1.28 a' at s = 0.2); 0 from u = 4 t_a on.

t_a = min(a / v_a, d / 2, T_st / 8) and a' = v_a t_a (a' = a unless the swing
or stance is too short for it; then the approach keeps its speed and gets
shallower).  Position and speed are continuous everywhere (C¹), the
acceleration jumps at u = d - t_a, at touchdown and at u = t_a, 4 t_a of the
press, as the paper's jumps at B and D.  Along the belt the foot moves with it
from t_a before the planned touchdown, so that an early foot lands without
slip: the swing's forward cubic ends at u = d - t_a at (s/2 + v_f t_a, -v_f),
then x = s/2 - v_f (u - d) (C¹ there too).  v_a = 0 is the paper's path, bit
for bit.

In the online generator (:mod:`exo_ctrl.plan.online`) the same curves run in
phase τ, with t_a and v_a taken at the reference gait's rate
(:func:`phase_constants`): at another belt speed the approach keeps its depth
and phase share, and its speed scales with the cadence.
"""

from __future__ import annotations

import numpy as np

from .. import _validate as v
from .._jit import kernel
from ..exceptions import InvalidParameter

__all__ = [
    "MAX_LANDING_DEPTH_M",
    "MAX_LANDING_SPEED_MPS",
    "approach",
    "checked",
    "phase_constants",
    "press",
    "press_phase",
    "swing_end",
    "swing_end_phase",
]


#: The fastest landing approach the planner takes [m/s] (issue 31's bound on a
#: touchdown is 0.05 m/s; the paper's path lands at 0).
MAX_LANDING_SPEED_MPS = 0.5
#: The deepest landing approach the planner takes [m]: millimetres of the sole.
MAX_LANDING_DEPTH_M = 0.01


def checked(speed_mps: float, depth_m: float, lift_height_m: float) -> tuple[float, float]:
    """(v_a [m/s], a [m]) as given, or InvalidParameter naming the one out of its range."""
    speed = v.within("landing_speed_mps", speed_mps, 0.0, MAX_LANDING_SPEED_MPS, "m/s")
    depth = v.positive("landing_depth_m", depth_m, "m")
    if depth > MAX_LANDING_DEPTH_M or (speed > 0.0 and depth >= 0.5 * lift_height_m):
        raise InvalidParameter(
            "landing_depth_m",
            depth_m,
            f"in (0, {MAX_LANDING_DEPTH_M:g}] m and below lift_height / 2 = "
            f"{0.5 * lift_height_m:g} m",
            "the approach is the last millimetres of the swing, into the sole's compliance",
        )
    return speed, depth


def approach(
    speed_mps: float, depth_m: float, half_swing_s: float, stance_s: float
) -> tuple[float, float]:
    """(t_a [s], a' [m]) of the approach (module docstring); (0, 0) for v_a = 0."""
    if speed_mps <= 0.0:
        return 0.0, 0.0
    t_a = min(depth_m / speed_mps, 0.5 * half_swing_s, stance_s / 8.0)
    return t_a, speed_mps * t_a


def phase_constants(
    speed_mps: float, depth_m: float, period_s: float, duty_factor: float
) -> tuple[float, float]:
    """(t_a / T [-], v_a T [m]): the approach's duration and speed in phase units."""
    t_a, _ = approach(
        speed_mps, depth_m, 0.5 * (1.0 - duty_factor) * period_s, duty_factor * period_s
    )
    return t_a / period_s, speed_mps * period_s


def swing_end(
    u: np.ndarray, d: float, h: float, t_a: float, v: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Z [m], Ż [m/s], Z̈ [m/s²] of the A → B lift with the approach at local times ``u`` ∈ [0, d].

    Args:
        u: local time into A → B [s].
        d: its duration T_sw / 2 [s].
        h: the lift h_s [m].
        t_a: the approach's duration [s] (> 0).
        v: its speed v_a [m/s] (> 0).

    """
    a = v * t_a
    d1 = d - t_a
    k2 = (3.0 * (a - h) + v * d1) / d1**2  # the Hermite cubic (h, 0) -> (a, -v) over d1
    k3 = (-2.0 * (a - h) - v * d1) / d1**3
    w = np.minimum(u, d1)
    z = np.where(u < d1, h + w * w * (k2 + w * k3), a - v * (u - d1))
    dz = np.where(u < d1, w * (2.0 * k2 + 3.0 * k3 * w), -v)
    ddz = np.where(u < d1, 2.0 * k2 + 6.0 * k3 * w, 0.0)
    return z, dz, ddz


def press(u: np.ndarray, t_a: float, v: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ℓ [m], ℓ̇ [m/s], ℓ̈ [m/s²] of the press at times ``u`` ≥ 0 since the planned touchdown [s]."""
    a = v * t_a
    s = np.clip((u - t_a) / (3.0 * t_a), 0.0, 1.0)
    first, release = u < t_a, u < 4.0 * t_a
    rate = 1.0 / (3.0 * t_a)
    z = np.where(
        first, -v * u, np.where(release, -a * (1.0 + s * (3.0 + s * (-9.0 + 5.0 * s))), 0.0)
    )
    dz = np.where(first, -v, np.where(release, -a * rate * (3.0 + s * (-18.0 + 15.0 * s)), 0.0))
    ddz = np.where(first, 0.0, np.where(release, -a * rate * rate * (-18.0 + 30.0 * s), 0.0))
    return z, dz, ddz


@kernel
def swing_end_phase(
    u: float, d: float, h: float, t_a: float, v: float
) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """:func:`swing_end` at one ``u`` in any time unit (the generator's: phase)."""
    a = v * t_a
    d1 = d - t_a
    k2 = (3.0 * (a - h) + v * d1) / (d1 * d1)
    k3 = (-2.0 * (a - h) - v * d1) / (d1 * d1 * d1)
    if u < d1:
        return h + u * u * (k2 + u * k3), u * (2.0 * k2 + 3.0 * k3 * u), 2.0 * k2 + 6.0 * k3 * u
    return a - v * (u - d1), -v, 0.0


@kernel
def press_phase(u: float, t_a: float, v: float) -> tuple[float, float, float]:  # pragma: no cover
    """:func:`press` at one ``u`` ≥ 0 in any time unit (the generator's: phase)."""
    if u < t_a:
        return -v * u, -v, 0.0
    if u >= 4.0 * t_a:
        return 0.0, 0.0, 0.0
    a = v * t_a
    rate = 1.0 / (3.0 * t_a)
    s = (u - t_a) * rate
    return (
        -a * (1.0 + s * (3.0 + s * (-9.0 + 5.0 * s))),
        -a * rate * (3.0 + s * (-18.0 + 15.0 * s)),
        -a * rate * rate * (-18.0 + 30.0 * s),
    )
