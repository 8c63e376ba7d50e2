r"""A patient's legs from height, body mass and sex: anthropometric regressions.

Segment masses, centres of mass and radii of gyration are de Leva's
adjustment of Zatsiorsky–Seluyanov's data (de Leva P., *Adjustments to
Zatsiorsky–Seluyanov's segment inertia parameters*, J. Biomech. 29(9),
1223–1230, 1996, Table 4): each segment's mass as a fraction of body mass,
its centre of mass and its radii of gyration as fractions of its length,
lengths between joint centres, the reference subjects' mean segment lengths
scaled by stature (the reference statures are 1.741 m, male, and 1.735 m,
female).  The foot point of the paper's two-link leg is on the sole under
the ankle: the knee-to-foot-point link is the leg segment (knee joint centre
to lateral malleolus) plus the ankle height, 0.039 × stature (Winter,
*Biomechanics and Motor Control of Human Movement*, 4th ed., 2009, Fig. 4.1,
after Drillis and Contini).

The paper's leg has two links; the patient's foot is carried by the shank
link.  Its mass joins the shank's, its centre of mass is taken on the link
axis at the ankle height above the foot point (the foot's forward offset
from the ankle is left out: the model's links are straight segments), and
the shank link's radius of gyration about the combined centre of mass
follows from the parallel-axis theorem,

.. math::

    m\,(ρ L)^2 = Σ_i m_i \left[(r_i L_i)^2 + (c_i - c)^2\right],
    \qquad c = Σ_i m_i c_i / m,

with the sagittal radii r_i of the leg and the foot (the foot's r over its
heel-to-toe length).  The axial moment uses de Leva's longitudinal radius of
gyration, written as the equivalent cylinder radius r = √2 r_long L
(I_axial = m r²/2).

For the paper's 80 kg, 1.75 m patient (male) this gives a thigh of 11.3 kg
and a shank with foot of 4.56 kg, against Table I's 11.3 and 4.65 kg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from .. import _validate as v
from ..exceptions import InvalidParameter
from .body_params import BodyParams

__all__ = [
    "SEXES",
    "Segment",
    "body_mass_from_legs",
    "nominal_patient",
    "patient_from_anthropometry",
    "stature_from_legs",
]

#: The sexes of de Leva's tables.
SEXES = ("female", "male")

#: Heights and body masses the regressions are used for [m], [kg]: adults.
HEIGHT_RANGE_M = (1.40, 2.10)
MASS_RANGE_KG = (35.0, 150.0)

#: Ankle height over stature (Winter 2009, after Drillis and Contini).
ANKLE_HEIGHT_RATIO = 0.039

#: Where the cuffs sit along their links, as in the default patient (paper
#: Table I: 0.39 m of the 0.52 m thigh, 0.45 m of the 0.52 m shank).
THIGH_CUFF_RATIO = 0.39 / 0.52
SHANK_CUFF_RATIO = 0.45 / 0.52


@dataclass(frozen=True)
class Segment:
    """One segment of de Leva's Table 4.

    Attributes:
        mass: mass over body mass [-].
        com: proximal end to the centre of mass over the length [-].
        r_sagittal: sagittal radius of gyration about the centre of mass over the length [-].
        r_long: longitudinal radius of gyration over the length [-].
        length: the reference subjects' mean length [m].

    """

    mass: float
    com: float
    r_sagittal: float
    r_long: float
    length: float


#: de Leva 1996, Table 4 (thigh: hip to knee joint centre; leg: knee joint
#: centre to lateral malleolus; foot: heel to toe tip), and the reference
#: statures [m].
TABLES: dict[str, dict[str, Any]] = {
    "male": {
        "stature": 1.741,
        "thigh": Segment(0.1416, 0.4095, 0.329, 0.149, 0.4222),
        "leg": Segment(0.0433, 0.4459, 0.255, 0.103, 0.4340),
        "foot": Segment(0.0137, 0.4415, 0.257, 0.124, 0.2581),
    },
    "female": {
        "stature": 1.735,
        "thigh": Segment(0.1478, 0.3612, 0.369, 0.162, 0.3685),
        "leg": Segment(0.0481, 0.4416, 0.271, 0.093, 0.4323),
        "foot": Segment(0.0129, 0.4014, 0.299, 0.139, 0.2283),
    },
}


def patient_from_anthropometry(
    height_m: float, mass_kg: float, sex: str = "male", **overrides: Any
) -> BodyParams:
    """The patient's legs for a height, body mass and sex (module docstring).

    Joint ranges, limits, damping and friction are the default patient's
    (:meth:`BodyParams.patient_default`); the cuffs sit at the default
    patient's fractions of the links.

    Args:
        height_m: stature [m], in :data:`HEIGHT_RANGE_M`.
        mass_kg: body mass [kg], in :data:`MASS_RANGE_KG`.
        sex: ``"female"`` or ``"male"``.
        **overrides: fields of :class:`BodyParams` to set after the regressions.

    Returns:
        The patient's body parameters.

    Raises:
        InvalidParameter: a height, mass or sex outside what the tables are
            for (naming the value and the range).

    """
    height = v.finite("height", height_m, "m")
    mass = v.finite("mass", mass_kg, "kg")
    for name, value, (lo, hi), unit in (
        ("height", height, HEIGHT_RANGE_M, "m"),
        ("mass", mass, MASS_RANGE_KG, "kg"),
    ):
        if not lo <= value <= hi:
            raise InvalidParameter(
                name, value, f"in [{lo:g}, {hi:g}] {unit}", "adults: the range of the regressions"
            )
    if sex not in SEXES:
        raise InvalidParameter("sex", sex, f"one of {', '.join(SEXES)}")
    table = TABLES[sex]
    scale = height / table["stature"]
    thigh, leg, foot = table["thigh"], table["leg"], table["foot"]
    thigh_length = thigh.length * scale
    leg_length = leg.length * scale
    foot_length = foot.length * scale
    ankle = ANKLE_HEIGHT_RATIO * height
    shank_length = leg_length + ankle
    m_thigh = thigh.mass * mass
    m_leg, m_foot = leg.mass * mass, foot.mass * mass
    m_shank = m_leg + m_foot
    c_leg, c_foot = leg.com * leg_length, leg_length  # the foot's COM at the ankle, on the axis
    c_shank = (m_leg * c_leg + m_foot * c_foot) / m_shank
    inertia = m_leg * ((leg.r_sagittal * leg_length) ** 2 + (c_leg - c_shank) ** 2) + m_foot * (
        (foot.r_sagittal * foot_length) ** 2 + (c_foot - c_shank) ** 2
    )
    axial_leg = m_leg * (leg.r_long * leg_length) ** 2
    axial_foot = m_foot * (foot.r_long * foot_length) ** 2
    values: dict[str, Any] = {
        "thigh_length": thigh_length,
        "shank_length": shank_length,
        "thigh_mass": m_thigh,
        "shank_mass": m_shank,
        "thigh_cuff": THIGH_CUFF_RATIO * thigh_length,
        "shank_cuff": SHANK_CUFF_RATIO * shank_length,
        "thigh_radius": math.sqrt(2.0) * thigh.r_long * thigh_length,
        "shank_radius": math.sqrt(2.0 * (axial_leg + axial_foot) / m_shank),
        "thigh_com_ratio": thigh.com,
        "shank_com_ratio": c_shank / shank_length,
        "thigh_gyration_ratio": thigh.r_sagittal,
        "shank_gyration_ratio": math.sqrt(inertia / m_shank) / shank_length,
    }
    return BodyParams.patient_default(**{**values, **overrides})


def nominal_patient(
    thigh_length_m: float,
    shank_length_m: float,
    height_m: float,
    mass_kg: float,
    sex: str = "male",
) -> BodyParams:
    """What a device can know of its patient: measured link lengths, the rest from the tables.

    A clinic measures the patient's stature, body mass and leg segment
    lengths (the exoskeleton is adjusted to them); masses, centres of mass
    and radii of gyration come from :func:`patient_from_anthropometry` for
    the stature, mass and sex, kept as fractions of each link's length (the
    radii scaled with it) and applied to the measured lengths.

    Args:
        thigh_length_m: measured hip to knee [m].
        shank_length_m: measured knee to foot point (sole) [m].
        height_m: stature [m].
        mass_kg: body mass [kg].
        sex: ``"female"`` or ``"male"``.

    Raises:
        InvalidParameter: as :func:`patient_from_anthropometry`, or a length
            that is not a finite number > 0.

    """
    table = patient_from_anthropometry(height_m, mass_kg, sex)
    thigh = v.positive("thigh_length", thigh_length_m, "m")
    shank = v.positive("shank_length", shank_length_m, "m")
    k_t, k_s = thigh / table.thigh_length, shank / table.shank_length
    return table.replace(
        thigh_length=thigh,
        shank_length=shank,
        thigh_cuff=THIGH_CUFF_RATIO * thigh,
        shank_cuff=SHANK_CUFF_RATIO * shank,
        thigh_radius=table.thigh_radius * k_t,
        shank_radius=table.shank_radius * k_s,
    )


def stature_from_legs(thigh_length_m: float, shank_length_m: float, sex: str = "male") -> float:
    """The stature [m] whose de Leva thigh and shank (leg + ankle height) sum to a measured leg.

    Inverts :func:`patient_from_anthropometry`'s lengths: thigh + shank =
    H (l_thigh + l_leg) / H_ref + a H, with a = :data:`ANKLE_HEIGHT_RATIO`.
    """
    table = TABLES[sex]
    per_height = (table["thigh"].length + table["leg"].length) / table["stature"]
    return (thigh_length_m + shank_length_m) / (per_height + ANKLE_HEIGHT_RATIO)


def body_mass_from_legs(legs_mass_kg: float, sex: str = "male") -> float:
    """The body mass [kg] whose de Leva thighs, legs and feet weigh ``legs_mass_kg`` (both legs).

    Inverts :func:`patient_from_anthropometry`'s masses:
    m_legs = 2 (μ_thigh + μ_leg + μ_foot) M.
    """
    table = TABLES[sex]
    share = table["thigh"].mass + table["leg"].mass + table["foot"].mass
    return legs_mass_kg / (2.0 * share)
