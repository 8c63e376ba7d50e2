r"""Optional joint compliance: a torsional spring–damper between each drive and its link.

A harmonic drive's flexspline (with the output bearing, the joint torque
sensor and the frame in series) is not rigid.  With :class:`CompliantJoint`
enabled, each exoskeleton joint j has two coordinates: the link angle q
(Pinocchio's joint) and the motor side's angle θ, the rotor angle referred
to the joint (rotor angle / i_G), with the reflected rotor inertia
J_r = i_G² J_rotor.  Between them acts

.. math::

    τ_s = K (θ - q) + C (\dot θ - \dot q),

and the two sides obey

.. math::

    J_r \ddot θ = τ_d(\dot θ) - τ_s, \qquad
    M(q)\,\ddot q + h(q, \dot q) = τ_s + τ_{cuffs} + τ_{stops} - b \dot q - …,

where τ_d is the drive's torque (:mod:`exo_ctrl.plant.motor`: the mean
current's torque through the gearbox's efficiency η^s, its back-EMF and
η^s taken at the rotor's speed θ̇).  The link's model loses the rotor
armature (it is on the far side of the spring); the URDF's joint damping
and friction stay on the link.  The joint torque sensor sits between the
gearbox and the link, so it reads τ_s; the encoders measure the link, q
(as on a device whose encoder is on the joint output); ``drive_torque`` is
the drive's τ_d, which acts on the rotor.  Off (the default)
the drive is rigid, as in :mod:`exo_ctrl.plant.plant`, bit for bit.

**Parameters.**  K = 2·10⁴ N·m/rad: the torsional stiffness K3 of a size-20
to 25 harmonic drive of ratio ≥ 80 (Harmonic Drive CSF/CSG catalogue,
engineering data, "Torsional stiffness": a few 10⁴ N·m/rad, from the
torque–torsion curve with the wave generator blocked), taken at the low end
because the bearing, the torque sensor and the frame are in series with it.
The full 150 N·m rating then deflects the joint by 7.5 mrad (0.43°).
C = 15 N·m·s/rad: harmonic drives have little structural damping (the
catalogue's "hysteresis loss"; identified flexspline damping ratios are of
a few percent to about 0.1, e.g. Taghirad and Bélanger, ASME J. Dyn. Syst.
Meas. Control 1998); with the default drive's J_r = 0.288 kg·m² it gives
ζ = C / (2 √(K J_r)) = 0.099.  The rotor's mode against a clamped link is
ω_r = √(K / J_r) = 263.5 rad/s (41.9 Hz); the drive's back-EMF damping,
D ≈ 330 N·m·s/rad at the joint, damps it far more (D / (2 √(K J_r)) = 2.2)
whenever the driver holds a voltage.

**Integration** (the plant's step h).  The rotor joins the plant's
drift–kick–drift leapfrog: θ½ = θ + (h/2) θ̇ and θ̇½ = θ̇ + (h/2) θ̈⁻
(extrapolated, as the links' speeds are), the spring–damper torque is taken
at mid-step from (θ½ − q½, θ̇½ − q̇½) and acts on the link in the plant's
ABA call and on the rotor.  The rotor's stiff back-EMF damping (time
constant J_r / D ≈ 0.9 ms) is taken implicitly as on a rigid joint:
(J_r + h D) θ̈ = τ_d − τ_s, the applied torque τ_d − h D θ̈ held within
the drive's cap like the rigid one's (a held drive is stepped at once with
J_r θ̈ = cap − τ_s: the rotor is not in the ABA call, nothing is solved
again).  Then θ̇⁺ = θ̇ + h θ̈ and θ⁺ = θ½ + (h/2) θ̇⁺.  The spring is
conservative and its forces are taken at mid-step, so the rotor–spring–link
system is Störmer–Verlet: stable for ω h < 2 with ω the fastest mode,
exactly ω_max² = K (1/J_r + 1/λ_min(M)) for the link mass matrix M
(λ_min = 0.0725 kg·m² for the default exoskeleton with the leg straight:
ω_max = 587 rad/s, ω_max h = 0.59 at 1 ms).  :class:`Rotors` refuses a
stiffness with ω_max h > 1 (:data:`MAX_OMEGA_H`).  Accuracy: second order;
a mode ω oscillates at (2/h) arcsin(ω h / 2), (ω h)²/24 fast (0.29 % for
ω_r, 1.4 % for ω_max at 1 ms), and the energy of an undamped mode is not
drifting but oscillates within a fraction (ω h)²/4 / (1 − (ω h)²/4) of it
(1.8 % for ω_r, 9.4 % for ω_max at 1 ms).  The damper's explicit part
C h / λ_min = 0.21 stays well inside its bound.

**Energy.**  :meth:`Rotors.energy` is the rotors' kinetic energy ½ J_r θ̇²
and the springs' ½ K (θ − q)² (part of
:meth:`~exo_ctrl.plant.plant.Plant.mechanical_energy` when enabled);
``spring_dissipated`` books the damper's work C (θ̇½ − q̇½) (Δθ − Δq) over each
step's travel [J] (Δθ = h (θ̇ + h θ̈ / 2), Δq likewise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pinocchio as pin

from .. import _validate as v
from .._jit import kernel
from ..exceptions import InvalidParameter
from .drive import MotorParams
from .energy import book_drives
from .motor import drive_cap, hold_drive, step_drives

__all__ = [
    "COMPLIANCE_FIELDS",
    "MAX_OMEGA_H",
    "CompliantJoint",
    "Rotors",
    "rotor_forces",
    "rotor_kick",
]

#: The largest ω_max h the plant accepts (Störmer–Verlet's bound is 2; the
#: margin covers the postures, the cuffs and the damper) [-].
MAX_OMEGA_H = 1.0


@dataclass(frozen=True)
class CompliantJoint:
    """A torsional spring–damper between each drive and its link (module docstring).

    Attributes:
        stiffness_Nm_per_rad: K [N·m/rad].
        damping_Nm_s_per_rad: C [N·m·s/rad].
        enabled: model the compliance (default off: a rigid drive).

    Raises:
        InvalidParameter: K not a number > 0, C not a number >= 0, or
            ``enabled`` not True or False.

    """

    stiffness_Nm_per_rad: float = 2.0e4
    damping_Nm_s_per_rad: float = 15.0
    enabled: bool = False

    def __post_init__(self) -> None:
        k = v.positive("joint_stiffness", self.stiffness_Nm_per_rad, "N·m/rad")
        c = v.non_negative("joint_damping", self.damping_Nm_s_per_rad, "N·m·s/rad")
        if not isinstance(self.enabled, bool):
            raise InvalidParameter("joint_compliance.enabled", self.enabled, "True or False")
        object.__setattr__(self, "stiffness_Nm_per_rad", k)
        object.__setattr__(self, "damping_Nm_s_per_rad", c)

    def rotor_frequency_rad_s(self, motor: MotorParams) -> float:
        """The rotor's mode against a clamped link, √(K / J_r) [rad/s]."""
        return math.sqrt(self.stiffness_Nm_per_rad / motor.reflected_inertia_kgm2)

    def damping_ratio(self, motor: MotorParams) -> float:
        """The damper's ratio against the rotor, C / (2 √(K J_r)) [-]."""
        k, c = self.stiffness_Nm_per_rad, self.damping_Nm_s_per_rad
        return c / (2.0 * math.sqrt(k * motor.reflected_inertia_kgm2))


#: The compliance's fields of the plant's record, per exoskeleton joint (4):
#: ``rotor_q`` θ [rad], ``rotor_v`` θ̇ [rad/s], ``rotor_acc`` the last step's
#: θ̈ [rad/s²], ``rotor_mid`` θ½ [rad], ``rotor_inertia`` J_r [kg·m²],
#: ``spring_torque`` τ_s at mid-step [N·m], ``deflection`` θ½ − q½ [rad],
#: ``spring_dissipated`` the dampers' work since the reset [J]; and
#: ``spring_k`` K [N·m/rad], ``spring_c`` C [N·m·s/rad], ``compliant``.
_ROTOR_ROWS = (
    "rotor_q", "rotor_v", "rotor_acc", "rotor_mid", "rotor_inertia", "spring_torque",
    "deflection", "spring_dissipated",
)  # fmt: skip
COMPLIANCE_FIELDS = [
    *((name, np.float64, (4,)) for name in _ROTOR_ROWS),
    ("spring_k", np.float64),
    ("spring_c", np.float64),
    ("compliant", np.bool_),
]


class Rotors:
    """The drives' rotors in the plant's record: set up, reset, their energy.

    Args:
        plant: the plant's record (its :data:`COMPLIANCE_FIELDS`, ``q``, ``v``,
            ``drive_torque``).
        joint: the compliance.
        motors: the drives (None: none).
        exo_model: the exoskeleton's Pinocchio model (its mass matrix bounds
            the fastest mode).
        h: the plant step [s].

    Attributes:
        link_armature_kgm2: the rotor inertia the link's model keeps [kg·m²]:
            i_G² J_rotor for a rigid drive, 0 for a compliant one (the rotor
            is its own body) and without drives.

    Raises:
        InvalidParameter: compliance without drives, or a stiffness whose
            fastest mode ω_max (module docstring, at the straight leg) has
            ω_max h > :data:`MAX_OMEGA_H`.

    """

    def __init__(
        self,
        plant: np.ndarray,
        joint: CompliantJoint,
        motors: MotorParams | None,
        exo_model: pin.Model,
        h: float,
    ) -> None:
        self._record = plant
        self.enabled = joint.enabled
        p = plant[0]
        p["spring_k"] = joint.stiffness_Nm_per_rad
        p["spring_c"] = joint.damping_Nm_s_per_rad
        p["compliant"] = joint.enabled
        self.link_armature_kgm2 = 0.0
        #: The fastest mode of the rotors, springs and links, ω_max [rad/s] (NaN: rigid).
        self.fastest_mode_rad_s = math.nan
        if motors is None:
            if joint.enabled:
                raise InvalidParameter(
                    "joint_compliance", joint, "disabled", "the plant has no drives to be compliant"
                )
            return
        rotor = motors.reflected_inertia_kgm2
        p["rotor_inertia"] = rotor
        if not joint.enabled:
            self.link_armature_kgm2 = rotor
            return
        mass = pin.crba(exo_model, exo_model.createData(), np.zeros(exo_model.nq))
        link = float(np.linalg.eigvalsh(np.triu(mass) + np.triu(mass, 1).T)[0])
        k = joint.stiffness_Nm_per_rad
        self.fastest_mode_rad_s = math.sqrt(k * (1.0 / rotor + 1.0 / link))
        if self.fastest_mode_rad_s * h > MAX_OMEGA_H:
            most = (MAX_OMEGA_H / h) ** 2 / (1.0 / rotor + 1.0 / link)
            raise InvalidParameter(
                "joint_stiffness",
                k,
                f"at most {most:.4g} N·m/rad at a plant step of {h * 1e3:g} ms",
                f"its fastest mode, {self.fastest_mode_rad_s:.4g} rad/s with the rotor's "
                f"{rotor:.4g} kg·m² and the link's {link:.4g} kg·m², needs ω h <= "
                f"{MAX_OMEGA_H:g}; more plant substeps allow a stiffer joint",
            )

    def reset(self) -> None:
        """Put each rotor at its link's speed, its spring holding the drive's torque.

        θ = q + τ_d / K, θ̇ = q̇: the spring at the static deflection of the
        drive torque ``drive_torque`` (set by the caller), so that a start at
        rest is bumpless.  Nothing without compliance.
        """
        if not self.enabled:
            return
        p = self._record[0]
        torque = p["drive_torque"]
        p["deflection"] = torque / p["spring_k"]
        p["rotor_q"] = p["q"][:4] + p["deflection"]
        p["rotor_v"] = p["v"][:4]
        p["rotor_mid"] = p["rotor_q"]
        p["rotor_acc"] = 0.0
        p["spring_torque"] = torque
        p["spring_dissipated"] = 0.0

    def energy(self) -> float:
        """The rotors' kinetic and the springs' energy, ½ J_r θ̇² + ½ K (θ − q)² [J] (0: rigid)."""
        if not self.enabled:
            return 0.0
        p = self._record[0]
        stretch = p["rotor_q"] - p["q"][:4]
        kinetic = 0.5 * float(p["rotor_inertia"] @ p["rotor_v"] ** 2)
        return kinetic + 0.5 * float(p["spring_k"]) * float(stretch @ stretch)

    @property
    def dissipated_J(self) -> float:
        """The dampers' energy since the reset, Σ C (θ̇½ − q̇½) (Δθ − Δq) [J]."""
        return float(np.sum(self._record[0]["spring_dissipated"]))


@kernel
def rotor_forces(p: Any, voltage_V: np.ndarray, qm: np.ndarray, vm: np.ndarray, tau: np.ndarray):
    """Drives at the rotors' speed, rotors to mid-step, the springs' torques added to ``tau``.

    ``p``: the plant's record (its :data:`COMPLIANCE_FIELDS`, ``h``, the
    drives' ``motors``); ``qm``, ``vm``, ``tau``: the links' mid-step state
    and torques (the exoskeleton's first).  Sets ``drive_torque`` (the
    drive's τ_d, not yet held within its cap) and ``damping_m`` = h D.
    """
    m = p.motors
    h = p.h
    half = 0.5 * h
    step_drives(m, voltage_V, p.rotor_v[:])
    for j in range(4):
        mid = p.rotor_q[j] + p.rotor_v[j] * half
        rate = p.rotor_v[j] + p.rotor_acc[j] * half - vm[j]
        p.rotor_mid[j] = mid
        p.deflection[j] = mid - qm[j]
        spring = p.spring_k * p.deflection[j] + p.spring_c * rate
        p.spring_torque[j] = spring
        tau[j] += spring
        p.drive_torque[j] = m.torque[j]
        p.damping_m[j] = m.damping[j] * h


@kernel
def rotor_kick(p: Any) -> None:
    """The rotors' kick and drift (module docstring), the drives held and booked.

    (J_r + h D) θ̈ = τ_d − τ_s; the applied torque τ_d − h D θ̈ is held within
    the cap of :func:`~exo_ctrl.plant.step.kick_and_drift` (then
    J_r θ̈ = cap − τ_s); the sensor reads τ_s.
    """
    m = p.motors
    h = p.h
    for j in range(4):
        cap, i_held = drive_cap(m, p.effort[j], j)
        spring = p.spring_torque[j]
        hd = p.damping_m[j]
        acc = (p.drive_torque[j] - spring) / (p.rotor_inertia[j] + hd)
        torque = p.drive_torque[j] - hd * acc
        if abs(torque) > cap:
            sign = 1.0 if torque > 0.0 else -1.0
            torque = sign * cap
            acc = (torque - spring) / p.rotor_inertia[j]
            p.damping_m[j] = 0.0
            hold_drive(m, j, torque, sign * i_held)
        p.drive_torque[j] = torque
        p.rotor_acc[j] = acc
        p.sensor_torque[j] = spring
        # The damper's work over the step's relative travel h (ω + h α / 2), rotor less link.
        damper = spring - p.spring_k * p.deflection[j]
        travel = (p.rotor_v[j] + 0.5 * h * acc) - (p.v[j] + 0.5 * h * p.acc[j])
        p.spring_dissipated[j] += damper * travel * h
    book_drives(m, p.rotor_v[:])  # ω held over the step: the rotor's at its start
    half = 0.5 * h
    for j in range(4):
        p.rotor_v[j] += p.rotor_acc[j] * h
        p.rotor_q[j] = p.rotor_mid[j] + p.rotor_v[j] * half
