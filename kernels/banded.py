"""Symmetric banded LDL^T (no pivoting) for the tangent stiffness, with its inertia.

Storage: the lower band of a symmetric matrix, column by column: ``ab`` of shape ``(n, kl + 1)``
with ``A[i, j] = ab[j, i - j]`` for ``0 <= i - j <= kl`` (the transpose of LAPACK's ``'L'`` band
storage, so that the inner loops run over contiguous memory).

No pivoting: like the LDL^T solvers of commercial FE codes, the factorisation relies on the
stiffness matrix being symmetric with few negative eigenvalues; a pivot that is zero to round-off
is reported as a failure (the continuation then cuts its step). The number of negative pivots is
the number of negative eigenvalues of ``K_T`` (Sylvester's law of inertia), which tells stable
from unstable equilibria.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def band_ldlt(ab: np.ndarray):
    """Factorise in place: on return ``ab[:, 0]`` holds ``D`` and ``ab[:, 1:]`` the unit-lower ``L``.

    Returns
    -------
    (ok, n_negative) : (bool, int)
    """
    n, m1 = ab.shape
    kl = m1 - 1
    scale = 0.0
    for j in range(n):
        a = abs(ab[j, 0])
        if a > scale:
            scale = a
    tiny = 1e-14 * scale
    nneg = 0
    l = np.empty(kl + 1)
    for j in range(n):
        d = ab[j, 0]
        if not (abs(d) > tiny):
            return False, nneg
        if d < 0.0:
            nneg += 1
        m = min(kl, n - 1 - j)
        for i in range(1, m + 1):
            l[i] = ab[j, i] / d
        # trailing update: A[j+k, j+i] -= l_k d l_i for k >= i
        for i in range(1, m + 1):
            f = l[i] * d
            row = ab[j + i]  # a contiguous row view lets the inner loop vectorise
            for k in range(i, m + 1):
                row[k - i] -= l[k] * f
        for i in range(1, m + 1):
            ab[j, i] = l[i]
    return True, nneg


@njit(cache=True)
def band_ldlt_solve(fac: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``A x = b`` with the factors from :func:`band_ldlt`."""
    n, m1 = fac.shape
    kl = m1 - 1
    x = b.copy()
    for j in range(n):  # L y = b
        xj = x[j]
        for i in range(1, min(kl, n - 1 - j) + 1):
            x[j + i] -= fac[j, i] * xj
    for j in range(n):  # D z = y
        x[j] /= fac[j, 0]
    for j in range(n - 1, -1, -1):  # L^T x = z
        s = x[j]
        for i in range(1, min(kl, n - 1 - j) + 1):
            s -= fac[j, i] * x[j + i]
        x[j] = s
    return x


@njit(cache=True)
def sym_band_matvec(ab: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``A @ x`` for the symmetric matrix whose lower band is ``ab`` (unfactorised)."""
    n, m1 = ab.shape
    kl = m1 - 1
    y = np.zeros(n)
    for j in range(n):
        y[j] += ab[j, 0] * x[j]
        for i in range(1, min(kl, n - 1 - j) + 1):
            a = ab[j, i]
            y[j + i] += a * x[j]
            y[j] += a * x[j + i]
    return y
