r"""Split cuffs in the QP's models: normal and shear stiffness and damping apart.

The truth's cuffs (:mod:`exo_ctrl.plant.cuffs`, :mod:`exo_ctrl.plant.cuff_split`)
are stiffer across the exoskeleton's link than along it.  With u the unit
direction of the exoskeleton link carrying cuff c (joint → cuff point) at
the measured angles and n = u turned by +90°, the cuff's force on the
exoskeleton, to first order in the stretch Δp = J_c δ, is

.. math::

    f_c = -\mathcal K_c J_c δ - \mathcal C_c J_c \dot δ, \qquad
    \mathcal K_c = k_n n n^T + k_u u u^T, \quad
    \mathcal C_c = C_n n n^T + C_u u u^T,

J_c the patient's cuff Jacobian (2×2, rows x, z; columns hip, knee).  The
moment the split spring puts on the exoskeleton's link, σ_n (u·Δp) −
σ_u (n·Δp) = (k_n − k_u) (n·Δp)(u·Δp) with the cuffs fitted where the
frames coincide, is second order in δ and left out, as is the turning of
n and u over the horizon (40 ms).  Per leg, with W_K = 𝒦 J, W_C = 𝒞 J
(4×2: rows thigh x, z, shank x, z) the joint-space stiffness and damping
are G_K = Jᵀ 𝒦 J and G_C = Jᵀ 𝒞 J (2×2, symmetric), and

- the horizon prediction (:mod:`~exo_ctrl.control.qp.prediction`) has
  G_K, G_C where the isotropic model has K G, C G (G = JᵀJ), and its
  forces are f = −W_K δ(t) − W_C δ̇(t) instead of −J (K δ + C δ̇);
- the cuff-state observer (:mod:`~exo_ctrl.control.qp.observer`) solves
  G_K δ + G_C δ̇ = g, g = −Jᵀ f̂ (the joint-space cuff load, what the joint
  torques observe), a first-order system δ̇ = −A δ + G_C⁻¹ g with
  A = G_C⁻¹ G_K, discretised exactly with g held over the tick (zero-order
  hold): δ ← δ_∞ + e^{−hA} (δ − δ_∞), δ_∞ = G_K⁻¹ g.  A is similar to the
  symmetric G_C^{-1/2} G_K G_C^{-1/2}, so its eigenvalues m ± r are real;
  e^{−hA} = e^{−hm} (cosh(hr) I − sinh(hr)/r (A − m I)).

With k_u = k_n and C_u = C_n every expression reduces to the isotropic one
(𝒦 = K I), which the kernels then compute in their original arithmetic
(the golden runs are bit-equal); this module is used for split cuffs only.
"""

from __future__ import annotations

import math

import numpy as np

from ..._jit import kernel

__all__ = ["filter_leg", "split_gains", "split_rows"]


@kernel
def split_gains(m: np.void, q: np.ndarray) -> None:  # pragma: no cover - compiled
    """W_K, W_C (``wk``, ``wc``) and G_K, G_C (``gk``, ``gc``) per leg in record ``m``.

    ``m``: a :class:`~exo_ctrl.control.qp.prediction.CuffHorizonModel`'s record
    with its cuff Jacobians ``jac`` filled at ``q`` [rad] (the exoskeleton's
    angles, the patient's taken equal); the exoskeleton link of cuff c turns
    by θ_c = S_c · q (rows 0–3 of ``select``), u = R(θ_c) u₀ (``along0``).
    """
    select, along0, jac = m.select, m.along0, m.jac
    wk, wc, gk, gc = m.wk, m.wc, m.gk, m.gc
    kn, ku, cn, cu = m.stiffness, m.shear_stiffness, m.damping, m.shear_damping
    for c in range(4):
        leg, k = c // 2, c % 2
        theta = 0.0
        for i in range(4):
            theta += select[c, i] * q[i]
        ct, st = math.cos(theta), math.sin(theta)
        ux = along0[c, 0] * ct - along0[c, 1] * st
        uz = along0[c, 1] * ct + along0[c, 0] * st
        nx, nz = -uz, ux
        kxx = kn * nx * nx + ku * ux * ux
        kxz = kn * nx * nz + ku * ux * uz
        kzz = kn * nz * nz + ku * uz * uz
        cxx = cn * nx * nx + cu * ux * ux
        cxz = cn * nx * nz + cu * ux * uz
        czz = cn * nz * nz + cu * uz * uz
        for col in range(2):
            jx, jz = jac[leg, 2 * k, col], jac[leg, 2 * k + 1, col]
            wk[leg, 2 * k, col] = kxx * jx + kxz * jz
            wk[leg, 2 * k + 1, col] = kxz * jx + kzz * jz
            wc[leg, 2 * k, col] = cxx * jx + cxz * jz
            wc[leg, 2 * k + 1, col] = cxz * jx + czz * jz
    for leg in range(2):
        for a in range(2):
            for b in range(2):
                sk = 0.0
                sc = 0.0
                for r in range(4):
                    sk += jac[leg, r, a] * wk[leg, r, b]
                    sc += jac[leg, r, a] * wc[leg, r, b]
                gk[leg, a, b] = sk
                gc[leg, a, b] = sc


@kernel
def split_rows(
    m: np.void, leg: int, p: int, sv: np.ndarray, delta: np.ndarray, ddelta: np.ndarray
) -> None:  # pragma: no cover - compiled
    """Add horizon point p's forces of leg ``leg`` to ``m.A`` and ``m.b``: f = −W_K δ(t) − W_C δ̇(t).

    ``sv``: rows δ (0, 1) and δ̇ = u_e − u_p (2, 3) of e^{F t_p}, (4, 9);
    z(0) = (δ, 0, −δ̇, τ, 1) with ``delta`` δ [rad] and ``ddelta`` δ̇ [rad/s].
    """
    a_out, b_out, wk, wc = m.A, m.b, m.wk, m.wc
    i0 = 2 * leg
    # Rows δ₁, δ₂, δ̇₁, δ̇₂ of z(t) = e^{F t} z(0) at τ = 0.
    v0 = sv[0, 8]
    v1 = sv[1, 8]
    v2 = sv[2, 8]
    v3 = sv[3, 8]
    for c in range(2):
        dc, ddc = delta[i0 + c], ddelta[i0 + c]
        v0 += sv[0, c] * dc - sv[0, 4 + c] * ddc
        v1 += sv[1, c] * dc - sv[1, 4 + c] * ddc
        v2 += sv[2, c] * dc - sv[2, 4 + c] * ddc
        v3 += sv[3, c] * dc - sv[3, 4 + c] * ddc
    for rr in range(4):
        row = p * 8 + leg * 4 + rr
        w0, w1, w2, w3 = wk[leg, rr, 0], wk[leg, rr, 1], wc[leg, rr, 0], wc[leg, rr, 1]
        a_out[row, i0] -= w0 * sv[0, 6] + w1 * sv[1, 6] + w2 * sv[2, 6] + w3 * sv[3, 6]
        a_out[row, i0 + 1] -= w0 * sv[0, 7] + w1 * sv[1, 7] + w2 * sv[2, 7] + w3 * sv[3, 7]
        b_out[row] -= w0 * v0 + w1 * v1 + w2 * v2 + w3 * v3


@kernel
def filter_leg(
    o: np.void, m: np.void, leg: int, g1: float, g2: float
) -> tuple[float, float]:  # pragma: no cover - compiled
    """One tick of the observer's δ̂ filter on leg ``leg`` for split cuffs (module docstring).

    ``o``: the observer's record (δ̂ ``delta`` updated in place, step ``dt``
    h [s]); ``m``: the cuff model's record at this tick (``gk``, ``gc``);
    (g1, g2) = g = −Jᵀ f̂ [N·m].  Returns δ̂̇ = G_C⁻¹ (g − G_K δ̂) [rad/s].
    The first update (``o.first``) starts δ̂ at rest under the first
    estimate, δ̂ = δ∞ (a run starts standing, the cuffs loaded and still).
    """
    i0 = 2 * leg
    k11, k12, k22 = m.gk[leg, 0, 0], m.gk[leg, 0, 1], m.gk[leg, 1, 1]
    c11, c12, c22 = m.gc[leg, 0, 0], m.gc[leg, 0, 1], m.gc[leg, 1, 1]
    dk = k11 * k22 - k12 * k12
    dc = c11 * c22 - c12 * c12
    # A = G_C⁻¹ G_K
    a11 = (c22 * k11 - c12 * k12) / dc
    a12 = (c22 * k12 - c12 * k22) / dc
    a21 = (c11 * k12 - c12 * k11) / dc
    a22 = (c11 * k22 - c12 * k12) / dc
    h = o.dt
    mid = 0.5 * (a11 + a22)
    half = 0.5 * (a11 - a22)
    r = math.sqrt(max(half * half + a12 * a21, 0.0))
    x = h * r
    sinhc = 1.0 + x * x / 6.0 if x < 1e-6 else math.sinh(x) / x  # sinh(hr)/(hr)
    decay = math.exp(-h * mid)
    ch, sh = decay * math.cosh(x), decay * h * sinhc
    e11, e12 = ch - sh * (a11 - mid), -sh * a12
    e21, e22 = -sh * a21, ch - sh * (a22 - mid)
    # δ∞ = G_K⁻¹ g; δ ← δ∞ + E (δ − δ∞)
    inf1 = (k22 * g1 - k12 * g2) / dk
    inf2 = (k11 * g2 - k12 * g1) / dk
    delta = o.delta
    x1, x2 = delta[i0] - inf1, delta[i0 + 1] - inf2
    if o.first != 0.0:  # the first estimate: the cuffs at rest under it, δ̂ = δ∞, δ̂̇ = 0
        x1 = x2 = 0.0
    delta[i0] = inf1 + e11 * x1 + e12 * x2
    delta[i0 + 1] = inf2 + e21 * x1 + e22 * x2
    y1 = g1 - (k11 * delta[i0] + k12 * delta[i0 + 1])
    y2 = g2 - (k12 * delta[i0] + k22 * delta[i0 + 1])
    return (c22 * y1 - c12 * y2) / dc, (c11 * y2 - c12 * y1) / dc
