"""Parameters of a generated two-leg body (exoskeleton or patient) and its segment inertias.

Every link with mass is a segment of length ``L`` along ``-z`` of its joint
frame, with its centre of mass at ``(0, 0, -c L)`` and a diagonal inertia
tensor about the centre of mass::

    I_xx = I_yy = m (ρ L)²       (transverse, about the COM)
    I_zz = m r² / 2              (axial, solid cylinder of radius r)

where ``c`` is the COM ratio, ``ρ`` the transverse radius-of-gyration ratio and
``r`` the segment radius.  Without a given ``ρ`` the segment is a uniform solid
cylinder: ``c = 1/2`` and ``I_xx = I_yy = m (3 r² + L²) / 12``.

:mod:`exo_ctrl.model.urdfgen` writes these parameters out as a URDF.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from .. import _validate as v
from ..exceptions import InvalidParameter

__all__ = ["BodyParams", "SegmentInertia", "segment_inertia"]

#: The kinds of body (:attr:`BodyParams.kind`).
_KINDS = ("exo", "patient")


@dataclass(frozen=True, kw_only=True)
class BodyParams:
    """Geometry, mass and joint limits of one two-leg model (exoskeleton or patient).

    Lengths are measured along the leg hanging straight down.  Both legs are
    identical.  See the module docstring for the inertia model and
    :mod:`exo_ctrl.model.urdfgen` for the frames.

    Sources of the defaults (:meth:`exo_default`, :meth:`patient_default`):

    - Paper Table I: masses (exo thigh 3.5 kg, shank 4.5 kg; patient thigh
      11.3 kg, shank and foot 4.65 kg for a 175 cm, 80 kg patient), link
      lengths 0.52 m, hip to thigh cuff 0.39 m, knee to shank cuff 0.45 m.
    - Exoskeleton mass distribution (chosen; the paper gives none): each link
      a uniform aluminium-beam-like solid cylinder of radius 0.03 m, COM at
      mid-length.
    - Patient mass distribution: Winter, *Biomechanics and Motor Control of
      Human Movement*, 4th ed. (2009), Table 4.1 — thigh COM 0.433 L from the
      hip, radius of gyration about the COM 0.323 L; leg and foot COM 0.606 L
      from the knee, radius of gyration 0.416 L.  Winter measures the leg to
      the medial malleolus; here the fractions are applied to the knee-to-foot
      link length.  The axial moment uses a plausible segment radius (chosen):
      0.06 m thigh, 0.04 m shank.
    - Joint ranges, effort, velocity, damping and friction: chosen values,
      not from the paper.  Exo: hip (-0.52, 2.09) rad, knee (-0.05, 2.09) rad,
      150 N·m, 6 rad/s, 0.5 N·m·s/rad, 0.3 N·m.  Patient: hip (-0.52, 2.09)
      rad, knee (-0.05, 2.36) rad, 300 N·m, 10 rad/s, 0.2 N·m·s/rad, 0 N·m.
    - ``hip_width`` 0.20 m for both, so that the hip joints coincide;
      ``pelvis_mass`` 1 kg (the pelvis is fixed to the world, its mass never
      enters the leg dynamics).

    Attributes:
        kind: ``"exo"`` or ``"patient"``; selects the robot name.
        thigh_length: hip to knee [m].
        shank_length: knee to foot point [m].
        thigh_mass: thigh mass [kg].
        shank_mass: shank mass [kg] (for the patient, shank and foot).
        thigh_cuff: hip to thigh cuff along the thigh [m], in (0, thigh_length].
        shank_cuff: knee to shank cuff along the shank [m], in (0, shank_length].
        thigh_radius: segment radius for the axial moment m r²/2 (and the
            cylinder model and the visual) [m].
        shank_radius: as ``thigh_radius`` for the shank [m].
        thigh_com_ratio: hip to thigh COM over thigh_length [-], in (0, 1).
        shank_com_ratio: knee to shank COM over shank_length [-], in (0, 1).
        thigh_gyration_ratio: transverse radius of gyration about the COM over
            thigh_length [-]; ``None`` for a uniform solid cylinder.
        shank_gyration_ratio: as ``thigh_gyration_ratio`` for the shank [-].
        hip_width: lateral distance between the two hip joints [m].
        pelvis_mass: mass of the root link, fixed to the world [kg].
        hip_range: (lower, upper) hip angle, flexion positive [rad].
        knee_range: (lower, upper) knee angle, flexion positive [rad].
        effort_limit: joint torque limit, every joint [N·m].
        velocity_limit: joint speed limit, every joint [rad/s].
        joint_damping: viscous joint damping [N·m·s/rad].
        joint_friction: dry (Coulomb) joint friction [N·m].

    """

    kind: str
    thigh_length: float
    shank_length: float
    thigh_mass: float
    shank_mass: float
    thigh_cuff: float
    shank_cuff: float
    thigh_radius: float
    shank_radius: float
    thigh_com_ratio: float = 0.5
    shank_com_ratio: float = 0.5
    thigh_gyration_ratio: float | None = None
    shank_gyration_ratio: float | None = None
    hip_width: float = 0.20
    pelvis_mass: float = 1.0
    hip_range: tuple[float, float]
    knee_range: tuple[float, float]
    effort_limit: float
    velocity_limit: float
    joint_damping: float
    joint_friction: float

    def __post_init__(self) -> None:
        if self.kind not in _KINDS:
            raise InvalidParameter("kind", self.kind, "'exo' or 'patient'")
        # (check, unit, the largest value: sanity bounds far beyond any leg or
        # drive, that keep the inertias' squares finite)
        checks = {
            "thigh_length": (v.positive, "m", 10.0),
            "shank_length": (v.positive, "m", 10.0),
            "thigh_mass": (v.positive, "kg", 1e4),
            "shank_mass": (v.positive, "kg", 1e4),
            "thigh_radius": (v.positive, "m", 10.0),
            "shank_radius": (v.positive, "m", 10.0),
            "hip_width": (v.positive, "m", 10.0),
            "pelvis_mass": (v.positive, "kg", 1e4),
            "effort_limit": (v.positive, "N·m", 1e6),
            "velocity_limit": (v.positive, "rad/s", 1e4),
            "joint_damping": (v.non_negative, "N·m·s/rad", 1e6),
            "joint_friction": (v.non_negative, "N·m", 1e6),
        }
        for name, (check, unit, most) in checks.items():
            value = check(name, getattr(self, name), unit)
            if value > most:
                low = "(0" if check is v.positive else "[0"
                raise InvalidParameter(name, value, f"in {low}, {most:g}] {unit}")
            self._set(name, value)
        for seg in ("thigh", "shank"):
            length = getattr(self, f"{seg}_length")
            cuff = v.finite(f"{seg}_cuff", getattr(self, f"{seg}_cuff"), "m")
            if not 0.0 < cuff <= length:
                raise InvalidParameter(
                    f"{seg}_cuff", cuff, f"in (0, {length:g}] m (the {seg} length)"
                )
            self._set(f"{seg}_cuff", cuff)
            name = f"{seg}_com_ratio"
            self._set(name, v.in_open_interval(name, getattr(self, name), 0.0, 1.0))
            self._check_gyration(seg)
        for name in ("hip_range", "knee_range"):
            self._set(name, _range(name, getattr(self, name)))

    def _set(self, name: str, value: Any) -> None:
        object.__setattr__(self, name, value)

    def _check_gyration(self, seg: str) -> None:
        name = f"{seg}_gyration_ratio"
        rho = getattr(self, name)
        if rho is None:
            return
        rho = v.positive(name, rho)
        self._set(name, rho)
        # Principal moments (I_t, I_t, I_a) are physical iff I_a < 2 I_t (strict
        # triangle inequality), i.e. m r²/2 < 2 m (ρ L)², i.e. r < 2 ρ L.
        radius_name = f"{seg}_radius"
        r_max = 2.0 * rho * getattr(self, f"{seg}_length")
        if not getattr(self, radius_name) < r_max:
            raise InvalidParameter(
                radius_name,
                getattr(self, radius_name),
                f"< {r_max:g} m (2 × {name} × {seg}_length)",
                "otherwise the inertia violates the triangle inequality",
            )

    @classmethod
    def exo_default(cls, **overrides: Any) -> BodyParams:
        """Exoskeleton of paper Table I; keyword arguments override single fields."""
        values: dict[str, Any] = {
            "kind": "exo",
            "thigh_length": 0.52,
            "shank_length": 0.52,
            "thigh_mass": 3.5,
            "shank_mass": 4.5,
            "thigh_cuff": 0.39,
            "shank_cuff": 0.45,
            "thigh_radius": 0.03,
            "shank_radius": 0.03,
            "hip_range": (-0.52, 2.09),
            "knee_range": (-0.05, 2.09),
            "effort_limit": 150.0,
            "velocity_limit": 6.0,
            "joint_damping": 0.5,
            "joint_friction": 0.3,
        }
        return cls(**{**values, **overrides})

    @classmethod
    def patient_default(cls, **overrides: Any) -> BodyParams:
        """Patient of paper Table I with Winter's segment data; keywords override fields."""
        values: dict[str, Any] = {
            "kind": "patient",
            "thigh_length": 0.52,
            "shank_length": 0.52,
            "thigh_mass": 11.3,
            "shank_mass": 4.65,
            "thigh_cuff": 0.39,
            "shank_cuff": 0.45,
            "thigh_radius": 0.06,
            "shank_radius": 0.04,
            "thigh_com_ratio": 0.433,
            "shank_com_ratio": 0.606,
            "thigh_gyration_ratio": 0.323,
            "shank_gyration_ratio": 0.416,
            "hip_range": (-0.52, 2.09),
            "knee_range": (-0.05, 2.36),
            "effort_limit": 300.0,
            "velocity_limit": 10.0,
            "joint_damping": 0.2,
            "joint_friction": 0.0,
        }
        return cls(**{**values, **overrides})

    def replace(self, **changes: Any) -> BodyParams:
        """Return a validated copy with some fields changed."""
        return dataclasses.replace(self, **changes)


@dataclass(frozen=True)
class SegmentInertia:
    """Mass distribution of one leg segment in its joint frame.

    Attributes:
        mass: segment mass [kg].
        com: distance from the proximal joint to the COM along -z [m].
        transverse: moment of inertia about the COM, x and y axes [kg·m²].
        axial: moment of inertia about the COM, z axis [kg·m²].

    """

    mass: float
    com: float
    transverse: float
    axial: float


def segment_inertia(params: BodyParams, segment: str) -> SegmentInertia:
    """Mass distribution of ``"thigh"`` or ``"shank"`` as written to the URDF.

    With a gyration ratio ρ: ``I_t = m (ρ L)²``; without: ``I_t = m (3 r² + L²) / 12``
    (uniform solid cylinder).  Always ``I_a = m r² / 2`` and COM at ``c L``.

    Args:
        params: body parameters.
        segment: ``"thigh"`` or ``"shank"``.

    Returns:
        The segment's mass, COM distance and principal moments about the COM.

    Raises:
        InvalidParameter: for an unknown segment name.

    """
    if segment not in ("thigh", "shank"):
        raise InvalidParameter("segment", segment, "'thigh' or 'shank'")
    m = getattr(params, f"{segment}_mass")
    length = getattr(params, f"{segment}_length")
    r = getattr(params, f"{segment}_radius")
    rho = getattr(params, f"{segment}_gyration_ratio")
    cylinder = rho is None
    transverse = m * (3.0 * r**2 + length**2) / 12.0 if cylinder else m * (rho * length) ** 2
    com = getattr(params, f"{segment}_com_ratio") * length
    return SegmentInertia(mass=m, com=com, transverse=transverse, axial=m * r**2 / 2.0)


def _range(name: str, value: Any) -> tuple[float, float]:
    allowed = "(lower, upper) with finite lower < upper [rad]"
    try:
        lower, upper = (float(x) for x in value)
    except (TypeError, ValueError):
        raise InvalidParameter(name, value, allowed) from None
    if not (math.isfinite(lower) and math.isfinite(upper) and lower < upper):
        raise InvalidParameter(name, value, allowed)
    return (lower, upper)
