r"""The pelvis on a vertical guide with body-weight support (beyond the paper).

The paper fixes the pelvis to the frame.  A gait trainer instead hangs the
patient in a harness: exoskeleton and patient share a pelvis that slides on
a vertical guide, and a constant-force unloading mechanism (a counterweight
or a force-controlled winch with dynamic unloading) lifts it with a force
F_s = β_s m_body g, a fraction β_s of the patient's body weight.  The legs
then carry the rest of the weight through the belt contact.

**Model.**  One prismatic degree of freedom z (up, metres from the hips'
nominal height in the URDFs) carries the pelvis: the patient's trunk, head
and arms (the body mass less the patient URDF's links, whose own pelvis link
rides on it too) and the URDFs' pelvis links.  Both legs' trees hang from
it, so the combined model has nine coordinates (:func:`pelvis_model`):
Pinocchio's order [z, q_exo (4), q_patient (4)].  The mass the guide moves,
M = m_body + m_exo (the exoskeleton's every link; a real trainer may carry
the exoskeleton's weight in its frame, which this model does not), enters
the contact's vertical balance: averaged over a periodic gait, the
vertical ground force equals M g − F_s (the momentum M ż returns to its
value each cycle).

**Forces on z** (generalised, N, taken at mid-step like the plant's others):
gravity (in the model), the support F_s, the feet's normal forces (the foot
height is z plus the leg's: ∂p_z/∂z = 1) and the harness's travel stops at
z_lo = −travel and z_hi = +travel, a unilateral spring–damper like the
joints' end stops (no pulling): F = max(0, K d + C ḋ) on the penetration d.
K = 10⁵ N/m holds the whole moving mass (≈ 100 kg) within 1 cm; with
M ≥ 50 kg, ω = √(K/M) ≤ 45 rad/s, ω h = 0.045 at 1 ms (the leapfrog needs
ω h < 2), and C = 2·10³ N·s/m gives a damping ratio C / (2√(K M)) ≤ 0.45.
No standard gives these; a harness's catch within a centimetre is the
design intent (a fall is stopped, not cushioned).

**The harness locks on a stop.**  When the device stops the gait (its safety
supervisor leaves ``normal``), the guide's brake locks the pelvis at its
height of that moment, z_l: a bilateral spring–damper of the stops' K and C,
F = −K (z − z_l) − C ż, so the legs no longer carry the weight while the
drives hold or yield (a gait trainer's body-weight support catches the
patient; without it a stopped, crouched leg under 700 N is beyond the knee
drive's 150 N·m and folds onto the travel stop).

**Stepping.**  The plant's leapfrog runs on z as on the joints; this module
packs the nine-coordinate vectors for ABA (:func:`pelvis_pack`), unpacks
its accelerations (:func:`pelvis_unpack`) and kicks z (:func:`pelvis_kick`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from .. import _validate as v
from .._jit import kernel
from ..exceptions import InvalidModel, InvalidParameter
from ..model import BodyModel

__all__ = [
    "PAPER_BODY_MASS_KG",
    "PELVIS_FIELDS",
    "PelvisParams",
    "moving_mass_kg",
    "pelvis_model",
    "pelvis_pack",
    "pelvis_unpack",
]

#: The paper patient's body mass [kg] (the 1.75 m, 80 kg man whose legs the
#: default patient URDF holds; :data:`exo_ctrl.sim.belief.PAPER_PATIENT`).
PAPER_BODY_MASS_KG = 80.0

#: Standard gravity [m/s²] for the support force's "body weight".
G0 = 9.80665


#: The heaviest body the pelvis guide takes [kg]: a sanity bound, twice the top of
#: the body masses the anthropometric model covers (MASS_RANGE_KG, 35–150 kg).
MAX_BODY_MASS_KG = 300.0


@dataclass(frozen=True)
class PelvisParams:
    """The pelvis's vertical guide and the body-weight support (module docstring).

    Attributes:
        supported: a vertical pelvis with support (off: the paper's fixed pelvis).
        bws_fraction: β_s, the support force as a fraction of the patient's
            body weight [-], in [0, 1].
        body_mass_kg: the true patient's body mass [kg] (None: the paper
            patient's 80 kg); more than the patient URDF's links.
        travel_m: the harness's stops at ±travel from the nominal height [m].
        stop_stiffness_N_per_m: K of the stops [N/m].
        stop_damping_N_s_per_m: C of the stops [N·s/m].

    Raises:
        InvalidParameter: a fraction outside [0, 1], a mass, travel or
            stiffness not > 0, a damping < 0.

    """

    supported: bool = False
    bws_fraction: float = 0.0
    body_mass_kg: float | None = None
    travel_m: float = 0.10
    stop_stiffness_N_per_m: float = 1.0e5
    stop_damping_N_s_per_m: float = 2.0e3

    def __post_init__(self) -> None:
        fraction = v.finite("bws", self.bws_fraction)
        if not 0.0 <= fraction <= 1.0:
            raise InvalidParameter(
                "bws", self.bws_fraction, "in [0, 1] (a fraction of body weight)"
            )
        if self.body_mass_kg is not None:
            mass = v.positive("body_mass", self.body_mass_kg, "kg")
            if mass > MAX_BODY_MASS_KG:
                raise InvalidParameter(
                    "body_mass", self.body_mass_kg, f"in (0, {MAX_BODY_MASS_KG:g}] kg"
                )
            object.__setattr__(self, "body_mass_kg", mass)
        object.__setattr__(self, "bws_fraction", fraction)
        object.__setattr__(self, "travel_m", v.positive("pelvis travel", self.travel_m, "m"))
        object.__setattr__(
            self,
            "stop_stiffness_N_per_m",
            v.positive("pelvis stop stiffness", self.stop_stiffness_N_per_m, "N/m"),
        )
        object.__setattr__(
            self,
            "stop_damping_N_s_per_m",
            v.non_negative("pelvis stop damping", self.stop_damping_N_s_per_m, "N·s/m"),
        )
        object.__setattr__(self, "supported", v.flag("pelvis supported", self.supported))

    @property
    def body_mass(self) -> float:
        """The patient's body mass [kg] (the paper's when not given)."""
        return PAPER_BODY_MASS_KG if self.body_mass_kg is None else float(self.body_mass_kg)

    @property
    def support_N(self) -> float:
        """F_s = β_s m_body g₀ [N]."""
        return self.bws_fraction * self.body_mass * G0


#: Fields of the pelvis's record: ``on``; ``support`` F_s [N]; ``mass`` M
#: [kg]; state ``z``, ``vz``, ``az`` [m, m/s, m/s²] and ``z_mid``,
#: ``vz_mid``; ``tau`` the generalised force on z at mid-step without the
#: feet's [N]; ``stop_force`` [N]; the stops ``lower``, ``upper`` [m],
#: ``stop_k``, ``stop_c``; the nine-coordinate vectors ``q9``, ``v9``,
#: ``tau9``, ``arm9``, ``acc9`` ([z, q_all]) and, for the friction solve,
#: ``chol`` (9, 9) and ``g9`` (2, 9) = M⁻¹ J_xᵀ per foot; ``locked`` and
#: ``lock_z`` [m]: the harness's brake (module docstring).
PELVIS_FIELDS = [
    ("on", np.bool_),
    *((name, np.float64) for name in ("support", "mass", "z", "vz", "az", "z_mid", "vz_mid")),
    *((name, np.float64) for name in ("tau", "stop_force", "lower", "upper", "stop_k", "stop_c")),
    *((name, np.float64, (9,)) for name in ("q9", "v9", "tau9", "arm9", "acc9")),
    ("locked", np.bool_),
    ("lock_z", np.float64),
    ("chol", np.float64, (9, 9)),
    ("g9", np.float64, (2, 9)),
]


def pelvis_model(combined: pin.Model, patient: BodyModel, params: PelvisParams) -> pin.Model:
    """The nine-coordinate model: a prismatic z carrying the trunk, both legs' trees below it.

    Args:
        combined: both bodies' model (:func:`~exo_ctrl.model.combined_model`).
        patient: the true patient (its links' mass is taken from the body mass).
        params: the guide and the support.

    Returns:
        A model with q = [z, q_exo, q_patient]; the URDFs' pelvis links ride on z.

    Raises:
        InvalidModel: a body mass not above the patient URDF's links' mass.

    """
    # Its links and its pelvis link (on the universe: appendModel moves it onto z).
    legs = float(pin.computeTotalMass(patient.model)) + patient.model.inertias[0].mass
    trunk = params.body_mass - legs
    if not trunk > 0.0:
        raise InvalidModel(
            patient.source,
            "",
            f"body mass {params.body_mass:g} kg is not above the patient model's "
            f"{legs:.4g} kg of links: the pelvis needs the trunk's mass (body_mass larger)",
        )
    base = pin.Model()
    joint = base.addJoint(0, pin.JointModelPZ(), pin.SE3.Identity(), "pelvis_z")
    # A point mass on the guide: z only translates, so no rotational inertia acts.
    base.appendBodyToJoint(
        joint, pin.Inertia(trunk, np.zeros(3), np.eye(3) * 1e-3), pin.SE3.Identity()
    )
    frame = base.addFrame(
        pin.Frame("pelvis_carriage", joint, 0, pin.SE3.Identity(), pin.FrameType.OP_FRAME)
    )
    model = pin.appendModel(base, combined, frame, pin.SE3.Identity())
    model.gravity = pin.Motion(combined.gravity)
    if model.nq != 9 or model.joints[1].idx_q != 0:
        raise InvalidModel(patient.source, "", "the pelvis model's coordinates are not [z, q_all]")
    return model


def moving_mass_kg(params: PelvisParams, exo: pin.Model) -> float:
    """M: the body mass and every exoskeleton link, its pelvis link included [kg]."""
    return params.body_mass + float(pin.computeTotalMass(exo)) + float(exo.inertias[0].mass)


@kernel
def pelvis_drift(pel: Any, h: float) -> None:
    """z½ = z + (h/2) ż, ż½ = ż + (h/2) z̈⁻; the stops' and the support's force at z½."""
    half = 0.5 * h
    pel.z_mid = pel.z + pel.vz * half
    pel.vz_mid = pel.vz + pel.az * half
    force = 0.0
    d = pel.z_mid - pel.upper
    if d > 0.0:
        force = -max(0.0, pel.stop_k * d + pel.stop_c * pel.vz_mid)
    d = pel.lower - pel.z_mid
    if d > 0.0:
        force = max(0.0, pel.stop_k * d - pel.stop_c * pel.vz_mid)
    if pel.locked:  # the harness's brake: a bilateral spring–damper at z_l
        force -= pel.stop_k * (pel.z_mid - pel.lock_z) + pel.stop_c * pel.vz_mid
    pel.stop_force = force
    pel.tau = pel.support + force


@kernel
def pelvis_pack(plant: np.ndarray) -> None:
    """[z, q_all] vectors for ABA: positions, speeds, forces (the feet's too), armature."""
    p = plant[0]
    pel = p.pelvis
    pel.q9[0] = pel.z_mid
    pel.v9[0] = pel.vz_mid
    pel.tau9[0] = pel.tau + p.contact.fz
    pel.arm9[0] = 0.0
    for i in range(8):
        pel.q9[i + 1] = p.q_mid[i]
        pel.v9[i + 1] = p.v_mid[i]
        pel.tau9[i + 1] = p.tau[i]
        pel.arm9[i + 1] = p.armature[i]


@kernel
def pelvis_unpack(pel: Any, acc9: np.ndarray) -> None:
    """ABA's (or the friction solve's) nine accelerations into the record; z̈ apart."""
    for i in range(9):
        pel.acc9[i] = acc9[i]
    pel.az = acc9[0]


@kernel
def pelvis_kick(pel: Any, h: float) -> float:
    """ż⁺ = ż + h z̈, z⁺ = z½ + (h/2) ż⁺; returns ż⁺² [m²/s²]."""
    pel.vz = pel.vz + pel.az * h
    pel.z = pel.z_mid + pel.vz * 0.5 * h
    return pel.vz * pel.vz
