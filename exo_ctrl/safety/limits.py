"""What the safety supervisor allows: its limits, their sources, and their resolution.

:class:`SafetyLimits` is the user's setting; :func:`resolve_limits` turns it,
with the exoskeleton's and the patient's models and the drive, into the
per-joint and per-cuff numbers the monitor compares the readings with
(:class:`ResolvedLimits`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import _validate as v
from ..exceptions import InvalidParameter
from ..model import CUFF_NAMES, JOINT_NAMES, BodyModel
from ..plant import MotorParams

__all__ = [
    "CURRENT_LIMIT_FACTOR",
    "ISO_TS_15066_CUFF_FORCE_N",
    "STATES",
    "ResolvedLimits",
    "SafetyLimits",
    "resolve_limits",
]

#: Supervisor states; the index is :attr:`SafetySupervisor.state_code` and
#: the ``state`` field of its record.
STATES = ("normal", "stopping", "holding", "power_cut", "yielding")

#: ISO/TS 15066:2016 Annex A, Table A.2, maximum permissible quasi-static
#: contact force for the body regions "thighs and knees" (220 N) and "lower
#: legs" (130 N), per cuff in CUFF_NAMES order [N].
ISO_TS_15066_CUFF_FORCE_N = (220.0, 130.0, 220.0, 130.0)

#: Default current monitor threshold as a multiple of the driver's current limit.
CURRENT_LIMIT_FACTOR = 1.1


@dataclass(frozen=True)
class SafetyLimits:
    """What the supervisor allows.  Every field has a default with its source.

    Attributes:
        cuff_force_N: maximum permissible force per cuff (magnitude of the
            sagittal force), CUFF_NAMES order (thigh, shank, thigh, shank)
            [N].  Default: ISO/TS 15066:2016 Annex A, Table A.2, quasi-static
            contact, "thighs and knees" 220 N, "lower legs" 130 N.
        cuff_force_factor: derating applied to ``cuff_force_N`` [-], in
            (0, 1].  Default 1.0 (not derated), a choice: the ISO values are
            pain-onset thresholds for clamping by a small contact surface,
            whereas a cuff spreads its load over a strap of ~100 cm², so the
            pressure, the other half of the ISO criterion, stays far below its
            limit; and the default passive run already needs 107 N on the
            shank cuffs (CT; 97 N with PD), so the ×0.5 often used for
            continuous contact (65 N) would stop every default run.  At ×1.0
            the passive runs keep a 20 % margin and the default spastic
            patient (≈ 180 N) is stopped.  Lower it for a stricter policy.
        rom_margin_rad: the joint range allowed is the intersection of the
            exoskeleton's and the patient's URDF ``<limit lower upper>``,
            shrunk by this margin at both ends [rad].  Default 0.05 (≈ 3°),
            a choice: room to stop before the mechanical end stop.
        position_lower_rad: explicit lower joint limits, JOINT_NAMES order
            [rad] (None: from the URDFs as above).
        position_upper_rad: explicit upper joint limits [rad] (None: URDFs).
        speed_limit_rad_s: joint speed limit [rad/s], a number or 4 (None:
            the smaller of the exoskeleton's and the patient's URDF
            ``<limit velocity>``, 6 rad/s with the default URDFs).
        current_limit_A: drive current monitor threshold [A] (None:
            ``CURRENT_LIMIT_FACTOR`` = 1.1 × the driver's current limit
            ``MotorParams.current_limit_A``).  The driver clips the current
            at its limit, so in simulation this monitor trips only when set
            below that limit (e.g. a motor's thermal rating); on hardware it
            catches a failed current loop (the 10 % allows the overshoot of a
            healthy current loop).

    Non-finite readings are always a violation (no setting).

    Raises:
        InvalidParameter: a value is not finite, not positive where a limit
            must be, has the wrong length, or a lower limit is not below the
            upper one.

    """

    cuff_force_N: tuple[float, ...] | float = ISO_TS_15066_CUFF_FORCE_N
    cuff_force_factor: float = 1.0
    rom_margin_rad: float = 0.05
    position_lower_rad: tuple[float, ...] | None = None
    position_upper_rad: tuple[float, ...] | None = None
    speed_limit_rad_s: tuple[float, ...] | float | None = None
    current_limit_A: float | None = None

    def __post_init__(self) -> None:
        force = v.per_item("cuff_force_N", self.cuff_force_N, "N", CUFF_NAMES, what="cuff")
        for cuff, f in zip(CUFF_NAMES, force, strict=True):
            v.positive(f"cuff_force_N[{cuff}]", f, "N")
        object.__setattr__(self, "cuff_force_N", force)
        factor = v.positive("cuff_force_factor", self.cuff_force_factor)
        if factor > 1.0:
            raise InvalidParameter("cuff_force_factor", self.cuff_force_factor, "in (0, 1]")
        v.non_negative("rom_margin_rad", self.rom_margin_rad, "rad")
        for name in ("position_lower_rad", "position_upper_rad"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, v.per_item(name, value, "rad", JOINT_NAMES))
        lo, hi = self.position_lower_rad, self.position_upper_rad
        if lo is not None and hi is not None:
            for joint, a, b in zip(JOINT_NAMES, lo, hi, strict=True):
                if not a < b:
                    raise InvalidParameter(
                        f"position_upper_rad[{joint}]", b, f"> position_lower_rad ({a:g} rad)"
                    )
        if self.speed_limit_rad_s is not None:
            speed = v.per_item("speed_limit_rad_s", self.speed_limit_rad_s, "rad/s", JOINT_NAMES)
            for joint, s in zip(JOINT_NAMES, speed, strict=True):
                v.positive(f"speed_limit_rad_s[{joint}]", s, "rad/s")
            object.__setattr__(self, "speed_limit_rad_s", speed)
        if self.current_limit_A is not None:
            v.positive("current_limit_A", self.current_limit_A, "A")

    @property
    def cuff_limit_N(self) -> np.ndarray:
        """Effective cuff force limits ``cuff_force_N × cuff_force_factor`` [N], (4,)."""
        return np.array(self.cuff_force_N) * self.cuff_force_factor


@dataclass(frozen=True)
class ResolvedLimits:
    """The limits as numbers, (4,) each, JOINT_NAMES order (the cuff limits CUFF_NAMES order).

    Attributes:
        q_lower: lower joint angle limits [rad].
        q_upper: upper joint angle limits [rad].
        speed_limit: joint speed limits [rad/s].
        current_limit: drive current limits [A].
        cuff_limit: cuff force limits (magnitude) [N].

    """

    q_lower: np.ndarray
    q_upper: np.ndarray
    speed_limit: np.ndarray
    current_limit: np.ndarray
    cuff_limit: np.ndarray


def resolve_limits(
    limits: SafetyLimits, exo: BodyModel, patient: BodyModel | None, motor: MotorParams
) -> ResolvedLimits:
    """Resolve ``limits`` against the models and the drive (see :class:`SafetyLimits`).

    The joint range is ``[max(lower_exo, lower_patient) + m, min(upper_exo,
    upper_patient) - m]`` with the margin m = ``rom_margin_rad`` unless given
    explicitly; the speed limit ``min(velocity_exo, velocity_patient)``
    unless given; the current limit ``CURRENT_LIMIT_FACTOR × current_limit_A``
    of the drive unless given.

    Args:
        limits: the setting.
        exo: the exoskeleton model.
        patient: the patient model (None: the exoskeleton's limits alone).
        motor: the drive as configured.

    Returns:
        The resolved limits.

    Raises:
        InvalidParameter: a joint is left without a range (lower >= upper),
            naming the setting that caused it.

    """
    bodies = [b for b in (exo, patient) if b is not None]
    lo = np.max([b.position_limits[0] for b in bodies], axis=0) + limits.rom_margin_rad
    hi = np.min([b.position_limits[1] for b in bodies], axis=0) - limits.rom_margin_rad
    if limits.position_lower_rad is not None:
        lo = np.array(limits.position_lower_rad)
    if limits.position_upper_rad is not None:
        hi = np.array(limits.position_upper_rad)
    for joint, a, b in zip(JOINT_NAMES, lo, hi, strict=True):
        if not a < b:
            if limits.position_upper_rad is not None:
                name, value = "position_upper_rad", limits.position_upper_rad
            elif limits.position_lower_rad is not None:
                name, value = "position_lower_rad", limits.position_lower_rad
            else:
                name, value = "rom_margin_rad", limits.rom_margin_rad
            raise InvalidParameter(
                name,
                value,
                f"such that {joint} keeps a range (lower {a:g} rad, upper {b:g} rad)",
            )
    if limits.speed_limit_rad_s is None:
        speed = np.min([b.velocity_limit for b in bodies], axis=0)
    else:
        speed = np.array(limits.speed_limit_rad_s)
    i_lim = limits.current_limit_A
    if i_lim is None:
        i_lim = CURRENT_LIMIT_FACTOR * motor.current_limit_A
    return ResolvedLimits(
        q_lower=lo,
        q_upper=hi,
        speed_limit=speed,
        current_limit=np.full(4, float(i_lim)),
        cuff_limit=limits.cuff_limit_N,
    )
