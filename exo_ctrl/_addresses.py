"""TEMPORARY: the old address tables, until the QP takes typed state (issue 14)."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, TypeVar

import numba
import numpy as np
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.arrayobj import populate_array

__all__ = [
    "address_table",
    "array_at",
    "kernel",
    "matrix_at",
    "preload",
    "tensor_at",
    "vector_at",
]

F = TypeVar("F", bound=Callable[..., Any])


def kernel(func: F) -> F:
    """Compile ``func`` as a cached, IEEE-exact, non-allocating tick kernel."""
    return numba.njit(cache=True, fastmath=False, error_model="numpy", nogil=True, _nrt=False)(func)


def preload(func: Any, *args: Any) -> None:
    """Load (or compile) kernel ``func`` for the types of ``args`` without running it.

    For a kernel first called inside a timed loop: loading it from the cache
    takes milliseconds.
    """
    func.compile(tuple(numba.typeof(a) for a in args))


def address_table(arrays: Sequence[np.ndarray]) -> np.ndarray:
    """Rows (address, n₀, n₁, n₂) of float64 C-contiguous arrays of 1-3 dimensions.

    Missing dimensions are 1.  The caller keeps the arrays alive.

    Raises:
        TypeError: an array of another kind (a programming error).

    """
    table = np.ones((len(arrays), 4), dtype=np.int64)
    for i, a in enumerate(arrays):
        if a.dtype != np.float64 or not a.flags.c_contiguous or a.ndim not in (1, 2, 3):
            raise TypeError(f"address_table: array {i} is {a.dtype}, {a.shape}, not C-ordered")
        table[i, 0] = a.ctypes.data
        table[i, 1 : 1 + a.ndim] = a.shape
    return table


@intrinsic
def array_at(typingctx, address, shape):
    """In a kernel: the float64 C-order array of ``shape`` (a tuple) at ``address``.

    The view does not own its memory (no reference counting, see the module
    docstring); ``address`` comes from :func:`address_table`.
    """
    if not isinstance(address, types.Integer) or not isinstance(shape, types.UniTuple):
        return None
    ndim = shape.count
    array_type = types.Array(types.float64, ndim, "C")

    def codegen(context, builder, signature, args):
        address, dims = args
        array = context.make_array(array_type)(context, builder)
        dims = cgutils.unpack_tuple(builder, dims, count=ndim)
        itemsize = context.get_constant(types.intp, 8)
        strides = []
        step = itemsize
        for dim in reversed(dims):
            strides.insert(0, step)
            step = builder.mul(step, dim)
        populate_array(
            array,
            data=builder.inttoptr(address, array.data.type),
            shape=dims,
            strides=strides,
            itemsize=itemsize,
            meminfo=None,
        )
        return array._getvalue()

    return array_type(address, shape), codegen


@numba.njit(inline="always", _nrt=False)
def vector_at(table: np.ndarray, i: int) -> np.ndarray:
    """In a kernel: row i of an :func:`address_table` as its 1-D array."""
    return array_at(table[i, 0], (table[i, 1],))


@numba.njit(inline="always", _nrt=False)
def matrix_at(table: np.ndarray, i: int) -> np.ndarray:
    """In a kernel: row i of an :func:`address_table` as its 2-D array."""
    return array_at(table[i, 0], (table[i, 1], table[i, 2]))


@numba.njit(inline="always", _nrt=False)
def tensor_at(table: np.ndarray, i: int) -> np.ndarray:
    """In a kernel: row i of an :func:`address_table` as its 3-D array."""
    return array_at(table[i, 0], (table[i, 1], table[i, 2], table[i, 3]))
