r"""The drive's parameters: motor constants, gearbox, supply and driver; presets.

A drive is a DC motor behind a gearbox of ratio ``i_G`` and efficiency ``η``
(the winding's dynamics and its exact step: :mod:`exo_ctrl.plant.motor`).

**Energy consistency.**  For a DC motor in SI units the torque constant
[N·m/A] equals the back-EMF constant [V·s/rad]: ``k_m = 1/k_E``.  Then the
power the back-EMF takes from the winding, ``e I``, is exactly the motor's
mechanical power ``τ_m ω``, and the energy books of
:mod:`exo_ctrl.plant.energy` balance.  :class:`MotorParams` refuses any
other pair (within 0.1 %, a datasheet's rounding) unless it is built as
:meth:`MotorParams.paper_printed`.

**Gearbox efficiency, direction-aware.**  When the motor drives the load
(motoring, ``τ_m ω > 0``) the joint gets ``η τ_m``; when the load drives the
motor (braking, ``τ_m ω < 0``) the joint must supply ``τ_m / η``.  Both are
``τ = η^{s} τ_m`` with ``s = sign(τ_m) tanh(ω/ω_η)``: ``s = ±1`` away from
standstill, smoothed over ``ω_η`` = :data:`EFFICIENCY_SMOOTHING_RAD_S` so
that the torque is continuous in ω (a held joint, ω = 0, sees the motor's
torque).  The gear loss ``(τ_m − τ) ω = τ_m ω (1 − η^{s}) ≥ 0`` for every
sign: the gearbox only dissipates.

**The paper's printed constants.**  Table I gives ``k_m = 0.35 N·m/A`` and
``k_E = 25.9 rad/(V·s)``: ``k_m k_E = 9.06``, so ``1/k_E = 0.0386 V·s/rad``
is nine times smaller than ``k_m`` and a drive with that pair delivers nine
times more mechanical power (``i_G k_m I ω``) than its back-EMF absorbs
(``e I``): in the default PD run each hip did 36 J of positive work from
4.9 J of electrical input.  (Read as 25.9 rpm/V, ``1/k_E`` would be
0.369 V·s/rad, within 5 % of ``k_m``.)  The default drive keeps the paper's
speed constant, whose motor class is known (below), and takes
``k_m = 1/k_E``; the printed pair is the preset
:meth:`MotorParams.paper_printed` (``exo-ctrl simulate --motor
paper-printed``), which warns that it is not energy-consistent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._validate import positive, within
from ..exceptions import InvalidParameter

__all__ = [
    "CONSISTENCY_TOLERANCE",
    "DRIVE_FAULTS",
    "EFFICIENCY_SMOOTHING_RAD_S",
    "MOTOR_PRESETS",
    "OPEN_PHASE",
    "PAPER_SPEED_CONSTANT_RAD_PER_VS",
    "SHORTED",
    "MotorParams",
    "consistency_warning",
    "gear_factor",
    "motor_preset",
]

#: Speed ω_η over which the gearbox efficiency turns from braking (τ_m/η) to
#: motoring (η τ_m) [rad/s at the joint]: tanh(ω/ω_η) is 0.76 at ω_η.  Small
#: against the gait's joint speeds (0.5–2 rad/s) and above the encoder's
#: speed noise.
EFFICIENCY_SMOOTHING_RAD_S = 0.05

#: Largest relative mismatch |k_m k_E − 1| an energy-consistent drive may have
#: (a datasheet's three-digit rounding of the two constants).
CONSISTENCY_TOLERANCE = 1e-3

#: The paper's speed constant k_E (Table I) [rad/(V·s)].
PAPER_SPEED_CONSTANT_RAD_PER_VS = 25.9


@dataclass(frozen=True)
class MotorParams:
    r"""Parameters of one drive (motor + gearbox), shared by a :class:`MotorBank`.

    The default is an energy-consistent drive of a real class: a flat
    brushless motor with the paper's winding (Table I: ``L``, ``R``, ``k_E``)
    behind a harmonic drive.  Values the paper does not give, and why:

    - ``torque_constant_Nm_per_A = 1/k_E = 0.0386 N·m/A``: the SI identity
      of a DC motor (module docstring).  A speed constant of 25.9 rad/(V·s)
      (247 rpm/V) with 0.1 Ω and 72 µH is the winding class of a 45–60 mm flat
      brushless motor of 100–200 W at 12–24 V (maxon EC flat and similar
      catalogues list 200–300 rpm/V windings of that size).
    - ``gear_ratio = 120``: harmonic drives of 100:1–160:1 are the usual
      exoskeleton joint reducers.  At 120 the default gait's joint speeds
      (≤ 2.2 rad/s) need ≤ 10.2 V of the 24 V supply and its hip torques
      (121 N·m motoring, 130 N·m braking, rotor included) ≤ 31 A.
    - ``gear_efficiency = 0.85``: harmonic-drive catalogue efficiency at
      rated torque and 1000–2000 rpm input, 25 °C (70–85 % for ratios
      100–120; lower at light load and low temperature), taken in both
      directions (module docstring).
    - ``supply_voltage_V = 24``: a common battery/bus voltage for
      exoskeleton drives.
    - ``current_limit_A = 32``: the peak current of a servo driver of this
      class, chosen so that the held torque ``i_G k_m I_max`` = 148 N·m stays
      within the joints' 150 N·m rating (motoring the joint gets η of it,
      126 N·m; braking, the plant holds the joint torque at the rating).
    - ``rotor_inertia_kgm2 = 2e-5``: rotor of a 45–60 mm flat brushless motor
      (1–3 × 10⁻⁵ kg·m² in such catalogues) with a harmonic drive's wave
      generator; reflected to the joint it is ``i_G² J_rotor = 0.29 kg·m²``,
      which the caller adds to the exoskeleton model's joint armature.

    Attributes:
        inductance_H: armature inductance L [H].
        resistance_ohm: armature resistance R [Ω].
        torque_constant_Nm_per_A: motor torque coefficient k_m [N·m/A].
        speed_constant_rad_per_Vs: speed coefficient k_E [rad/(V·s)]; the
            back-EMF is ``i_G ω / k_E``.
        gear_ratio: total gear ratio i_G (motor speed / joint speed) [-].
        supply_voltage_V: supply voltage limit U_max [V].
        current_limit_A: driver current limit I_max [A].
        rotor_inertia_kgm2: rotor inertia J_rotor, at the motor shaft [kg·m²].
        gear_efficiency: gearbox efficiency η in (0, 1] [-] (1: lossless).
        energy_consistent: refuse a pair with ``k_m k_E ≠ 1``; False only
            for :meth:`paper_printed` (a run with it warns).

    Raises:
        InvalidParameter: a number is not finite and > 0 (text and bools are
            refused, not converted), ``gear_efficiency`` beyond 1, or
            ``k_m k_E`` off 1 by more than :data:`CONSISTENCY_TOLERANCE`
            for an energy-consistent drive (naming both and the product).

    """

    inductance_H: float = field(default=0.072e-3, metadata={"unit": "H"})
    resistance_ohm: float = field(default=0.103, metadata={"unit": "Ω"})
    torque_constant_Nm_per_A: float = field(
        default=1.0 / PAPER_SPEED_CONSTANT_RAD_PER_VS, metadata={"unit": "N·m/A"}
    )
    speed_constant_rad_per_Vs: float = field(
        default=PAPER_SPEED_CONSTANT_RAD_PER_VS, metadata={"unit": "rad/(V·s)"}
    )
    gear_ratio: float = field(default=120.0, metadata={"unit": ""})
    supply_voltage_V: float = field(default=24.0, metadata={"unit": "V"})
    current_limit_A: float = field(default=32.0, metadata={"unit": "A"})
    rotor_inertia_kgm2: float = field(default=2e-5, metadata={"unit": "kg·m²"})
    gear_efficiency: float = field(default=0.85, metadata={"unit": ""})
    energy_consistent: bool = field(default=True, metadata={"unit": None})

    def __post_init__(self) -> None:
        for f in fields(self):
            unit = f.metadata["unit"]
            if unit is None:
                continue
            value = positive(f.name, getattr(self, f.name), unit)
            # any drive's constants, in SI units
            value = within(f.name, value, 1e-9, 1e9, unit, "a sanity range for any drive")
            object.__setattr__(self, f.name, value)
        if self.gear_efficiency > 1.0:
            raise InvalidParameter("gear_efficiency", self.gear_efficiency, "in (0, 1]")
        if not isinstance(self.energy_consistent, bool):
            raise InvalidParameter("energy_consistent", self.energy_consistent, "True or False")
        product = self.torque_constant_Nm_per_A * self.speed_constant_rad_per_Vs
        if self.energy_consistent and abs(product - 1.0) > CONSISTENCY_TOLERANCE:
            raise InvalidParameter(
                "torque_constant_Nm_per_A",
                self.torque_constant_Nm_per_A,
                f"1/speed_constant_rad_per_Vs = {1.0 / self.speed_constant_rad_per_Vs:.4g} "
                f"N·m/A within {CONSISTENCY_TOLERANCE:.1%} (an energy-consistent DC motor)",
                f"with speed_constant_rad_per_Vs = {self.speed_constant_rad_per_Vs:g} the "
                f"product k_m k_E is {product:.4g}, not 1: the motor would put out "
                f"{product:.3g} times the power its back-EMF takes in; "
                "MotorParams.paper_printed() is the paper's printed pair",
            )

    @classmethod
    def paper_printed(cls) -> MotorParams:
        """The paper's Table I constants as printed, with the earlier defaults.

        ``k_m = 0.35 N·m/A``, ``k_E = 25.9 rad/(V·s)`` (not energy-consistent:
        ``k_m k_E = 9.06``, module docstring), a lossless gearbox of ratio 50,
        24 V and 10 A.  Kept to reproduce the paper's figures and earlier runs;
        a run with it warns.
        """
        return cls(
            torque_constant_Nm_per_A=0.35,
            gear_ratio=50.0,
            current_limit_A=10.0,
            rotor_inertia_kgm2=6e-5,
            gear_efficiency=1.0,
            energy_consistent=False,
        )

    @property
    def electrical_time_constant_s(self) -> float:
        """Electrical time constant ``τ_e = L/R`` [s]."""
        return self.inductance_H / self.resistance_ohm

    @property
    def torque_per_amp_Nm_per_A(self) -> float:
        """Motor torque per armature ampere referred to the joint, ``i_G k_m`` [N·m/A].

        Before the gearbox's efficiency (the joint gets ``η^{s}`` of it).
        """
        return self.gear_ratio * self.torque_constant_Nm_per_A

    @property
    def back_emf_V_per_rad_s(self) -> float:
        """Back-EMF per unit joint speed ``i_G / k_E`` [V·s/rad]."""
        return self.gear_ratio / self.speed_constant_rad_per_Vs

    @property
    def reflected_inertia_kgm2(self) -> float:
        """Rotor inertia seen at the joint ``i_G² J_rotor`` [kg·m²]."""
        return self.gear_ratio**2 * self.rotor_inertia_kgm2

    @property
    def peak_torque_Nm(self) -> float:
        """Motor torque at the current limit ``i_G k_m I_max``, at the joint [N·m].

        What the drive holds at standstill; motoring it delivers η of it,
        braking it resists with 1/η of it.
        """
        return self.torque_per_amp_Nm_per_A * self.current_limit_A

    @property
    def log_efficiency(self) -> float:
        """``ln η`` [-]: the gear factor is ``exp(s ln η)``."""
        return math.log(self.gear_efficiency)


#: Drive faults, the values of a drive's ``fault`` field in the drives' record
#: (:func:`motor_fields`), set only by fault injection (:mod:`exo_ctrl.sim.faults`)
#: and honoured by :func:`step_drives`: 0 healthy; ``OPEN_PHASE`` (1), a winding
#: or a phase lead open: no current flows, the drive gives no torque and no
#: back-EMF braking (the rotor's inertia stays on the joint; the field's
#: ½ L I² at the opening is lost in the arc, outside the energy books);
#: ``SHORTED`` (2), the winding shorted: U = 0 whatever the command, the
#: back-EMF drives a braking current (the drive is the viscous brake of a
#: power cut).
DRIVE_FAULTS = ("healthy", "open_phase", "shorted")
OPEN_PHASE = 1.0
SHORTED = 2.0

#: Named drives: ``exo-ctrl simulate --motor NAME``.
MOTOR_PRESETS = ("default", "paper-printed")


def motor_preset(name: str) -> MotorParams:
    """The drive of a :data:`MOTOR_PRESETS` name.

    Raises:
        InvalidParameter: an unknown name.

    """
    if name == "default":
        return MotorParams()
    if name == "paper-printed":
        return MotorParams.paper_printed()
    raise InvalidParameter("motor", name, f"one of {', '.join(MOTOR_PRESETS)}")


def consistency_warning(params: MotorParams) -> str | None:
    """What a run with an energy-inconsistent drive must be told (None for a consistent one)."""
    if params.energy_consistent:
        return None
    product = params.torque_constant_Nm_per_A * params.speed_constant_rad_per_Vs
    return (
        f"the drive is not energy-consistent: k_m = {params.torque_constant_Nm_per_A:g} N·m/A "
        f"with k_E = {params.speed_constant_rad_per_Vs:g} rad/(V·s) gives k_m k_E = "
        f"{product:.3g} (1 for a real DC motor), so it puts out {product:.3g} times the "
        "mechanical power its back-EMF takes in; its voltages, currents and energy books are "
        "not a real drive's (the paper's printed constants, kept to reproduce its figures)"
    )


def gear_factor(efficiency: float, torque_Nm: ArrayLike, omega_rad_s: ArrayLike) -> NDArray:
    """The gearbox's ``η^{s}``, ``s = sign(τ_m) tanh(ω/ω_η)`` (module docstring).

    Args:
        efficiency: η in (0, 1].
        torque_Nm: motor torques referred to the joint τ_m, broadcastable [N·m].
        omega_rad_s: joint speeds, broadcastable [rad/s].

    Returns:
        The factor, broadcast shape: η motoring, 1/η braking, 1 at standstill.

    """
    s = np.sign(torque_Nm) * np.tanh(
        np.asarray(omega_rad_s, dtype=float) / EFFICIENCY_SMOOTHING_RAD_S
    )
    return np.exp(s * math.log(efficiency))
