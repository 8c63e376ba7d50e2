r"""The true cuffs of one patient: the published cuffs scattered by the patient's soft tissue.

A manufacturer builds its device's cuff model from the published interface
stiffness (:class:`~exo_ctrl.plant.cuffs.CuffParams`' defaults, cited there);
the soft tissue under the cuffs of a given patient is stiffer or softer.
:class:`CuffScatter` draws that patient's true cuffs around the published
ones, seeded, so that a run is reproducible and the device's belief (the
published values) is honest rather than exact:

    k_n = f_n k̄_n,   k_u = f_u k̄_u,   C_n = √f_n C̄_n,   C_u = √f_u C̄_u,
    f = 1 + s z,   z ~ N(0, 1) truncated to |z| ≤ 2 (drawn again beyond),

with k̄, C̄ the published (given) cuffs, s the spread (a coefficient of
variation), f_n and f_u independent (compression across the limb and shear
along it load different tissue), the damping scaled by √f so that each
direction keeps its damping ratio, the preload unchanged.  One pair of
factors per patient, the same for its four cuffs (a per-cuff scatter,
thigh apart from shank, is not modelled).  z_n and z_u are the first two
accepted draws of ``numpy.random.default_rng(seed)``.

**The spread** (default s = 0.20, factors within [0.6, 1.4]).  The
inter-subject coefficient of variation of limb soft-tissue stiffness is
about 20 %: Isogai et al. 2022 (J Phys Ther Sci 34(12):777–783, "Young's
moduli of subcutaneous tissues and muscles under different loads at the
gluteal region calculated using ultrasonography"), 21 men, muscle under a
30 N load 440.4 ± 80.0 kPa (18 %); Le Sant et al. 2017 (J Anat
230(5):639–650, "Stiffness mapping of lower leg muscles during passive
dorsiflexion"), 22 subjects, gastrocnemius medialis 128.5 ± 27.3 kPa
(21 %).  (Subcutaneous tissue scatters more, 62 % in Isogai et al.; a cuff
presses through it onto muscle, and its strap is tightened to the limb.)
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .. import _validate as v
from ..exceptions import InvalidParameter
from .cuffs import CuffParams

__all__ = [
    "DEFAULT_SPREAD",
    "MAX_SPREAD",
    "TRUNCATE_SD",
    "CuffScatter",
    "checked_spread",
    "scaled_cuffs",
]

#: The default spread s, the inter-subject coefficient of variation of limb
#: soft-tissue stiffness (module docstring: Isogai et al. 2022, 18 %; Le Sant
#: et al. 2017, 21 %) [-].
DEFAULT_SPREAD = 0.20

#: The draws z are truncated to |z| ≤ TRUNCATE_SD standard deviations [-].
TRUNCATE_SD = 2.0

#: Largest spread: with |z| ≤ 2 every factor stays ≥ 1 - 2 s > 0 [-].
MAX_SPREAD = 0.45


@dataclass(frozen=True)
class CuffScatter:
    """How far the true cuffs of the run's patient are from the published ones (module docstring).

    Attributes:
        spread_rel: s, the coefficient of variation of each stiffness factor
            [-], in [0, :data:`MAX_SPREAD`]; default :data:`DEFAULT_SPREAD`
            (cited in the module docstring); 0: the true cuffs are exactly the
            given ones (``SimConfig.cuffs``: by default the published cuffs).
        seed: the patient: the seed of the draw (an integer ≥ 0; default 0).

    Raises:
        InvalidParameter: a spread outside [0, MAX_SPREAD] or not a number; a
            seed that is not an integer ≥ 0.

    """

    spread_rel: float = DEFAULT_SPREAD
    seed: int = 0

    def __post_init__(self) -> None:
        spread = checked_spread("cuff_scatter spread_rel", self.spread_rel)
        seed = v.seed("cuff_scatter seed", self.seed)
        object.__setattr__(self, "spread_rel", spread)
        object.__setattr__(self, "seed", seed)

    @classmethod
    def exact(cls) -> CuffScatter:
        """No scatter: the true cuffs are the given (published) ones exactly."""
        return cls(spread_rel=0.0)

    def factors(self) -> tuple[float, float]:
        """(f_n, f_u), the patient's normal and shear stiffness factors [-] (module docstring)."""
        if self.spread_rel == 0.0:
            return 1.0, 1.0
        rng = np.random.default_rng(self.seed)
        z: list[float] = []
        while len(z) < 2:
            x = float(rng.standard_normal())
            if abs(x) <= TRUNCATE_SD:
                z.append(x)
        return 1.0 + self.spread_rel * z[0], 1.0 + self.spread_rel * z[1]

    def apply(self, published: CuffParams) -> CuffParams:
        """The patient's true cuffs: ``published`` with its stiffness and damping scattered.

        k_n, k_u times f_n, f_u; C_n, C_u times √f_n, √f_u; the preload kept.
        The published cuffs themselves when the spread is 0.
        """
        if self.spread_rel == 0.0:
            return published
        return scaled_cuffs(published, *self.factors())

    def extremes(self, published: CuffParams) -> tuple[CuffParams, CuffParams]:
        """The two most unequal true cuffs the spread allows, around ``published``.

        (f_n, f_u) = (1 + 2s, 1 − 2s) and (1 − 2s, 1 + 2s), z at its
        truncation: the largest and the smallest ratio k_n/k_u.  How a cuff
        pair shares a load depends on that ratio only (a common factor scales
        both cuffs alike), so these two bound every draw's share.
        """
        high = 1.0 + TRUNCATE_SD * self.spread_rel
        low = 1.0 - TRUNCATE_SD * self.spread_rel
        return scaled_cuffs(published, high, low), scaled_cuffs(published, low, high)


def scaled_cuffs(published: CuffParams, f_n: float, f_u: float) -> CuffParams:
    """``published`` with k_n, k_u times f_n, f_u and C_n, C_u times √f_n, √f_u [-].

    The preload kept (module docstring).
    """
    k_u = published.shear_stiffness_N_per_m
    c_u = published.shear_damping_N_s_per_m
    return dataclasses.replace(
        published,
        stiffness_N_per_m=f_n * published.stiffness_N_per_m,
        damping_N_s_per_m=math.sqrt(f_n) * published.damping_N_s_per_m,
        shear_stiffness_N_per_m=f_u * float(k_u),  # type: ignore[arg-type]
        shear_damping_N_s_per_m=math.sqrt(f_u) * float(c_u),  # type: ignore[arg-type]
    )


def checked_spread(name: str, value: object) -> float:
    """``value`` as a spread s [-], a number in [0, :data:`MAX_SPREAD`].

    Raises:
        InvalidParameter: naming ``name``, for anything else.

    """
    spread = v.finite(name, value)
    if not 0.0 <= spread <= MAX_SPREAD:
        raise InvalidParameter(name, value, f"in [0, {MAX_SPREAD:g}]")
    return spread
