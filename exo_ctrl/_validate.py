"""Small checks shared by the parameter classes.

Each raises :class:`~exo_ctrl.exceptions.InvalidParameter` naming the
parameter, its value and what is allowed.

Memory cap: no command allocates arrays whose size a user's number sets
beyond :data:`MAX_ALLOCATION_BYTES` (1 GiB) for one purpose (a plan, a log
chunk, a run's history).  Each such allocation is checked up front by
:func:`allocation`, given the element count and the bytes per element, so a
bad number is refused with the size it would need instead of ending in a
``MemoryError``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence

import numpy as np

from .exceptions import InvalidParameter


def finite(name: str, value: float, unit: str = "") -> float:
    """Return ``value`` as float if it is a finite real number (not a string or a bool)."""
    if isinstance(value, (str, bytes, bool, np.bool_)):
        raise InvalidParameter(name, value, f"a finite number{_in(unit)}")
    try:
        x = float(value)
    except (TypeError, ValueError, OverflowError):  # OverflowError: an int beyond float's range
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


def held_arrays(shape: tuple[int, ...], **values: object) -> None:
    """Refuse the first ``name=value`` that is not a float64 ndarray of ``shape``.

    For arrays a component holds and reads at each later call (checked once,
    when it takes them).
    """
    for name, value in values.items():
        if not (type(value) is np.ndarray and value.dtype == np.float64 and value.shape == shape):
            raise InvalidParameter(name, value, f"a float64 array of shape {shape}")


#: The largest allocation [bytes] a user's number may set: 1 GiB (:func:`allocation`).
MAX_ALLOCATION_BYTES = 1 << 30


def format_bytes(n: float) -> str:
    """A size [bytes] in binary units: ``480 B``, ``1 GiB``, ``44.7 GiB``."""
    for unit in ("B", "KiB", "MiB", "GiB"):
        if abs(n) < 1024.0:
            return f"{n:.4g} {unit}" if unit != "B" else f"{n:.0f} B"
        n /= 1024.0
    return f"{n:.4g} TiB"


def max_items(item_bytes: int) -> int:
    """How many elements of ``item_bytes`` bytes fit in :data:`MAX_ALLOCATION_BYTES`."""
    return MAX_ALLOCATION_BYTES // max(int(item_bytes), 1)


def allocation(
    name: str,
    value: object,
    count: int,
    item_bytes: int,
    *,
    what: str = "samples",
    limit: str = "",
    note: str = "",
) -> int:
    """Return ``count`` if ``count`` elements of ``item_bytes`` bytes fit in the memory cap.

    Args:
        name: the parameter that sets the count (as the user spells it).
        value: its value.
        count: the number of elements the caller is about to allocate.
        item_bytes: bytes per element, every array that grows with the count
            included [bytes].
        what: what the elements are, plural ("samples", "plan rows").
        limit: the largest allowed ``value`` in words ("at most 1.2e+04 s"),
            worked out by the caller from :func:`max_items`; "" for "smaller".
        note: added to the size in the message (why the count is what it is).

    Raises:
        InvalidParameter: ``count × item_bytes`` > :data:`MAX_ALLOCATION_BYTES`,
            naming the parameter, the size it would need and the limit.

    """
    need = int(count) * int(item_bytes)
    if need <= MAX_ALLOCATION_BYTES:
        return int(count)
    cap = format_bytes(MAX_ALLOCATION_BYTES)
    size = format_bytes(need)
    if size == cap:  # just over: rounding would hide it
        size = f"{need:,} B"
    shown = f"{int(count):,}" if count < 1e15 else f"{float(count):.4g}"  # not 300 digits
    detail = f"{shown} {what} would need {size}"
    raise InvalidParameter(
        name,
        value,
        f"{limit or 'smaller'} so that the {what} fit in the {cap} memory cap "
        f"(at most {max_items(item_bytes):,} of {int(item_bytes)} B each)",
        f"{detail}{'; ' + note if note else ''}",
    )


def one_of(name: str, value: object, choices: Sequence[object]) -> object:
    """Return ``value`` if it is one of ``choices`` (an array or unhashable value is none)."""
    try:
        ok = not isinstance(value, np.ndarray) and value in choices
    except TypeError:
        ok = False
    if not ok:
        raise InvalidParameter(name, value, f"one of {', '.join(str(c) for c in choices)}")
    return value


def flag(name: str, value: object) -> bool:
    """Return ``value`` as a bool if it is True or False (numpy's included)."""
    if not isinstance(value, (bool, np.bool_)):
        raise InvalidParameter(name, value, "True or False")
    return bool(value)


def within(name: str, value: float, lo: float, hi: float, unit: str = "", why: str = "") -> float:
    """Return ``value`` if it is finite and in [lo, hi] (a sanity range, ``why`` said)."""
    x = finite(name, value, unit)
    if not lo <= x <= hi:
        raise InvalidParameter(name, value, f"in [{lo:g}, {hi:g}]{_u(unit)}", why)
    return x


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


def seed(name: str, value: object) -> int:
    """Return ``value`` as an int if it is an integer >= 0 (a bool is not): a generator's seed."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise InvalidParameter(name, value, "an integer >= 0")
    return int(value)


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


#: The deepest nesting of JSON arrays and objects read from a user's file
#: (a session, a recording's metadata need 4; Python's parser recurses per level).
MAX_JSON_DEPTH = 64

_JSON_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')
_JSON_BRACKET = re.compile(r"[\[\]{}]")


def json_depth(text: str) -> int:
    """The deepest nesting of ``[`` and ``{`` in a JSON text (strings skipped; linear time)."""
    depth = deepest = 0
    for match in _JSON_BRACKET.finditer(_JSON_STRING.sub("", text)):
        if match.group() in "[{":
            depth += 1
            deepest = max(deepest, depth)
        else:
            depth -= 1
    return deepest


def json_depth_problem(text: str) -> str:
    """Why a JSON text is too deeply nested to parse ("" if it is not)."""
    depth = json_depth(text)
    if depth <= MAX_JSON_DEPTH:
        return ""
    return f"nested {depth} levels deep; at most {MAX_JSON_DEPTH} are read"


#: What a TOML text holds that is not nesting: strings of each kind and comments.
_TOML_SKIP = re.compile(
    r'"""(?:[^\\]|\\.)*?"""|\'\'\'.*?\'\'\'|"(?:[^"\\\n]|\\.)*"|\'[^\'\n]*\'|#[^\n]*',
    re.S,
)


def toml_depth(text: str) -> int:
    """The deepest nesting of arrays and inline tables in a TOML text.

    Strings and comments are skipped; a table header (``[gait]``) counts as
    one level while it is open.  Python's TOML parser recurses per level.
    """
    return json_depth(_TOML_SKIP.sub("", text).replace('"', ""))


def toml_depth_problem(text: str) -> str:
    """Why a TOML text is too deeply nested to parse ("" if it is not)."""
    depth = toml_depth(text)
    if depth <= MAX_JSON_DEPTH:
        return ""
    return f"nested {depth} levels deep; at most {MAX_JSON_DEPTH} are read"
