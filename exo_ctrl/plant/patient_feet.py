"""The patient's feet on the belt (optional: ``ContactParams.patient_feet``), all four feet solved.

The patient's foot rests on the exoskeleton's foot plate, but the two bodies
are joined by elastic cuffs only, so the patient's leg sags in them: in the
default CT run on the belt the patient's foot point is below the belt's top
for 61 % of the gait with nothing pushing back, 7.6 mm deep while the
exoskeleton's foot is on the belt and 11.5 mm at a touchdown (the leg swings
on in the cuffs as the exoskeleton's foot stops).  With this option each
patient foot point meets the belt as the exoskeleton's do
(:mod:`exo_ctrl.plant.contact`):

- **where**: the patient URDF's foot frames (``left_foot``, ``right_foot``,
  read into its legs' geometry by :func:`~exo_ctrl.model.geometry.leg_geometry`),
  in the exoskeleton's world: the patient's hips at their URDF place plus the
  plant's ``patient_offset_xz`` (the cuffs' alignment), riding on the pelvis;
- **law**: the same Hunt–Crossley normal force and friction cone, with the
  same k, n, d and μ (:func:`~exo_ctrl.plant.contact.foot_on_belt`): the
  patient wears a shoe, so the simplest defensible model is the shoe sole of
  Falisse et al. 2019 on the belt (the contact module's source); a bare foot or
  the plate's own sole between shoe and belt would change k and μ, and no
  source gives that stack's values;
- **forces**: F_n enters the patient's hip and knee through the patient's
  foot Jacobian, J_zᵀ F_n (and the pelvis's z with a supported pelvis,
  ∂p_z/∂z = 1); no pulling, as for the exoskeleton's feet.

**Friction of four feet.**  The velocity-level impulses of the contact
module, now for the feet f = [exo left, exo right, patient left, patient
right], each on its leg's two coordinates: with M the combined model's mass
matrix with its armature (8×8, or 9×9 with the pelvis's z ahead),
g_f = M⁻¹ J_x,fᵀ (from a Cholesky factor of M) and W_fe = J_x,f g_e, the slip
at the end of the step is

    s_f⁺ = s_f^free + Σ_e W_fe P_e + (Σ_e P_e) / m_b,

and the impulses are solved by projected Gauss–Seidel on the cones
|P_f| ≤ μ F_n,f h (the same brake handling as two feet).  With the pelvis
fixed, M is block diagonal (each leg its own 2×2 block: the cuffs are forces,
not constraints), so W is diagonal and the feet couple through the belt
only.  Each impulse at most cancels its foot's slip, so the kinetic energy
of legs and belt changes by Σ_f P_f (s_f^free + s_f⁺) / 2 ≤ 0 over the step
(tests/plant/test_contact_patient.py).

**What follows** (the default CT run, measured): the patient's feet carry
part of their legs' weight (peak F_n ≈ 130 N, ≤ 3.8 mm deep), touch down
ahead of the exoskeleton's (they hang lower) while still moving relative to
the belt, so they slide (slip RMS 0.08 m/s against the exoskeleton's
0.01 m/s: the plan's synchronised touchdown holds at the exoskeleton's foot
point).  The device reads the patient's feet with load cells under the
shoes (:mod:`exo_ctrl.sensing.foot_load`), so the safety supervisor's belt
monitor counts their friction on the belt (without them the default run
stopped at its first touchdown that slides: 0.87 s, belt speed deviation
0.039 m/s).

**Cost.**  Nothing with the option off: its kernels are behind a compile-time
switch (:func:`~exo_ctrl.plant.step.plant_switches`) and the plant picks the
two-feet friction solve.  On: two more foot points per step and, on steps
with a foot in contact, the four-feet solve (an 8×8 or 9×9 Cholesky) in
place of the two-feet one.

Outputs per patient foot (left, right), of the last step, as the
exoskeleton's: ``fn``, ``ft`` [N], ``pen`` [m], ``slip`` [m/s], ``state``
(0 free, 1 stick, 2 slide), ``fn_rate`` [N/s], ``td_vx``, ``td_vz`` [m/s].
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .._jit import kernel, leaf, record
from ..model import SIDES, BodyModel
from ..model.leg_kernels import LEG_FIELDS, fill_legs, foot_point, legs_record
from .belt import belt_commit, brake_holds
from .contact import SWEEPS, ContactParams, cholesky, cholesky_solve, foot_on_belt

__all__ = ["PATIENT_FEET_FIELDS", "PatientFeet"]

#: Fields of the patient feet's record.  ``on``; geometry per leg (left,
#: right) in the exoskeleton's world: ``hip`` (x, z) [m] and :data:`LEG_FIELDS`;
#: per foot, of the last step, as the contact's (:data:`~exo_ctrl.plant.contact.CONTACT_FIELDS`):
#: ``pos``, ``vel``, ``jx``, ``jz``, ``pen``, ``fn``, ``ft``, ``slip``,
#: ``state``, ``fn_rate``, ``fn_prev``, ``td_vx``, ``td_vz``, ``imp``.  The
#: four feet's friction solve (exo left, exo right, patient left, patient
#: right): ``imp4`` P [N·s], ``s_free4`` [m/s], ``w4`` W [1/kg], ``g4`` the
#: rows g_f over the model's coordinates (9; the first 8 with the pelvis
#: fixed), ``chol`` the Cholesky factor of M.
_FOOT_ROWS = (
    "pen", "fn", "ft", "slip", "state", "fn_rate", "fn_prev", "td_vx", "td_vz", "imp",
)  # fmt: skip
PATIENT_FEET_FIELDS = [
    ("on", np.bool_),
    ("hip", np.float64, (2, 2)),
    *LEG_FIELDS,
    *((name, np.float64, (2, 2)) for name in ("pos", "vel", "jx", "jz")),
    *((name, np.float64, (2,)) for name in _FOOT_ROWS),
    ("imp4", np.float64, (4,)),
    ("s_free4", np.float64, (4,)),
    ("w4", np.float64, (4, 4)),
    ("g4", np.float64, (4, 9)),
    ("chol", np.float64, (9, 9)),
]


class PatientFeet:
    """The patient's two foot points on the belt: geometry and parameters into a record.

    Args:
        patient: the patient (its legs' geometry, foot frames included).
        params: the contact (``patient_feet`` switches this on).
        patient_offset_xz: where the patient's world origin sits in the
            exoskeleton's (x, z) [m] (:attr:`Plant.patient_offset_xz`).
        z_belt: the belt's top in the exoskeleton's world [m]
            (:attr:`FootContact.z_belt <exo_ctrl.plant.contact.FootContact.z_belt>`).
        into: a record of :data:`PATIENT_FEET_FIELDS` (a field of the plant's
            record); default one of its own.

    """

    def __init__(
        self,
        patient: BodyModel,
        params: ContactParams,
        patient_offset_xz: tuple[float, float],
        z_belt: float,
        into: np.ndarray | None = None,
    ) -> None:
        self.params = params
        self.record = record(PATIENT_FEET_FIELDS) if into is None else into
        r = self.record[0]
        for i, side in enumerate(SIDES):
            hip = patient.legs[side].hip_xz
            r["hip"][i] = (hip[0] + patient_offset_xz[0], hip[1] + patient_offset_xz[1])
        fill_legs(r, patient)
        self._legs = legs_record(patient)  # Python's calls of foot_point
        r["on"] = params.enabled and params.patient_feet
        #: The belt's top in the exoskeleton's world [m].
        self.z_belt = float(z_belt)

    @property
    def on(self) -> bool:
        """Whether the patient's feet meet the belt."""
        return bool(self.record["on"][0])

    def reset(self) -> None:
        """Feet free, outputs zero."""
        r = self.record[0]
        for name in _FOOT_ROWS:
            r[name] = 0.0
        for name in ("imp4", "s_free4", "w4", "g4"):
            r[name] = 0.0

    def feet(self, q: np.ndarray, z_pelvis_m: float = 0.0) -> np.ndarray:
        """World (x, z) of the patient's foot points at ``q`` (q_all, 8) [m], (2, 2).

        ``z_pelvis_m``: the pelvis's height above its nominal (:mod:`exo_ctrl.plant.pelvis`).
        """
        r = self.record[0]
        out = np.array(r["hip"], dtype=float)
        for leg in range(2):
            x, z, *_ = foot_point(self._legs[0], leg, float(q[4 + 2 * leg]), float(q[5 + 2 * leg]))
            out[leg] += (x, z)
        out[:, 1] += z_pelvis_m
        return out

    def penetration(self, q: np.ndarray, z_pelvis_m: float = 0.0) -> np.ndarray:
        """δ = z_b - p_z of each patient foot at ``q`` (q_all, 8) [m], (2,)."""
        return self.z_belt - self.feet(q, z_pelvis_m)[:, 1]

    def rest_torque(self, q_patient: np.ndarray) -> np.ndarray:
        """The belt's force at rest on the patient's joints, J_zᵀ k δⁿ (δ > 0) [N·m], (4,).

        ``q_patient``: the patient's angles [rad], (4,), the pelvis at its
        nominal height; no damping and no friction at rest.
        """
        r, p = self.record[0], self.params
        out = np.zeros(4)
        for leg in range(2):
            q_hip, q_knee = float(q_patient[2 * leg]), float(q_patient[2 * leg + 1])
            _, z, _, _, jz0, jz1 = foot_point(self._legs[0], leg, q_hip, q_knee)
            depth = self.z_belt - (float(r["hip"][leg, 1]) + z)
            if depth > 0.0:
                fn = p.stiffness_N_per_m_n * depth**p.exponent
                out[2 * leg : 2 * leg + 2] = (jz0 * fn, jz1 * fn)
        return out


@kernel
def patient_forces(c: Any, f: Any, qm: np.ndarray, vm: np.ndarray, tau: np.ndarray, h: float):
    """The patient's feet at mid-step: normal forces into ``tau[4:]``, and into ``c.fz``.

    After :func:`~exo_ctrl.plant.contact.contact_forces` (which starts the
    step's ``c.any`` and ``c.fz``); ``c``: the contact record, ``f``: this
    module's.
    """
    for leg in range(2):
        f.imp[leg] = 0.0
        foot_on_belt(c, f, leg, 4 + 2 * leg, qm, vm, tau, h)
    c.fz += f.fn[0] + f.fn[1]


@kernel
def _normal(c: Any, f: Any, foot: int) -> float:
    """F_n of foot ``foot`` (0, 1 the exoskeleton's, 2, 3 the patient's) [N]."""
    return c.fn[foot] if foot < 2 else f.fn[foot - 2]


@kernel
def _jac_x(c: Any, f: Any, foot: int) -> tuple:
    """J_x of foot ``foot`` over its leg's (hip, knee) [m/rad]."""
    if foot < 2:
        return c.jx[foot, 0], c.jx[foot, 1]
    return f.jx[foot - 2, 0], f.jx[foot - 2, 1]


@kernel
def feet_friction(plant: np.ndarray, acc_in: np.ndarray, mass: np.ndarray) -> None:
    """The four feet's friction impulses, pelvis fixed: ``p.contact.acc`` (8,) with them.

    As :func:`~exo_ctrl.plant.contact.friction_impulse`: ``acc_in`` ABA's
    accelerations, ``mass`` CRBA's M with the armature (upper triangle read).
    """
    p = plant[0]
    _solve_feet(p, acc_in, mass, 0, p.contact.acc)


@kernel
def feet_friction_coupled(plant: np.ndarray, acc_in: np.ndarray, mass: np.ndarray) -> None:
    """:func:`feet_friction` with the pelvis's z ahead: ``p.pelvis.acc9`` (9,) and ``az``."""
    p = plant[0]
    _solve_feet(p, acc_in, mass, 1, p.pelvis.acc9)
    p.pelvis.az = p.pelvis.acc9[0]


@kernel
def _solve_feet(p: Any, acc_in: np.ndarray, mass: np.ndarray, off: int, out: np.ndarray):
    """The impulses P_f (module docstring) and ``out`` = ``acc_in`` + Σ_f g_f P_f / h.

    ``off``: 1 with the pelvis's z as the model's first coordinate, else 0.
    """
    c, f, h = p.contact, p.patient_feet, p.h
    b = c.belt
    held = b.held != 0.0  # braked at rest (plant.belt): the feet push on a fixed belt
    v_free = 0.0 if held else b.v_free
    inv_mb = 0.0 if held else 1.0 / b.mass
    n = 8 + off
    for i in range(n):
        out[i] = acc_in[i]
    low = f.chol
    cholesky(mass, low, n)  # M = L Lᵀ, from the upper triangle
    for foot in range(4):
        f.imp4[foot] = 0.0
        g = f.g4[foot]
        g[:] = 0.0
        if _normal(c, f, foot) <= 0.0:
            continue
        col = off + 2 * foot
        j0, j1 = _jac_x(c, f, foot)
        g[col], g[col + 1] = j0, j1
        cholesky_solve(low, g, n)  # g = M⁻¹ J_xᵀ
        i = 2 * foot  # the leg's coordinates in q_all
        vx = j0 * (p.v[i] + h * acc_in[col]) + j1 * (p.v[i + 1] + h * acc_in[col + 1])
        f.s_free4[foot] = vx + v_free
    for a in range(4):
        j0, j1 = _jac_x(c, f, a)
        col = off + 2 * a
        for e in range(4):
            f.w4[a, e] = j0 * f.g4[e, col] + j1 * f.g4[e, col + 1]
    _sweeps4(c, f, inv_mb, h)
    total = f.imp4[0] + f.imp4[1] + f.imp4[2] + f.imp4[3]
    if held and not brake_holds(b, total / h, h):  # the feet overpower the brake
        inv_mb = b.inv_m
        for foot in range(4):
            f.s_free4[foot] += b.v_free
        _sweeps4(c, f, inv_mb, h)
        total = f.imp4[0] + f.imp4[1] + f.imp4[2] + f.imp4[3]
    b.v_next = 0.0 if held and inv_mb == 0.0 else b.v_free + total * inv_mb
    b.f_feet = total / h
    for foot in range(4):
        for i in range(n):
            out[i] += f.g4[foot, i] * f.imp4[foot] / h
    for leg in range(2):  # each foot's own share, as the two-feet solve leaves them
        c.imp[leg], f.imp[leg] = f.imp4[leg], f.imp4[2 + leg]
        c.s_free[leg], c.w[leg] = f.s_free4[leg], f.w4[leg, leg]


@kernel
def _sweeps4(c: Any, f: Any, inv_mb: float, h: float) -> None:
    """Projected Gauss–Seidel on the four feet's impulses; 1/m_b = ``inv_mb``."""
    imp = f.imp4
    for _ in range(SWEEPS):
        for a in range(4):
            fn = _normal(c, f, a)
            if fn <= 0.0:
                continue
            r = f.s_free4[a] + (imp[0] + imp[1] + imp[2] + imp[3]) * inv_mb
            for e in range(4):
                r += f.w4[a, e] * imp[e]
            new = imp[a] - r / (f.w4[a, a] + inv_mb)
            bound = c.mu * fn * h
            if new > bound:
                new = bound
            elif new < -bound:
                new = -bound
            imp[a] = new


@kernel
def feet_commit(c: Any, f: Any, h: float) -> None:
    """End of step, four feet: each one's force, slip and state; the belt's new state."""
    b = c.belt
    inv_mb = b.inv_m  # 1/m_b, or 0 while a brake holds the belt (plant.belt)
    for leg in range(2):
        _commit_foot(c, f, c, leg, leg, inv_mb, h)
        _commit_foot(c, f, f, leg, 2 + leg, inv_mb, h)
    belt_commit(b, h)


@leaf
def _commit_foot(c: Any, f: Any, g: Any, leg: int, a: int, inv_mb: float, h: float) -> None:
    """Foot ``a`` of the four, leg ``leg`` of the record ``g`` (``c`` or ``f``): F_t, s⁺, state."""
    fn = g.fn[leg]
    g.fn_prev[leg] = fn
    if fn <= 0.0:
        g.state[leg] = 0.0
        g.ft[leg] = 0.0
        g.slip[leg] = 0.0
        return
    imp = f.imp4
    slip = f.s_free4[a] + (imp[0] + imp[1] + imp[2] + imp[3]) * inv_mb
    for e in range(4):
        slip += f.w4[a, e] * imp[e]
    g.ft[leg] = imp[a] / h
    g.slip[leg] = slip
    g.state[leg] = 2.0 if abs(imp[a]) >= c.mu * fn * h * (1.0 - 1e-12) else 1.0
