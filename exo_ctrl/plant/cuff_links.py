"""The cuffs' link kinematics shared by the isotropic and the split cuff kernels.

Each of the 8 cuff links (exoskeleton and patient thigh and shank, both legs)
turns by θ_j = S_j · q_all, with S the selection matrix of the cuffs' record
(:mod:`exo_ctrl.plant.cuffs`); its rotation enters the cuff points as
(cos θ, sin θ) and their Jacobians as (-sin θ, cos θ).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._jit import kernel

__all__ = ["add_link_torques", "link_turn"]


@kernel
def link_turn(r: Any, q_all: np.ndarray, v_all: np.ndarray, j: int) -> float:
    """Write link j's ``cs`` = (cos θ, sin θ) and ``csr`` = (-sin θ, cos θ); return θ̇ [rad/s]."""
    select, cs, csr = r.select, r.cs, r.csr
    th = 0.0
    dth = 0.0
    for i in range(8):
        s = select[j, i]
        if s != 0.0:
            th += s * q_all[i]
            dth += s * v_all[i]
    cj, sj = np.cos(th), np.sin(th)
    cs[j] = cj
    cs[8 + j] = sj
    csr[j] = -sj
    csr[8 + j] = cj
    return dth


@kernel
def add_link_torques(r: Any) -> None:
    """Add the cuff forces ``f``' generalised torques, Sᵀ (csr ∘ Pᵀ f), to ``tau``."""
    select, dpt, f, tau, csr = r.select, r.dpt, r.f, r.tau, r.csr
    for j in range(16):
        g = 0.0
        for row in range(8):
            g += dpt[j, row] * f[row]
        g *= csr[j]
        jj = j if j < 8 else j - 8
        for i in range(8):
            s = select[jj, i]
            if s != 0.0:
                tau[i] += s * g
