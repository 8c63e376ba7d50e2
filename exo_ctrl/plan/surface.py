r"""The landing approach planned against the belt's surface as the stance foot measures it.

A landing approach (:mod:`exo_ctrl.plan.landing`) meets the belt at v_a only
if the foot is within a' of its planned height when it gets there.  Under
body-weight support it is not: with computed torque at 30 % support the
stance leg sinks 1–1.5 mm more than planned (the stance knee at its drive's
150 N·m cap, the sole loaded beyond the planned W₀) and the hip comes down on
the belt at 0.02–0.04 m/s faster than planned in the last tens of
milliseconds before touchdown (docs/performance.md, "Touchdowns under load").
The swing foot, planned relative to the hip, follows the hip down.

So in the synchronised plan the swing foot's approach is planned relative to
the surface under the stance foot as measured: in the hip's frame the surface
is at z_s = z_o + δ_o, z_o the stance (other) foot's height from the joint
encoders (the device's leg geometry), δ_o = (F_z / k)^{1/n} its sink from its
foot plate's vertical load F_z (:mod:`exo_ctrl.sensing.foot_load`, the last
tick's reading) through the soles' contact law the device holds; the plan
puts it at z_o* + δ_o* (the planned foot and, with a loading sink, its
planned sink Δs + s₀; without one, 0 and the sink is not measured).  The
surface's offset ε = (z_o − z_o*) + (δ_o − δ_o*), low-passed with time
constant :data:`FILTER_S`, is added to the swing foot's z over A → B with the
weight S(τ/τ_B) (S the quintic smoothstep: 0 at the top of the swing, 1 at
touchdown), then held from touchdown and let go over the press's 4 t_a with
1 − S.  The plan's ż has the weight's rate and the filtered ε's (the filter's
(ε − ε̄) / (T_f + Δt)), its z̈ the weight's only.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import leaf
from ..model.leg_kernels import foot_point

__all__ = ["CONTACT_N", "FILTER_S", "surface_offsets"]

#: Time constant of the low-pass on the surface's offset ε [s].
FILTER_S = 0.005

#: A foot plate reading at least this vertical load [N] bears its foot: the
#: offset is held from then on (five times the plates' default noise, 2 N, twice).
CONTACT_N = 20.0


@leaf
def _smooth(x: float) -> tuple[float, float, float]:  # pragma: no cover - compiled
    """S(x) = 10x³ − 15x⁴ + 6x⁵ on [0, 1] and its first two derivatives."""
    if x <= 0.0:
        return 0.0, 0.0, 0.0
    if x >= 1.0:
        return 1.0, 0.0, 0.0
    w = 1.0 - x
    return (
        x**3 * (10.0 - 15.0 * x + 6.0 * x * x),
        30.0 * (x * w) ** 2,
        60.0 * x * w * (1.0 - 2.0 * x),
    )


@leaf
def _track(g, leg: int, q_meas: np.ndarray) -> float:  # pragma: no cover - compiled
    """Update leg ``leg``'s filtered offset ε̄ from the other leg's encoders; its rate [m/s]."""
    o = 1 - leg
    eps = foot_point(g, o, q_meas[2 * o], q_meas[2 * o + 1])[1] - g.out[17 + 2 * o]
    de = (eps - g.eps[leg]) / (FILTER_S + g.dt)  # the filtered ε's rate
    g.eps[leg] += de * g.dt
    return de


@leaf
def surface_offsets(g, q_meas: np.ndarray, f_z: np.ndarray, r: float) -> None:  # pragma: no cover
    """Each leg's offset (m, m/s, m/s²) into ``g.surf`` (module docstring); zeros without one.

    ``q_meas``: the encoders' joint angles [rad], (4,) (NaN: none, no offset);
    ``f_z``: the plates' vertical loads [N], (2,); ``r``: the phase rate [1/s].
    """
    half = 0.5 * (1.0 - g.law[4])
    press = 4.0 * g.land[0]
    for leg in range(2):
        tau = g.phase[leg]
        g.surf[leg, 0], g.surf[leg, 1], g.surf[leg, 2] = 0.0, 0.0, 0.0
        if g.land[0] <= 0.0 or math.isnan(q_meas[0]):
            continue
        if tau < half:  # A -> B: the other leg stands
            de = _track(g, leg, q_meas)
            w, w1, w2 = _smooth(tau / half)
            rate = r / half
        elif tau < half + press:  # tracked until the foot bears load, then let go
            de = 0.0
            if f_z[leg] < CONTACT_N and not g.held[leg]:
                de = _track(g, leg, q_meas)
            else:
                g.held[leg] = 1
            w, w1, w2 = _smooth((tau - half) / press)
            w, w1, w2 = 1.0 - w, -w1, -w2
            rate = r / press
        else:
            g.eps[leg], g.held[leg] = 0.0, 0
            continue
        e = g.eps[leg]
        g.surf[leg, 0] = w * e
        g.surf[leg, 1] = w1 * rate * e + w * de
        g.surf[leg, 2] = w2 * rate * rate * e
