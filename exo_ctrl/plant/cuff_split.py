"""The forces of split cuffs: normal and shear stiffness apart, an optional strap preload.

The model is :mod:`exo_ctrl.plant.cuffs`'s (its module docstring: the cuff
point offsets Δp in the exoskeleton link's frame, split into the normal n
and along-link u directions, each with its own stiffness and damping, the
preload as two pads that each press with P when fitted); this module holds
its kernel, called by :func:`exo_ctrl.plant.cuffs.forces_of` for a record
whose ``split`` flag is set.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._jit import kernel
from .cuff_links import add_link_torques, link_turn

__all__ = ["split_forces"]


@kernel
def split_forces(r: Any, q_all: np.ndarray, v_all: np.ndarray) -> None:
    """Forces of split cuffs (normal and shear, preload; module docstring), in place.

    Δp = D P u + D p₀, Δṗ = D P w; per cuff u, n of its exo link, s_n, s_u,
    σ_n, σ_u, f = -(σ_n + C_n n · Δṗ) n - (σ_u + C_u u · Δṗ) u; τ as the
    isotropic cuffs' plus the moment M = σ_n (u · Δp) - σ_u (n · Δp) on each
    cuff's exo link (rotation c of S).
    """
    select, dp = r.select, r.dp
    f, tau, cs, y, rel = r.f, r.tau, r.cs, r.y, r.rel
    for j in range(8):
        dth = link_turn(r, q_all, v_all, j)
        cj, sj = cs[j], cs[8 + j]
        y[j] = -sj * dth
        y[8 + j] = cj * dth
    for row in range(8):
        acc = r.dp0[row]
        rate = 0.0
        for j in range(16):
            acc += dp[row, j] * cs[j]
            rate += dp[row, j] * y[j]
        rel[row] = acc
        rel[8 + row] = rate
    kn, cn, ku, cu = r.k, r.c, r.k_u, r.c_u
    d0 = 2.0 * r.preload / kn
    for i in range(8):
        tau[i] = 0.0
    for c in range(4):
        if r.slipped[c] != 0.0:
            f[c] = 0.0
            f[4 + c] = 0.0
            continue
        cc, sc = cs[c], cs[8 + c]
        ux = r.along0[c, 0] * cc - r.along0[c, 1] * sc
        uz = r.along0[c, 1] * cc + r.along0[c, 0] * sc
        nx, nz = -uz, ux
        dx, dz = rel[c], rel[4 + c]
        pu = ux * dx + uz * dz
        pn = nx * dx + nz * dz
        s_n = pn - r.r0n[c]
        s_u = pu - r.r0u[c]
        if r.preload > 0.0:
            sigma_n = 0.5 * kn * (max(d0 + s_n, 0.0) - max(d0 - s_n, 0.0))
        else:
            sigma_n = kn * s_n
        sigma_u = ku * s_u
        f_n = -sigma_n - cn * (nx * rel[8 + c] + nz * rel[12 + c])
        f_u = -sigma_u - cu * (ux * rel[8 + c] + uz * rel[12 + c])
        f[c] = f_n * nx + f_u * ux
        f[4 + c] = f_n * nz + f_u * uz
        moment = sigma_n * pu - sigma_u * pn
        for i in range(8):
            s = select[c, i]
            if s != 0.0:
                tau[i] += s * moment
    add_link_torques(r)
