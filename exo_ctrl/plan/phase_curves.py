"""The curves of the online gait in its phase: ramp-in, phase rate, cubics, lift, hip rise.

Small compiled kernels of :mod:`exo_ctrl.plan.online` (its module docstring
has the gait they make): each returns a value and its first two
derivatives, with respect to time or to the phase τ as stated.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel

__all__ = ["cubic", "hip_rise", "lift", "phase_rate", "ramp_factor"]


@kernel
def ramp_factor(t: float, t_r: float) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """σ, σ̇ [1/s], σ̈ [1/s²] of the quintic ramp-in over ``t_r`` (1, 0, 0 without one)."""
    if t_r <= 0.0 or t >= t_r:
        return 1.0, 0.0, 0.0
    if t <= 0.0:
        return 0.0, 0.0, 0.0
    u = t / t_r
    w = 1.0 - u
    return (
        u**3 * (10.0 - 15.0 * u + 6.0 * u * u),
        30.0 * (u * w) ** 2 / t_r,
        (60.0 * u * w * (1.0 - 2.0 * u) / (t_r * t_r)),
    )


@kernel
def phase_rate(law: np.ndarray, v: float, a: float) -> tuple[float, float]:  # pragma: no cover
    """The phase rate r = 1 / T(v) [1/s] and ṙ = dr/dv · v̇ [1/s²] (:mod:`exo_ctrl.plan.adapt`)."""
    s = law[0] * (v / law[1]) ** law[2]
    expo = 1.0 - law[2]
    if s >= law[3]:
        s = law[3]
        expo = 1.0
    r = law[4] * v / s
    return r, expo * r / v * a


@kernel
def cubic(
    x0: float, dx0: float, x1: float, dx1: float, d: float, u: float
) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """Position, velocity, acceleration at ``u`` of the cubic on [0, d] meeting (x0, x1, ẋ0, ẋ1)."""
    if d <= 0.0:
        return x1, dx1, 0.0
    delta = x1 - x0
    k2 = (3.0 * delta - (2.0 * dx0 + dx1) * d) / (d * d)
    k3 = (-2.0 * delta + (dx0 + dx1) * d) / (d * d * d)
    return (
        x0 + u * (dx0 + u * (k2 + u * k3)),
        dx0 + u * (2.0 * k2 + 3.0 * k3 * u),
        2.0 * k2 + 6.0 * k3 * u,
    )


@kernel
def lift(tau: float, half: float, h: float) -> tuple[float, float, float]:  # pragma: no cover
    """Z(τ), dZ/dτ, d²Z/dτ² of the swing's lift (0 in stance); ``half`` = τ_B = (1 - β)/2."""
    if tau < half:  # A -> B: h down to 0
        u = tau / half
        return (
            h * (1.0 - 3.0 * u * u + 2.0 * u**3),
            h * 6.0 * u * (u - 1.0) / half,
            (h * (12.0 * u - 6.0) / (half * half)),
        )
    if tau >= 1.0 - half:  # D -> A: 0 up to h
        u = (tau - (1.0 - half)) / half
        return (
            h * (3.0 * u * u - 2.0 * u**3),
            h * 6.0 * u * (1.0 - u) / half,
            (h * (6.0 - 12.0 * u) / (half * half)),
        )
    return 0.0, 0.0, 0.0


@kernel
def hip_rise(tau: float, e: float) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """The hip's rise at phase τ: ΔH = (e/2) cos(4π τ) [m], dΔH/dτ, d²ΔH/dτ² (module docstring)."""
    w = 4.0 * math.pi
    c, s = math.cos(w * tau), math.sin(w * tau)
    a = 0.5 * e
    return a * c, -a * w * s, -a * w * w * c
