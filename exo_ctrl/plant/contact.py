"""Foot–belt contact at the exoskeleton's foot points: Hunt–Crossley normal force, Coulomb friction.

Each exoskeleton foot point (the end of the shank, the paper's O_L3 and
O_R3; the patient's foot rests on the exoskeleton's foot plate) meets the
belt's top at z_b = z_hip - H (:class:`~exo_ctrl.plant.belt.BeltParams`).
In the sagittal plane, with the leg's absolute angles φ1 = φ1₀ + s_h q_hip,
φ2 = φ2₀ + s_h q_hip + s_k q_knee (:class:`~exo_ctrl.model.geometry.LegGeometry`),

    p = hip + l1 (cos φ1, sin φ1) + l2 (cos φ2, sin φ2),   ṗ = J q̇,

and, with ``ContactParams.patient_feet``, the patient's foot points meet it
too, by the same law (:func:`foot_on_belt`; :mod:`exo_ctrl.plant.patient_feet`).

**Normal force** (Hunt & Crossley 1975), on the penetration δ = z_b - p_z:

    F_n = max(0, k δⁿ (1 + d δ̇)),   n = 3/2,   F_n = 0 for δ ≤ 0,

no pulling: a foot leaving faster than 1/d relaxes the spring feels no force.
It is taken at mid-step with the plant's other forces (explicit).  Its
stability: linearised, the stiffness is n k δⁿ⁻¹ and the damping F_n d; with
the foot's effective normal mass m_n = 1 / (J_z A⁻¹ J_zᵀ) (A the leg's mass
matrix with the armature) the leapfrog is stable for h √(n k δⁿ⁻¹ / m_n) < 2
and F_n d h / m_n < 2.  With the defaults and m_n ≥ 2 kg (the exoskeleton's
shank alone): δ < (4 m_n / (n k h²))² = 110 m, and F_n < 2 m_n / (d h) =
1300 N at 1 ms — both far beyond what the default runs reach.

**Friction** relative to the moving belt, whose surface moves at -v_b: the
slip is s = ṗ_x + v_b.  A regularised Coulomb law μ F_n tanh(s / v_ε) has
the slope μ F_n / v_ε (1e4–1e5 N·s/m for v_ε = 1 cm/s), which an explicit
1 ms step on a foot of a few kg cannot integrate.  So friction is a
velocity-level impulse over the step (Moreau's time stepping): with A the
leg's 2×2 mass matrix at mid-step with the armature (Pinocchio's CRBA adds
the model's armature, so A is exactly the matrix ABA solved with, implicit
damping included), the slip at the end of the step is linear in the
friction impulses P_i = F_t,i h of the feet,

    s_i⁺ = s_i^free + w_i P_i + (P_L + P_R) / m_b,   w_i = J_x,i A⁻¹ J_x,iᵀ,

(the last term: the belt's inertia, both feet on one belt), and P_i is the
impulse that makes s_i⁺ = 0 clipped to the cone |P_i| ≤ μ F_n,i h (a
projected Gauss–Seidel over the two feet, exact in a few sweeps since
1 / m_b ≪ w_i).  Inside the cone the foot sticks (state 1, s⁺ = 0 to
rounding), on it the foot slides (state 2) with |F_t| = μ F_n opposite to
the slip.  The impulse adds A⁻¹ J_xᵀ P / h to the leg's accelerations: the
scheme dissipates (an impulse that at most cancels the slip) and is stable
for every step and every μ.  Cost: one CRBA (≈ 0.7 µs) and a small kernel,
on steps with a foot in contact only.

**Parameters.**  Falisse et al. 2019 (J R Soc Interface 16: 20190402)
model the shoe–ground contact in predictive gait simulation with six
smooth Hunt–Crossley spheres per foot (OpenSim's SmoothSphereHalfSpaceForce):
"stiffness" E = 1e6 N/m², dissipation c = 2 s/m, friction 0.8, sphere radius
R = 0.032 m at the heel.  That model's force is (4/3) k √(R k) δ^{3/2}
(1 + 1.5 c δ̇) with k = E^{2/3} / 2: 8.4e4 N/m^{3/2} per sphere.  One point
per foot takes the six spheres in parallel at one indentation: k = 5e5
N/m^{3/2} (an upper bound: Falisse's toe spheres are smaller), d = 1.5 c =
3 s/m, μ = 0.8 (rubber sole on a treadmill belt).  A foot carrying 400 N
sinks (400 / 5e5)^{2/3} = 8.6 mm, a shoe sole's compression.

Outputs per foot (left, right), of the last step: ``fn`` and ``ft`` [N]
(on the foot, z and x), ``pen`` δ [m], ``slip`` s⁺ [m/s] (0 out of
contact), ``state`` (0 free, 1 stick, 2 slide), ``fn_rate`` dF_n/dt [N/s],
and at the last touchdown ``td_vx`` (the foot's speed relative to the belt)
and ``td_vz`` [m/s].
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .. import _validate as v
from .._jit import kernel, leaf, record, shared_dtype
from ..exceptions import InvalidParameter
from ..model import SIDES, BodyModel
from ..model.leg_kernels import LEG_FIELDS, fill_legs, foot_point, legs_record
from .belt import BELT_FIELDS, BeltParams, belt_commit, belt_drive, brake_holds

__all__ = ["CONTACT_FIELDS", "ContactParams", "FootContact"]

#: Projected Gauss–Seidel sweeps of the friction solve (two feet).
SWEEPS = 8


@dataclass(frozen=True)
class ContactParams:
    """Foot–belt contact (module docstring) and the belt.

    Attributes:
        enabled: model the belt and the contact (off: the feet move in free
            air, as before).
        stiffness_N_per_m_n: k [N/m^n].
        exponent: n [-], ≥ 1.
        dissipation_s_per_m: d [s/m].
        friction_coeff: μ [-], > 0.
        belt: the belt and its drive.
        patient_feet: the patient's foot points meet the belt too, with the
            same law (:mod:`exo_ctrl.plant.patient_feet`; off: only the
            exoskeleton's feet, the patient's foot free to sink below the belt).

    Raises:
        InvalidParameter: k not > 0, n < 1, d < 0, μ not > 0, patient_feet
            without the contact enabled.

    """

    enabled: bool = False
    stiffness_N_per_m_n: float = 5.0e5
    exponent: float = 1.5
    dissipation_s_per_m: float = 3.0
    friction_coeff: float = 0.8
    belt: BeltParams = field(default_factory=BeltParams)
    patient_feet: bool = False

    def __post_init__(self) -> None:
        k = v.positive("contact stiffness", self.stiffness_N_per_m_n, "N/m^n")
        n = v.finite("contact exponent", self.exponent)
        if n < 1.0:
            raise InvalidParameter("contact exponent", self.exponent, ">= 1")
        d = v.non_negative("contact dissipation", self.dissipation_s_per_m, "s/m")
        mu = v.positive("friction coefficient", self.friction_coeff)
        if not isinstance(self.belt, BeltParams):
            raise InvalidParameter("belt", self.belt, "a BeltParams")
        for name, value in (
            ("stiffness_N_per_m_n", k),
            ("exponent", n),
            ("dissipation_s_per_m", d),
            ("friction_coeff", mu),
        ):
            object.__setattr__(self, name, value)
        object.__setattr__(self, "enabled", v.flag("contact enabled", self.enabled))
        if not isinstance(self.patient_feet, (bool, np.bool_)):
            raise InvalidParameter("patient_feet", self.patient_feet, "True or False")
        if self.patient_feet and not self.enabled:
            raise InvalidParameter(
                "patient_feet", self.patient_feet, "False with the contact off (enabled=False)",
                "the patient's feet meet the belt only with the belt contact on: --contact on",
            )  # fmt: skip
        object.__setattr__(self, "patient_feet", bool(self.patient_feet))


#: Fields of the contact's record.  Geometry per leg (left, right): ``hip``
#: (x, z) [m], ``l1``, ``l2`` [m], ``s_h``, ``s_k``, ``phi1_0``, ``phi2_0``
#: [rad]; ``z_belt`` [m]; parameters ``k``, ``n``, ``d``, ``mu``, ``on``.
#: Per foot, of the last step: ``pos``, ``vel`` (x, z) at mid-step [m, m/s],
#: ``jx``, ``jz`` the rows of ∂p/∂(q_hip, q_knee) [m/rad], ``pen``, ``fn``,
#: ``ft``, ``slip``, ``state``, ``fn_rate``, ``fn_prev``, ``td_vx``, ``td_vz``
#: (module docstring), ``imp`` P [N·s], ``g`` A⁻¹ J_xᵀ [1/(kg·m)·…], ``w``,
#: ``s_free``; ``z_pelvis``, ``vz_pelvis`` the pelvis's height and speed at
#: mid-step (:mod:`exo_ctrl.plant.pelvis`; 0 with a fixed pelvis) [m, m/s],
#: ``fz`` the feet's normal forces summed [N], ``w_x`` the feet's coupling
#: J_x,L M⁻¹ J_x,Rᵀ through the pelvis (0 with a fixed pelvis) [1/kg];
#: ``any``: a foot in contact this step; ``acc`` (8,) the
#: accelerations with friction [rad/s²]; ``belt``: the belt's record.
_FOOT_ROWS = (
    "pen", "fn", "ft", "slip", "state", "fn_rate", "fn_prev", "td_vx", "td_vz", "imp", "w",
    "s_free",
)  # fmt: skip
CONTACT_FIELDS = [
    ("hip", np.float64, (2, 2)),
    *LEG_FIELDS,
    *((name, np.float64) for name in ("z_belt", "k", "n", "d", "mu")),
    *((name, np.float64) for name in ("z_pelvis", "vz_pelvis", "fz", "w_x")),
    ("on", np.bool_),
    ("pos", np.float64, (2, 2)),
    ("vel", np.float64, (2, 2)),
    ("jx", np.float64, (2, 2)),
    ("jz", np.float64, (2, 2)),
    ("g", np.float64, (2, 2)),
    *((name, np.float64, (2,)) for name in _FOOT_ROWS),
    ("any", np.bool_),
    ("acc", np.float64, (8,)),
    ("belt", shared_dtype(BELT_FIELDS, align=True)),
]


class FootContact:
    """The two exoskeleton feet on the belt: parameters and geometry into a record.

    Args:
        exo: the exoskeleton (its legs' geometry).
        params: contact and belt parameters.
        belt_height_m: the belt's top below the hip joint [m] (the plan's H_s
            unless ``params.belt.height_m`` is set).
        into: a record of :data:`CONTACT_FIELDS` (a field of the plant's
            record); default one of its own.

    Raises:
        InvalidParameter: a belt the feet cannot reach (its top farther below
            the hip than the leg's length).

    """

    def __init__(
        self,
        exo: BodyModel,
        params: ContactParams,
        belt_height_m: float,
        into: np.ndarray | None = None,
    ) -> None:
        self.params = params
        self.record = record(CONTACT_FIELDS) if into is None else into
        c = self.record[0]
        height = params.belt.height_m if params.belt.height_m is not None else belt_height_m
        reach = min(exo.legs[s].reach[1] for s in SIDES)
        if not 0.0 < height < reach:
            raise InvalidParameter(
                "belt height", height, f"in (0, {reach:.4g}) m, within the leg's reach"
            )
        for i, side in enumerate(SIDES):
            c["hip"][i] = exo.legs[side].hip_xz
        fill_legs(c, exo)
        self._legs = legs_record(exo)  # Python's calls of foot_point
        #: The belt's top in the exoskeleton's world [m].
        self.z_belt = float(exo.legs["left"].hip_xz[1]) - float(height)
        c["z_belt"] = self.z_belt
        c["k"], c["n"] = params.stiffness_N_per_m_n, params.exponent
        c["d"], c["mu"] = params.dissipation_s_per_m, params.friction_coeff
        c["on"] = params.enabled
        params.belt.into(c["belt"])
        #: The belt's record (a field of this one).
        self.belt = self.record["belt"]

    def reset(self, belt_speed_mps: float = 0.0) -> None:
        """Belt at ``belt_speed_mps`` [m/s] with its set speed, feet free, outputs zero."""
        c = self.record[0]
        for name in ("fn", "ft", "slip", "state", "fn_rate", "fn_prev", "pen", "imp", "w_x"):
            c[name] = 0.0
        b = c["belt"]
        b["v"] = b["v_set"] = b["v_next"] = b["v_free"] = float(belt_speed_mps)
        b["x"] = b["integral"] = b["integral_next"] = 0.0
        b["brake"] = b["held"] = 0.0
        b["inv_m"] = 1.0 / b["mass"]

    def feet(self, q: np.ndarray, z_pelvis_m: float = 0.0) -> np.ndarray:
        """World (x, z) of the two exo foot points at joint angles ``q`` (≥ 4) [m], (2, 2).

        ``z_pelvis_m``: the pelvis's height above its nominal (:mod:`exo_ctrl.plant.pelvis`).
        """
        c = self.record[0]
        out = np.array(c["hip"], dtype=float)
        for leg in range(2):
            x, z, *_ = foot_point(self._legs[0], leg, float(q[2 * leg]), float(q[2 * leg + 1]))
            out[leg] += (x, z)
        out[:, 1] += z_pelvis_m
        return out

    def normal_jacobian(self, q: np.ndarray) -> np.ndarray:
        """Rows ∂p_z/∂(q_hip, q_knee) of each foot at joint angles ``q`` [m/rad], (2, 2)."""
        out = np.zeros((2, 2))
        for leg in range(2):
            out[leg] = foot_point(self._legs[0], leg, float(q[2 * leg]), float(q[2 * leg + 1]))[4:]
        return out

    def penetration(self, q: np.ndarray, z_pelvis_m: float = 0.0) -> np.ndarray:
        """δ = z_b - p_z of each foot at joint angles ``q`` [m], (2,) (negative: above the belt)."""
        return self.z_belt - self.feet(q, z_pelvis_m)[:, 1]


@kernel
def contact_forces(c: Any, qm: np.ndarray, vm: np.ndarray, tau: np.ndarray, h: float) -> None:
    """Feet at mid-step (q½, v½), their normal forces into ``tau``, the belt's drive force.

    ``c``: a contact record (:data:`CONTACT_FIELDS`); ``tau`` (8,) gets
    J_zᵀ F_n on each leg's hip and knee.
    """
    belt_drive(c.belt, h)
    c.any = False
    for leg in range(2):
        c.imp[leg] = 0.0
        foot_on_belt(c, c, leg, 2 * leg, qm, vm, tau, h)
    c.fz = c.fn[0] + c.fn[1]


@leaf
def foot_on_belt(
    c: Any, g: Any, leg: int, i: int, qm: np.ndarray, vm: np.ndarray, tau: np.ndarray, h: float
) -> None:
    """One foot at mid-step: its point, penetration, Hunt–Crossley force (module docstring).

    ``c``: the contact record (belt, law, pelvis); ``g``: the record of the
    legs the foot ends (the exoskeleton's: ``c`` itself; the patient's:
    :data:`~exo_ctrl.plant.patient_feet.PATIENT_FEET_FIELDS`), leg ``leg``
    whose hip and knee are ``qm[i]``, ``qm[i + 1]``; sets its ``pos``,
    ``vel``, ``jx``, ``jz``, ``pen``, ``fn``, ``fn_rate`` and at a
    touchdown ``td_vx``, ``td_vz``, ``c.any`` when it touches; adds
    J_zᵀ F_n to ``tau[i]``, ``tau[i + 1]``.
    """
    b = c.belt
    x, z, g.jx[leg, 0], g.jx[leg, 1], g.jz[leg, 0], g.jz[leg, 1] = foot_point(
        g, leg, qm[i], qm[i + 1]
    )
    g.pos[leg, 0] = g.hip[leg, 0] + x
    g.pos[leg, 1] = g.hip[leg, 1] + c.z_pelvis + z
    vx = g.jx[leg, 0] * vm[i] + g.jx[leg, 1] * vm[i + 1]
    vz = g.jz[leg, 0] * vm[i] + g.jz[leg, 1] * vm[i + 1] + c.vz_pelvis
    g.vel[leg, 0], g.vel[leg, 1] = vx, vz
    pen = c.z_belt - g.pos[leg, 1]
    g.pen[leg] = pen
    fn = 0.0
    if pen > 0.0:
        fn = c.k * pen**c.n * (1.0 - c.d * vz)
        if fn < 0.0:
            fn = 0.0
    if fn > 0.0:
        c.any = True
        if g.state[leg] == 0.0:  # touchdown: the foot's speed relative to the belt
            g.td_vx[leg] = vx + b.v
            g.td_vz[leg] = vz
    g.fn[leg] = fn
    g.fn_rate[leg] = (fn - g.fn_prev[leg]) / h
    tau[i] += g.jz[leg, 0] * fn
    tau[i + 1] += g.jz[leg, 1] * fn


@kernel
def friction_impulse(plant: np.ndarray, acc_in: np.ndarray, mass: np.ndarray) -> None:
    """The feet's friction impulses over the step (module docstring), in ``p.contact.acc``.

    ``plant``: the plant's record (fields ``contact``, ``v``, ``h``); ``acc_in``:
    ABA's accelerations without friction (8,); ``mass``: CRBA's mass matrix
    of the combined model with its armature (upper triangle read).
    """
    p = plant[0]
    c = p.contact
    b = c.belt
    h = p.h
    held = b.held != 0.0  # braked at rest (plant.belt): the feet push on a fixed belt
    v_free = 0.0 if held else b.v_free
    inv_mb = 0.0 if held else 1.0 / b.mass
    for i in range(8):
        c.acc[i] = acc_in[i]
    for leg in range(2):
        c.imp[leg] = 0.0
        if c.fn[leg] <= 0.0:
            continue
        i = 2 * leg
        a00, a01, a11 = mass[i, i], mass[i, i + 1], mass[i + 1, i + 1]
        det = a00 * a11 - a01 * a01
        j0, j1 = c.jx[leg, 0], c.jx[leg, 1]
        g0 = (a11 * j0 - a01 * j1) / det
        g1 = (a00 * j1 - a01 * j0) / det
        c.g[leg, 0], c.g[leg, 1] = g0, g1
        c.w[leg] = j0 * g0 + j1 * g1
        vx = j0 * (p.v[i] + h * acc_in[i]) + j1 * (p.v[i + 1] + h * acc_in[i + 1])
        c.s_free[leg] = vx + v_free
    _solve(c, held, inv_mb, h)
    for leg in range(2):
        i = 2 * leg
        c.acc[i] += c.g[leg, 0] * c.imp[leg] / h
        c.acc[i + 1] += c.g[leg, 1] * c.imp[leg] / h


@kernel
def friction_impulse_coupled(plant: np.ndarray, acc_in: np.ndarray, mass: np.ndarray) -> None:
    """:func:`friction_impulse` with the pelvis's vertical coordinate: into ``p.pelvis.acc9``.

    With z in the model (:mod:`exo_ctrl.plant.pelvis`) the mass matrix M
    (9×9, [z, q_all]) couples both legs and the patient's, so
    g_i = M⁻¹ J_x,iᵀ is solved in full (a Cholesky factor of M) and the feet
    are coupled: s_i⁺ = s_i^free + w_i P_i + w_x P_j + (P_L + P_R) / m_b with
    w_x = J_x,i M⁻¹ J_x,jᵀ.  ``acc_in``: ABA's nine accelerations without
    friction; ``mass``: CRBA's M with the armature (upper triangle read).
    """
    p = plant[0]
    c = p.contact
    pel = p.pelvis
    h = p.h
    held = c.belt.held != 0.0
    v_free = 0.0 if held else c.belt.v_free
    inv_mb = 0.0 if held else 1.0 / c.belt.mass
    n = 9
    for i in range(n):
        pel.acc9[i] = acc_in[i]
    low = pel.chol
    cholesky(mass, low, n)  # M = L Lᵀ, from the upper triangle
    c.w_x = 0.0
    for leg in range(2):
        c.imp[leg] = 0.0
        g = pel.g9[leg]
        g[:] = 0.0
        if c.fn[leg] <= 0.0:
            continue
        i = 2 * leg + 1
        g[i], g[i + 1] = c.jx[leg, 0], c.jx[leg, 1]
        cholesky_solve(low, g, n)  # g = M⁻¹ J_xᵀ
        c.w[leg] = c.jx[leg, 0] * g[i] + c.jx[leg, 1] * g[i + 1]
        vx = c.jx[leg, 0] * (p.v[i - 1] + h * acc_in[i])
        vx += c.jx[leg, 1] * (p.v[i] + h * acc_in[i + 1])
        c.s_free[leg] = vx + v_free
    if c.fn[0] > 0.0 and c.fn[1] > 0.0:
        c.w_x = c.jx[0, 0] * pel.g9[1, 1] + c.jx[0, 1] * pel.g9[1, 2]
    _solve(c, held, inv_mb, h)
    for leg in range(2):
        for i in range(n):
            pel.acc9[i] += pel.g9[leg, i] * c.imp[leg] / h
    pel.az = pel.acc9[0]


@kernel
def cholesky(mass: np.ndarray, low: np.ndarray, n: int) -> None:
    """M = L Lᵀ: L of M's leading n × n block, from its upper triangle, into ``low``."""
    for j in range(n):
        d = mass[j, j]
        for k in range(j):
            d -= low[j, k] * low[j, k]
        low[j, j] = np.sqrt(d)
        for i in range(j + 1, n):
            s = mass[j, i]
            for k in range(j):
                s -= low[i, k] * low[j, k]
            low[i, j] = s / low[j, j]


@kernel
def cholesky_solve(low: np.ndarray, g: np.ndarray, n: int) -> None:
    """Solve M x = g in place (g ← x), M = L Lᵀ (:func:`cholesky`): L y = g, then Lᵀ x = y."""
    for r in range(n):
        s = g[r]
        for k in range(r):
            s -= low[r, k] * g[k]
        g[r] = s / low[r, r]
    for r in range(n - 1, -1, -1):
        s = g[r]
        for k in range(r + 1, n):
            s -= low[k, r] * g[k]
        g[r] = s / low[r, r]


@kernel
def _solve(c: Any, held: bool, inv_mb: float, h: float) -> None:
    """The impulses (:func:`_sweeps`), a brake overpowered giving way; the belt's next speed."""
    b = c.belt
    _sweeps(c, inv_mb, h)
    total = c.imp[0] + c.imp[1]
    if held and not brake_holds(b, total / h, h):  # the feet overpower the brake
        inv_mb = b.inv_m
        for leg in range(2):
            c.s_free[leg] += b.v_free
        _sweeps(c, inv_mb, h)
        total = c.imp[0] + c.imp[1]
    b.v_next = 0.0 if held and inv_mb == 0.0 else b.v_free + total * inv_mb
    b.f_feet = total / h


@kernel
def _sweeps(c: Any, inv_mb: float, h: float) -> None:
    """Projected Gauss–Seidel on the feet's impulses (module docstring); 1/m_b = ``inv_mb``."""
    for _ in range(SWEEPS):
        for leg in range(2):
            if c.fn[leg] <= 0.0:
                continue
            r = c.s_free[leg] + c.w[leg] * c.imp[leg] + c.w_x * c.imp[1 - leg]
            r += (c.imp[0] + c.imp[1]) * inv_mb
            new = c.imp[leg] - r / (c.w[leg] + inv_mb)
            bound = c.mu * c.fn[leg] * h
            if new > bound:
                new = bound
            elif new < -bound:
                new = -bound
            c.imp[leg] = new


@kernel
def contact_commit(c: Any, h: float) -> None:
    """End of step: the belt's new state, each foot's force, slip and contact state."""
    b = c.belt
    inv_mb = b.inv_m  # 1/m_b, or 0 while a brake holds the belt (plant.belt)
    total = c.imp[0] + c.imp[1]
    for leg in range(2):
        fn = c.fn[leg]
        c.fn_prev[leg] = fn
        if fn <= 0.0:
            c.state[leg] = 0.0
            c.ft[leg] = 0.0
            c.slip[leg] = 0.0
            continue
        imp = c.imp[leg]
        c.ft[leg] = imp / h
        c.slip[leg] = c.s_free[leg] + c.w[leg] * imp + c.w_x * c.imp[1 - leg] + total * inv_mb
        c.state[leg] = 2.0 if abs(imp) >= c.mu * fn * h * (1.0 - 1e-12) else 1.0
    belt_commit(b, h)
