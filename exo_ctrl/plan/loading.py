r"""The loading phase: each stance foot planned into the belt by the sink its load gives.

With the pelvis on its vertical guide (body-weight support,
:mod:`exo_ctrl.plant.pelvis`) the stance legs carry the weight the support
leaves, W ≈ 560 N for the default 80 kg body at 50 %, and the compliant
sole and belt (:mod:`exo_ctrl.plant.contact`, F = k δⁿ) give under it:
δ = (W / k)^{1/n} ≈ 11 mm.  A plan that puts the stance foot on the belt
line then walks the whole body that much lower than it thinks, and the
swing foot, planned relative to the hip, meets the belt before its planned
touchdown while still coming down: measured with computed torque at 50 %
support, 0.42 m/s down and 0.85 m/s of slip at touchdown, slip RMS
0.10 m/s in stance (the paper's no-slip, no-impact claim, broken by the
load).  With the paper's schedule (β = ½) the load also has to pass from
one foot to the other at the instant of touchdown, which no foot can follow.

So with double support (β > ½) the plan gives each foot the share of the
load it is to carry and plans it into the belt by that share's sink:

- **share** w_i(τ) of leg i at its phase τ: 0 in swing, 1 in single
  support, and across each double support (the first and the last
  δ = β − ½ of the stance, in phase) the quintic smoothstep
  S(x) = 10x³ − 15x⁴ + 6x⁵ up (x = u/δ, u = τ − τ_B the time into stance)
  and down (x = (β − u)/δ): the leading foot's S(x) and the trailing
  foot's S(1 − x) = 1 − S(x) sum to one;
- **load** W(t) = W₀ + M ΔḦ(t): the static W₀ = M g − F_s (the moving
  mass M on the guide, the support F_s) and the planned hip's vertical
  acceleration (:mod:`exo_ctrl.plan.gait`'s ΔH; at its lowest, mid double
  support, ΔḦ = (e/2)(4π/T)² ≈ 2.7 m/s², a quarter of g for the default
  gait: measured, the touchdown speed doubles without this term);
- **sink** Δs_i = (w_i W / k)^{1/n} − s₀ below the belt line, s₀ = (W₀ / (2k))^{1/n}
  the standing sink (both feet carrying W₀/2: the session starts at rest
  there, :func:`~exo_ctrl.sim.setup`'s pelvis rest), so the ramp-in, which
  grows the gait out of standing, starts from Δs = 0.  A foot in swing is
  Δs = −s₀ (it is planned relative to the hip, which stands s₀ low).

With the legs tracking the plan the hip is then H_s + ΔH − s₀ above the belt
throughout, and the landing foot reaches the belt's surface at its planned
touchdown with zero speed and loads from there (its sink grows as
x² for n = 1.5: w ≈ 10x³, so the planned acceleration stays finite at touchdown for n ≤ 1.5).
The loads the sinks imply, k (Δs_i + s₀)ⁿ, sum to W(t) at every instant.

In phase τ of a plan of rate r = 1/T: W = W₀ + M r² ΔH''(τ_h), with τ_h the
hip's phase; :func:`sink_phase` gives Δs and its first two τ-derivatives
(the time derivatives are r Δs' and r² Δs'' at a constant rate; the online
planner takes them through its chain rule).  What the device holds: its
moving mass and the support it applies (as
:mod:`exo_ctrl.control.stance_load`), and k and n of its soles on the belt
(the contact law's datasheet values).  Measured (tests/plan/test_loading.py,
computed torque, 50 % support, β = 0.6, touchdowns after the ramp-in; the
belt-line plan → the loading plan): precomputed plan, 0.52 → 0.11 m/s down
and 0.94 → 0.05 m/s along the belt at touchdown, slip RMS 0.094 → 0.003
m/s; synchronised, 0.51 → 0.12, 0.90 → 0.03 and 0.082 → 0.005 m/s.  The
0.11 m/s left comes with the stance knee at its drive's 150 N·m cap just
before each transfer (the hip lowest, the load largest).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import _validate as v
from .._jit import kernel
from ..exceptions import InvalidParameter

__all__ = ["StanceSink", "sink_phase", "sink_samples"]


@dataclass(frozen=True)
class StanceSink:
    """What the plan needs to sink the stance feet (module docstring).

    Attributes:
        weight_N: W₀ = M g − F_s, the static load on the stance legs [N].
        mass_kg: M, the mass on the pelvis's guide [kg].
        stiffness_N_per_m_n: k of the soles on the belt, F = k δⁿ [N/mⁿ].
        exponent: n [-], ≥ 1.

    Raises:
        InvalidParameter: a weight < 0, a mass or stiffness not > 0, n < 1.

    """

    weight_N: float
    mass_kg: float
    stiffness_N_per_m_n: float
    exponent: float = 1.5

    def __post_init__(self) -> None:
        v.non_negative("stance sink weight", self.weight_N, "N")
        v.positive("stance sink mass", self.mass_kg, "kg")
        v.positive("stance sink stiffness", self.stiffness_N_per_m_n, "N/m^n")
        n = v.finite("stance sink exponent", self.exponent)
        if n < 1.0:
            raise InvalidParameter("stance sink exponent", self.exponent, ">= 1")

    @property
    def standing_sink_m(self) -> float:
        """s₀ = (W₀ / (2k))^{1/n}: each foot's sink standing on both [m]."""
        return (0.5 * self.weight_N / self.stiffness_N_per_m_n) ** (1.0 / self.exponent)

    def kernel_params(self) -> np.ndarray:
        """(W₀, M, k, 1/n, s₀) for :func:`sink_phase`."""
        return np.array(
            [
                self.weight_N,
                self.mass_kg,
                self.stiffness_N_per_m_n,
                1.0 / self.exponent,
                self.standing_sink_m,
            ]
        )


@kernel
def _share(tau: float, beta: float) -> tuple[float, float, float]:  # pragma: no cover
    """w, dw/dτ, d²w/dτ² of a leg at its phase τ (module docstring); β > ½."""
    t_b = 0.5 * (1.0 - beta)
    u = tau - t_b
    if u < 0.0 or u >= beta:
        return 0.0, 0.0, 0.0
    d = beta - 0.5
    sign = 1.0
    if u < d:
        x = u / d
    elif u > beta - d:
        x = (beta - u) / d
        sign = -1.0
    else:
        return 1.0, 0.0, 0.0
    w = x * x * x * (10.0 - 15.0 * x + 6.0 * x * x)
    w1 = 30.0 * (x * (1.0 - x)) ** 2 / d
    w2 = 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x) / (d * d)
    return w, sign * w1, w2


@kernel
def sink_phase(
    p: np.ndarray, tau: float, tau_hip: float, beta: float, rate: float, excursion: float
) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """Δs [m] below the belt line and dΔs/dτ, d²Δs/dτ² of a leg (module docstring).

    Args:
        p: :meth:`StanceSink.kernel_params`.
        tau: the leg's phase τ ∈ [0, 1).
        tau_hip: the hip's phase (the left leg's: ΔH has period ½).
        beta: the duty factor β (> ½; at ½ the sink is the standing one, 0).
        rate: the phase rate r = 1/T [1/s].
        excursion: the hip's peak-to-peak excursion e [m].

    """
    if beta <= 0.5:
        return 0.0, 0.0, 0.0
    w, w1, w2 = _share(tau, beta)
    s0 = p[4]
    if w <= 0.0:
        return -s0, 0.0, 0.0
    om = 4.0 * math.pi
    c, s = math.cos(om * tau_hip), math.sin(om * tau_hip)
    a = 0.5 * excursion * p[1] * rate * rate  # M r² e/2
    load = p[0] - a * om * om * c  # W₀ + M r² ΔH''
    if load <= 0.0:
        return -s0, 0.0, 0.0
    load1 = a * om * om * om * s
    load2 = a * om * om * om * om * c
    k, expo = p[2], p[3]
    g = w * load / k
    g1 = (w1 * load + w * load1) / k
    g2 = (w2 * load + 2.0 * w1 * load1 + w * load2) / k
    f = g**expo
    f1 = expo * f / g * g1
    f2 = expo * f / g * g2 + expo * (expo - 1.0) * f / (g * g) * g1 * g1
    return f - s0, f1, f2


@kernel
def sink_samples(
    p: np.ndarray,
    tau: np.ndarray,
    tau_hip: np.ndarray,
    beta: float,
    rate: float,
    excursion: float,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """``out[i] = (Δs, dΔs/dt, d²Δs/dt²)`` at constant rate r for each sample's phases."""
    for i in range(tau.shape[0]):
        f, f1, f2 = sink_phase(p, tau[i], tau_hip[i], beta, rate, excursion)
        out[i, 0] = f
        out[i, 1] = f1 * rate
        out[i, 2] = f2 * rate * rate
