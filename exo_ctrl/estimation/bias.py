r"""Torque-sensor bias: its effect on the cuff-force estimate, and its measurement.

A constant sensor offset β (reading = true + β) is indistinguishable from a
constant external torque: the observer's r → τ_ext − β, and the force
estimate is off by the solution of the 2×2 map of
:mod:`exo_ctrl.estimation.cuff_geometry` for −β.  Bounds over all postures
(the thigh's denominator is at least a):

    |Δf_s⊥| = |β_knee| / c,   |Δf_t⊥| ≤ (|β_hip| + (l₁ + c)/c |β_knee|) / a;

with the default exoskeleton (a = 0.39 m, c = 0.45 m, l₁ = 0.52 m): shank
2.2 N per N·m of knee bias, thigh up to 2.6 N per N·m of hip bias plus 5.5 N
per N·m of knee bias (:func:`bias_effect_bound`).  It is detected and
measured by :func:`estimate_bias` from a run in which the interaction is
known to be zero (the device walking with the straps open), and removed by
passing it as ``torque_bias_Nm`` to
:class:`~exo_ctrl.estimation.observer.CuffForceEstimator`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import _validate as v
from ..exceptions import InvalidParameter
from ..model import CUFF_NAMES, JOINT_NAMES, BodyModel
from .cuff_geometry import _geometry

__all__ = ["BiasEstimate", "bias_effect_bound", "estimate_bias"]


@dataclass
class BiasEstimate:
    """A torque-sensor bias measured where the interaction is known to be zero.

    Attributes:
        bias_Nm: the bias β = −mean(r) over the window [N·m], (4,).
        std_error_Nm: its standard error from the means of 10 consecutive
            blocks [N·m], (4,).  Conservative on a walking window: the gait's
            periodic model errors differ between blocks but cancel over
            whole cycles.
        force_bound_N: the largest cuff-force error this bias causes over all
            postures (:func:`bias_effect_bound`) [N], (4,), CUFF_NAMES order.
        detected: per joint, |β| exceeds both 2 standard errors and the
            tolerance.

    """

    bias_Nm: np.ndarray
    std_error_Nm: np.ndarray
    force_bound_N: np.ndarray
    detected: np.ndarray

    def report(self) -> str:
        """One line per joint: bias, standard error, and whether it is significant."""
        lines = []
        for j, name in enumerate(JOINT_NAMES):
            flag = "DETECTED" if self.detected[j] else "not significant"
            lines.append(
                f"{name}: bias {self.bias_Nm[j]:+.3f} ± {self.std_error_Nm[j]:.3f} N·m ({flag})"
            )
        for c, name in enumerate(CUFF_NAMES):
            lines.append(f"{name}: cuff-force error up to {self.force_bound_N[c]:.2f} N")
        return "\n".join(lines)


def estimate_bias(
    tau_ext: np.ndarray, exo: BodyModel | None = None, tolerance_Nm: float = 0.05
) -> BiasEstimate:
    """Torque-sensor bias from the observer's output over a zero-interaction window.

    With no interaction (the device walking with the straps open, or a
    window known to be free of cuff forces) the observer's r is −β (the
    reading's offset seen as an external torque) plus noise and model
    error; minus its mean is the estimate of β.  Pass it as
    ``torque_bias_Nm`` to :class:`~exo_ctrl.estimation.observer.CuffForceEstimator`
    (or :func:`~exo_ctrl.estimation.series.estimate_series`) to remove it.
    Prefer a window of whole gait cycles, or a still posture: errors that
    follow the motion (the speed filter's lag) average out over a cycle.

    Args:
        tau_ext: observer output r over the window (skip the observer's
            start-up) [N·m], (N, 4) with N >= 10.
        exo: the exoskeleton model (None: the default URDF), for the force bound.
        tolerance_Nm: smallest bias reported as detected [N·m].

    Raises:
        InvalidParameter: ``tau_ext`` is not (N, 4) with N >= 10, or the
            tolerance is negative.

    """
    r = np.asarray(tau_ext, dtype=float)
    if r.ndim != 2 or r.shape[1] != 4 or r.shape[0] < 10:
        raise InvalidParameter("tau_ext", r.shape, "shape (N, 4) with N >= 10")
    v.non_negative("tolerance", tolerance_Nm, "N·m")
    bias = -r.mean(axis=0)
    blocks = np.array_split(r, 10)
    means = np.array([b.mean(axis=0) for b in blocks])
    se = means.std(axis=0, ddof=1) / math.sqrt(len(blocks))
    detected = (np.abs(bias) > 2.0 * se) & (np.abs(bias) > tolerance_Nm)
    return BiasEstimate(
        bias_Nm=bias,
        std_error_Nm=se,
        force_bound_N=bias_effect_bound(bias, exo),
        detected=detected,
    )


def bias_effect_bound(bias_Nm: np.ndarray | float, exo: BodyModel | None = None) -> np.ndarray:
    """Largest error a torque-sensor bias β causes in the normal components [N], (4,).

    Shank: |Δf_s⊥| = |β_knee| / c (every posture).  Thigh: |Δf_t⊥| =
    |β_hip − s_h w β_knee / (s_k c)| / a ≤ (|β_hip| + (l₁ + c)/c |β_knee|) / a,
    since |w| = |l₁ cos(ψ_s − ψ_k) + c| ≤ l₁ + c.

    Args:
        bias_Nm: bias per joint, (4,) or scalar [N·m].
        exo: the exoskeleton model (None: the default URDF).

    """
    beta = np.abs(np.broadcast_to(np.asarray(bias_Nm, dtype=float), (4,)))
    g = _geometry(exo)
    out = np.zeros(4)
    for s in range(2):
        a, c, l1 = g.thigh_arm[s], g.shank_arm[s], g.knee_arm[s]
        out[2 * s + 1] = beta[2 * s + 1] / c
        out[2 * s] = (beta[2 * s] + (l1 + c) / c * beta[2 * s + 1]) / a
    return out
