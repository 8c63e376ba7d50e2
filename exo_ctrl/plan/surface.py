r"""The landing approach planned against the belt's surface as the stance foot measures it.

A landing approach (:mod:`exo_ctrl.plan.landing`) meets the belt at v_a only
if the foot is within a' of its planned height when it gets there.  Under
body-weight support it is not: with computed torque at 30 % support the
stance leg is 0.5–2.5 mm shorter than planned at touchdown and shortening at
0.02–0.05 m/s (its knee at the drive's 150 N·m cap for the last 40 ms), so
the hip comes down on the belt faster than planned (docs/performance.md,
"Touchdowns under load").  The swing foot, planned relative to the hip,
follows the hip down.

So in the synchronised plan the swing foot's approach is planned against the
stance (other) foot's measured height: ε = z_o − z_o*, z_o that foot's height
below the hip from the joint encoders (the device's leg geometry), z_o* the
plan's (the last tick's row), low-passed with time constant
:data:`FILTER_S`, is added to the swing foot's z over A → B with the weight
S(τ/τ_B) (S the quintic smoothstep: 0 at the top of the swing, 1 at the
planned touchdown).  It is followed on past the planned touchdown until the
foot's own plate reads :data:`CONTACT_N` (a late foot keeps tracking a
stance leg that is still giving way), then held and let go over the press's
4 t_a with 1 − S.  The plan's ż has the weight's rate and the filtered ε's
(the filter's (ε − ε̄) / (T_f + Δt)), its z̈ the weight's only.

Measured (``exo-ctrl simulate --preset clinic-bws --set
interaction.patient_torque=none --set pelvis.bws_fraction=0.3``, CT, on the preset's
former 1.2 s gait: ``--set gait.period=1.2 --set gait.pelvis_excursion=0.05``): without
it the feet met the belt 10-30 ms early at 0.06-0.11 m/s; with it within a
few milliseconds of the plan, at 0.03-0.04 m/s.  The sole's sink read from
the foot plates' load (δ = (F_z/k)^{1/n} against the plan's) was tried as a
further term and did not help (0.14 / 0.07 m/s at 30 / 50 % support against
0.18 / 0.04 without it, both before the tracking past touchdown): the
planned sink grows with the planned load while the measured one does not,
and the term cancelled the encoders'.
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
