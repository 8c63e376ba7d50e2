"""The QP's cuff-force bound per cuff: one for every cuff, or one per body region.

ISO/TS 15066 (Annex A, Table A.2) gives each body region its own
quasi-static limit: 220 N on the thigh, 130 N on the lower leg, and the
safety supervisor holds each cuff to its region's (:mod:`exo_ctrl.safety`).
The QP's bound F_max may follow it: ``cuff_force_limit_N`` is one number
[N] for all four cuffs, or two, (thigh, shank), each for both legs' cuffs
of that region.  With the pelvis supported the thigh cuffs carry the
patient's weight along the plan (122 N on the ``clinic-bws`` preset's gait,
the shanks 42 N: the margin's ``load_N``, tests/control/qp/test_bounds.py):
one bound for all four is set by the thighs' load, while the shanks' ISO
limit is the lower.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ... import _validate as v
from ...exceptions import InvalidParameter
from ...model import CUFF_NAMES

__all__ = ["bound_words", "cuff_limits"]

#: The body region of each cuff, in CUFF_NAMES order: 0 thigh, 1 shank.
_REGION = tuple(0 if name.endswith("_thigh") else 1 for name in CUFF_NAMES)


def cuff_limits(given: float | Sequence[float]) -> np.ndarray:
    """F_max per cuff [N], (4,) in CUFF_NAMES order, from one bound or (thigh, shank).

    Raises:
        InvalidParameter: not one number or two, or a bound not a finite number > 0.

    """
    if isinstance(given, (str, bytes)) or not isinstance(given, Sequence):
        return np.full(4, v.positive("cuff_force_limit", given, "N"))
    if len(given) != 2:
        raise InvalidParameter(
            "cuff_force_limit", given, "one bound > 0 [N], or two: (thigh, shank)"
        )
    pair = [
        v.positive(f"cuff_force_limit {r}", x, "N")
        for r, x in zip(("thigh", "shank"), given, strict=True)
    ]
    return np.array([pair[r] for r in _REGION])


def bound_words(given: float | Sequence[float]) -> str:
    """The bound in words: ``120 N``, or ``200 N on the thighs, 120 N on the shanks``."""
    limits = cuff_limits(given)
    thigh, shank = limits[_REGION.index(0)], limits[_REGION.index(1)]
    if thigh == shank:
        return f"{thigh:g} N"
    return f"{thigh:g} N on the thighs, {shank:g} N on the shanks"
