r"""A virtual cohort: seeded true patients around de Leva's nominal patient.

A regression such as de Leva's (1996, Table 4; :mod:`~exo_ctrl.model.anthropometry`)
gives the *mean* segment parameters of people of a stature, body mass and
sex; a person differs from it.  :func:`draw_cohort` draws patients around
the nominal one: each of the ten parameters ``x`` of the two leg links

    thigh and shank length L, mass m, centre-of-mass ratio c,
    transverse radius-of-gyration ratio ρ, axial radius r,

is the nominal value times an independent factor

.. math::

    x = x_0 (1 + s_x z), \qquad z \sim N(0, 1) \text{ truncated to } |z| \le z_{max},

with the coefficient of variation ``s_x`` of :class:`CohortSpread` and
``z_max`` = 2.5 (a draw beyond it is drawn again).  Both legs of a patient
are alike (the URDFs are symmetric); the cuffs keep their fractions of the
links (:data:`~exo_ctrl.model.anthropometry.THIGH_CUFF_RATIO`); joint
ranges, damping and friction are the nominal's.  The sample standard
deviation of ``x / x_0`` is then ``s_x σ_t`` with the truncated normal's

.. math::

    σ_t^2 = 1 - \frac{2 z_{max} φ(z_{max})}{2Φ(z_{max}) - 1}, \qquad σ_t = 0.9546
    \text{ at } z_{max} = 2.5.

**Spreads (default :class:`CohortSpread`).**  Against each subject's own
segment parameters measured by dual-energy X-ray absorptiometry, every
regression and geometric method tried erred by more than 10 % on at least one
segment parameter of every group of subjects (Rossi M. et al., *Body segment
inertial parameters of elite swimmers using DXA and indirect methods*,
J. Sports Sci. Med. 12:761–775, 2013, abstract; 28 young men and the two
groups of swimmers).  The values taken here are of that size:

- segment mass: 10 % (the ">10 %" above);
- transverse radius-of-gyration ratio: 5 %; centre-of-mass ratio: 4 %
  (chosen: de Leva's ratios are fractions of the segment length, which is
  what varies least; half the mass's spread);
- segment length at a given stature: 3 % (chosen: the reference subjects'
  segment lengths scale with stature within a few percent);
- axial radius: 5 % (chosen; it enters only the axial moment, which the
  sagittal dynamics never see).

Together they give a transverse moment of inertia I = m ρ² L² a
coefficient of variation of about √(0.10² + (2·0.05)² + (2·0.03)²) = 15 %,
the size of the standard error of estimate of limb-segment moments of
inertia from a person's own anthropometry, 13 % with non-linear and 21 %
with linear regressions (Yeadon M.R., Morlock M., *The appropriate use of
regression equations for the estimation of segmental inertia
parameters*, J. Biomech. 22:683–689, 1989, on Chandler et al.'s 1975
cadavers); a table-based prediction such as de Leva's errs by more (up to
40 % on some segments, Durkin & Dowling 2003, as cited by the DXA study
PMC6905426).  None of the five is itself a table's standard deviation: a
search of the available corpora found no table of inter-subject standard
deviations about de Leva's means; replace the defaults with such a table
when at hand.  The spread is an argument.

**Bounds.**  Every factor is within ``1 ± z_max s_x`` and every ``s_x`` at
most :data:`MAX_CV` (0.2), so every factor is at least 0.5: masses and
lengths positive; the patient is then built as a
:class:`~exo_ctrl.model.BodyParams`, which checks the centre of mass inside
its link (0 < c < 1) and the principal moments' triangle inequality
(r < 2 ρ L), so every drawn inertia is positive definite (tests load each
drawn URDF through the project's checks, pseudo-inertia included).

**The benchmark's cohort** (:func:`benchmark_cohort`, issue 17, item 6):
stature uniform in [1.55, 1.95] m; body mass uniform in [50, 110] kg
intersected with a body-mass index of 18.5–35 kg/m² at that stature (the
WHO's normal-weight lower bound to obesity class I's upper: a 1.95 m, 50 kg
or 1.55 m, 110 kg patient is not a patient this device takes); sex male or
female with equal probability; the patient drawn around that nominal one by
:func:`draw_cohort`'s spread; and a knee misalignment of uniform magnitude
in [0, 3] cm in a uniform direction of the sagittal plane (Schiele & van der
Helm 2006: fitted knee exoskeletons are off by up to about 3 cm;
:mod:`exo_ctrl.plant.misalignment`).  The exoskeleton is adjusted to each
patient's leg lengths (:func:`fitted_exo`), as a clinic adjusts it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import _validate as v
from ..exceptions import InvalidParameter
from .anthropometry import SEXES, SHANK_CUFF_RATIO, THIGH_CUFF_RATIO, patient_from_anthropometry
from .body_params import BodyParams

__all__ = [
    "BENCHMARK_HEIGHT_RANGE_M",
    "BENCHMARK_KNEE_MISALIGNMENT_M",
    "BENCHMARK_MASS_RANGE_KG",
    "BMI_RANGE",
    "MAX_COHORT",
    "MAX_CV",
    "TRUNCATION_Z",
    "CohortPatient",
    "CohortSpread",
    "benchmark_cohort",
    "draw_cohort",
    "drawn_patient",
    "fitted_exo",
    "truncated_sd",
]

#: Draws of the standard normal beyond ±TRUNCATION_Z are drawn again.
TRUNCATION_Z = 2.5

#: The largest coefficient of variation accepted (every factor then ≥ 0.5).
MAX_CV = 0.2

#: The largest cohort drawn at once.
MAX_COHORT = 10_000

#: The benchmark's statures [m], body masses [kg] and body-mass indices [kg/m²].
BENCHMARK_HEIGHT_RANGE_M = (1.55, 1.95)
BENCHMARK_MASS_RANGE_KG = (50.0, 110.0)
BMI_RANGE = (18.5, 35.0)

#: The benchmark's largest knee misalignment [m] (Schiele & van der Helm 2006).
BENCHMARK_KNEE_MISALIGNMENT_M = 0.03

#: The drawn parameters, in the order of the draws (both segments).
_FIELDS = ("length", "mass", "com_ratio", "gyration_ratio", "radius")


def truncated_sd(z_max: float = TRUNCATION_Z) -> float:
    """Standard deviation of N(0, 1) truncated to [-z_max, z_max] (module docstring)."""
    phi = math.exp(-0.5 * z_max * z_max) / math.sqrt(2.0 * math.pi)
    mass = math.erf(z_max / math.sqrt(2.0))  # 2Φ(z_max) - 1
    return math.sqrt(1.0 - 2.0 * z_max * phi / mass)


@dataclass(frozen=True)
class CohortSpread:
    """Inter-subject coefficients of variation of the drawn parameters (module docstring).

    Attributes:
        length: segment length at a given stature [-].
        mass: segment mass [-].
        com_ratio: centre-of-mass position over the length [-].
        gyration_ratio: transverse radius of gyration over the length [-].
        radius: the axial moment's radius [-].

    Raises:
        InvalidParameter: a value not in [0, MAX_CV].

    """

    length: float = 0.03
    mass: float = 0.10
    com_ratio: float = 0.04
    gyration_ratio: float = 0.05
    radius: float = 0.05

    def __post_init__(self) -> None:
        for name in _FIELDS:
            value = v.finite(f"spread.{name}", getattr(self, name))
            if not 0.0 <= value <= MAX_CV:
                raise InvalidParameter(f"spread.{name}", value, f"in [0, {MAX_CV:g}]")
            object.__setattr__(self, name, value)


@dataclass(frozen=True)
class CohortPatient:
    """One patient of the benchmark's cohort.

    Attributes:
        index: the patient's place in the cohort (0-based).
        height_m: stature [m] (what the device knows).
        mass_kg: body mass [kg] (what the device knows).
        sex: ``"female"`` or ``"male"`` (which of de Leva's tables).
        params: the true patient's legs (drawn around the nominal).
        knee_misalignment_xz: the true knee axis from the exoskeleton's,
            (forward, up) with the legs straight [m].

    """

    index: int
    height_m: float
    mass_kg: float
    sex: str
    params: BodyParams
    knee_misalignment_xz: tuple[float, float]


def _count(name: str, value: object, low: int, high: int | None = None) -> int:
    """An integer (not a bool) in [low, high]."""
    allowed = f"an integer >= {low}" if high is None else f"an integer in [{low}, {high}]"
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InvalidParameter(name, value, allowed)
    if value < low or (high is not None and value > high):
        raise InvalidParameter(name, value, allowed)
    return int(value)


def _factors(rng: np.random.Generator, size: int) -> np.ndarray:
    """``size`` draws of N(0, 1) truncated to ±TRUNCATION_Z (rejection)."""
    z = rng.standard_normal(size)
    bad = np.abs(z) > TRUNCATION_Z
    while bad.any():
        z[bad] = rng.standard_normal(int(bad.sum()))
        bad = np.abs(z) > TRUNCATION_Z
    return z


def drawn_patient(nominal: BodyParams, z: np.ndarray, spread: CohortSpread) -> BodyParams:
    """The nominal patient with each parameter times ``1 + s z`` (module docstring).

    Args:
        nominal: the nominal patient (de Leva's for a stature, mass and sex).
        z: ten standard scores, thigh then shank, each in :data:`_FIELDS`' order.
        spread: the coefficients of variation.

    Raises:
        InvalidParameter: a drawn patient that is not physical (cannot happen
            within the module's bounds; :class:`BodyParams` checks it).

    """
    changes: dict[str, float] = {}
    for s, seg in enumerate(("thigh", "shank")):
        for k, name in enumerate(_FIELDS):
            field = f"{seg}_{name}"
            changes[field] = getattr(nominal, field) * (
                1.0 + getattr(spread, name) * z[len(_FIELDS) * s + k]
            )
    changes["thigh_cuff"] = THIGH_CUFF_RATIO * changes["thigh_length"]
    changes["shank_cuff"] = SHANK_CUFF_RATIO * changes["shank_length"]
    return nominal.replace(**changes)


def draw_cohort(
    n: int,
    seed: int,
    height_m: float,
    mass_kg: float,
    sex: str = "male",
    spread: CohortSpread | None = None,
) -> list[BodyParams]:
    """``n`` true patients around de Leva's patient of a stature, mass and sex.

    Deterministic for a seed (``numpy.random.default_rng(seed)``; patient i
    is the same whatever ``n`` > i).

    Args:
        n: number of patients, in [1, MAX_COHORT].
        seed: the seed, an integer >= 0.
        height_m: stature [m] (the range of de Leva's regressions).
        mass_kg: body mass [kg].
        sex: ``"female"`` or ``"male"``.
        spread: coefficients of variation (default :class:`CohortSpread`).

    Raises:
        InvalidParameter: a bad n, seed, stature, mass or sex.

    """
    n = _count("n", n, 1, MAX_COHORT)
    seed = _count("seed", seed, 0)
    spread = spread or CohortSpread()
    nominal = patient_from_anthropometry(height_m, mass_kg, sex)
    rng = np.random.default_rng(seed)
    return [drawn_patient(nominal, _factors(rng, 2 * len(_FIELDS)), spread) for _ in range(n)]


def benchmark_cohort(
    n: int = 20, seed: int = 0, spread: CohortSpread | None = None
) -> list[CohortPatient]:
    """The robustness benchmark's cohort (module docstring): statures, masses, sexes, knees.

    Deterministic for a seed; patient i is the same whatever ``n`` > i.

    Args:
        n: number of patients, in [1, MAX_COHORT].
        seed: the seed, an integer >= 0.
        spread: coefficients of variation of the segments (default :class:`CohortSpread`).

    Raises:
        InvalidParameter: a bad n or seed.

    """
    n = _count("n", n, 1, MAX_COHORT)
    seed = _count("seed", seed, 0)
    spread = spread or CohortSpread()
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        height = float(rng.uniform(*BENCHMARK_HEIGHT_RANGE_M))
        low = max(BENCHMARK_MASS_RANGE_KG[0], BMI_RANGE[0] * height**2)
        high = min(BENCHMARK_MASS_RANGE_KG[1], BMI_RANGE[1] * height**2)
        mass = float(rng.uniform(low, high))
        sex = SEXES[int(rng.integers(0, 2))]
        offset = float(rng.uniform(0.0, BENCHMARK_KNEE_MISALIGNMENT_M))
        angle = float(rng.uniform(0.0, 2.0 * math.pi))
        z = _factors(rng, 2 * len(_FIELDS))
        params = drawn_patient(patient_from_anthropometry(height, mass, sex), z, spread)
        knee = (offset * math.cos(angle), offset * math.sin(angle))
        out.append(CohortPatient(i, height, mass, sex, params, knee))
    return out


def fitted_exo(patient: BodyParams, exo: BodyParams | None = None) -> BodyParams:
    """The exoskeleton adjusted to a patient's leg lengths (cuffs at the patient's).

    Masses, radii and joint limits are ``exo``'s (default: paper Table I's,
    :meth:`BodyParams.exo_default`); the link lengths and the cuff places
    along them are the patient's, so that the joints are coaxial before any
    misalignment.
    """
    base = exo or BodyParams.exo_default()
    return base.replace(
        thigh_length=patient.thigh_length,
        shank_length=patient.shank_length,
        thigh_cuff=patient.thigh_cuff,
        shank_cuff=patient.shank_cuff,
    )
