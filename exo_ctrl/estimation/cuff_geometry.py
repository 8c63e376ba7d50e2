r"""Cuff lever arms and directions, cuff-force components, and the torque ↔ force map.

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
cuff (κ = 1: equal cuffs, as ``CuffParams.isotropic()`` models them; the
default truth's cuffs are softer in shear and break it on purpose, as does a
misaligned patient, :mod:`exo_ctrl.plant.misalignment`: the estimator keeps
its assumption, :mod:`.errors` measures what it costs).  The cuff forces
then come from the relative rotations δφ₁, δφ₂ of the patient's thigh and
shank about the common axes: to first order in δφ,
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
observer's lag; tests/estimation/test_observer.py prints both).  The
assumption fails where the anatomy differs from the device (e.g. the human
model, whose 0.44 m thigh is not the exoskeleton's 0.52 m): the knees are
then not coaxial, the thigh cuff carries an along-thigh force that no torque
sees, and only f_s⊥ remains exact.

**Outputs.**  An estimate is given as the normal components f⊥ (4,) and as
2-D forces (4, 2): f_t⊥ n_t for the thigh cuffs, f_s⊥ n_s + f_s∥ u_s for
the shank cuffs (with f_s∥ from the assumption; κ = 0 makes it f_s⊥ n_s).
For cuffs on the link axis (the default URDFs, the human model) u is the
link direction and n the link direction turned by +90°; for a link hanging
straight down n points forward (+x).  A positive f_t⊥ turns the
exoskeleton's thigh forward (hip flexion with the default URDF).
:func:`cuff_components` and :func:`cuff_normal_components` split any cuff
force the same way, to compare estimates with the truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
import pinocchio as pin

from .. import _validate as v
from .._jit import kernel
from ..exceptions import InvalidModel, InvalidParameter
from ..model import SIDES, BodyModel, load_exo

__all__ = [
    "GEOMETRY_FIELDS",
    "CuffGeometry",
    "cuff_components",
    "cuff_forces_from_torque",
    "cuff_normal_components",
]


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

    def fill(self, state: np.ndarray) -> None:
        """Write the geometry into a record that has the :data:`GEOMETRY_FIELDS`."""
        for f in fields(self):
            state[f.name][0] = getattr(self, f.name)

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

    def joint_arms(self) -> np.ndarray:
        """Per joint the lever of the cuff its torque loads [m], (4,) JOINT_NAMES order.

        Hip: a (hip → thigh cuff); knee: c (knee → shank cuff).
        """
        return np.stack((self.thigh_arm, self.shank_arm), axis=1).ravel()

    def joint_torques(self, q_exo: np.ndarray, cuff_force: np.ndarray) -> np.ndarray:
        """τ = Σ_c J_cᵀ f_c, the torques cuff forces put on the exoskeleton's joints [N·m], (4,).

        Per leg, with u × f = cos ψ f_z − sin ψ f_x (the moment of f about the
        joint per metre of arm along u): τ_knee = s_k c (u_s × f_s) and τ_hip =
        s_h (a (u_t × f_t) + l₁ (u_k × f_s) + c (u_s × f_s)).  ``q_exo`` (4,) [rad],
        ``cuff_force`` (4, 2) on the exoskeleton (x, z) [N], CUFF_NAMES order.
        """
        psi_t, psi_k, psi_s = self.directions(q_exo)
        f = np.asarray(cuff_force, dtype=float).reshape(2, 2, 2)  # leg, (thigh, shank), (x, z)
        ft, fs = f[:, 0], f[:, 1]

        def cross(psi: np.ndarray, force: np.ndarray) -> np.ndarray:
            return np.cos(psi) * force[:, 1] - np.sin(psi) * force[:, 0]

        shank = self.shank_arm * cross(psi_s, fs)
        out = np.empty(4)
        out[0::2] = self.sign_hip * (
            self.thigh_arm * cross(psi_t, ft) + self.knee_arm * cross(psi_k, fs) + shank
        )
        out[1::2] = self.sign_knee * shank
        return out


#: The geometry as record fields (:func:`exo_ctrl._jit.record` syntax): each
#: :class:`CuffGeometry` attribute by name, float64 per leg (2,), units as there.
GEOMETRY_FIELDS: list[tuple[Any, ...]] = [(f.name, np.float64, (2,)) for f in fields(CuffGeometry)]


@kernel
def _cuff_directions(sign_hip, sign_knee, psi_t0, psi_s0, q_hip, q_knee):
    """ψ_t = ψ_t0 + s_h q_hip, ψ_s = ψ_s0 + s_h q_hip + s_k q_knee [rad] (as CuffGeometry).

    Compiled, for the kernels of this package (the observer's force map and
    the running error statistics).
    """
    turn = sign_hip * q_hip
    return psi_t0 + turn, psi_s0 + turn + sign_knee * q_knee


_GEOMETRY_CACHE: dict[int, tuple[BodyModel, CuffGeometry]] = {}


def _geometry(exo: BodyModel | None) -> CuffGeometry:
    """The geometry of ``exo`` (None: the default exoskeleton URDF), cached per model."""
    if exo is None:
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
    form of what :class:`~exo_ctrl.estimation.observer.CuffForceEstimator`
    does every tick.

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
