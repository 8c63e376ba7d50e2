"""Small checks shared by the parameter classes.

Each raises :class:`~exo_ctrl.exceptions.InvalidParameter` naming the
parameter, its value and what is allowed.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from .exceptions import InvalidParameter


def finite(name: str, value: float, unit: str = "") -> float:
    """Return ``value`` as float if it is a finite real number."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InvalidParameter(name, value, f"a finite number{_in(unit)}") from None
    if not math.isfinite(x):
        raise InvalidParameter(name, value, f"a finite number{_in(unit)}")
    return x


_FLOAT64 = np.dtype(np.float64)  # the canonical instance: an identity test suffices


def array(name: str, value: object, shape: tuple[int, ...]) -> np.ndarray:
    """Return ``value`` as a float64 array of ``shape`` for a compiled kernel.

    A float64 array of that shape is returned as it is (the per-tick case,
    no copy); anything else that broadcasts to the shape (a scalar, a list)
    is broadcast; what does not raises, as a kernel would otherwise read
    past the end of a short array.
    """
    if type(value) is np.ndarray and value.dtype is _FLOAT64 and value.shape == shape:
        return value
    try:
        return np.broadcast_to(np.asarray(value, dtype=float), shape)
    except (TypeError, ValueError):
        raise InvalidParameter(name, value, f"numbers broadcastable to shape {shape}") from None


def arrays(shape: tuple[int, ...], **values: object) -> tuple[np.ndarray, ...]:
    """:func:`array` for each ``name=value``, in order (for non-array inputs)."""
    return tuple(array(name, value, shape) for name, value in values.items())


def refuse_shapes(shape: tuple[int, ...], **values: object) -> None:
    """Raise for the first ``name=value`` whose shape is not ``shape``.

    For a compiled kernel that found an input of the wrong shape (it checks
    before it writes anything, so the call had no effect).
    """
    for name, value in values.items():
        if np.shape(value) != shape:
            raise InvalidParameter(name, value, f"an array of shape {shape}")


def positive(name: str, value: float, unit: str = "") -> float:
    """Return ``value`` if it is finite and > 0."""
    x = finite(name, value, unit)
    if x <= 0.0:
        raise InvalidParameter(name, value, f"> 0{_u(unit)}")
    return x


def non_negative(name: str, value: float, unit: str = "") -> float:
    """Return ``value`` if it is finite and >= 0."""
    x = finite(name, value, unit)
    if x < 0.0:
        raise InvalidParameter(name, value, f">= 0{_u(unit)}")
    return x


def in_open_interval(name: str, value: float, lo: float, hi: float, unit: str = "") -> float:
    """Return ``value`` if it is finite and lo < value < hi."""
    x = finite(name, value, unit)
    if not lo < x < hi:
        raise InvalidParameter(name, value, f"in ({lo:g}, {hi:g}){_u(unit)}")
    return x


def _u(unit: str) -> str:
    return f" {unit}" if unit else ""


def _in(unit: str) -> str:
    return f" [{unit}]" if unit else ""


def per_item(
    name: str,
    value: object,
    unit: str,
    labels: Sequence[str],
    what: str = "joint",
    check: Callable[[str, float, str], float] = finite,
) -> tuple[float, ...]:
    """One number for every item, or one each: return a float per label.

    Each item is checked with ``check`` under the name ``name[label]``.

    Raises:
        InvalidParameter: neither a number nor ``len(labels)`` numbers, or an
            item that ``check`` refuses.

    """
    n = len(labels)
    arr = np.asarray(value, dtype=object)
    if arr.ndim == 0:
        items = [value] * n
    elif arr.shape == (n,):
        items = list(arr)
    else:
        raise InvalidParameter(
            name, value, f"a number or {n} numbers (one per {what}: {', '.join(labels)})"
        )
    return tuple(
        check(f"{name}[{label}]", item, unit) for label, item in zip(labels, items, strict=True)
    )
