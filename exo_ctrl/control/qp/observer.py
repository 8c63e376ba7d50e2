r"""The cuffs' state, reconstructed from the estimated cuff forces, for the horizon prediction.

The horizon prediction (:mod:`~exo_ctrl.control.qp.prediction`) starts from
the patient's lag δ behind the exoskeleton, its rate δ̇ and the patient's
own joint torque d.  None is measured; all three follow from the live cuff
force estimate f̂ (:mod:`exo_ctrl.estimation.observer`) and the cuff law.
Per leg, with J the patient's cuff Jacobians and G = JᵀJ, the joint-space
cuff load is

.. math::

    s = -G^{-1} J^T \hat f, \qquad C \dot δ = s - K δ

(isotropic spring–damper, exact; split cuffs, normal and shear apart:
G_K δ + G_C δ̇ = −Jᵀ f̂, filtered the same way with matrices,
:mod:`~exo_ctrl.control.qp.split_cuffs`), so

- δ̂ is s/K through a first-order filter of time constant C/K (12.5 ms
  with the defaults), discretised exactly (zero-order hold of s):
  δ̂ ← δ̂ + a_δ (s/K − δ̂), a_δ = 1 − e^{−h K/C}, started at rest under
  the first estimate (δ̂ = s/K: a run starts standing, the cuffs loaded
  and still; δ̂ = 0 took a loaded start for a cuff deflecting at s/C);
- δ̂̇ = (s − K δ̂)/C, and the patient's joint speed v̂_p = q̇ − δ̂̇;
- d̂ from the patient's equation M_p v̇_p + h_p = G s + d: the residual
  M_p Δv̂_p/h + h_p − G s through a first-order filter,
  d̂ ← d̂ + a_d (residual − d̂), a_d = 1 − e^{−h ω_d}.

**The estimate's lag, shortened.**  f̂ is the momentum observer's output
(:mod:`exo_ctrl.estimation.observer`): the external torque per step e_k
through r_k = r_{k−1} + a_o (e_k − r_{k−1}), a_o = 1 − e^{−h K_O}, mapped
to the cuffs by a linear, slowly varying map, so it lags the cuff forces by
about 1/K_O = 10 ms.  Where a shank cuff's force rises at 2–3 N/ms (the
fast gaits) that is 20–30 N, and a prediction started from it overshoots
the bound by as much (tools/load_held.py).  The observer first undoes that
filter and applies a faster one, ω_f > K_O:

.. math::

    ê_k = \hat f_{k-1} + (\hat f_k - \hat f_{k-1}) / a_o, \qquad
    \tilde f_k = \tilde f_{k-1} + a_f (ê_k - \tilde f_{k-1}), \quad
    a_f = 1 - e^{-h ω_f},

a lead–lag (1 + s/K_O)/(1 + s/ω_f) on f̂: the lag falls to 1/ω_f, the
estimate's noise (mostly from the encoder speed) grows by up to ω_f/K_O.
ω_f = K_O is the identity (f̃ = f̂).  f̃ is what the cuff state is rebuilt
from.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ... import _validate as v
from ..._jit import Status, check, kernel, record
from ...estimation import DEFAULT_GAIN_PER_S
from ...exceptions import InvalidParameter
from .prediction import CuffHorizonModel
from .split_cuffs import filter_leg

__all__ = ["OBSERVER_FIELDS", "CuffStateObserver", "add_residual", "observe", "shorten_lag"]

#: The fields of a :class:`CuffStateObserver`'s record: K [N/m], C [N·s/m]
#: (isotropic cuffs; split cuffs take the cuff model's G_K and G_C,
#: :mod:`~exo_ctrl.control.qp.split_cuffs`), h [s], the filter factors a_δ
#: and a_d, δ̂ [rad], δ̂̇ [rad/s], the last v̂_p [rad/s], d̂ [N·m]; ``first``
#: is 1 until the first update (no speed difference yet), then 0;
#: ``observed`` whether the last update took its estimate (False: not
#: finite, the state was left as it was).  The lead–lag on f̂: 1/a_o and
#: a_f, the last f̂ and f̃ [N] (module docstring, "The estimate's lag,
#: shortened").
OBSERVER_FIELDS: list[tuple[Any, ...]] = [
    ("stiffness", np.float64),
    ("damping", np.float64),
    ("dt", np.float64),
    ("a_delta", np.float64),
    ("a_dist", np.float64),
    ("delta", np.float64, (4,)),
    ("ddelta", np.float64, (4,)),
    ("vp", np.float64, (4,)),
    ("disturbance", np.float64, (4,)),
    ("first", np.float64),
    ("observed", np.bool_),
    ("inv_a_est", np.float64),
    ("a_fast", np.float64),
    ("last_est", np.float64, (4, 2)),
    ("fast", np.float64, (4, 2)),
]


@kernel
def observe(
    o: np.void, m: np.void, force: np.ndarray, omega: np.ndarray, split: bool | None
) -> bool:  # pragma: no cover - compiled
    """One observer tick per leg (module docstring) on observer record ``o``.

    ``m``: the record of a :class:`~exo_ctrl.control.qp.prediction.CuffHorizonModel`
    linearised at this tick (its patient mass, bias and cuff Jacobians).
    ``force``: f̂, (4, 2) [N]; ``omega``: q̇ [rad/s], (4,) (shapes checked by
    the caller); ``split``: the model's switch (its ``split_switch``).
    Returns False (and nothing done) if an entry of ``force`` is not finite.
    """
    for c in range(4):
        if not (math.isfinite(force[c, 0]) and math.isfinite(force[c, 1])):
            return False
    force = shorten_lag(o, force)
    mp, hp, jac = m.mass_patient, m.bias_patient, m.jac
    stiff, damp_c, a_delta, a_dist, h = o.stiffness, o.damping, o.a_delta, o.a_dist, o.dt
    delta, ddelta, vp_prev, dist = o.delta, o.ddelta, o.vp, o.disturbance
    for leg in range(2):
        i0 = 2 * leg
        g11 = g12 = g22 = 0.0
        r1 = r2 = 0.0
        for r in range(4):
            j0, j1 = jac[leg, r, 0], jac[leg, r, 1]
            g11 += j0 * j0
            g12 += j0 * j1
            g22 += j1 * j1
            fr = force[2 * leg + r // 2, r % 2]
            r1 += j0 * fr
            r2 += j1 * fr
        if split is not None and m.split:  # G_K δ + G_C δ̇ = g = −Jᵀ f̂; the cuffs' load is g
            load1, load2 = -r1, -r2
            dd1, dd2 = filter_leg(o, m, leg, load1, load2)
        else:
            dg = g11 * g22 - g12 * g12
            # s = -G⁻¹ Jᵀ f̂
            s1 = -(g22 * r1 - g12 * r2) / dg
            s2 = -(g11 * r2 - g12 * r1) / dg
            if o.first != 0.0:  # the first estimate: the cuffs at rest under it
                delta[i0], delta[i0 + 1] = s1 / stiff, s2 / stiff
            delta[i0] += a_delta * (s1 / stiff - delta[i0])
            delta[i0 + 1] += a_delta * (s2 / stiff - delta[i0 + 1])
            dd1 = (s1 - stiff * delta[i0]) / damp_c
            dd2 = (s2 - stiff * delta[i0 + 1]) / damp_c
            load1, load2 = g11 * s1 + g12 * s2, g12 * s1 + g22 * s2
        ddelta[i0], ddelta[i0 + 1] = dd1, dd2
        vp1, vp2 = omega[i0] - dd1, omega[i0 + 1] - dd2
        if o.first == 0.0:
            a1 = (vp1 - vp_prev[i0]) / h
            a2 = (vp2 - vp_prev[i0 + 1]) / h
            e1 = mp[i0, i0] * a1 + mp[i0, i0 + 1] * a2 + hp[i0] - load1
            e2 = mp[i0, i0 + 1] * a1 + mp[i0 + 1, i0 + 1] * a2 + hp[i0 + 1] - load2
            dist[i0] += a_dist * (e1 - dist[i0])
            dist[i0 + 1] += a_dist * (e2 - dist[i0 + 1])
        vp_prev[i0], vp_prev[i0 + 1] = vp1, vp2
    o.first = 0.0
    return True


@kernel
def add_residual(o: np.void, m: np.void, split: bool | None) -> None:  # pragma: no cover
    """Hold over the horizon what the cuff state does not reproduce of the estimate: b += r.

    r_c = f̃_c − f_c(δ̂, δ̂̇) per cuff and component, f the cuff model's force at
    the observer's state (split: −W_K δ̂ − W_C δ̂̇; isotropic: −J (K δ̂ + C δ̂̇)),
    which carries exactly the joint-space load the estimate does (Jᵀ r = 0):
    r is the part of the estimate the joint torques do not see, the split
    between a leg's cuffs that cuff sensors measured.  Added to every
    horizon point of ``m.b`` (row 8 p + 2 c + i), after
    :func:`~exo_ctrl.control.qp.prediction.predict`.
    """
    b, fast, delta, ddelta = m.b, o.fast, o.delta, o.ddelta
    for leg in range(2):
        i0 = 2 * leg
        d0, d1, r0, r1 = delta[i0], delta[i0 + 1], ddelta[i0], ddelta[i0 + 1]
        for rr in range(4):
            if split is not None and m.split:
                wk, wc = m.wk[leg, rr], m.wc[leg, rr]
                model = -(wk[0] * d0 + wk[1] * d1 + wc[0] * r0 + wc[1] * r1)
            else:
                j0, j1 = m.jac[leg, rr, 0], m.jac[leg, rr, 1]
                model = -(o.stiffness * (j0 * d0 + j1 * d1) + o.damping * (j0 * r0 + j1 * r1))
            res = fast[i0 + rr // 2, rr % 2] - model
            for row in range(leg * 4 + rr, b.shape[0], 8):
                b[row] += res


@kernel
def shorten_lag(o: np.void, force: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """f̃ from f̂ = ``force`` by the lead–lag of the module docstring, in record ``o``.

    Returns ``o.fast``; on the first update (no last f̂ yet) f̃ = f̂.
    """
    fast, last = o.fast, o.last_est
    for c in range(4):
        for i in range(2):
            if o.first != 0.0:
                fast[c, i] = force[c, i]
            else:
                e = last[c, i] + (force[c, i] - last[c, i]) * o.inv_a_est
                fast[c, i] += o.a_fast * (e - fast[c, i])
            last[c, i] = force[c, i]
    return fast


@kernel
def _update(
    state: np.ndarray, model: np.ndarray, force: np.ndarray, omega: np.ndarray, split: bool | None
) -> int:  # pragma: no cover - compiled
    """:func:`observe` with the shapes checked; its outcome in ``state[0].observed``.

    Returns a :class:`~exo_ctrl._jit.Status` value: WRONG_LENGTH (nothing
    done) unless ``force`` is (4, 2) and ``omega`` (4,).
    """
    o = state[0]
    if force.shape[0] != 4 or force.shape[1] != 2 or omega.shape[0] != 4:
        return Status.WRONG_LENGTH.value
    o.observed = observe(o, model[0], force, omega, split)
    return Status.OK.value


class CuffStateObserver:
    """Cuff deflection δ, its rate δ̇ and the patient's torque d from the force estimate.

    The filters of the module docstring, one compiled kernel per tick on
    :attr:`record`.

    Args:
        stiffness: K [N/m] (isotropic cuffs; for split cuffs, those of the
            model handed to :meth:`update`, its G_K and G_C, are used).
        damping: C [N·s/m], > 0 (likewise).
        dt: control period [s].
        disturbance_bandwidth_per_s: bandwidth ω_d of the d̂ filter [1/s], ≥ 0
            (0: d̂ = 0).
        estimate_gain_per_s: K_O, the bandwidth of the force estimate [1/s], > 0.
        restored_bandwidth_per_s: ω_f, the bandwidth f̂ is brought to [1/s],
            ≥ K_O (K_O: f̂ taken as it is).

    Attributes:
        record: the observer's parameters and state (:data:`OBSERVER_FIELDS`);
            the arrays below are views of its fields.
        delta: δ̂ [rad], (4,).
        ddelta: δ̂̇ [rad/s], (4,).
        disturbance: d̂ [N·m], (4,).
        first: (1,): 1 until the first update, then 0.

    Raises:
        InvalidParameter: a value outside its range.

    """

    def __init__(
        self,
        stiffness: float,
        damping: float,
        dt: float = 1e-3,
        disturbance_bandwidth_per_s: float = 30.0,
        estimate_gain_per_s: float = DEFAULT_GAIN_PER_S,
        restored_bandwidth_per_s: float = DEFAULT_GAIN_PER_S,
    ) -> None:
        k = v.positive("cuff stiffness", stiffness, "N/m")
        c = v.positive("cuff damping", damping, "N·s/m")
        h = v.positive("dt", dt, "s")
        bw = v.non_negative("disturbance_bandwidth", disturbance_bandwidth_per_s, "1/s")
        k_o = v.positive("estimate_gain", estimate_gain_per_s, "1/s")
        w_f = v.finite("restored_bandwidth", restored_bandwidth_per_s, "1/s")
        if not w_f >= k_o:
            raise InvalidParameter(
                "restored_bandwidth",
                restored_bandwidth_per_s,
                f">= the estimate's bandwidth K_O = {k_o:g} 1/s",
            )
        self.stiffness, self.damping, self.dt = k, c, h
        self.record = record(OBSERVER_FIELDS)
        o = self.record[0]
        o["stiffness"], o["damping"], o["dt"] = k, c, h
        o["a_delta"] = -math.expm1(-h * k / c)
        o["a_dist"] = -math.expm1(-h * bw)
        o["first"] = 1.0
        o["inv_a_est"] = -1.0 / math.expm1(-h * k_o)
        o["a_fast"] = -math.expm1(-h * w_f)
        self.delta = self.record["delta"][0]
        self.ddelta = self.record["ddelta"][0]
        self.disturbance = self.record["disturbance"][0]
        self.first = self.record["first"]

    def reset(self) -> None:
        """Forget the state (cuffs taken as just fitted: δ = 0, d = 0)."""
        self.delta.fill(0.0)
        self.ddelta.fill(0.0)
        self.disturbance.fill(0.0)
        self.first[0] = 1.0

    def update(self, model: CuffHorizonModel, force_est: np.ndarray, omega: np.ndarray) -> bool:
        """One tick: f̂ (4, 2) [N] and q̇ [rad/s], with ``model`` linearised at this tick.

        Returns False, and leaves the observer as it was, if f̂ is not finite.

        Raises:
            InvalidParameter: f̂ not (4, 2) or q̇ not (4,).

        """
        force = np.asarray(force_est, dtype=float)
        omega = np.asarray(omega, dtype=float)
        if force.ndim != 2 or omega.ndim != 1:
            v.refuse_shapes((4, 2), force_est=force)
            v.refuse_shapes((4,), omega=omega)
        status = _update(self.record, model.record, force, omega, model.split_switch)
        if status:
            v.refuse_shapes((4, 2), force_est=force)
            check(status, "CuffStateObserver.update", omega=omega)
        return bool(self.record["observed"][0])
