r"""Cuff (interaction) forces from the joint torque sensors: momentum observer.

**Link dynamics seen by the sensors.**  The joint torque sensors sit between
gearbox and link, so the rotor's reflected inertia is on the far side of
them: the observer uses the exoskeleton's *link* model only (no armature),

    M(q) q̈ + C(q, q̇) q̇ + g(q) = τ_s − b q̇ − f_c tanh(q̇/ε) + τ_ext,
    τ_ext = Σ_c J_cᵀ f_c,

with τ_s the sensor torque, b and f_c the URDF joint damping and dry
friction (link side, not seen by the sensor; ε =
:data:`~exo_ctrl.model.body.FRICTION_SMOOTHING_RAD_S`), f_c the (x, z) force of
cuff c on the exoskeleton and J_c the x, z rows of its frame Jacobian.

**Generalised-momentum observer** (De Luca & Mattone 2005; Haddadin, De
Luca & Albu-Schäffer, "Robot collisions: a survey on detection, isolation,
and identification", IEEE T-RO 33(6), 2017).  With p = M(q) q̇ and
Ṁ = C + Cᵀ, ṗ = τ_s − b q̇ − f_c tanh(q̇/ε) + Cᵀ q̇ − g + τ_ext, so

    r(t) = K_O [p(t) − p(0) − ∫₀ᵗ (τ_s − b q̇ − f_c tanh(q̇/ε) + Cᵀ q̇ − g + r) ds]

obeys ṙ = K_O (τ_ext − r): r is τ_ext through a first-order low-pass of
bandwidth K_O [1/s] (K_O / 2π Hz).  Neither q̈ nor a derivative of the
measured speed is needed.  The update makes two Pinocchio calls, ``crba``
(M) and ``nonLinearEffects`` (n = C q̇ + g): with Ṁ = C + Cᵀ (Pinocchio's C
is the Christoffel-consistent one), Cᵀ q̇ − g = Ṁ q̇ − n, and the Ṁ q̇ part
is integrated along the path from the encoder readings alone, ∫ Ṁ q̇ ds
over a step ≈ (M_k − M_{k-1}) (q_k − q_{k-1}) / h, so C itself is never
formed (pairing M(q_k) with the filtered speed instead would pair it with
a lagged signal: a mean error of up to 0.05 N·m on the default gait).

*Discrete form* (step h, readings q_k, q̇_k, τ_k, where τ_k is the sensor
reading over [t_{k-1}, t_k]; the plant's reading at tick k is the one of the
step just taken):  with m = −n(q, q̇) − b q̇ − f_c tanh(q̇/ε) and M_k = M(q_k),

    s_k = s_{k-1} + h (τ_k + ½ (m_{k-1} + m_k) + r_{k-1})
                  + (M_k − M_{k-1}) (q_k − q_{k-1}) / h,   s_0 = p_0,
    r_k = K_d (p_k − s_k),   K_d = (1 − e^{−K_O h}) / h,

which gives r_k = r_{k-1} + (1 − e^{−K_O h}) (e_k − r_{k-1}) with e_k the
external torque over the step.  As M_k q̇_k − M_{k-1} q̇_{k-1} =
½ (M_k + M_{k-1}) (q̇_k − q̇_{k-1}) + ½ (M_k − M_{k-1}) (q̇_k + q̇_{k-1}),
and (q_k − q_{k-1}) / h ≈ ½ (q̇_{k-1} + q̇_k),

    e_k ≈ ½ (M_{k-1} + M_k) (q̇_k − q̇_{k-1}) / h − ½ (m_{k-1} + m_k) − τ_k,

inverse dynamics with the mean mass matrix times the finite-difference
acceleration.  Given e_k, the r recursion is the exact zero-order-hold
discretisation of the continuous filter, stable for every K_O > 0 (K_d → K_O
as h → 0).  When h changes (a log with uneven time stamps) s is re-anchored
to s = p − r/K_d, which keeps that identity.

**Default gain** K_O = 100 1/s (bandwidth 16 Hz, time constant 10 ms).
The observer passes encoder-speed noise to r with a gain of about K_O M
(p = M q̇ enters r multiplied by K_O), and lags the cuff forces by 1/K_O.
On the default gait (cycle 1.2 s) with the default sensors
(:mod:`exo_ctrl.sensing.sensors`) the worst cuff's RMS error of the normal
component is 7.3 % of its peak at K_O = 50 1/s (lag), 4.4 % at 100 and 200,
and 7.0 % at 400 (speed noise) (tests/test_estimation.py prints this);
100 1/s is the less noisy end of the flat optimum.  With ideal sensors the
error is the lag alone: 4.6 % at 100 1/s, 0.45 % at 1000 1/s.

**Which cuff-force components are observable.**  Per leg the two joint
torques see two 2-D cuff forces (4 unknowns).  Let a be the hip-to-thigh-cuff
distance, c the knee-to-shank-cuff distance, l₁ the hip-to-knee distance,
ψ_t, ψ_k, ψ_s the directions (angles in the x–z plane from +x towards +z) of
hip → thigh cuff, hip → knee and knee → shank cuff, u = (cos ψ, sin ψ) the
*along* direction of a cuff and n = (−sin ψ, cos ψ) its *normal* (u turned
by +90°).  Split each force as f = f⊥ n + f∥ u.  With s_h, s_k the signs of
the hip and knee coordinates (+1 when the joint turns its link from +x
towards +z; the default URDF has s_h = +1, s_k = −1), τ = Σ J_cᵀ f_c gives

    τ_knee = s_k c f_s⊥,
    τ_hip  = s_h (a f_t⊥ + w f_s⊥ + l₁ sin(ψ_s − ψ_k) f_s∥),
    w = l₁ cos(ψ_s − ψ_k) + c.

So

- the thigh cuff's along-thigh component f_t∥ is invisible (no lever arm);
- the shank cuff's normal component f_s⊥ is exactly observable (knee torque);
- f_t⊥ and the shank's along-shank component f_s∥ appear only in the
  combination a f_t⊥ + l₁ sin(ψ_s − ψ_k) f_s∥ (the hip torque: with a bent
  knee, a force along the shank has a lever arm about the hip).

**Assumption** (``stiffness_ratio`` κ, default 1).  The patient's hip and
knee are coaxial with the exoskeleton's (how the device is fitted to a
patient, and what the computed-torque feedforward assumes) and the cuffs
are isotropic spring–dampers, the shank cuff κ times as stiff as the thigh
cuff (κ = 1: equal cuffs, as :class:`~exo_ctrl.plant.cuffs.CuffParams` models
them).  The cuff forces then come from the relative rotations δφ₁, δφ₂ of
the patient's thigh and shank about the common axes: to first order in δφ,
f_t = F₁ a n_t and f_s = κ (F₁ l₁ n_k + F₂ c n_s) (n_k: normal of
hip → knee) — when the thigh turns relative to the patient's thigh the
knees separate and the shank cuff is pulled partly along the shank.  So
f_t∥ = 0 and f_s∥ = κ (l₁/a) sin(ψ_s − ψ_k) f_t⊥, and per leg

    f_s⊥ = τ_knee / (s_k c),
    f_t⊥ = (τ_hip / s_h − w f_s⊥) / (a + κ l₁² sin²(ψ_s − ψ_k) / a).

κ = 0 is the other common assumption, "straps transmit only the force
normal to the limb" (f_s∥ = 0).  It is not the default because it does not
hold here: in the default run the shank cuff's along-shank force peaks at
about 107 N, twice its normal force (48 N), and with κ = 0 the thigh
estimate is off by half its peak, against 0.3 % with κ = 1 (beyond the
observer's lag; tests/test_estimation.py prints both).  The assumption fails where the
anatomy differs from the device (e.g. the human model, whose 0.44 m thigh is
not the exoskeleton's 0.52 m): the knees are then not coaxial, the thigh
cuff carries an along-thigh force that no torque sees, and only f_s⊥
remains exact.

The estimate is returned as the normal components f⊥ (4,) and as 2-D forces
(4, 2): f_t⊥ n_t for the thigh cuffs, f_s⊥ n_s + f_s∥ u_s for the shank
cuffs (with f_s∥ from the assumption; κ = 0 makes it f_s⊥ n_s).  For cuffs
on the link axis (the default URDFs, the human model) u is the link
direction and n the link direction turned by +90°; for a link hanging
straight down n points forward (+x).  A positive f_t⊥ turns the
exoskeleton's thigh forward (hip flexion with the default URDF).
:func:`cuff_components` and :func:`cuff_normal_components` split any cuff
force the same way, to compare estimates with the truth.

**Torque-sensor bias.**  A constant sensor offset β (reading = true + β) is
indistinguishable from a constant external torque: r → τ_ext − β, and the
force estimate is off by the solution of the 2×2 map above for −β.  Bounds over all postures
(the thigh's denominator is at least a):
|Δf_s⊥| = |β_knee| / c and |Δf_t⊥| ≤ (|β_hip| + (l₁ + c)/c |β_knee|) / a;
with the default exoskeleton (a = 0.39 m, c = 0.45 m, l₁ = 0.52 m): shank
2.2 N per N·m of knee bias, thigh up to 2.6 N per N·m of hip bias plus 5.5 N
per N·m of knee bias (:func:`bias_effect_bound`).
It is detected and measured by :func:`estimate_bias` from a run in which the
interaction is known to be zero (the device walking with the straps open),
and removed by passing it as ``torque_bias_Nm`` to the estimator.

**Offline.**  :func:`estimate_series` runs the same observer along a logged
series (the sensor readings q, q̇, τ logged every tick reproduce the live
estimate exactly); :func:`read_csv_log` reads a user's own log, a CSV file
whose header names (in any order; extra columns are ignored)::

    t,left_hip_q,left_knee_q,right_hip_q,right_knee_q,left_hip_tau,left_knee_tau,right_hip_tau,right_knee_tau

and optionally ``left_hip_dq,left_knee_dq,right_hip_dq,right_knee_dq``
(t [s], q [rad], dq [rad/s], tau: joint torque sensor readings [N·m]).
"""

from __future__ import annotations

import csv
import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from .. import _validate as v
from .._io import atomic_write
from .._jit import kernel, preload
from ..exceptions import InvalidLog, InvalidModel, InvalidParameter
from ..model.body import CUFF_NAMES, FRICTION_SMOOTHING_RAD_S, JOINT_NAMES, SIDES, BodyModel
from ..sensing.readings import SensorReadings

__all__ = [
    "CSV_DQ_COLUMNS",
    "CSV_REQUIRED_COLUMNS",
    "DEFAULT_GAIN_PER_S",
    "BiasEstimate",
    "CuffForceEstimator",
    "CuffGeometry",
    "EstimateErrorStats",
    "EstimateErrors",
    "EstimateSeries",
    "InvalidLog",
    "bias_effect_bound",
    "cuff_components",
    "cuff_forces_from_torque",
    "cuff_normal_components",
    "estimate_bias",
    "estimate_series",
    "first_order_filter",
    "normal_component_errors",
    "read_csv_log",
    "write_csv_log",
]

#: Default observer gain K_O [1/s] (bandwidth K_O / 2π ≈ 16 Hz).
DEFAULT_GAIN_PER_S = 100.0

#: Columns a CSV log must have, in any order (extra columns are ignored).
CSV_REQUIRED_COLUMNS = (
    "t",
    *(f"{j}_q" for j in JOINT_NAMES),
    *(f"{j}_tau" for j in JOINT_NAMES),
)
#: Optional joint-speed columns (all four or none).
CSV_DQ_COLUMNS = tuple(f"{j}_dq" for j in JOINT_NAMES)


# --------------------------------------------------------------------------- geometry


@dataclass(frozen=True)
class CuffGeometry:
    """Sagittal lever arms and directions of the cuffs, per leg (left, right).

    Read from the model at q = 0.  Directions are angles in the x–z plane
    from +x towards +z [rad]; at joint angles q they turn by s_h q_hip
    (thigh) and s_h q_hip + s_k q_knee (shank).

    Attributes:
        sign_hip: s_h per leg, (2,).
        sign_knee: s_k per leg, (2,).
        thigh_arm: a, hip to thigh cuff [m], (2,).
        thigh_dir0: ψ_t at q = 0, direction hip → thigh cuff [rad], (2,).
        knee_arm: l₁, hip to knee [m], (2,).
        knee_dir0: ψ_k at q = 0, direction hip → knee [rad], (2,).
        shank_arm: c, knee to shank cuff [m], (2,).
        shank_dir0: ψ_s at q = 0, direction knee → shank cuff [rad], (2,).

    """

    sign_hip: np.ndarray
    sign_knee: np.ndarray
    thigh_arm: np.ndarray
    thigh_dir0: np.ndarray
    knee_arm: np.ndarray
    knee_dir0: np.ndarray
    shank_arm: np.ndarray
    shank_dir0: np.ndarray

    @classmethod
    def from_body(cls, exo: BodyModel) -> CuffGeometry:
        """The geometry of an exoskeleton model (positions from Pinocchio at q = 0)."""
        data = exo.model.createData()
        pin.framesForwardKinematics(exo.model, data, pin.neutral(exo.model))
        values: dict[str, list[float]] = {f: [] for f in cls.__dataclass_fields__}
        for s, side in enumerate(SIDES):
            leg = exo.legs[side]
            hip = data.oMi[exo.joint_ids[2 * s]].translation[[0, 2]]
            knee = data.oMi[exo.joint_ids[2 * s + 1]].translation[[0, 2]]
            thigh = data.oMf[exo.cuff_frame_ids[2 * s]].translation[[0, 2]]
            shank = data.oMf[exo.cuff_frame_ids[2 * s + 1]].translation[[0, 2]]
            for name, vec in (
                ("thigh", thigh - hip),
                ("knee", knee - hip),
                ("shank", shank - knee),
            ):
                arm = float(np.hypot(vec[0], vec[1]))
                if arm < 1e-3:
                    raise InvalidModel(
                        exo.source,
                        f"{side}_{name}",
                        "a cuff (or the knee) sits on its joint axis: its force has no "
                        "lever arm and cannot be estimated from the joint torques",
                    )
                values[f"{name}_arm"].append(arm)
                values[f"{name}_dir0"].append(math.atan2(vec[1], vec[0]))
            values["sign_hip"].append(leg.sign_hip)
            values["sign_knee"].append(leg.sign_knee)
        return cls(**{k: np.array(x) for k, x in values.items()})

    def directions(self, q_exo: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """ψ_t, ψ_k, ψ_s at joint angles q_exo (…, 4) [rad], each (…, 2) (per leg)."""
        q = np.asarray(q_exo, dtype=float)
        hip, knee = q[..., 0::2], q[..., 1::2]
        thigh_turn = self.sign_hip * hip
        psi_t = self.thigh_dir0 + thigh_turn
        psi_k = self.knee_dir0 + thigh_turn
        psi_s = self.shank_dir0 + thigh_turn + self.sign_knee * knee
        return psi_t, psi_k, psi_s

    def cuff_directions(self, q_exo: np.ndarray) -> np.ndarray:
        """ψ of the four cuffs (thigh: ψ_t, shank: ψ_s), CUFF_NAMES order, (…, 4) [rad]."""
        psi_t, _, psi_s = self.directions(q_exo)
        return np.stack((psi_t[..., 0], psi_s[..., 0], psi_t[..., 1], psi_s[..., 1]), axis=-1)

    def normals(self, q_exo: np.ndarray) -> np.ndarray:
        """Unit normals n = (−sin ψ, cos ψ) of the four cuffs, (…, 4, 2)."""
        psi = self.cuff_directions(q_exo)
        return np.stack((-np.sin(psi), np.cos(psi)), axis=-1)

    def alongs(self, q_exo: np.ndarray) -> np.ndarray:
        """Unit along directions u = (cos ψ, sin ψ) (joint → cuff), (…, 4, 2)."""
        psi = self.cuff_directions(q_exo)
        return np.stack((np.cos(psi), np.sin(psi)), axis=-1)

    def torque_per_normal_force(
        self, q_exo: np.ndarray, stiffness_ratio: float = 1.0
    ) -> np.ndarray:
        """A(q): (τ_hip, τ_knee) = A (f_t⊥, f_s⊥) per leg under the assumption κ, (…, 2, 2, 2).

        A = [[s_h (a + κ l₁² sin²(ψ_s − ψ_k) / a), s_h w], [0, s_k c]] with
        w = l₁ cos(ψ_s − ψ_k) + c [m]; κ = 0: forces normal to the links only
        (default κ = 1, as the estimator).
        """
        _, psi_k, psi_s = self.directions(q_exo)
        w = self.knee_arm * np.cos(psi_s - psi_k) + self.shank_arm
        sn = np.sin(psi_s - psi_k)
        out = np.zeros((*np.shape(w), 2, 2))
        out[..., 0, 0] = self.sign_hip * (
            self.thigh_arm + stiffness_ratio * self.knee_arm**2 * sn**2 / self.thigh_arm
        )
        out[..., 0, 1] = self.sign_hip * w
        out[..., 1, 1] = self.sign_knee * self.shank_arm
        return out


_GEOMETRY_CACHE: dict[int, tuple[BodyModel, CuffGeometry]] = {}


def _geometry(exo: BodyModel | None) -> CuffGeometry:
    if exo is None:
        from ..model.body import load_exo

        key = 0
        if key not in _GEOMETRY_CACHE:
            body = load_exo()
            _GEOMETRY_CACHE[key] = (body, CuffGeometry.from_body(body))
        return _GEOMETRY_CACHE[key][1]
    key = id(exo)
    cached = _GEOMETRY_CACHE.get(key)
    if cached is None or cached[0] is not exo:
        _GEOMETRY_CACHE[key] = (exo, CuffGeometry.from_body(exo))
    return _GEOMETRY_CACHE[key][1]


def cuff_components(
    q_exo: np.ndarray, cuff_force: np.ndarray, exo: BodyModel | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Normal and along components (f⊥ = n · f, f∥ = u · f) of cuff forces [N].

    Args:
        q_exo: exoskeleton joint angles [rad], (4,) or (N, 4), JOINT_NAMES order.
        cuff_force: cuff forces on the exoskeleton (x, z) [N], (4, 2) or (N, 4, 2).
        exo: the exoskeleton model (None: the default exoskeleton URDF).

    Returns:
        (f⊥, f∥), each (…, 4) in CUFF_NAMES order; n and u as in the module
        docstring (u: joint → cuff, n: u turned by +90°).

    """
    q = np.asarray(q_exo, dtype=float)
    f = np.asarray(cuff_force, dtype=float)
    if q.shape[-1:] != (4,) or f.shape[-2:] != (4, 2) or q.shape[:-1] != f.shape[:-2]:
        raise InvalidParameter(
            "q_exo, cuff_force",
            (q.shape, f.shape),
            "shapes (4,) and (4, 2), or (N, 4) and (N, 4, 2)",
        )
    psi = _geometry(exo).cuff_directions(q)
    cos, sin = np.cos(psi), np.sin(psi)
    fx, fz = f[..., 0], f[..., 1]
    return -sin * fx + cos * fz, cos * fx + sin * fz


def cuff_normal_components(
    q_exo: np.ndarray, cuff_force: np.ndarray, exo: BodyModel | None = None
) -> np.ndarray:
    """Normal components f⊥ = n(q) · f of cuff forces [N], (…, 4).

    The part of a cuff force the estimator reports for every cuff (see
    :func:`cuff_components` for the arguments).
    """
    return cuff_components(q_exo, cuff_force, exo)[0]


def cuff_forces_from_torque(
    q_exo: np.ndarray,
    tau_ext: np.ndarray,
    exo: BodyModel | None = None,
    stiffness_ratio: float = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Cuff forces that explain external joint torques, under the assumption κ.

    Solves τ = A(q) (f_t⊥, f_s⊥) per leg (module docstring); the vectorised
    form of what :class:`CuffForceEstimator` does every tick.

    Args:
        q_exo: exoskeleton joint angles [rad], (4,) or (N, 4).
        tau_ext: external joint torques [N·m], same shape.
        exo: the exoskeleton model (None: the default URDF).
        stiffness_ratio: κ (0: forces normal to the links only).

    Returns:
        (normal components (…, 4) [N], forces on the exoskeleton (…, 4, 2) [N]).

    """
    q = np.asarray(q_exo, dtype=float)
    tau = np.asarray(tau_ext, dtype=float)
    if q.shape[-1:] != (4,) or q.shape != tau.shape:
        raise InvalidParameter("q_exo, tau_ext", (q.shape, tau.shape), "equal shapes (…, 4)")
    g = _geometry(exo)
    kappa = v.non_negative("stiffness_ratio", stiffness_ratio, "")
    _, psi_k, psi_s = g.directions(q)
    sn = np.sin(psi_s - psi_k)
    w = g.knee_arm * np.cos(psi_s - psi_k) + g.shank_arm
    f_s = tau[..., 1::2] / (g.sign_knee * g.shank_arm)
    f_t = (tau[..., 0::2] / g.sign_hip - w * f_s) / (
        g.thigh_arm + kappa * g.knee_arm**2 * sn**2 / g.thigh_arm
    )
    normal = np.zeros(q.shape)
    normal[..., 0::2] = f_t
    normal[..., 1::2] = f_s
    along = np.zeros(q.shape)
    along[..., 1::2] = kappa * g.knee_arm * sn / g.thigh_arm * f_t
    force = normal[..., None] * g.normals(q) + along[..., None] * g.alongs(q)
    return normal, force


# --------------------------------------------------------------------------- observer


class CuffForceEstimator:
    """Live cuff-force estimate from the sensor readings, one update per tick.

    An update is two Pinocchio calls (CRBA and nonLinearEffects, see
    :meth:`model_terms`) and one call of the compiled kernel
    :func:`_observer_kernel`, which does the rest (momentum, model terms, the
    observer step, the cuff forces).

    Args:
        exo: the exoskeleton model (its link model is used; see the module
            docstring).
        dt: control period h [s].
        gain_per_s: observer gain K_O [1/s] (bandwidth K_O / 2π Hz).
        torque_bias_Nm: a known (calibrated) torque-sensor bias to subtract,
            (4,) or scalar [N·m] (see :func:`estimate_bias`).
        stiffness_ratio: κ of the assumption (module docstring): shank-cuff
            over thigh-cuff stiffness with coaxial joints; 0: straps carry
            only normal forces [-].

    Attributes:
        tau_ext: external joint torques r of the last update [N·m], (4,).
        normal: estimated normal components f⊥ [N], (4,), CUFF_NAMES order.
        force: estimated cuff forces on the exoskeleton [N], (4, 2): f_t⊥ n_t
            (thighs), f_s⊥ n_s + f_s∥ u_s (shanks).
        geometry: the cuff lever arms and directions.

    """

    def __init__(
        self,
        exo: BodyModel,
        dt: float,
        gain_per_s: float = DEFAULT_GAIN_PER_S,
        torque_bias_Nm: np.ndarray | float = 0.0,
        stiffness_ratio: float = 1.0,
    ) -> None:
        if not np.array_equal(exo.q_index, np.arange(4)) or exo.model.nq != 4:
            raise InvalidModel(
                exo.source, "", f"the estimator needs exactly the joints {JOINT_NAMES} in order"
            )
        self.dt = v.positive("dt", dt, "s")
        self.gain_per_s = v.positive("gain", gain_per_s, "1/s")
        bias = np.broadcast_to(np.asarray(torque_bias_Nm, dtype=float), (4,))
        for b in bias:
            v.finite("torque_bias", b, "N·m")
        # The kernel's parameters, state and outputs in one buffer (layout:
        # the _P_* and _B_* indices); tau_ext, normal and force are views of it.
        self._work = np.zeros(_W_SIZE)
        self.torque_bias_Nm = self._work[_P_BIAS : _P_BIAS + 4]
        self.torque_bias_Nm[:] = bias
        self._has_bias = bool(np.any(bias != 0))
        self.stiffness_ratio = stiffness_ratio
        self.exo = exo
        self.geometry = CuffGeometry.from_body(exo)
        self._model = pin.Model(exo.model)
        self._model.armature = np.zeros(self._model.nv)  # link side: no rotor inertia
        self._data = self._model.createData()
        par = self._work
        par[_P_DAMPING : _P_DAMPING + 4] = exo.damping
        par[_P_FRICTION : _P_FRICTION + 4] = exo.friction
        par[_P_EPS] = FRICTION_SMOOTHING_RAD_S
        par[_P_HAS_FRICTION] = bool(np.any(exo.friction > 0))
        par[_P_HAS_BIAS] = self._has_bias
        g = self.geometry
        for s in range(2):
            par[_P_LEGS + 8 * s : _P_LEGS + 8 * s + 8] = (
                g.sign_hip[s],
                g.sign_knee[s],
                g.thigh_arm[s],
                g.thigh_dir0[s],
                g.knee_arm[s],
                g.knee_dir0[s],
                g.shank_arm[s],
                g.shank_dir0[s],
            )
        self._s = self._work[_B_S : _B_S + 4]  # p_0 + ∫ (τ + m + r) dt
        self._p = self._work[_B_P : _B_P + 4]
        self._tmp = np.zeros(4)
        self._zeros = np.zeros(4)
        self._h_cached = math.nan
        self._started = False
        self.tau_ext = self._work[_B_R : _B_R + 4]
        self.normal = self._work[_B_NORMAL : _B_NORMAL + 4]
        self.force = self._work[_B_FORCE : _B_FORCE + 8].reshape(4, 2)
        #: (tau_ext, normal, force) as one contiguous (16,) view, for logging.
        self.outputs_flat = self._work[_B_R : _B_R + 16]

    @property
    def stiffness_ratio(self) -> float:
        """κ of the assumption [-] (module docstring)."""
        return self._stiffness_ratio

    @stiffness_ratio.setter
    def stiffness_ratio(self, value: float) -> None:
        self._stiffness_ratio = v.non_negative("stiffness_ratio", value, "")
        self._work[_P_KAPPA] = self._stiffness_ratio

    # ------------------------------------------------------------------ public

    def reset(self, q: np.ndarray | None = None, dq: np.ndarray | None = None) -> None:
        """Restart the observer (estimate zero).

        Args:
            q: joint angles [rad] at the tick *before* the next :meth:`update`
                (which then integrates over one period dt from this state);
                None: the next update starts the observer at its own readings.
            dq: joint speeds [rad/s] with ``q``.

        """
        self.tau_ext[:] = 0.0
        self.normal[:] = 0.0
        self.force[:] = 0.0
        self._started = False
        self._work[_B_STARTED] = 0.0
        if q is None or dq is None:
            return
        self.step(np.asarray(q, dtype=float), np.asarray(dq, dtype=float), self._zeros, self.dt)

    def update(self, sensors: SensorReadings) -> np.ndarray:
        """Advance by one control period with this tick's readings.

        Args:
            sensors: encoder angles q [rad], speeds dq [rad/s] and sensor
                torques tau [N·m] of this tick.

        Returns:
            The estimated cuff forces on the exoskeleton, (4, 2) [N]
            (:attr:`force`, overwritten by the next update).

        """
        return self.step(sensors.q, sensors.dq, sensors.tau, self.dt)

    def step(self, q: np.ndarray, dq: np.ndarray, tau: np.ndarray, h: float) -> np.ndarray:
        """Advance by a step h [s] with readings (q, dq, tau); as :meth:`update`.

        The first step after construction or :meth:`reset` starts the observer
        at these readings (estimate zero; ``tau`` and ``h`` unused).
        """
        if not (type(q) is type(dq) is type(tau) is np.ndarray):
            q, dq, tau = v.arrays((4,), q=q, dq=dq, tau=tau)
        if q.shape != (4,) or dq.shape != (4,):  # before Pinocchio sees them
            v.refuse_shapes((4,), q=q, dq=dq)
        if not self._started:
            self._started = True  # the kernel starts the observer at these readings
        elif h != self._h_cached:
            self._set_step(h)
        if _observer_kernel(*self.model_terms(q, dq), q, dq, tau, h, self._work) < 0:
            v.refuse_shapes((4,), tau=tau)
        return self.force

    def model_terms(self, q: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """M(q) and n(q, q̇) = C(q, q̇) q̇ + g(q) of the link model: the kernel's first two arguments.

        Pinocchio's ``crba`` and ``nonLinearEffects`` (arrays of its data,
        overwritten by the next call).  ``q`` and ``dq`` must be (4,) arrays.
        """
        model, data = self._model, self._data
        return pin.crba(model, data, q), pin.nonLinearEffects(model, data, q, dq)

    def running_at(self, h: float) -> bool:
        """Whether the observer has started and steps by h (its next update takes no set-up)."""
        return self._started and h == self._h_cached

    # ------------------------------------------------------------------ internals

    def _set_step(self, h: float) -> None:
        """A new step h: K_d = (1 − e^{−K_O h}) / h, and s re-anchored to p − r / K_d."""
        if not h > 0:
            raise InvalidParameter("step", h, "> 0 s")
        self._h_cached = h
        kd = -math.expm1(-self.gain_per_s * h) / h
        self._work[_B_KD] = kd
        # A new step length changes K_d: re-anchor s so that r_{k-1} = K_d (p_{k-1} - s_{k-1}).
        np.divide(self.tau_ext, kd, out=self._tmp)
        np.subtract(self._p, self._tmp, out=self._s)


# Layout of the observer kernel's buffer.  Parameters: damping b, friction
# f_c, bias β (4 each), ε, has-friction and has-bias flags, κ, then per leg
# (s_h, s_k, a, ψ_t0, l₁, ψ_k0, c, ψ_s0).
_P_DAMPING, _P_FRICTION, _P_BIAS, _P_EPS, _P_HAS_FRICTION, _P_HAS_BIAS = 0, 4, 8, 12, 13, 14
_P_KAPPA, _P_LEGS = 15, 16
# Then, from 32 (after the two legs' 8), state and outputs: s, p, m,
# m_{k-1}, r, f⊥ (4 each), the forces (4 × 2, row-major), K_d, started flag,
# M_{k-1} (4 × 4, row-major), q_{k-1} (4).  r, f⊥ and the forces stay
# contiguous (CuffForceEstimator.outputs_flat).
_B_S, _B_P, _B_M, _B_M_PREV, _B_R, _B_NORMAL, _B_FORCE = 32, 36, 40, 44, 48, 52, 56
_B_KD, _B_STARTED, _B_MASS_PREV, _B_Q_PREV = 64, 65, 66, 82
_W_SIZE = 86


@kernel
def _observer_kernel(mass, nle, q, dq, tau, h, w):
    """One observer step in place (module docstring, discrete form), then the cuff forces.

    ``mass``, ``nle``: M(q) and n(q, q̇) (:meth:`CuffForceEstimator.model_terms`).
    p = M q̇, m = −n − b q̇ − f_c tanh(q̇/ε);
    s += h (τ − β + ½ (m_{k-1} + m) + r) + (M − M_{k-1}) (q − q_{k-1}) / h,
    r = K_d (p − s).
    Not started (w's flag 0): s = p, m_{k-1} = m, M_{k-1} = M, q_{k-1} = q,
    r = f = 0, flag set.
    Returns 0, or -1 (and nothing done) when ``tau`` is not of length 4.
    """
    if tau.shape[0] != 4:
        return -1
    has_friction = w[_P_HAS_FRICTION] != 0.0
    eps = w[_P_EPS]
    for i in range(4):
        p = 0.0
        for j in range(4):
            p += mass[i, j] * dq[j]
        m = -nle[i] - w[_P_DAMPING + i] * dq[i]
        if has_friction:
            m = m - math.tanh(dq[i] / eps) * w[_P_FRICTION + i]
        w[_B_P + i] = p
        w[_B_M + i] = m
    if w[_B_STARTED] == 0.0:
        for i in range(4):
            w[_B_S + i] = w[_B_P + i]
            w[_B_M_PREV + i] = w[_B_M + i]
            w[_B_R + i] = 0.0
            w[_B_NORMAL + i] = 0.0
            w[_B_FORCE + 2 * i] = 0.0
            w[_B_FORCE + 2 * i + 1] = 0.0
            w[_B_Q_PREV + i] = q[i]
            for j in range(4):
                w[_B_MASS_PREV + 4 * i + j] = mass[i, j]
        w[_B_STARTED] = 1.0
        return 0
    has_bias = w[_P_HAS_BIAS] != 0.0
    kd = w[_B_KD]
    for i in range(4):
        x = (w[_B_M_PREV + i] + w[_B_M + i]) * 0.5 + tau[i]
        if has_bias:
            x = x - w[_P_BIAS + i]
        dp = 0.0  # (M_k − M_{k-1}) (q_k − q_{k-1}), row i; then M_{k-1} = M_k
        for j in range(4):
            o = _B_MASS_PREV + 4 * i + j
            dp += (mass[i, j] - w[o]) * (q[j] - w[_B_Q_PREV + j])
            w[o] = mass[i, j]
        s = w[_B_S + i] + (x + w[_B_R + i]) * h + dp / h
        w[_B_S + i] = s
        w[_B_R + i] = (w[_B_P + i] - s) * kd
        w[_B_M_PREV + i] = w[_B_M + i]
    for i in range(4):
        w[_B_Q_PREV + i] = q[i]
    _cuffs_kernel(q, w)
    return 0


@kernel
def _cuff_directions(sign_hip, sign_knee, psi_t0, psi_s0, q_hip, q_knee):
    """ψ_t = ψ_t0 + s_h q_hip, ψ_s = ψ_s0 + s_h q_hip + s_k q_knee [rad] (as CuffGeometry)."""
    turn = sign_hip * q_hip
    return psi_t0 + turn, psi_s0 + turn + sign_knee * q_knee


@kernel
def _cuffs_kernel(q, w):
    """Normal components and forces from r: solve A(q) (f_t⊥, f_s⊥) = (τ_hip, τ_knee) per leg."""
    kappa = w[_P_KAPPA]
    for s in range(2):
        o = _P_LEGS + 8 * s
        sh, sk, a, dt0 = w[o], w[o + 1], w[o + 2], w[o + 3]
        l1, dk0, c, ds0 = w[o + 4], w[o + 5], w[o + 6], w[o + 7]
        qh, qk = q[2 * s], q[2 * s + 1]
        psi_t, psi_s = _cuff_directions(sh, sk, dt0, ds0, qh, qk)
        psi_k = dk0 + sh * qh
        f_s = w[_B_R + 2 * s + 1] / (sk * c)
        w_arm = l1 * math.cos(psi_s - psi_k) + c  # w of the module docstring
        sn = math.sin(psi_s - psi_k)
        kappa_sn = kappa * sn
        f_t = (w[_B_R + 2 * s] / sh - w_arm * f_s) / (a + kappa_sn * sn * l1 * l1 / a)
        w[_B_NORMAL + 2 * s] = f_t
        w[_B_NORMAL + 2 * s + 1] = f_s
        f = _B_FORCE + 4 * s  # rows 2s and 2s + 1 of the (4, 2) forces
        w[f] = -f_t * math.sin(psi_t)
        w[f + 1] = f_t * math.cos(psi_t)
        f_sa = kappa_sn * l1 / a * f_t  # f_s∥, along knee → shank cuff
        w[f + 2] = -f_s * math.sin(psi_s) + f_sa * math.cos(psi_s)
        w[f + 3] = f_s * math.cos(psi_s) + f_sa * math.sin(psi_s)


# --------------------------------------------------------------------------- offline


@dataclass
class EstimateSeries:
    """The observer's output along a logged series.

    Attributes:
        t: times [s], (N,).
        normal: estimated normal components f⊥ [N], (N, 4), CUFF_NAMES order.
        force: estimated cuff forces on the exoskeleton f⊥ n [N], (N, 4, 2).
        tau_ext: external joint torques r [N·m], (N, 4), JOINT_NAMES order.
        gain_per_s: the observer gain used [1/s].

    """

    t: np.ndarray
    normal: np.ndarray
    force: np.ndarray
    tau_ext: np.ndarray
    gain_per_s: float


def _check_series(t, q, dq, tau) -> tuple[np.ndarray, ...]:
    t = np.asarray(t, dtype=float)
    arrays = {"q": q, "tau": tau} if dq is None else {"q": q, "dq": dq, "tau": tau}
    if t.ndim != 1 or t.shape[0] < 2:
        raise InvalidLog("arrays", f"t must have shape (N,) with N >= 2; got {t.shape}")
    out = {}
    for name, arr in arrays.items():
        a = np.asarray(arr, dtype=float)
        if a.shape != (t.shape[0], 4):
            raise InvalidLog(
                "arrays", f"{name} must have shape ({t.shape[0]}, 4) like t; got {a.shape}"
            )
        out[name] = a
    for name, a in {"t": t, **out}.items():
        bad = np.flatnonzero(~np.all(np.isfinite(a.reshape(a.shape[0], -1)), axis=1))
        if bad.size:
            raise InvalidLog("arrays", f"{name} has a non-finite value in row {bad[0]}")
    steps = np.diff(t)
    if not np.all(steps > 0):
        i = int(np.flatnonzero(~(steps > 0))[0])
        raise InvalidLog(
            "arrays",
            f"t must be strictly increasing; t[{i + 1}] = {float(t[i + 1])!r} <= t[{i}]",
        )
    return t, out["q"], out.get("dq"), out["tau"]


def estimate_series(
    t: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray | None,
    tau_sensor: np.ndarray,
    exo: BodyModel,
    gain_per_s: float = DEFAULT_GAIN_PER_S,
    dt: float | None = None,
    torque_bias_Nm: np.ndarray | float = 0.0,
    stiffness_ratio: float = 1.0,
) -> EstimateSeries:
    """Run the momentum observer along a logged series of sensor readings.

    Row 0 starts the observer (estimate zero); row k > 0 advances it by
    h_k = t_k − t_{k-1} (or ``dt``), exactly as :meth:`CuffForceEstimator.update`
    does live, so the logged readings of a run reproduce its live estimate.

    Args:
        t: times [s], (N,), strictly increasing.
        q: encoder joint angles [rad], (N, 4), JOINT_NAMES order.
        dq: joint speeds [rad/s], (N, 4); None: central differences of q
            (``numpy.gradient``; then the result differs from a live estimate
            that used the sensors' own speed).
        tau_sensor: joint torque sensor readings [N·m], (N, 4).
        exo: the exoskeleton model.
        gain_per_s: observer gain K_O [1/s].
        dt: a fixed step [s] to use for every row (the control period of a
            recorded run, so that the estimate matches the live one to
            rounding); None: the differences of t.
        torque_bias_Nm: a known torque-sensor bias to subtract [N·m].
        stiffness_ratio: κ of the assumption (see :class:`CuffForceEstimator`).

    Returns:
        The estimate at every row.

    Raises:
        InvalidLog: shapes differ, a value is not finite, or t does not increase.

    """
    t, q, dq, tau = _check_series(t, q, dq, tau_sensor)
    if dq is None:
        dq = np.gradient(q, t, axis=0)
    if dt is not None:
        v.positive("dt", dt, "s")
        steps = np.diff(t)
        if np.max(np.abs(steps - dt)) > 1e-6 * dt + 1e-12:
            raise InvalidLog("arrays", f"t is not sampled every dt = {dt!r} s")
    est = CuffForceEstimator(
        exo,
        dt if dt is not None else float(t[1] - t[0]),
        gain_per_s,
        torque_bias_Nm,
        stiffness_ratio,
    )
    n = t.shape[0]
    normal = np.zeros((n, 4))
    force = np.zeros((n, 4, 2))
    tau_ext = np.zeros((n, 4))
    for k in range(n):
        h = dt if dt is not None else (t[k] - t[k - 1] if k else 1.0)
        est.step(q[k], dq[k], tau[k], h)
        normal[k] = est.normal
        force[k] = est.force
        tau_ext[k] = est.tau_ext
    return EstimateSeries(t=t, normal=normal, force=force, tau_ext=tau_ext, gain_per_s=gain_per_s)


def first_order_filter(x: np.ndarray, dt: float, gain_per_s: float) -> np.ndarray:
    """The observer's own filter applied to a series: y_k = y_{k-1} + α (x_k − y_{k-1}).

    α = 1 − e^{−K_O dt}, y_0 = 0 (as the observer starts at zero).  Applied to
    the true external torques (or cuff forces) aligned with the readings, it
    gives what an exact observer would output, separating the observer's lag
    from its errors.

    Args:
        x: series, (N, …).
        dt: sampling period [s].
        gain_per_s: K_O [1/s].

    """
    x = np.asarray(x, dtype=float)
    alpha = -math.expm1(-v.positive("gain", gain_per_s, "1/s") * v.positive("dt", dt, "s"))
    y = np.zeros_like(x)
    for k in range(1, x.shape[0]):
        y[k] = y[k - 1] + alpha * (x[k] - y[k - 1])
    return y


# --------------------------------------------------------------------------- errors


@dataclass
class EstimateErrors:
    """Errors of estimated normal components against the truth, per cuff.

    Attributes:
        rms_error_N: RMS of (estimate − true normal component) [N], (4,).
        max_error_N: largest |estimate − true| [N], (4,).
        peak_true_N: peak |true normal component| [N], (4,).
        rms_error_rel: rms_error_N / peak_true_N [-], (4,).
        rows: number of rows compared.

    """

    rms_error_N: np.ndarray
    max_error_N: np.ndarray
    peak_true_N: np.ndarray
    rms_error_rel: np.ndarray
    rows: int

    def summary(self) -> dict[str, dict[str, float]]:
        """``cuff_force_estimate_rms_error_N`` and ``…_rel``, keyed by cuff."""

        def keyed(x: np.ndarray) -> dict[str, float]:
            return {c: float(val) for c, val in zip(CUFF_NAMES, x, strict=True)}

        return {
            "cuff_force_estimate_rms_error_N": keyed(self.rms_error_N),
            "cuff_force_estimate_rms_error_rel": keyed(self.rms_error_rel),
        }


def normal_component_errors(
    q_exo: np.ndarray,
    cuff_force_true: np.ndarray,
    normal_est: np.ndarray,
    exo: BodyModel | None = None,
    skip: int = 0,
    lag: int = 0,
) -> EstimateErrors:
    """Compare estimated normal components with the true cuff forces.

    Row k of the estimate is compared with the normal component of row
    k − ``lag`` of the truth, taken along the normals at q_exo row k.  In
    :func:`exo_ctrl.sim.loop.simulate` row k of ``cuff_force`` is the force
    over [t_k, t_k+1), while the estimate of tick k uses the sensor torque of
    [t_{k-1}, t_k]: pass ``lag=1`` there (as :class:`EstimateErrorStats`
    does).

    Args:
        q_exo: true exoskeleton joint angles [rad], (N, 4), rows as the estimate.
        cuff_force_true: true cuff forces on the exoskeleton [N], (N, 4, 2).
        normal_est: estimated normal components [N], (N, 4).
        exo: the exoskeleton model (None: the default URDF).
        skip: estimate rows to leave out at the start (the observer's
            start-up, a few 1/K_O).
        lag: rows by which the estimate trails the truth.

    """
    q = np.asarray(q_exo, dtype=float)
    force = np.asarray(cuff_force_true, dtype=float)
    est = np.asarray(normal_est, dtype=float)
    n = est.shape[0]
    start = max(skip, lag)
    if n - start < 1 or force.shape[0] < n - lag or q.shape[0] < n:
        raise InvalidParameter("skip", skip, f"< {n - lag} rows with these series")
    truth = cuff_normal_components(q[start:n], force[start - lag : n - lag], exo)
    err = est[start:n] - truth
    rms = np.sqrt(np.mean(err**2, axis=0))
    peak = np.max(np.abs(truth), axis=0)
    rel = np.divide(rms, peak, out=np.full(4, np.inf), where=peak > 0)
    return EstimateErrors(
        rms_error_N=rms,
        max_error_N=np.max(np.abs(err), axis=0),
        peak_true_N=peak,
        rms_error_rel=rel,
        rows=int(err.shape[0]),
    )


class EstimateErrorStats:
    """Running errors of a live estimate against the simulated truth, chunk by chunk.

    Fed with the rows :func:`exo_ctrl.sim.loop.simulate` logs: ``q`` (true
    exoskeleton angles at t_k), ``cuff_force`` (true force over
    [t_k, t_k+1)) and the estimate of tick k.  The estimate of tick k uses
    the torque reading of the step just taken, so it is compared with the
    previous row's force (carried across chunks): the pairing of
    :func:`normal_component_errors` with ``lag=1``.  Rows before ``skip_s``
    (the observer's start-up) are left out.

    Args:
        exo: the exoskeleton model.
        dt: control period [s].
        skip_s: start-up left out [s] (default 50 ms, five time constants of
            the default observer).

    """

    def __init__(self, exo: BodyModel | None, dt: float, skip_s: float = 0.05) -> None:
        self.exo = exo
        self.skip = round(v.non_negative("skip", skip_s, "s") / v.positive("dt", dt, "s"))
        self.rows = 0
        g = _geometry(exo)
        # Per leg: s_h, s_k, ψ_t0, ψ_s0 (the cuff directions of CuffGeometry).
        self._legs = np.stack((g.sign_hip, g.sign_knee, g.thigh_dir0, g.shank_dir0), axis=1)
        self._prev_force = np.zeros((4, 2))  # the last row's force, once a row was seen
        # Σ err², max |err|, max |truth| per cuff: _error_sums' buffer.
        self._sums = np.zeros((3, 4))
        self._n = 0

    def update(self, q: np.ndarray, cuff_force: np.ndarray, normal_est: np.ndarray) -> None:
        """Add rows: q (n, 4) [rad], cuff_force (n, 4, 2) [N], normal_est (n, 4) [N]."""
        n = np.shape(q)[0]
        if n == 0:
            return
        # Truth paired with row i: the force of row i - 1 (the previous chunk's last).
        start = max(self.skip - self.rows, 0 if self.rows else 1)
        if start < n:
            _error_sums(q, cuff_force, self._prev_force, normal_est, start, self._legs, self._sums)
            self._n += n - start
        self._prev_force[:] = cuff_force[-1]
        self.rows += n

    def preload(self, q: np.ndarray, cuff_force: np.ndarray, normal_est: np.ndarray) -> None:
        """Load the compiled kernel for rows of these arrays' types (before a timed run)."""
        preload(_error_sums, q, cuff_force, self._prev_force, normal_est, 0, self._legs, self._sums)

    def result(self) -> EstimateErrors:
        """The errors so far (zeros before any compared row)."""
        sq, max_err, peak = self._sums
        rms = np.sqrt(sq / max(self._n, 1))
        rel = np.divide(rms, peak, out=np.zeros(4), where=peak > 0)
        return EstimateErrors(
            rms_error_N=rms,
            max_error_N=max_err.copy(),
            peak_true_N=peak.copy(),
            rms_error_rel=rel,
            rows=self._n,
        )

    def summary(self) -> dict[str, dict[str, float]]:
        """``cuff_force_estimate_rms_error_N`` and ``…_rel`` keyed by cuff."""
        return self.result().summary()


@kernel
def _error_sums(q, force, prev_force, normal_est, start, legs, sums):
    """Add rows start… to :class:`EstimateErrorStats`' sums (Σ err², max |err|, max |truth|).

    The truth of row i is the normal component n(q_i) · f_{i-1} of the
    previous row's force (``prev_force`` for row 0), per cuff in CUFF_NAMES
    order, with ψ_t = ψ_t0 + s_h q_hip and ψ_s = ψ_s0 + s_h q_hip + s_k q_knee
    (:meth:`CuffGeometry.directions`; ``legs`` rows (s_h, s_k, ψ_t0, ψ_s0)).
    """
    for r in range(start, q.shape[0]):
        for s in range(2):
            psi_t, psi_s = _cuff_directions(
                legs[s, 0], legs[s, 1], legs[s, 2], legs[s, 3], q[r, 2 * s], q[r, 2 * s + 1]
            )
            for c in range(2 * s, 2 * s + 2):
                psi = psi_t if c == 2 * s else psi_s
                if r == 0:
                    fx, fz = prev_force[c, 0], prev_force[c, 1]
                else:
                    fx, fz = force[r - 1, c, 0], force[r - 1, c, 1]
                truth = -math.sin(psi) * fx + math.cos(psi) * fz
                err = normal_est[r, c] - truth
                sums[0, c] += err * err
                sums[1, c] = max(sums[1, c], abs(err))
                sums[2, c] = max(sums[2, c], abs(truth))


# --------------------------------------------------------------------------- bias


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
    ``torque_bias_Nm`` to :class:`CuffForceEstimator` (or
    :func:`estimate_series`) to remove it.  Prefer a window of whole gait
    cycles, or a still posture: errors that follow the motion (the speed
    filter's lag) average out over a cycle.

    Args:
        tau_ext: observer output r over the window (skip the observer's
            start-up) [N·m], (N, 4) with N >= 10.
        exo: the exoskeleton model (None: the default URDF), for the force bound.
        tolerance_Nm: smallest bias reported as detected [N·m].

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


# --------------------------------------------------------------------------- CSV


def read_csv_log(
    path: str | os.PathLike[str],
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
    """Read a sensor log written as CSV.

    The first line is a header naming the columns, comma-separated, in any
    order; extra columns are ignored.  Required::

        t,left_hip_q,left_knee_q,right_hip_q,right_knee_q,
        left_hip_tau,left_knee_tau,right_hip_tau,right_knee_tau

    (one line), optional: ``left_hip_dq,left_knee_dq,right_hip_dq,right_knee_dq``
    (all four or none).  Units: t [s], *_q [rad], *_dq [rad/s], *_tau [N·m]
    (joint torque sensor readings); joints positive in flexion.

    Args:
        path: the CSV file.

    Returns:
        (t (N,), q (N, 4), dq (N, 4) or None, tau (N, 4)).

    Raises:
        InvalidLog: the file is missing or empty, a column is missing, a value
            is not a finite number, fewer than 2 rows, or t is not strictly
            increasing; the message names the line and column.

    """
    src = str(path)
    p = Path(path)
    if not p.is_file():
        raise InvalidLog(src, "file not found")
    with p.open(newline="", encoding="utf-8") as handle:
        reader = csv.reader(handle)
        header = next(reader, None)
        if header is None:
            raise InvalidLog(src, "the file is empty; expected a header line")
        header = [h.strip() for h in header]
        missing = [c for c in CSV_REQUIRED_COLUMNS if c not in header]
        if missing:
            raise InvalidLog(
                src,
                f"missing column(s) {', '.join(missing)}; the header must name "
                f"{','.join(CSV_REQUIRED_COLUMNS)} (and optionally {','.join(CSV_DQ_COLUMNS)})",
                line=1,
            )
        have_dq = [c for c in CSV_DQ_COLUMNS if c in header]
        if have_dq and len(have_dq) != 4:
            lacking = [c for c in CSV_DQ_COLUMNS if c not in header]
            raise InvalidLog(
                src, f"has {have_dq[0]} but not {lacking[0]}: give all four *_dq or none", line=1
            )
        wanted = list(CSV_REQUIRED_COLUMNS) + (list(CSV_DQ_COLUMNS) if have_dq else [])
        cols = [header.index(c) for c in wanted]
        rows = []
        for line_no, row in enumerate(reader, start=2):
            if not row or all(not x.strip() for x in row):
                continue
            if len(row) < len(header):
                raise InvalidLog(
                    src, f"{len(row)} fields, the header has {len(header)}", line=line_no
                )
            values = []
            for name, col in zip(wanted, cols, strict=True):
                text = row[col].strip()
                try:
                    x = float(text)
                except ValueError:
                    raise InvalidLog(
                        src, f"not a number: {text!r}", line=line_no, column=name
                    ) from None
                if not math.isfinite(x):
                    raise InvalidLog(
                        src, f"not a finite number: {text!r}", line=line_no, column=name
                    )
                values.append(x)
            rows.append((line_no, values))
    if len(rows) < 2:
        raise InvalidLog(src, f"needs at least 2 data rows; got {len(rows)}")
    data = np.array([vals for _, vals in rows])
    t = data[:, 0]
    steps = np.diff(t)
    if not np.all(steps > 0):
        i = int(np.flatnonzero(~(steps > 0))[0])
        raise InvalidLog(
            src,
            f"t must be strictly increasing; t = {float(t[i + 1])!r} s follows "
            f"t = {float(t[i])!r} s",
            line=rows[i + 1][0],
            column="t",
        )
    q = data[:, 1:5]
    tau = data[:, 5:9]
    dq = data[:, 9:13] if have_dq else None
    return t, q, dq, tau


def write_csv_log(
    path: str | os.PathLike[str],
    t: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray | None,
    tau: np.ndarray,
) -> Path:
    """Write a sensor log in the format :func:`read_csv_log` reads (values round-trip exactly).

    Args:
        path: the CSV file to write (replaced atomically).
        t: times [s], (N,).
        q: joint angles [rad], (N, 4).
        dq: joint speeds [rad/s], (N, 4), or None (no *_dq columns).
        tau: joint torque sensor readings [N·m], (N, 4).

    """
    t, q, dq, tau = _check_series(t, q, dq, tau)
    header = list(CSV_REQUIRED_COLUMNS) + (list(CSV_DQ_COLUMNS) if dq is not None else [])
    parts = [t[:, None], q, tau] + ([dq] if dq is not None else [])
    data = np.hstack(parts)
    with atomic_write(path) as handle:
        handle.write(",".join(header) + "\n")
        for row in data:
            handle.write(",".join(repr(float(x)) for x in row) + "\n")
    return Path(path)
