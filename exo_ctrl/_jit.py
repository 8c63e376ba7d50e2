"""Compiled kernels for the control tick: one numba decorator, one status enum.

A control tick does a few hundred arithmetic operations on 4- and 8-element
vectors around the Pinocchio calls.  As numpy calls each costs about 1 µs of
dispatch on these machines, so the tick would be dominated by Python
overhead; fused into one compiled kernel per stage, the same arithmetic costs
well under a microsecond plus one dispatch.

:func:`kernel` is ``numba.njit`` with the project's settings, all of them
public numba options:

- ``cache=True``: compiled once per machine into ``__pycache__`` (the first
  run after an install compiles; later processes load; a cache made from
  other sources than the package's present ones is deleted at import,
  :mod:`exo_ctrl._jit_cache`, because numba checks a kernel's own file only);
- no ``fastmath``: results are IEEE, run-to-run bit-identical, and equal to
  the numpy formulation up to rounding;
- ``error_model="numpy"``: a division by zero gives inf/NaN as numpy does,
  for the divergence checks to report, instead of raising inside the kernel.

A component keeps its state in a numpy structured array of one element
(:func:`record`): the kernel takes that array and reads and writes its
fields by name, so a layout is declared once, as a dtype, and numba checks
every field's type and shape.  A call costs about 0.2 µs for one record
against 0.12 µs per plain array argument.

**Switches.**  A feature a run may leave off (the belt contact, the pelvis
guide, compliant drives, split cuffs) is a branch of the kernel that calls
it.  numba compiles every branch, callees included, unless the branch is
pruned before typing, which it does for a test ``if arg is not None:`` on
an argument that is None.  Such a kernel takes the feature's compile-time
switch, :func:`switch` (``True`` or ``None``), as an argument and tests
``if feature is not None and <the runtime flag>:``; a run that leaves the
feature off passes None and compiles nothing of it.  Each pattern of
switches is a signature of its own (compiled once per machine, as any).

**One signature per kernel and run.**  Two processes that compile one run
at once (:mod:`exo_ctrl.sim.warmup`) must never save two signatures of one
kernel at the same moment: numba's cache index could cross them.  So within
a run every kernel is called with one set of argument types: a callee shared
by kernels of different records takes plain arrays, and a small callee that
takes records of several types, or literal integers, is a :func:`leaf`:
inlined into each caller's code before typing, it has no compiled
signatures of its own (unless Python calls it).

**Status.**  A kernel that can refuse its input returns a :class:`Status`
as its integer value (``return Status.OK.value``: returning the enum member
itself boxes an ``IntEnum`` on every call, about 0.5 µs); :func:`check`
turns a status into the matching exception, in this one place.
"""

from __future__ import annotations

import enum
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numba
import numpy as np

from . import _jit_cache
from ._validate import refuse_shapes
from .exceptions import InvalidParameter, KernelStatusError, SimulationDiverged

# The package's folder as imported (numba names its cache folders by that path).
_jit_cache.refresh(Path(os.path.abspath(os.path.dirname(__file__))), numba.config.CACHE_DIR)

__all__ = ["Status", "check", "kernel", "leaf", "preload", "record", "shared_dtype", "switch"]

F = TypeVar("F", bound=Callable[..., Any])


def kernel(func: F) -> F:
    """Compile ``func`` as a cached, IEEE-exact tick kernel."""
    return numba.njit(cache=True, fastmath=False, error_model="numpy", nogil=True)(func)


def leaf(func: F) -> F:
    """A :func:`kernel` inlined into its callers (``inline="always"``; module docstring)."""
    return numba.njit(cache=True, fastmath=False, error_model="numpy", nogil=True, inline="always")(
        func
    )


def preload(func: Any, *args: Any) -> None:
    """Load (or compile) kernel ``func`` for the types of ``args`` without running it.

    For a kernel first called inside a timed loop: loading it from the cache
    takes milliseconds.
    """
    func.compile(tuple(numba.typeof(a) for a in args))


def switch(on: bool) -> bool | None:
    """The compile-time switch of a feature (module docstring): True when ``on``, else None.

    Derive it from the same flag the kernel tests at run time: a None switch
    with the flag set would skip the feature's code.
    """
    return True if on else None


def record(fields: list[tuple[Any, ...]]) -> np.ndarray:
    """A zeroed structured array of one element with ``fields`` (numpy dtype syntax).

    Kernels take the array and use ``state[0]`` as a record whose fields
    they read and write in place.  Equal field lists share one dtype object
    (:func:`shared_dtype`).
    """
    return np.zeros(1, dtype=shared_dtype(fields, align=True))


_DTYPES: dict[tuple[Any, ...], np.dtype] = {}


def shared_dtype(fields: list[tuple[Any, ...]], align: bool = False) -> np.dtype:
    """The one dtype object of a field list (numpy dtype syntax).

    numba looks a record argument's type up by the identity of its dtype:
    a second, equal dtype object is typed anew on every call (measured: a
    41-field record's call went from 0.23 to 2.3 µs).  So every record of
    the same layout, in every run of a process, uses this one object.
    """
    key = (tuple(tuple(f) for f in fields), align)
    dtype = _DTYPES.get(key)
    if dtype is None:
        dtype = _DTYPES[key] = np.dtype(fields, align=align)
    return dtype


class Status(enum.IntEnum):
    """What a kernel reports (usable inside kernels: ``Status.OK``)."""

    #: Done.
    OK = 0
    #: An input array of the wrong length; nothing was written.
    WRONG_LENGTH = 1
    #: An input that is not finite (NaN or inf); nothing was written.
    NOT_FINITE = 2
    #: The state left its physical bounds (a joint speed above the limit).
    DIVERGED = 3


def check(
    status: int,
    where: str,
    t: float = float("nan"),
    shapes: dict[str, tuple[int, ...]] | None = None,
    **inputs: object,
) -> None:
    """Raise the exception that matches kernel ``status`` (nothing for ``Status.OK``).

    Args:
        status: what the kernel returned.
        where: the component and call, for the message.
        t: simulated time [s], for a divergence.
        shapes: the shape each input must have, by name (default (4,)).
        inputs: the call's inputs by name: for WRONG_LENGTH and NOT_FINITE
            the first one that is wrong is named; for DIVERGED, the
            ``quantity``, ``value`` and ``limit``.

    Raises:
        InvalidParameter: WRONG_LENGTH or NOT_FINITE, naming the input.
        SimulationDiverged: DIVERGED.
        KernelStatusError: a status that is not a :class:`Status`.

    """
    if status == Status.OK:
        return
    if status == Status.WRONG_LENGTH:
        shapes = shapes or {}
        for name, value in inputs.items():
            refuse_shapes(shapes.get(name, (4,)), **{name: value})
        raise InvalidParameter(where, tuple(inputs), "arrays of the shapes it needs")
    if status == Status.NOT_FINITE:
        for name, value in inputs.items():
            if not np.all(np.isfinite(np.asarray(value, dtype=float))):
                raise InvalidParameter(name, value, "finite numbers")
        raise InvalidParameter(where, tuple(inputs), "finite numbers")
    if status == Status.DIVERGED:
        raise SimulationDiverged(
            t,
            str(inputs.get("quantity", where)),
            float(inputs.get("value", float("nan"))),  # type: ignore[arg-type]
            float(inputs.get("limit", float("nan"))),  # type: ignore[arg-type]
        )
    raise KernelStatusError(f"{where}: kernel returned {status!r}, not a Status")
