"""Compiled kernels for the control tick: one numba decorator, used everywhere.

A control tick does a few hundred arithmetic operations on 4- and 8-element
vectors around the Pinocchio calls.  As numpy calls each costs about 1 µs of
dispatch on these machines, so the tick would be dominated by Python
overhead; fused into one compiled kernel per stage, the same arithmetic costs
well under a microsecond plus one dispatch.

:func:`kernel` is ``numba.njit`` with the project's settings:

- ``cache=True``: compiled once per machine into ``__pycache__`` (the first
  run after an install compiles for a few seconds; later processes load);
- no ``fastmath``: results are IEEE, run-to-run bit-identical, and equal to
  the numpy formulation up to rounding;
- ``error_model="numpy"``: a division by zero gives inf/NaN as numpy does,
  for the divergence checks to report, instead of raising inside the kernel;
- no reference counting (numba's ``_nrt`` target option off): kernels take
  and fill preallocated arrays and never allocate, so they need no runtime
  memory management, and without it a call neither boxes a reference per
  array argument (48 bytes each) nor pays for it (about 40 % of the
  dispatch).  A kernel that tried to allocate would fail to compile.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

import numba

__all__ = ["kernel"]

F = TypeVar("F", bound=Callable[..., Any])


def kernel(func: F) -> F:
    """Compile ``func`` as a cached, IEEE-exact, non-allocating tick kernel."""
    return numba.njit(cache=True, fastmath=False, error_model="numpy", nogil=True, _nrt=False)(func)
