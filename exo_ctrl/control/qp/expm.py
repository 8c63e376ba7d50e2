r"""The matrix exponential of the cuff prediction's block matrices, in compiled kernels.

The horizon model's state z = (δ, u_e, u_p, τ, 1) of one leg has :data:`NZ`
= 9 entries of which the first :data:`NM` = 6 move (τ and 1 are held), so
its matrix F has zero rows 6–8 and

.. math::

    e^{F t} = \begin{bmatrix} E_{11} & E_{12} \\ 0 & I \end{bmatrix},

as is every product of such matrices.  The kernels here store and compute
only rows 0–5 of every 9×9 matrix: :func:`mul_top` multiplies two of them,
:func:`expm_top` forms e^F by scaling and squaring a degree-10 Taylor
polynomial, evaluated Paterson–Stockmeyer in blocks of :data:`PS_BLOCK` = 3
terms (X, X², X³ formed, then Horner in X³: 5 products for degree 10,
against 9 for Horner in X).  Against scipy's ``expm`` of the full matrix the
result agrees to ≤ 2e-14 (relative) up to ‖F‖ ≈ 5, growing with the
squarings beyond (tests/control/qp/test_prediction.py).
"""

from __future__ import annotations

import numpy as np

from ..._jit import kernel

__all__ = ["NM", "NZ", "PS_BLOCK", "TAYLOR_ORDER", "copy_top", "expm_top", "mul_top", "power_rows"]

#: Entries of a leg's state z = (δ, u_e, u_p, τ, 1).
NZ = 9
#: Its entries that move (rows of F that are not zero).
NM = 6
#: Degree of the Taylor polynomial.
TAYLOR_ORDER = 10
#: Terms per Paterson–Stockmeyer block: X, …, X^PS_BLOCK are formed.
PS_BLOCK = 3


@kernel
def mul_top(
    a: np.ndarray, b: np.ndarray, beta: float, out: np.ndarray
) -> None:  # pragma: no cover - compiled
    """Write the first rows of a b to ``out`` (as many as it has); b's rows 6–8 are β [0 | I].

    a: rows of 9 columns (rows 0–5 of a 9×9 matrix of the block form, or
    combinations of them); b: rows 0–5 of a 9×9 matrix; out must overlap
    neither.  out = a[:, :6] b[:6] + β a[:, 6:] (added to columns 6–8), each
    entry summed over k in order; the six a[i, k] are held in registers and
    the loop over j is independent (it vectorises).
    """
    for i in range(out.shape[0]):
        a0, a1, a2, a3, a4, a5 = a[i, 0], a[i, 1], a[i, 2], a[i, 3], a[i, 4], a[i, 5]
        for j in range(NM):
            out[i, j] = (
                a0 * b[0, j] + a1 * b[1, j] + a2 * b[2, j] + a3 * b[3, j] + a4 * b[4, j]
            ) + a5 * b[5, j]
        for j in range(NM, NZ):
            out[i, j] = (
                (a0 * b[0, j] + a1 * b[1, j] + a2 * b[2, j] + a3 * b[3, j] + a4 * b[4, j])
                + a5 * b[5, j]
            ) + beta * a[i, j]


@kernel
def copy_top(src: np.ndarray, dst: np.ndarray) -> None:  # pragma: no cover - compiled
    """dst[:] = src for 2-D arrays of one shape."""
    for i in range(src.shape[0]):
        for j in range(src.shape[1]):
            dst[i, j] = src[i, j]


@kernel
def expm_top(
    f: np.ndarray, out: np.ndarray, powers: np.ndarray, tmp: np.ndarray
) -> None:  # pragma: no cover - compiled
    """Rows 0–5 of exp(F), by scaling and squaring a degree-10 Taylor polynomial.

    F is 9×9 with rows 6–8 zero: ``f`` holds its rows 0–5, (6, 9), and
    ``out`` gets those of exp(F), whose rows 6–8 are [0 | I].  With
    X = F/2^s, ‖X‖∞ ≤ 1/4, T(X) = Σ_{k≤10} X^k/k! = B_0 + X³ (B_1 + X³ (B_2 +
    X³ B_3)), B_j = Σ_{i<3} X^i/(3j+i)!; then squared s times.

    Args:
        f: rows 0–5 of F, (6, 9).
        out: rows 0–5 of exp(F), (6, 9), written.
        powers: scratch, (PS_BLOCK, 6, 9): X, X², X³.
        tmp: scratch, (6, 9).

    """
    norm = 0.0
    for i in range(NM):
        row = 0.0
        for j in range(NZ):
            row += abs(f[i, j])
        norm = max(norm, row)
    s = 0
    while norm > 0.25 and s < 40:
        norm *= 0.5
        s += 1
    scale = 0.5**s
    q = PS_BLOCK
    # powers[k] = X^(k+1) (rows 6-8 zero: the product's β is 0)
    for i in range(NM):
        for j in range(NZ):
            powers[0, i, j] = scale * f[i, j]
    for k in range(1, q):
        mul_top(powers[0], powers[k - 1], 0.0, powers[k])
    top = TAYLOR_ORDER // q
    # Horner in X^q over the blocks B_j, top one first; the running
    # polynomial's rows 6-8 are beta [0 | I] (beta = 1/(jq)!).
    beta = 0.0
    for jb in range(top, -1, -1):
        c = 1.0
        for k in range(2, jb * q + 1):
            c /= k
        if jb == top:
            for i in range(NM):
                for j in range(NZ):
                    out[i, j] = 0.0
        else:
            mul_top(powers[q - 1], out, beta, tmp)
            copy_top(tmp, out)
        beta = c
        for i in range(NM):
            out[i, i] += c
        for k in range(1, q):
            if jb * q + k > TAYLOR_ORDER:
                break
            c /= jb * q + k
            xk = powers[k - 1]
            for i in range(NM):
                for j in range(NZ):
                    out[i, j] += c * xk[i, j]
    for _ in range(s):
        mul_top(out, out, 1.0, tmp)
        copy_top(tmp, out)


@kernel
def power_rows(
    sv: np.ndarray, sv_tmp: np.ndarray, squares: np.ndarray, n: int, k: int
) -> None:  # pragma: no cover - compiled
    """``sv`` ← ``sv`` times e^{FΔ 2^j} for every set bit j ≥ k of n (``squares[j]``)."""
    while n >> k > 0:
        if (n >> k) & 1 == 1:
            mul_top(sv, squares[k], 1.0, sv_tmp)
            copy_top(sv_tmp, sv)
        k += 1
