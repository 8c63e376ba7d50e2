r"""The shank cuffs' along force the device cannot see, added to the estimate the supervisor reads.

Without 2-axis cuff sensors the along-shank component of each shank cuff's force is the
cuff model's (:mod:`exo_ctrl.estimation.kalman`, "What is observed"): no joint torque sees
it.  A knee axis d off the exoskeleton's adds one the model does not hold.  With the straps
fitted at the start (:mod:`exo_ctrl.plant.misalignment`), the shank cuff parts from the limb
by

.. math::

    Δp = A d, \qquad A = (R(θ_s) − R(θ_t)) − (R(θ_s^0) − R(θ_t^0)),

θ_t, θ_s the thigh and shank links' angles (the cuffs' S_c q) now and at the fit, R(θ) the
rotation in the (x, z) plane as :func:`~exo_ctrl.control.qp.cuff_knowledge.link_normals`
turns the links.  Its along-shank part u_sᵀ A d is largest, over every direction of d, at
‖Aᵀ u_s‖ |d|.  The device knows neither d nor its patient's shear stiffness, only a fit
tolerance d_max (``belief.knee_fit_tolerance_m``) and the spread s of the true cuffs around
its model (a factor within 1 ± 2s, :mod:`exo_ctrl.plant.cuff_scatter`), so the along force it
cannot see is at most

.. math::

    m_s(q) = k_u (1 + 2s)\, d_{max}\, ‖A(q)^T u_s(q)‖ \quad [\text{N}].

:class:`AlongWidening` hands the supervisor (``safety_widen``) each shank cuff's estimate
with its along component moved that much further from zero, f_w = n̂ n + sgn(â) (|â| + m_s) u,
so that its limit holds on the largest force the estimate leaves possible; the thighs'
estimates pass unchanged (their along force has no knee offset in it).  The margin is zero
at the fit posture and grows as the knee bends away from it (0.41 d_max k_u (1 + 2s) at the
``clinic-*`` gait's deepest flexion: 64 N at 3 cm).  Before the run
:mod:`exo_ctrl.sim.tone_load` predicts the same along the plan.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import kernel

__all__ = ["AlongWidening", "along_reach_into", "widen_along"]


@kernel
def along_reach_into(
    select: np.ndarray, along0: np.ndarray, q: np.ndarray, q_fit: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """‖Aᵀ u_s‖ per shank cuff into ``out`` (2,) left, right [-] (module docstring).

    ``select``: the cuffs' S (its first 4 × 4 block, exoskeleton joints); ``along0``: u of
    each cuff at q = 0, (4, 2) (x, z); ``q``, ``q_fit``: the exoskeleton's joints now and at
    the fit [rad].
    """
    for leg in range(2):
        t, s = 2 * leg, 2 * leg + 1
        th_t = 0.0
        th_s = 0.0
        f_t = 0.0
        f_s = 0.0
        for j in range(4):
            th_t += select[t, j] * q[j]
            th_s += select[s, j] * q[j]
            f_t += select[t, j] * q_fit[j]
            f_s += select[s, j] * q_fit[j]
        # A = R(θ_s) − R(θ_t) − R(θ_s⁰) + R(θ_t⁰), R = [[c, −s], [s, c]]: A = [[a, −b], [b, a]]
        a = math.cos(th_s) - math.cos(th_t) - math.cos(f_s) + math.cos(f_t)
        b = math.sin(th_s) - math.sin(th_t) - math.sin(f_s) + math.sin(f_t)
        # A of this form is a scaled rotation: ‖Aᵀu‖ = √(a² + b²) ‖u‖, ‖u‖ = ‖R(θ_s) u₀‖ = ‖u₀‖
        out[leg] = math.sqrt(a * a + b * b) * math.hypot(along0[s, 0], along0[s, 1])


@kernel
def widen_along(
    force: np.ndarray,
    select: np.ndarray,
    along0: np.ndarray,
    q: np.ndarray,
    q_fit: np.ndarray,
    unseen_N: float,
    reach: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover - compiled
    """``force`` (4, 2) with each shank's along component widened by unseen_N ‖Aᵀu‖, into ``out``.

    ``unseen_N``: k_u (1 + 2s) d_max [N]; ``reach``: (2,) scratch, left with ‖Aᵀu‖.  A
    non-finite estimate passes through unchanged (the supervisor's check refuses it).
    """
    along_reach_into(select, along0, q, q_fit, reach)
    for c in range(4):
        out[c, 0] = force[c, 0]
        out[c, 1] = force[c, 1]
    for leg in range(2):
        s = 2 * leg + 1
        th = 0.0
        for j in range(4):
            th += select[s, j] * q[j]
        c, sn = math.cos(th), math.sin(th)
        ux = along0[s, 0] * c - along0[s, 1] * sn
        uz = along0[s, 1] * c + along0[s, 0] * sn
        norm = math.sqrt(ux * ux + uz * uz)
        if not norm > 0.0:
            continue
        ux /= norm
        uz /= norm
        along = ux * force[s, 0] + uz * force[s, 1]
        more = unseen_N * reach[leg] * (1.0 if along >= 0.0 else -1.0)
        out[s, 0] = force[s, 0] + more * ux
        out[s, 1] = force[s, 1] + more * uz


class AlongWidening:
    """The estimate widened by what the device cannot see, for the supervisor (module docstring).

    Args:
        select: the device's cuffs' S, (≥ 4, ≥ 4) (:class:`~exo_ctrl.plant.cuffs.CuffSet`'s).
        along0: the device's cuffs' u at q = 0, (4, 2).
        unseen_N: k_u (1 + 2s) d_max [N] (:func:`~exo_ctrl.sim.tone_load.unseen_along_N`).

    Attributes:
        out: the widened forces (x, z), (4, 2) [N]; refilled in place by each call.
        reach: ‖Aᵀu‖ per shank cuff at the last call, (2,) [-].

    The fit is the first call's posture (the run's start, where the straps are fitted).

    """

    def __init__(self, select: np.ndarray, along0: np.ndarray, unseen_N: float) -> None:
        self._select = np.ascontiguousarray(np.asarray(select, dtype=float)[:4, :4])
        self._along0 = np.ascontiguousarray(np.asarray(along0, dtype=float))
        self._unseen = float(unseen_N)
        self._fit: np.ndarray | None = None
        self.out = np.zeros((4, 2))
        self.reach = np.zeros(2)

    def __call__(self, force: np.ndarray, q: np.ndarray) -> np.ndarray:
        """Widen ``force`` (4, 2) [N] at the encoders' ``q`` (4,) [rad]; returns :attr:`out`."""
        if self._fit is None:
            self._fit = np.array(q, dtype=float)
        widen_along(
            force, self._select, self._along0, q, self._fit, self._unseen, self.reach, self.out
        )
        return self.out
